"""The ``optimisation`` report (paper Sec. VII): Figs. 8–9, Table IV, wall times and the Sec. VII claims."""

from __future__ import annotations

import numpy as np

from ...hypotheses import GROUP_NAMES as GROUPS
from . import figures as F
from .budget import budget_section
from .capped import capped_section, last_rows
from .identifiability import gap_section
from .optimisation_claims import JUDGED, KEY, PERSON, RESCALED, claims, table4
from .parts import Figure, Report, Table
from .regrets import regrets_section
from .stats import METRIC_AXES, METRIC_RANGE, METRICS, fmt
from .sweep import protocol_note, require_columns, workers_text
from .tables import means_table, pearson_cell

__all__ = ["JUDGED", "KEY", "PERSON", "RESCALED", "build", "claims", "rescaled_box"]

ORDER = list(F.METHOD_COLORS)  # discrete, birl_box (the paper's), then ours
NEEDED = [*KEY, "method", "n_capped", "mean_episode_length", "n_states", "beta_true", "group_true",
          "prior", "prior_text", "wall_time_s", *METRICS]


def _methods(rows) -> list[str]:
    present = set(rows["method"])
    return [m for m in ORDER if m in present] + sorted(present - set(ORDER))


def _label(m: str) -> str:
    return F.METHOD_LABELS.get(m, m)


def fig8(at_e, e: int, methods: list[str]) -> Figure:
    fig, axes = F.new_figure(3, width=3.8, height=3.6)
    colors = {m: F.METHOD_COLORS.get(m, F.GREY) for m in methods}
    counts = {m: len(at_e[at_e["method"] == m]) for m in methods}
    labels = {m: f"{_label(m)} (n = {counts[m]})" for m in methods}
    for ax, metric in zip(axes, ["policy_regret", "cosine_similarity", "expertise_distance"], strict=True):
        means = at_e.groupby("method")[metric].mean()
        log = metric == "policy_regret" and F.needs_log(means)
        series = {m: {_label(m): at_e.loc[at_e["method"] == m, metric]} for m in methods}
        F.ci_bars(ax, [_label(m) for m in methods], series, colors, labels, dodge=False, log=log,
                  bounds=METRIC_RANGE[metric])
        ax.tick_params(axis="x", labelrotation=30, labelsize=8)
        for label in ax.get_xticklabels():
            label.set_horizontalalignment("right")
        ax.set_ylabel(METRIC_AXES[metric] + (" (log scale)" if log else ""))
    F.figure_legend(fig, F.patches(methods, colors, labels))
    fig.suptitle(f"Fig. 8: methods after {e} episodes, all environments (n = instances per method)",
                 fontsize=11)
    return Figure("fig8", "Fig. 8: discrete set vs Algorithm 1 (and our methods)",
                  f"Rows at episodes = {e}; bars are means over all environments and instances, error bars "
                  f"{F.CI_TEXT}. `{JUDGED}` is the paper's optimisation approach "
                  "(Algorithm 1 as printed); the others are ours.", fig)


def fig9(rows, methods: list[str]) -> Figure:
    fig, axes = F.new_figure(3, width=3.6, height=3.5)
    colors = {m: F.METHOD_COLORS.get(m, F.GREY) for m in methods}
    labels = {m: _label(m) for m in methods}
    for ax, metric in zip(axes, ["policy_regret", "cosine_similarity", "expertise_distance"], strict=True):
        log = metric == "policy_regret" and F.needs_log(rows.groupby(["method", "episodes"])[metric].mean())
        F.bands(ax, rows, "episodes", metric, "method", methods, colors, labels, log=log, legend=False,
                bounds=METRIC_RANGE[metric])
        ax.set_xlabel("episodes seen")
        ax.set_xticks(sorted(rows["episodes"].unique()))
        ax.set_ylabel(METRIC_AXES[metric] + (" (log scale)" if log else ""))
    F.figure_legend(fig, F.lines(methods, colors, labels))
    fig.suptitle("Fig. 9: metrics vs episodes per method", fontsize=11)
    return Figure("fig9", "Fig. 9: metrics vs number of episodes",
                  "All rows, at the sweep's episode counts "
                  f"({', '.join(map(str, sorted(rows['episodes'].unique())))}); lines are means per method, "
                  "bands 95% confidence intervals (Student t, clipped to the metric's range).", fig)


THETA_HAT = [f"theta_hat_{f}" for f in ("length", "road", "avoid", "slow", "traffic")]


def rescaled_box(rows):
    """``birl_box``'s rows with β̂ put on θ*'s scale: β̂ / ‖θ̂‖₁ and its |β* − β̂/‖θ̂‖₁| (method
    :data:`RESCALED`); empty where the rows lack θ̂. The ratio of the chain's means, not the chain's
    mean of ratios."""
    box = rows[rows["method"] == JUDGED]
    if not len(box) or not all(c in box.columns for c in THETA_HAT):
        return box.iloc[:0]
    l1 = box[THETA_HAT].sum(axis=1)
    beta = box["beta_hat"] / l1
    return box.assign(method=RESCALED, theta_hat_l1=l1, beta_hat=beta,
                      expertise_distance=(box["beta_true"] - beta).abs())


def scale_note(at_e, e: int) -> str | None:
    """Algorithm 1 (box)'s estimates are on a scale the data cannot fix: the note, from the rows."""
    scaled = rescaled_box(at_e)
    if not len(scaled):
        return None
    l1 = scaled["theta_hat_l1"]
    return (f"Scale of Algorithm 1 as printed (`{JUDGED}`): it samples θ in the box [0, 1]^5 (‖θ‖₁ ≤ 1), "
            "and only θ/β enters the likelihood, so the data cannot fix the scale of its posterior means "
            f"E[θ] and E[β]. At {e} episodes its mean ‖θ̂‖₁ is {fmt(l1.mean())} (range "
            f"{fmt(l1.min())}–{fmt(l1.max())}, {len(l1)} instances), where θ* has ‖θ*‖₁ = 1: its β̂ is on "
            "a smaller scale than β*, and its β distance and its regret (θ̂ evaluated at β*) carry that "
            "scale; its cosine does not. The judged VII-B claims use these numbers as they come out. "
            f"Beside them, `{RESCALED}` (not judged) puts β̂ on θ*'s scale from the rows, "
            f"|β* − β̂/‖θ̂‖₁| (mean {fmt(scaled['expertise_distance'].mean())} against "
            f"{fmt(at_e.loc[at_e['method'] == JUDGED, 'expertise_distance'].mean())} unscaled): the ratio "
            "of the chain's means E[β] / ‖E[θ]‖₁, not the chain's mean of β/‖θ‖₁. The regret cannot be "
            "rescaled from the rows (it needs a solve).")


def walltime_table(rows, methods: list[str], runs_text: str = "runs not recorded") -> Table:
    import pandas as pd

    disc = rows[rows["method"] == "discrete"].set_index(KEY)["wall_time_s"] if "discrete" in methods else None
    data = []
    for m in methods:
        sub = rows[rows["method"] == m]
        t = sub["wall_time_s"]
        rec = {"method": m, "rows": len(sub), "mean_s": float(t.mean()), "median_s": float(t.median())}
        if disc is not None:
            mt = sub.set_index(KEY)["wall_time_s"]
            common = mt.index.intersection(disc.index)
            rec["ratio_to_discrete"] = float(mt.loc[common].mean() / disc.loc[common].mean()) if len(common) \
                else np.nan
        for col, agg in (("acceptance_rate", "mean"), ("divergences", "mean"), ("max_rhat", "max")):
            v = sub[col].dropna() if col in sub.columns else []
            rec[f"{col}_{agg}"] = float(getattr(v, agg)()) if len(v) else np.nan
        data.append(rec)
    data = pd.DataFrame(data)
    display = pd.DataFrame({
        "method": [_label(m) for m in data["method"]], "rows": data["rows"],
        "mean (s)": data["mean_s"].map(fmt), "median (s)": data["median_s"].map(fmt),
        "mean / discrete's": data.get("ratio_to_discrete", pd.Series(np.nan, index=data.index)).map(
            lambda x: f"{fmt(x)}×" if np.isfinite(x) else "n/a"),
        "acceptance rate": data["acceptance_rate_mean"].map(fmt),
        "divergences (mean)": data["divergences_mean"].map(fmt), "max R̂": data["max_rhat_max"].map(fmt)})
    return Table("walltime", "Wall time per method",
                 "Every row's `wall_time_s` (that method at that episode count, timed in its task's "
                 f"process; {runs_text}); the ratio compares means over the (environment, instance, "
                 "episodes) both methods ran. Acceptance "
                 "rate: Algorithm 1; divergences and R̂: NUTS (n/a elsewhere).", display, data)


def factors_table(at_e) -> Table:
    import pandas as pd

    data = []
    for g in GROUPS:
        sub = at_e[at_e["group_true"] == g]
        if not len(sub):
            continue
        data.append({"group_true": g, "people": len(sub), "beta_true_min": sub["beta_true"].min(),
                     "beta_true_max": sub["beta_true"].max(),
                     "mean_episode_length_mean": sub["mean_episode_length"].mean(),
                     "mean_episode_length_min": sub["mean_episode_length"].min(),
                     "mean_episode_length_max": sub["mean_episode_length"].max(),
                     "n_states_mean": sub["n_states"].mean(), "n_states_min": sub["n_states"].min(),
                     "n_states_max": sub["n_states"].max(),
                     "share_capped": sub["n_capped"].sum() / sub["episodes"].sum()})
    data = pd.DataFrame(data)
    display = pd.DataFrame({
        "group_true": data["group_true"], "people": data["people"],
        "β*": [f"{fmt(a)}–{fmt(b)}"
               for a, b in zip(data["beta_true_min"], data["beta_true_max"], strict=True)],
        "mean episode length": [f"{fmt(m)} ({fmt(a)}–{fmt(b)})" for m, a, b in
                                zip(data["mean_episode_length_mean"], data["mean_episode_length_min"],
                                    data["mean_episode_length_max"], strict=True)],
        "states": [f"{fmt(m)} ({fmt(a)}–{fmt(b)})" for m, a, b in
                   zip(data["n_states_mean"], data["n_states_min"], data["n_states_max"], strict=True)],
        "capped": data["share_capped"].map(lambda x: f"{x:.0%}")}) if len(data) else data
    return Table("table4_factors", "Table IV's factors per expertise group",
                 "One row per instance at the largest episode count (method-independent columns): mean "
                 "(min–max) of the average episode length and of the number of states.", display, data)


def capped_effect(rows, at_e, max_steps=None) -> str:
    """How the cap ties Table IV's episode-length factor to β*, from the birl_box rows."""
    box = rows[rows["method"] == JUDGED] if (rows["method"] == JUDGED).any() else rows
    cell = pearson_cell(box["mean_episode_length"], box["beta_true"])
    cap = f"{max_steps} actions" if max_steps else "max_steps"
    text = (f"Capped episodes are all {cap} long, so the average episode length mostly says how many of a "
            f"person's episodes are capped: over the `{box['method'].iloc[0]}` rows ")
    if np.isfinite(cell.rho):
        same = "measure much the same thing" if abs(cell.rho) >= 0.7 else "overlap only in part"
        text += (f"it correlates with β* at ρ = {cell.text} (n = {cell.n}), so Table IV's episode-length "
                 f"and true-expertise rows {same}. ")
    else:
        text += f"its correlation with β* is {cell.text} (n = {cell.n}). "
    at = at_e[at_e["method"] == JUDGED] if (at_e["method"] == JUDGED).any() else at_e
    from .capped import capped_shares

    shares = capped_shares(at)
    parts = [f"{g} {fmt(at.loc[at['group_true'] == g, 'expertise_distance'].mean())} ({shares[g]:.0%} capped)"
             for g in GROUPS if g in shares]
    if parts:
        text += (f"Per expertise group the mean |β* − β̂| of `{at['method'].iloc[0]}` at the largest episode "
                 f"count is {', '.join(parts)}: claim VII-B's β-distance ratio pools these groups.")
    return text


def prior_note(rows, methods: list[str]) -> str:
    """Each prior once, with the methods that use it."""
    order = {m: i for i, m in enumerate(methods)}
    groups = rows.drop_duplicates(["method", "prior", "prior_text"]).groupby(["prior", "prior_text"],
                                                                             sort=False)["method"]
    parts = []
    for (prior, text), ms in groups:
        names = ", ".join(f"`{m}`" for m in sorted(ms, key=lambda m: order.get(m, len(order))))
        parts.append(f"{names}: {prior} ({text})")
    return "Priors: " + "; ".join(parts) + "."


def build(sweep) -> Report:
    require_columns(sweep, NEEDED, f"{sweep.root}/rows")
    rows = sweep.rows
    methods = _methods(rows)
    e = int(rows["episodes"].max())
    at_e = rows[rows["episodes"] == e]
    report = Report("optimisation", "Report: `optimisation` (paper Sec. VII)")
    report.notes.append(protocol_note(sweep))
    report.people = len(rows.drop_duplicates(PERSON))
    report.notes.append(prior_note(rows, methods))
    report.notes.append(
        f"Methods: {', '.join(f'`{m}`' for m in methods)}. The Sec. VII claims are judged on `{JUDGED}` "
        "(Algorithm 1 as printed, the paper's optimisation approach); the same numbers for the other "
        "continuous methods stand beside them, not judged. Episode counts: "
        f"{', '.join(map(str, sorted(rows['episodes'].unique())))}; "
        f"{rows.drop_duplicates(PERSON).shape[0]} instances over {rows['environment'].nunique()} "
        "environment(s).")
    if "nuts" in methods:
        n_nuts = rows[rows["method"] == "nuts"].drop_duplicates(PERSON).shape[0]
        report.notes.append(f"NUTS ran on {n_nuts} of the instances; its numbers (and ratios) are over "
                            "those.")
    note = scale_note(at_e, e)
    if note:
        report.notes.append(note)
    shared = sweep.shared_machine()
    t4 = table4(rows)
    report.claims = claims(rows, e, methods, shared, rescaled_box(at_e), t4)
    report.figures = [fig8(at_e, e, methods), fig9(rows, methods)]
    report.tables.append(t4)
    order = {m: i for i, m in enumerate(methods)}
    shown = at_e.sort_values("method", key=lambda s: s.map(order), kind="stable")
    report.tables.append(means_table("optimisation_means", "Metrics per method",
                                     f"Rows at episodes = {e} (the numbers behind Fig. 8).", shown,
                                     ["method"]))
    runs = sweep.working_runs
    report.tables.append(walltime_table(rows, methods, workers_text(runs) if runs else "runs not recorded"))
    one = at_e[at_e["method"] == methods[0]]
    report.tables.append(factors_table(one))
    last = last_rows(rows[rows["method"] == methods[0]], PERSON)
    report.sections.append(capped_section(last, capped_effect(rows, at_e, sweep.config.get("max_steps")),
                                          model=sweep.config.get("model"),
                                          max_steps=sweep.config.get("max_steps"), everyone="the instances"))
    gap = gap_section(rows)
    if gap is not None:
        report.sections.append(gap)
    report.sections.append(regrets_section(rows, PERSON, "method"))
    ablation = budget_section(rows, e, shared)
    if ablation is not None:
        report.sections.append(ablation)
    return report
