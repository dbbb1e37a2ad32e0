"""The ``cardinality`` report (paper Sec. VI-E, Table III): the discrete set as Ψ_k grows."""

from __future__ import annotations

from . import claims as C
from . import figures as F
from .capped import capped_section, capped_shares, last_rows
from .fixed_vs_joint import PERSON
from .parts import Figure, Report
from .stats import METRIC_AXES, METRIC_RANGE, METRICS
from .sweep import require_columns
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


def claims(at_n, n: int) -> list[C.ClaimResult]:
    inn, out = at_n[at_n["truth"] == "in_set"], at_n[at_n["truth"] == "out_of_set"]
    return [
        C.correlation_claim("VI-E-card-in-regret", "VI-E", f"in-set regret grows with |Ψ_k| ({n} episodes)",
                            "ρ = 0.14†", inn["n_hypotheses"], inn["policy_regret"], "|Ψ_k|", "regret",
                            claimed="positive"),
        C.correlation_claim("VI-E-card-out-cosine", "VI-E",
                            f"out-of-set cosine grows with |Ψ_k| ({n} episodes)",
                            "ρ = 0.20†", out["n_hypotheses"], out["cosine_similarity"], "|Ψ_k|",
                            "cosine similarity", claimed="positive"),
        C.correlation_claim("VI-E-card-out-regret", "VI-E",
                            f"out-of-set regret falls with |Ψ_k| ({n} episodes)",
                            "ρ = −0.12†", out["n_hypotheses"], out["policy_regret"], "|Ψ_k|", "regret",
                            claimed="negative"),
    ]


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
    report.people = len(rows.drop_duplicates(PERSON))
    report.claims = claims(at_n, n)
    report.figures = [figure(at_n, n)]
    report.tables.append(pearson_table(
        "table3", "Table III: metrics vs the cardinality of Ψ_k",
        f"Full-set rows at episodes = {n}, factor n_hypotheses (|Ψ_k| = 6k) against each metric, per "
        "inference case.",
        [PearsonRow(label, at_n[at_n["truth"] == t], "n_hypotheses") for t, label in TRUTHS.items()],
        first="Inference case"))
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
