"""The ``conditions`` report (paper Secs. VI-A–E): Figs. 2–7, Tables I–II and the claims of Sec. VI."""

from __future__ import annotations

import numpy as np

from ...hypotheses import EXPERTISE_GROUPS, GROUP_BOUNDARIES
from ...hypotheses import GROUP_NAMES as GROUPS
from . import figures as F
from .capped import capped_section, capped_shares, last_rows
from .conditions_claims import PERSON, V2, claims, table1, table2
from .parts import Figure, Report
from .regret_scale import random_theta_section
from .regrets import regrets_section
from .stats import METRIC_AXES, METRIC_RANGE, METRICS
from .sweep import protocol_note, require_columns
from .tables import means_table

__all__ = ["PERSON", "V2", "build", "claims"]
NEEDED = [*PERSON, "condition", "episodes", "n_capped", "n_states", "n_hypotheses", "group_true",
          "group_hat", *METRICS]


def _spread_text() -> str:
    spans = [f"{max(b) - min(b):g} for {g} ({', '.join(f'{x:g}' for x in b)})"
             for g, b in EXPERTISE_GROUPS.items()]
    return ("The largest distance between two β values of the same group is " + ", ".join(spans[:-1])
            + f" and {spans[-1]}: a |β* − β̂| above it means β̂ left β*'s group (it lies outside the range "
            "of that group's β values).")


#: Fig. 2's reading of its y axes: how far apart the β values of one expertise group lie.
GROUP_SPREAD_TEXT = _spread_text()


def _groups(frame) -> list[str]:
    present = set(frame["group_true"])
    return [g for g in GROUPS if g in present]


def episodes_of(sweep) -> tuple[int, int]:
    """(N, N_low): the config's episode counts (falling back to what the rows hold)."""
    rows, cfg = sweep.rows, sweep.config
    n = int(cfg.get("episodes", rows.loc[rows["truth"] == "out_of_set", "episodes"].max()
                    if (rows["truth"] == "out_of_set").any() else rows["episodes"].max()))
    return n, int(cfg.get("low_episodes", rows["episodes"].max()))


def _people(frame) -> int:
    return len(frame.drop_duplicates(PERSON))


# ------------------------------------------------------------------------------- figures
def fig2(inset_n, n: int) -> Figure:
    groups = _groups(inset_n)
    fig, axes = F.new_figure(len(groups), width=3.3, height=3.4)
    for ax, g in zip(axes, groups, strict=True):
        sub = inset_n[inset_n["group_true"] == g]
        F.violins(ax, [g], ["full", "fixed_theta"],
                  lambda _g, c, sub=sub: sub.loc[sub["condition"] == c, "expertise_distance"],
                  F.CONDITION_COLORS, F.CONDITION_LABELS, legend=False)
        ax.set_xticks([])
        ax.set_title(f"{g} expertise (n = {_people(sub[sub['condition'] == 'full'])} people)", fontsize=10)
        ax.set_ylabel(METRIC_AXES["expertise_distance"])
    F.figure_legend(fig, F.patches(["full", "fixed_theta"], F.CONDITION_COLORS, F.CONDITION_LABELS))
    fig.suptitle(f"Fig. 2: expertise distance after {n} episodes, in-set people", fontsize=11)
    return Figure("fig2", "Fig. 2: expertise distance, Full set vs Fixed θ set",
                  f"In-set rows (truth = in_set) at episodes = {n}, conditions `full` and `fixed_theta`, all "
                  "environments, runs and k combined; one violin per expertise group of β* and condition "
                  "(density, quartiles as a black bar, median as a white dot). Panels have their own "
                  f"y scale. {GROUP_SPREAD_TEXT}", fig)


def fig3(low, n_low: int) -> Figure:
    counts = sorted(low["episodes"].unique())
    if len(counts) > 10:
        counts = [c for c in counts if c % 5 == 0 or c == 1] or counts
    fig, axes = F.new_figure(1, width=8.0, height=3.6)
    ax = axes[0]
    F.violins(ax, [str(c) for c in counts], ["full", "fixed_theta"],
              lambda c, h: low.loc[(low["episodes"] == int(c)) & (low["condition"] == h),
                                   "expertise_distance"],
              F.CONDITION_COLORS, F.CONDITION_LABELS)
    ax.set_xlabel("episodes seen")
    ax.set_ylabel(METRIC_AXES["expertise_distance"])
    ax.set_title(f"Fig. 3: low expertise, in-set, up to {n_low} episodes "
                 f"(n = {_people(low[low['condition'] == 'full'])} people)", fontsize=11)
    return Figure("fig3", "Fig. 3: low expertise, expertise distance vs episodes",
                  f"In-set low-expertise rows (group_true = low), conditions `full` and `fixed_theta`, at "
                  f"episode counts {', '.join(map(str, counts))} (of 1..{n_low}); all environments, runs "
                  "and k combined.", fig)


def _fixed_beta_fig(inset_n, n: int, metric: str, name: str, number: str, log: bool) -> Figure:
    groups = _groups(inset_n)
    fig, axes = F.new_figure(1, width=6.0, height=3.8)
    ax = axes[0]
    F.violins(ax, groups, ["full", "fixed_beta"],
              lambda g, c: inset_n.loc[(inset_n["group_true"] == g) & (inset_n["condition"] == c), metric],
              F.CONDITION_COLORS, F.CONDITION_LABELS, log=log)
    ax.set_xlabel("expertise group of β*")
    ax.set_ylabel(METRIC_AXES[metric] + (" (log scale)" if log else ""))
    people = _people(inset_n[inset_n["condition"] == "full"])
    ax.set_title(f"Fig. {number}: {METRICS[metric].lower()} after {n} episodes, in-set "
                 f"(n = {people} people)", fontsize=11)
    floor = (f" Regret is drawn on a log axis; values below {F.LOG_FLOOR:g} (numerically zero) are drawn "
             f"at {F.LOG_FLOOR:g}." if log else "")
    return Figure(name, f"Fig. {number}: {METRICS[metric].lower()}, Full set vs Fixed β set",
                  f"In-set rows at episodes = {n}, conditions `full` and `fixed_beta` (Fixed β's β from "
                  "another expertise group than β*), all environments, runs and k combined; one violin "
                  f"per expertise group of β* and condition.{floor} Regret uses the true β* (Sec. VI-C)."
                  if metric == "policy_regret" else
                  f"In-set rows at episodes = {n}, conditions `full` and `fixed_beta` (Fixed β's β from "
                  "another expertise group than β*), all environments, runs and k combined; one violin "
                  "per expertise group of β* and condition.", fig)


def fig6(at_k, n: int, k: int) -> Figure:
    fig, axes = F.new_figure(3, width=3.2, height=3.4)
    truths = {"in_set": "in set", "out_of_set": "out of set"}
    for ax, metric in zip(axes, ["policy_regret", "cosine_similarity", "expertise_distance"], strict=True):
        series = {t: {truths[t]: at_k.loc[at_k["truth"] == t, metric]} for t in truths}
        F.ci_bars(ax, list(truths.values()), series, {"in_set": F.GREEN, "out_of_set": F.ORANGE},
                  truths, dodge=False, bounds=METRIC_RANGE[metric])
        ax.set_ylabel(METRIC_AXES[metric])
    counts = {t: _people(at_k[at_k["truth"] == t]) for t in truths}
    fig.suptitle(f"Fig. 6: in vs out of set, Full set, k = {k}, {n} episodes "
                 f"(n = {counts['in_set']} in / {counts['out_of_set']} out)", fontsize=11)
    return Figure("fig6", "Fig. 6: in-set vs out-of-set truths",
                  f"Full-set rows with k = {k} (the largest k) at episodes = {n}; bars are means over all "
                  f"expertise groups and environments, error bars {F.CI_TEXT}.", fig)


def fig7(full_in, n: int) -> Figure:
    fig, axes = F.new_figure(3, width=3.4, height=3.4)
    groups = _groups(full_in)
    labels = {g: f"{g} (n = {_people(full_in[full_in['group_true'] == g])})" for g in groups}
    for ax, metric in zip(axes, ["policy_regret", "cosine_similarity", "expertise_distance"], strict=True):
        log = metric == "policy_regret" and F.needs_log(full_in.groupby("episodes")[metric].mean())
        F.bands(ax, full_in, "episodes", metric, "group_true", groups, F.GROUP_COLORS, labels, log=log,
                legend=False, bounds=METRIC_RANGE[metric])
        F.episodes_axis(ax)
        ax.set_ylabel(METRIC_AXES[metric] + (" (log scale)" if log else ""))
    F.figure_legend(fig, F.lines(groups, F.GROUP_COLORS, labels))
    fig.suptitle(f"Fig. 7: metrics vs episodes 1..{n}, in-set, Full set, by expertise group", fontsize=11)
    return Figure("fig7", "Fig. 7: metrics vs number of episodes",
                  f"In-set Full-set rows at episodes 1..{n}, all environments, runs and k combined; lines "
                  f"are means per expertise group of β*, bands {F.CI_TEXT}.", fig)


# -------------------------------------------------------------------------------- report
def build(sweep) -> Report:
    require_columns(sweep, NEEDED, f"{sweep.root}/rows")
    rows = sweep.rows
    n, n_low = episodes_of(sweep)
    kmax = int(rows["k"].max())
    inset_n = rows[(rows["truth"] == "in_set") & (rows["episodes"] == n)]
    full_in = rows[(rows["truth"] == "in_set") & (rows["condition"] == "full") & (rows["episodes"] <= n)]
    low = rows[(rows["truth"] == "in_set") & (rows["group_true"] == "low")
               & rows["condition"].isin(["full", "fixed_theta"])]
    at_k = rows[(rows["condition"] == "full") & (rows["k"] == kmax) & (rows["episodes"] == n)]
    report = Report("conditions", "Report: `conditions` (paper Secs. VI-A–E)")
    model = sweep.config.get("model", "maxent")
    report.notes.append(
        f"Observation model of the simulated people and of the inference: `{model}`"
        + (" (the paper's)." if model == "maxent" else " (not the paper's maxent).")
        + f" {n} episodes per person ({n_low} for in-set low-expertise people, Fig. 3); k ∈ "
        f"{{{', '.join(str(k) for k in sorted(rows['k'].unique()))}}}. Claims VI-B to VI-D use the rows at "
        f"episodes = {n}.")
    report.notes.append(
        f"The \"right group\" of claim VI-E is the expertise group of the posterior-mean β̂ "
        f"(`group_hat`) equal to β*'s (`group_true`), with groups split at the geometric midpoints "
        f"between the paper's groups (β < {GROUP_BOUNDARIES[0]:.3g} high, {GROUP_BOUNDARIES[0]:.3g} ≤ β < "
        f"{GROUP_BOUNDARIES[1]:.4g} medium, β ≥ {GROUP_BOUNDARIES[1]:.4g} low; "
        "`expertise_irl.hypotheses.expertise_group`). The claim's why also gives the other reading, "
        "the share of people whose posterior puts more than half its mass on β*'s group "
        "(`p_group_true` > 0.5), not judged.")
    report.notes.append(protocol_note(sweep))
    report.people = _people(rows)
    tables = (table1(rows, n), table2(rows, n))
    report.claims = claims(rows, n, n_low, tables)
    report.figures = [fig2(inset_n, n)]
    if len(low):
        report.figures.append(fig3(low, n_low))
    log5 = F.needs_log(inset_n.loc[inset_n["condition"].isin(["full", "fixed_beta"]), "policy_regret"])
    report.figures += [_fixed_beta_fig(inset_n, n, "cosine_similarity", "fig4", "4", False),
                       _fixed_beta_fig(inset_n, n, "policy_regret", "fig5", "5", log5),
                       fig6(at_k, n, kmax), fig7(full_in, n)]
    report.tables.extend(tables)
    order = {c: i for i, c in enumerate([*F.CONDITION_LABELS, *GROUPS])}
    shown = inset_n.sort_values(["condition", "group_true"], key=lambda s: s.map(order), kind="stable")
    shown = shown.assign(condition=shown["condition"].map(F.CONDITION_LABELS))
    report.tables.append(means_table(
        "conditions_means", "Metrics per condition and expertise group",
        f"In-set rows at episodes = {n} (the numbers behind Figs. 2, 4 and 5).", shown,
        ["condition", "group_true"]))
    last = last_rows(rows[rows["condition"] == "full"], PERSON)
    report.sections.append(capped_section(last, capped_effect(inset_n, last), by=["truth"], model=model,
                                          max_steps=sweep.config.get("max_steps")))
    scale = random_theta_section(rows, n)
    if scale is not None:
        report.sections.append(scale)
    report.sections.append(regrets_section(rows[rows["truth"] == "in_set"], PERSON, "condition"))
    return report


def capped_effect(inset_n, last) -> str:
    """Where the cap moves our numbers: VI-C's regret ratio per expertise group, from the rows."""
    from .stats import fmt

    shares = capped_shares(last[last["truth"] == "in_set"])
    ratios = {}
    for g in _groups(inset_n):
        sub = inset_n[inset_n["group_true"] == g]
        full = sub.loc[sub["condition"] == "full", "policy_regret"].mean()
        fixed = sub.loc[sub["condition"] == "fixed_beta", "policy_regret"].mean()
        if np.isfinite(full) and np.isfinite(fixed) and full > 0:
            ratios[g] = fixed / full
    text = ""
    if ratios:
        full = inset_n.loc[inset_n["condition"] == "full", "policy_regret"].mean()
        pooled = inset_n.loc[inset_n["condition"] == "fixed_beta", "policy_regret"].mean() / full
        parts = ", ".join(f"{g} {fmt(r)}× ({shares.get(g, np.nan):.0%} of episodes capped)"
                          for g, r in ratios.items())
        text += (f"Claim VI-C's Fixed β / Full regret ratio per expertise group of the in-set people: "
                 f"{parts}. ")
        least = min(ratios, key=lambda g: shares.get(g, 1.0))
        if len(ratios) > 1 and ratios[least] > pooled:
            text += ("For a person with a large β the soft values are dominated by the entropy term, so "
                     "a wrong θ costs little regret there whether or not the walks are capped: the "
                     f"large-β groups pull the pooled ratio down to {fmt(pooled)}× from the {least} group's "
                     f"{fmt(ratios[least])}× (the paper: ≈ 100×). ")
    text += ("The cap also bears on the low group's β distances (Figs. 2, 3 and 7, claims VI-B and VI-E: "
             "capped walks separate β* = 5 from 10 slowly) and on Table II's states factor (a capped walk "
             "covers more of a larger map).")
    return text
