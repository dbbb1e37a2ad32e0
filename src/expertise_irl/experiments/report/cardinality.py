"""The ``cardinality`` report (paper Sec. VI-E, Table III): the discrete set as Ψ_k grows."""

from __future__ import annotations

from . import claim_kinds as K
from . import claims as C
from . import figures as F
from .capped import capped_section, capped_shares, last_rows
from .conditions_claims import COLUMNS
from .fixed_vs_joint import PERSON
from .parts import Figure, Report
from .stats import METRIC_AXES, METRIC_RANGE, METRICS
from .sweep import protocol_note, require_columns
from .tables import PearsonRow, means_table, pearson_cell, pearson_table

NEEDED = [*PERSON, "condition", "episodes", "n_capped", "n_hypotheses", "group_true", *METRICS]
TRUTHS = {"in_set": "In set (θ*_in, β*_in)", "out_of_set": "Out of set (θ*_out, β*_out)"}
TRUTH_COLORS = {"in_set": F.GREEN, "out_of_set": F.ORANGE}


def figure(at_n, n: int) -> Figure:
    fig, axes = F.new_figure(3, width=3.4, height=3.4)
    truths = [t for t in TRUTHS if (at_n["truth"] == t).any()]
    def per_k(t):
        counts = sorted(set(at_n[at_n["truth"] == t].drop_duplicates(PERSON).groupby("k").size()))
        return str(counts[0]) if len(counts) == 1 else f"{counts[0]}–{counts[-1]}"

    labels = {t: f"{TRUTHS[t].split(' (')[0].lower()} (n = {per_k(t)} per k)" for t in truths}
    for ax, metric in zip(axes, ["policy_regret", "cosine_similarity", "expertise_distance"], strict=True):
        F.bands(ax, at_n, "k", metric, "truth", truths, TRUTH_COLORS, labels, legend=False,
                bounds=METRIC_RANGE[metric])
        ax.set_xlabel("k (|Ψ_k| = 6k)")
        ax.set_ylabel(METRIC_AXES[metric])
        ax.set_xticks(sorted(at_n["k"].unique()))
    F.figure_legend(fig, F.lines(truths, TRUTH_COLORS, labels))
    fig.suptitle(f"Metrics vs k after {n} episodes, Full set, one environment", fontsize=11)
    return Figure("fig_cardinality", "Metrics vs the cardinality of Ψ_k",
                  f"Full-set rows at episodes = {n}, in-set and out-of-set people, all runs and expertise "
                  f"groups combined; lines are means per k, bands {F.CI_TEXT}; n = people at each k.", fig)


#: Table III as printed: {truth: (cosine, distance, regret)}.
TABLE3 = {"in_set": ("0.03", "0.04", "0.14†"), "out_of_set": ("0.20†", "0.06", "−0.12†")}
#: The ids of Table III's cells; the three the report judged first keep their ids.
CELL_IDS = {("in_set", "policy_regret"): "VI-E-card-in-regret",
            ("out_of_set", "cosine_similarity"): "VI-E-card-out-cosine",
            ("out_of_set", "policy_regret"): "VI-E-card-out-regret"}


def table3(at_n, n: int):
    return pearson_table(
        "table3", "Table III: metrics vs the cardinality of Ψ_k",
        f"Full-set rows at episodes = {n}, factor n_hypotheses (|Ψ_k| = 6k) against each metric, per "
        "inference case.",
        [PearsonRow(label, at_n[at_n["truth"] == t], "n_hypotheses") for t, label in TRUTHS.items()],
        first="Inference case")


def claims(at_n, n: int, table=None) -> list[C.ClaimResult]:
    """Every cell of Table III (``table``: the table if built)."""
    table = table if table is not None else table3(at_n, n)
    label_truth = {label: t for t, label in TRUTHS.items()}
    out = []
    for rec in table.data.to_dict("records"):
        truth = label_truth[rec["row"]]
        metric = rec["metric"]
        paper = dict(zip(METRICS, TABLE3[truth], strict=True))[metric]
        part, name = COLUMNS[metric]
        cid = CELL_IDS.get((truth, metric), f"T3-{truth}-{part}")
        who = "in-set" if truth == "in_set" else "out-of-set"
        out.append(K.cell_claim(cid, "VI-E", "Table III", rec["row"], name, paper, rec,
                                f"the {who} Full-set rows at {n} episodes, factor |Ψ_k|"))
    order = {**{v: i for i, v in enumerate(CELL_IDS.values())}}
    return sorted(out, key=lambda c: order.get(c.id, len(order)))


def build(sweep) -> Report:
    require_columns(sweep, NEEDED, f"{sweep.root}/rows")
    rows = sweep.rows[sweep.rows["condition"] == "full"]
    n = int(sweep.config.get("episodes", rows["episodes"].max()))
    at_n = rows[rows["episodes"] == n]
    ks = sorted(at_n["k"].unique())
    report = Report("cardinality", "Report: `cardinality` (paper Sec. VI-E, Table III)")
    model = sweep.config.get("model", "maxent")
    report.notes.append(
        f"Full set only, k ∈ {{{', '.join(map(str, ks))}}} (|Ψ_k| = 6k), "
        f"{sweep.config.get('environments', 1)} environment(s), {n} episodes; observation model `{model}`"
        + (" (the paper's)." if model == "maxent" else " (not the paper's maxent)."))
    report.notes.append(protocol_note(sweep))
    report.people = len(rows.drop_duplicates(PERSON))
    table = table3(at_n, n)
    report.claims = claims(at_n, n, table)
    report.figures = [figure(at_n, n)]
    report.tables.append(table)
    report.tables.append(means_table("cardinality_means", "Metrics per k",
                                     f"Full-set rows at episodes = {n}.",
                                     at_n.sort_values(["truth", "k"], kind="stable"), ["truth", "k"]))
    last = last_rows(rows, PERSON)
    report.sections.append(capped_section(last, capped_effect(at_n, last), by=["truth"], model=model,
                                          max_steps=sweep.config.get("max_steps")))
    return report


def capped_effect(at_n, last) -> str:
    """Table III's in-set regret row, split by expertise group, beside each group's capped share."""
    from ...hypotheses import GROUP_NAMES as GROUPS
    from .stats import fmt

    inn = at_n[at_n["truth"] == "in_set"]
    shares = capped_shares(last[last["truth"] == "in_set"])
    parts = []
    for g in GROUPS:
        sub = inn[inn["group_true"] == g]
        if len(sub):
            cell = pearson_cell(sub["n_hypotheses"], sub["policy_regret"])
            parts.append(f"{g} ρ = {cell.text} (mean regret {fmt(sub['policy_regret'].mean())}, "
                         f"{shares.get(g, float('nan')):.0%} of episodes capped)")
    if not parts:
        return ""
    return ("Table III's in-set regret row per expertise group: " + "; ".join(parts) + ". For a person with "
            "a large β the soft values are dominated by the entropy term, so a capped group's regret "
            "has little room to move with Ψ_k (compare the mean regrets).")
