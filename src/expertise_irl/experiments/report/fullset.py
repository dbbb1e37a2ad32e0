"""The ``fullset`` report (beyond the paper): does the whole paper-sim set close the out-of-set gap?"""

from __future__ import annotations

import numpy as np

from . import figures as F
from .capped import capped_section, capped_shares, last_rows
from .parts import Figure, Report, Table
from .stats import HIGHER_IS_BETTER, METRIC_AXES, METRIC_RANGE, METRICS, fmt, mean_ci
from .sweep import require_columns
from .tables import means_table

SLOT = ["source", "environment", "run", "k", "group", "instance"]
#: A person: their slot and whether their truth is in their Ψ_k (conditions' in- and out-of-set
#: people share a slot).
PERSON = [*SLOT, "truth"]
NEEDED = [*SLOT, "set", "episodes", "n_capped", "n_hypotheses", "group_true", "truth_probability",
          "set_solve_time_s", *METRICS]
SETS = {"theta_k": "own Ψ_k", "full": "full set"}
SET_COLORS = {"theta_k": F.GREEN, "full": F.ORANGE}
TRUTH_LABELS = {"in_set": "in-set", "out_of_set": "out-of-set"}
GAP_RULE = ("Gap rule: the out-of-set gap of a metric is the out-of-set people's mean under their own "
            "Ψ_k minus the in-set people's mean under theirs (the reference, with its 95% CI). If the "
            "out-of-set mean under Ψ_k is already as good as the reference's 95% CI bound on the worse "
            "side there is *no gap* (beyond the in-set CI); otherwise the full set *closes* it if the "
            "out-of-set mean under the full set is that good; *narrows* it if it is better than under "
            "Ψ_k but not that good; otherwise it does *not narrow* it. Share closed = 1 − (full-set gap / "
            "Ψ_k gap).")


def with_truth(rows):
    """Rows with a ``truth`` column: as given, or in_set where the slot's Ψ_k holds the exact truth.

    Without the column each slot must hold one person (its Ψ_k rows say whether the truth is in it).
    """
    if "truth" in rows.columns:
        return rows
    own = rows[rows["set"] == "theta_k"]
    inset = own.groupby(SLOT, observed=True)["truth_probability"].apply(lambda s: s.notna().any())
    truth = inset.map({True: "in_set", False: "out_of_set"}).rename("truth").reset_index()
    return rows.merge(truth, on=SLOT, how="left")


def source_episodes(rows) -> dict[str, int]:
    """Each source's largest episode count that all its people reach (conditions' in-set low-expertise
    people may show more episodes than the rest)."""
    per_person = rows.groupby(PERSON, observed=True)["episodes"].max().reset_index()
    return {str(s): int(v) for s, v in per_person.groupby("source")["episodes"].min().items()}


def at_max(rows):
    """Each source's rows at that source's :func:`source_episodes`."""
    top = rows["source"].map(source_episodes(rows))
    return rows[rows["episodes"] == top]


def _cases(at) -> list[tuple[str, str]]:
    seen = at.drop_duplicates(["source", "truth"])
    order = {"in_set": 0, "out_of_set": 1}
    return sorted(((r.source, r.truth) for r in seen.itertuples()), key=lambda c: (c[0], order.get(c[1], 9)))


def figure(at) -> Figure:
    cases = _cases(at)
    names = [f"{s}\n{TRUTH_LABELS.get(t, t)}" for s, t in cases]
    fig, axes = F.new_figure(3, width=3.9, height=3.6)
    for ax, metric in zip(axes, ["policy_regret", "cosine_similarity", "expertise_distance"], strict=True):
        series = {st: {name: at.loc[(at["source"] == s) & (at["truth"] == t) & (at["set"] == st), metric]
                       for name, (s, t) in zip(names, cases, strict=True)} for st in SETS}
        log = metric == "policy_regret" and F.needs_log(at.groupby(["source", "truth", "set"])[metric].mean())
        F.ci_bars(ax, names, series, SET_COLORS, SETS, log=log, bounds=METRIC_RANGE[metric])
        ax.tick_params(axis="x", labelsize=8)
        ax.set_ylabel(METRIC_AXES[metric] + (" (log scale)" if log else ""))
    people = {c: len(at[(at["source"] == c[0]) & (at["truth"] == c[1])].drop_duplicates(PERSON))
              for c in cases}
    n_text = ", ".join(f"{s} {TRUTH_LABELS.get(t, t)} {people[(s, t)]}" for s, t in cases)
    tops = ", ".join(f"{s} {n}" for s, n in source_episodes(at).items())
    fig.suptitle(f"Own Ψ_k vs the full set after {tops} episodes (people: {n_text})",
                 fontsize=10)
    return Figure("fig_fullset", "Own Ψ_k vs the full paper-sim set",
                  "Rows at each source's largest episode count that all its people reach, every person "
                  "scored under their own Ψ_k and under the full set on the same episodes; bars are means, "
                  f"error bars {F.CI_TEXT}.", fig)


def cost_table(rows) -> Table:
    import pandas as pd

    full = rows[rows["set"] == "full"]
    data = []
    for e, g in full.groupby("environment", sort=True):
        people = len(g.drop_duplicates(PERSON))
        t = float(g["set_solve_time_s"].iloc[0])
        data.append({"environment": int(e), "n_hypotheses": int(g["n_hypotheses"].max()),
                     "set_solve_time_s": t, "people_served": people,
                     "solve_s_per_person": t / people if people else np.nan})
    data = pd.DataFrame(data)
    if len(data):
        total = {"environment": "all", "n_hypotheses": int(data["n_hypotheses"].max()),
                 "set_solve_time_s": float(data["set_solve_time_s"].sum()),
                 "people_served": int(data["people_served"].sum())}
        total["solve_s_per_person"] = total["set_solve_time_s"] / max(total["people_served"], 1)
        data = pd.concat([data, pd.DataFrame([total])], ignore_index=True)
    display = data.copy()
    for c in ("set_solve_time_s", "solve_s_per_person"):
        if c in display:
            display[c] = display[c].map(fmt)
    return Table("fullset_cost", "Cost of the full set",
                 "One solve of the full set per map (`set_solve_time_s`, the same on every row of the map) "
                 "serves every person on that map, from both sources.", display, data)


def gap_sentences(at) -> tuple[str, list[dict]]:
    """Whether the full set closes each source's out-of-set gap, per metric (see :data:`GAP_RULE`)."""
    ref_rows = at[(at["truth"] == "in_set") & (at["set"] == "theta_k")]
    if not len(ref_rows):
        return "No in-set people: there is no reference to measure the out-of-set gap against.", []
    records, sentences = [], []
    for source in sorted(at.loc[at["truth"] == "out_of_set", "source"].unique()):
        own_ref = ref_rows[ref_rows["source"] == source]
        ref_src = source if len(own_ref) else str(ref_rows["source"].iloc[0])
        ref = own_ref if len(own_ref) else ref_rows
        out = at[(at["source"] == source) & (at["truth"] == "out_of_set")]
        parts = []
        for metric in METRICS:
            r = mean_ci(ref[metric])
            k = out.loc[out["set"] == "theta_k", metric].mean()
            f = out.loc[out["set"] == "full", metric].mean()
            better = HIGHER_IS_BETTER[metric]
            bound = r.low if better else r.high
            if not np.isfinite(bound):
                bound = r.mean
            closes = f >= bound if better else f <= bound
            improves = f > k if better else f < k
            gap_k, gap_f = k - r.mean, f - r.mean
            share = 1 - gap_f / gap_k if gap_k != 0 else np.nan
            no_gap = (k >= bound) if better else (k <= bound)
            if no_gap:  # out of set is already as good as in set under Ψ_k
                verdict, share = "no gap (within the in-set 95% CI)", np.nan
            else:
                verdict = "closes" if closes else "narrows" if improves else "does not narrow"
            records.append({"source": source, "reference": ref_src, "metric": metric,
                            "in_set_theta_k": r.mean, "in_set_ci_low": r.low, "in_set_ci_high": r.high,
                            "out_of_set_theta_k": k,
                            "out_of_set_full": f, "share_closed": share, "verdict": verdict})
            name = METRICS[metric].lower()
            head = (f"{name}: the full set {verdict} the gap" if not no_gap
                    else f"{name}: no gap beyond the in-set 95% CI")
            parts.append(f"{head} ({fmt(k)} → {fmt(f)} against "
                         f"in-set {fmt(r.mean)}" + (f", {share:.0%} closed)" if np.isfinite(share) else ")"))
        ref_text = "" if ref_src == source else f" (reference: the {ref_src} study's in-set people)"
        sentences.append(f"For the {source} study's out-of-set people{ref_text}, own Ψ_k → full set: "
                         + "; ".join(parts) + ".")
    return " ".join(sentences), records


def build(sweep) -> Report:
    import pandas as pd

    require_columns(sweep, NEEDED, f"{sweep.root}/rows")
    rows = with_truth(sweep.rows)
    at = at_max(rows)
    report = Report("fullset", "Report: `fullset` (beyond the paper: the full paper-sim set)")
    tops = source_episodes(rows)
    full = rows.loc[rows["set"] == "full", "n_hypotheses"]
    n_full = int(full.max()) if len(full) else 0
    report.notes.append(
        f"Every person is scored under their own Ψ_k (`theta_k`) and under the full set (`full`, {n_full:,} "
        "hypotheses) on the same episodes. Compared at each source's largest episode count that all its "
        "people reach: " + ", ".join(f"{s} {n}" for s, n in tops.items()) + ".")
    gap_text, gap_records = gap_sentences(at)
    report.notes.append(gap_text)
    report.rules.append(GAP_RULE + "\n")
    report.figures = [figure(at)]
    order = {"theta_k": 0, "full": 1}
    shown = at.sort_values(["source", "truth", "set"], key=lambda s: s.map(order) if s.name == "set" else s,
                           kind="stable")
    report.tables.append(means_table("fullset_means", "Metrics with own Ψ_k vs the full set",
                                     "Rows at each source's largest episode count.", shown,
                                     ["source", "truth", "set"]))
    if gap_records:
        data = pd.DataFrame(gap_records)
        display = data.assign(**{c: data[c].map(fmt) for c in ("in_set_theta_k", "out_of_set_theta_k",
                                                               "out_of_set_full")},
                              metric=data["metric"].map(METRICS),
                              share_closed=data["share_closed"].map(
                                  lambda x: f"{x:.0%}" if np.isfinite(x) else "n/a"))
        display = display.drop(columns=["in_set_ci_low", "in_set_ci_high"])
        report.tables.append(Table("fullset_gap", "The out-of-set gap, own Ψ_k vs the full set",
                                   "Per source and metric, by the gap rule above.", display, data))
    report.tables.append(cost_table(rows))
    last = last_rows(rows[rows["set"] == "full"], PERSON)
    report.sections.append(capped_section(last, capped_effect(at, last), by=["source"]))
    return report


def capped_effect(at, last) -> str:
    """Per expertise group: capped share and the β distance under Ψ_k and the full set."""
    from .stats import GROUPS

    shares = capped_shares(last)
    parts = []
    for g in GROUPS:
        sub = at[at["group_true"] == g]
        if len(sub) and g in shares:
            k = sub.loc[sub["set"] == "theta_k", "expertise_distance"].mean()
            f = sub.loc[sub["set"] == "full", "expertise_distance"].mean()
            parts.append(f"{g} {fmt(k)} → {fmt(f)} ({shares[g]:.0%} capped)")
    if not parts:
        return ""
    return ("Mean |β* − β̂| per expertise group, own Ψ_k → full set: " + ", ".join(parts) + ". The full set "
            "adds θ directions, not β values (B is the same six values in both), so what it can change in "
            "β̂ comes through θ̂ alone.")
