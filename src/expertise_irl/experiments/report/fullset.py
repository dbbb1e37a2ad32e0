"""The ``fullset`` report (beyond the paper): does the whole paper-sim set close the out-of-set gap?"""

from __future__ import annotations

import re

import numpy as np

from . import figures as F
from .capped import capped_section, capped_shares, last_rows
from .parts import Figure, Report, Table
from .regrets import regrets_section
from .stats import (
    HIGHER_IS_BETTER,
    METRIC_AXES,
    METRIC_RANGE,
    METRICS,
    fmt,
    fmt_p,
    mean_ci,
    paired,
    wilcoxon_p,
)
from .sweep import protocol_note, require_columns
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


def _environment_of(task: str) -> int | None:
    """The map of a fullset task key (``e003`` -> 3)."""
    m = re.fullmatch(r"e(\d+)", str(task))
    return int(m.group(1)) if m else None


def cost_table(rows, timings) -> Table:
    """Per map: the full set's solve(s), the whole task's wall time and the people it served."""
    import pandas as pd

    full = rows[rows["set"] == "full"]
    tasks = {}
    if "task" in getattr(timings, "columns", ()):
        for t in timings.itertuples():
            e = _environment_of(t.task)
            if e is not None:
                tasks[e] = t._asdict()
    data = []
    for e, g in full.groupby("environment", sort=True):
        people = len(g.drop_duplicates(PERSON))
        task = tasks.get(int(e), {})
        # the timings' sum over the task's solves; else the distinct solve times its rows carry
        solve = task.get("set_solve_time_s", float(np.sum(g["set_solve_time_s"].unique())))
        solves = task.get("set_solves", g["set_solve_time_s"].nunique())
        wall = task.get("wall_time_s", np.nan)
        data.append({"environment": int(e), "n_hypotheses": int(g["n_hypotheses"].max()),
                     "set_solves": int(solves), "set_solve_time_s": float(solve),
                     "task_wall_time_s": float(wall), "people_served": people,
                     "solve_s_per_person": solve / people if people else np.nan,
                     "task_s_per_person": wall / people if people else np.nan})
    data = pd.DataFrame(data)
    if len(data):
        total = {"environment": "all", "n_hypotheses": int(data["n_hypotheses"].max()),
                 "set_solves": int(data["set_solves"].sum()),
                 "set_solve_time_s": float(data["set_solve_time_s"].sum()),
                 "task_wall_time_s": float(data["task_wall_time_s"].sum(min_count=len(data))),
                 "people_served": int(data["people_served"].sum())}
        total["solve_s_per_person"] = total["set_solve_time_s"] / max(total["people_served"], 1)
        total["task_s_per_person"] = total["task_wall_time_s"] / max(total["people_served"], 1)
        data = pd.concat([data, pd.DataFrame([total])], ignore_index=True)
    display = data.copy()
    for c in ("set_solve_time_s", "task_wall_time_s", "solve_s_per_person", "task_s_per_person"):
        if c in display:
            display[c] = display[c].map(fmt)
    return Table("fullset_cost", "Cost of the full set",
                 "Per map (one task each): `set_solve_time_s` is the full set's solve on the map (two "
                 "where the sources' maps differ in size), timed around the solve alone and including "
                 "JAX's compilation of that shape on its first use in the task's process (no warm-up "
                 "solve is run first), so it overstates a warm solve; `task_wall_time_s` is the whole "
                 "task from the timings table: the solve(s) plus scoring every person on the map (belief "
                 "updates under the full set and under their Ψ_k, and the regret solves). Per person: "
                 "each divided by the people the map served, from both sources. n/a where the timings "
                 "table lacks the task.", display, data)


def beta_text(frame) -> str:
    """How the people of ``frame`` draw β*: the values (with counts) if few, else their range."""
    people = frame.drop_duplicates(PERSON)
    if "beta_true" not in people.columns or not len(people):
        return "β* not in the rows"
    b = people["beta_true"].round(6)
    values = b.value_counts().sort_index()
    if len(values) <= 6:
        return "β* ∈ {" + ", ".join(f"{fmt(v)} ×{c}" for v, c in values.items()) + "}"
    return f"β* from {fmt(b.min())} to {fmt(b.max())}, median {fmt(b.median())}"


def _people_text(frame, n: int) -> str:
    return f"{len(frame.drop_duplicates(PERSON))} people, {n} episodes, {beta_text(frame)}"


def gap_sentences(at) -> tuple[str, list[dict]]:
    """Whether the full set closes each source's out-of-set gap, per metric (see :data:`GAP_RULE`),
    and what the full set does to the in-set reference people themselves."""
    ref_rows = at[(at["truth"] == "in_set") & (at["set"] == "theta_k")]
    if not len(ref_rows):
        return "No in-set people: there is no reference to measure the out-of-set gap against.", []
    tops = source_episodes(at)
    records, sentences = [], []
    for source in sorted(at.loc[at["truth"] == "out_of_set", "source"].unique()):
        own_ref = ref_rows[ref_rows["source"] == source]
        ref_src = source if len(own_ref) else str(ref_rows["source"].iloc[0])
        ref = own_ref if len(own_ref) else ref_rows
        ref_full = at[(at["source"] == ref_src) & (at["truth"] == "in_set") & (at["set"] == "full")]
        out = at[(at["source"] == source) & (at["truth"] == "out_of_set")]
        parts = []
        for metric in METRICS:
            r = mean_ci(ref[metric])
            rf = ref_full[metric].mean()
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
                            "in_set_full": rf, "out_of_set_theta_k": k,
                            "out_of_set_full": f, "share_closed": share, "verdict": verdict})
            name = METRICS[metric].lower()
            head = (f"{name}: the full set {verdict} the gap" if not no_gap
                    else f"{name}: no gap beyond the in-set 95% CI")
            parts.append(f"{head} ({fmt(k)} → {fmt(f)} against "
                         f"in-set {fmt(r.mean)}" + (f", {share:.0%} closed)" if np.isfinite(share) else ")"))
        who = f"{source} study's out-of-set people ({_people_text(out, tops[source])})"
        if ref_src == source:
            ref_text = f"; reference: its in-set people ({_people_text(ref, tops[ref_src])})"
        else:
            ref_text = (f"; reference, from another protocol: the {ref_src} study's in-set people "
                        f"({_people_text(ref, tops[ref_src])})")
        sentences.append(f"For the {who}{ref_text}, own Ψ_k → full set: " + "; ".join(parts) + ".")
    for ref_src in sorted(ref_rows["source"].unique()):
        sentences.append(inset_cost(at, ref_src))
    return " ".join(sentences), records


def inset_cost(at, source: str) -> str:
    """What the full set does to the in-set people of ``source`` (whose truth is in their Ψ_k)."""
    inset = at[(at["source"] == source) & (at["truth"] == "in_set")]
    worse, same = [], []
    for metric in METRICS:
        p = paired(inset, PERSON, "set", metric, "theta_k", "full")
        k, f = float(p["theta_k"].mean()), float(p["full"].mean())
        text = f"{METRICS[metric].lower()} {fmt(k)} → {fmt(f)} (paired Wilcoxon p = " \
               f"{fmt_p(wilcoxon_p(p['full'], p['theta_k']))}, {len(p)} people)"
        is_worse = f < k if HIGHER_IS_BETTER[metric] else f > k
        (worse if is_worse else same).append(text)
    text = f"The {source} study's in-set people, own Ψ_k → full set: "
    if worse:
        text += ("the full set makes them worse on " + "; ".join(worse)
                 + (f"; not worse on {'; '.join(same)}" if same else "")
                 + ": the hypotheses it adds compete with their true one.")
    else:
        text += "the full set leaves them no worse: " + "; ".join(same) + "."
    return text


def build(sweep) -> Report:
    import pandas as pd

    require_columns(sweep, NEEDED, f"{sweep.root}/rows")
    rows = with_truth(sweep.rows)
    at = at_max(rows)
    report = Report("fullset", "Report: `fullset` (beyond the paper: the full paper-sim set)")
    report.notes.append(protocol_note(sweep))
    report.people = len(rows.drop_duplicates(PERSON))
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
        nums = ("in_set_theta_k", "in_set_full", "out_of_set_theta_k", "out_of_set_full")
        display = data.assign(**{c: data[c].map(fmt) for c in nums}, metric=data["metric"].map(METRICS),
                              share_closed=data["share_closed"].map(
                                  lambda x: f"{x:.0%}" if np.isfinite(x) else "n/a"))
        display = display.drop(columns=["in_set_ci_low", "in_set_ci_high"]).rename(columns={
            "in_set_theta_k": "in-set, own Ψ_k", "in_set_full": "in-set, full set",
            "out_of_set_theta_k": "out-of-set, own Ψ_k", "out_of_set_full": "out-of-set, full set",
            "share_closed": "share closed"})
        report.tables.append(Table("fullset_gap", "The out-of-set gap, own Ψ_k vs the full set",
                                   "Per source and metric, by the gap rule above; the reference is the "
                                   "in-set people under their own Ψ_k, and \"in-set, full set\" the same "
                                   "people under the full set.", display, data))
    report.tables.append(cost_table(rows, sweep.timings))
    last = last_rows(rows[rows["set"] == "full"], PERSON)
    report.sections.append(capped_section(last, capped_effect(at, last), by=["source", "truth"],
                                          max_steps=source_caps(sweep.config)))
    report.sections.append(regrets_section(at, PERSON, "set"))
    return report


def source_caps(config) -> dict[str, int]:
    """Each source study's ``max_steps`` at the sweep's ``source_scale`` (the fullset study rebuilds
    its people from those named scales); empty where the scale is not one of them."""
    from ..studies import fixed_vs_joint as cond
    from ..studies import optimisation as opt

    scale = config.get("source_scale")
    out = {}
    for name, module in (("conditions", cond), ("optimisation", opt)):
        cfg = module.SCALES.get(scale) if isinstance(scale, str) else None
        if cfg is not None and name in config.get("sources", (name,)):
            out[name] = int(cfg.max_steps)
    return out


def capped_effect(at, last) -> str:
    """Per population (source and truth): the mean β distance of each expertise group under Ψ_k and
    under the full set, one sentence each (the capped shares are in the sentences before)."""
    from ...hypotheses import GROUP_NAMES as GROUPS
    from .capped import population

    pops = []
    for (source, truth), sub_last in last.groupby(["source", "truth"], sort=True, observed=True):
        shares = capped_shares(sub_last)
        sub_at = at[(at["source"] == source) & (at["truth"] == truth)]
        parts = []
        for g in GROUPS:
            sub = sub_at[sub_at["group_true"] == g]
            if len(sub) and g in shares:
                k = sub.loc[sub["set"] == "theta_k", "expertise_distance"].mean()
                f = sub.loc[sub["set"] == "full", "expertise_distance"].mean()
                parts.append(f"{g} {fmt(k)} → {fmt(f)}")
        if parts:
            pops.append(f"For {population({'source': source, 'truth': truth})}: " + ", ".join(parts) + ".")
    if not pops:
        return ""
    return ("Mean |β* − β̂| per expertise group, own Ψ_k → full set. " + " ".join(pops) + " The full set "
            "adds θ directions, not β values (B is the same six values in both), so what it can change in "
            "β̂ comes through θ̂ alone.")
