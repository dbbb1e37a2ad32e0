"""The tables of a study: ``study.csv`` / ``study.md`` (one row per participant) and
``tasks.csv`` (one row per manifest row), and the modes of a discrete posterior.

Columns: the manifest's extra columns right after ``participant``, verbatim (a participant's
value is their rows' value, or their distinct values joined by ``;``); Table V's counts are
empty where a task's world is not a floor plan (:data:`.paths.PLAN_COUNTS`)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_open
from ..inference.belief import DiscreteBelief
from .paths import COUNTS, world_counts

GROUP_COLUMNS = ("p_high", "p_medium", "p_low")
#: A mode must hold at least this posterior probability to be named.
MODE_MIN_PROBABILITY = 0.1
MAX_MODES = 3


def posterior_modes(
    belief: DiscreteBelief, *, min_probability: float = MODE_MIN_PROBABILITY, top: int = MAX_MODES
) -> list[dict[str, Any]]:
    """The separated modes of a discrete posterior, most probable first.

    A hypothesis (θ, β) is a mode when no neighbour is more probable; its neighbours are the
    same θ with the next β of the grid on either side, and the same β with every θ within
    l1 distance r of θ, where r is 1.5 × the largest nearest-neighbour distance of the θ set
    (0.6 for ``paper-real``), so that two modes are separated by more than a grid step.
    Modes with probability below ``min_probability`` are dropped; at most ``top`` are
    returned, as ``{"theta", "beta", "probability"}``.
    """
    hyp = belief.hypotheses
    p = belief.probabilities.reshape(hyp.n_theta, hyp.n_beta)
    thetas = hyp.thetas
    d = np.abs(thetas[:, None, :] - thetas[None, :, :]).sum(-1)
    np.fill_diagonal(d, np.inf)
    radius = 1.5 * float(d.min(axis=1).max()) if len(thetas) > 1 else 0.0
    near = d <= radius + 1e-9  # [n_theta, n_theta] θ neighbours
    modes = []
    for i in range(hyp.n_theta):
        for j in range(hyp.n_beta):
            q = p[i, j]
            if q < min_probability:
                continue
            beta_nb = [p[i, k] for k in (j - 1, j + 1) if 0 <= k < hyp.n_beta]
            theta_nb = p[near[i], j]
            if all(q >= x for x in beta_nb) and np.all(q >= theta_nb):
                modes.append(
                    {
                        "theta": [float(x) for x in thetas[i]],
                        "beta": float(hyp.betas[j]),
                        "probability": float(q),
                    }
                )
    modes.sort(key=lambda m: -m["probability"])
    return modes[:top]


def _csv_cell(v: Any) -> str:
    """A CSV field: a float by ``repr`` (every digit; NaN empty), anything else by ``str``."""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> None:
    with atomic_open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow([_csv_cell(r.get(c, math.nan)) for c in columns])


#: The columns that close a row of ``study.csv`` and of ``tasks.csv``: groups, Table V-VI counts, ingestion.
_SUMMARY_COLUMNS = (
    *GROUP_COLUMNS,
    *COUNTS,
    *(f"optimal_{c}" for c in COUNTS),
    "optimal_reached_goal",
    "filled_gaps",
    "snapped_samples",
)


#: β summaries of ``study.csv`` (``beta_hat`` stays the posterior mean).
BETA_SUMMARY_COLUMNS = ("beta_mean", "beta_median", "beta_geomean", "beta_q05", "beta_q95")
HELDOUT_COLUMNS = ("heldout_split", "heldout_actions", "heldout_log_likelihood_per_action")
#: ``--check``'s verdict on each participant (``diagnostics.misspecification.verdict`` of their result;
#: empty with ``--check off`` or ``--share beta``).
MISSPECIFICATION_COLUMN = "misspecification"


def _world_columns(feature_names: Sequence[str]) -> list[str]:
    """Every world's counts of the observed paths and of the optimal ones (Table VI)."""
    own = list(world_counts(feature_names))
    return own + [f"optimal_{c}" for c in own if c != "goal_reached"]


def study_columns(feature_names: Sequence[str], models: Sequence[str] = (),
                  extra: Sequence[str] = ()) -> list[str]:
    cols = ["participant", *extra, "tasks", "episodes", "beta_hat", *(f"theta_{f}" for f in feature_names),
            *_SUMMARY_COLUMNS, *BETA_SUMMARY_COLUMNS, "share", *_world_columns(feature_names),
            *HELDOUT_COLUMNS, "warnings", MISSPECIFICATION_COLUMN]
    if models:
        cols += [f"log_evidence_{m}" for m in models] + ["best_model"]
    return cols


def task_columns(feature_names: Sequence[str], extra: Sequence[str] = ()) -> list[str]:
    return ["participant", *extra, "task", "line", "map", "recording", "demos", "episodes", "beta_hat",
            *(f"theta_{f}" for f in feature_names), *_SUMMARY_COLUMNS, *_world_columns(feature_names)]


def _sig_or_blank(x: float, digits: int = 3) -> str:
    """``x`` to ``digits`` significant figures for a Markdown table; empty for None or NaN."""
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}g}"


#: ``study --expertise changing``: each participant's Bayes factor and trend.
CHANGING_COLUMNS = ("changing_log_bf", "p_changing", "trend_p_falls", "trend_p_rises", "trend_log_ratio")


def sign_test(falls: int, rises: int) -> float | None:
    """The two-sided sign test's p-value of ``falls`` against ``rises`` (ties, the participants who
    neither fall nor rise, are left out, as the test requires); None when nobody changed."""
    from scipy.stats import binomtest

    n = falls + rises
    return float(binomtest(falls, n, 0.5).pvalue) if n else None


def _improve_words(falls: int, rises: int, n: int, by_p: bool) -> str:
    """The ``Do people improve?`` sentence: who falls, who rises, who keeps, and the sign test over the
    participants who changed."""
    if by_p:
        rule, rule_up = "P(β falls) > 0.5", "more likely than not to end less expert"
    else:
        rule, rule_up = "MAP λ̂ < 0, a point estimate", "estimated to end less expert (λ̂ > 0)"
    p = sign_test(falls, rises)
    keep = n - falls - rises
    test = ("no change: nobody is more likely to end more expert than less, so there is nothing for a "
            "sign test to weigh" if p is None else
            f"a two-sided sign test against 1/2 over the {falls + rises} who changed gives p = {p:.3g}")
    return (f"**Do people improve?** {falls} of {n} participants are "
            f"{'more likely than not' if by_p else 'estimated'} to end more expert than they began "
            f"({rule}); {rises} are {rule_up}; {keep} most likely keep their expertise (ties, left out "
            f"of the test); {test}.")


def changing_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """``--expertise changing``: do people improve over the study? The share of participants with
    P(β falls from their first episode to their last) > 0.5 (with ``--method map``, whose curve is a
    point estimate: with λ̂ < 0), with a two-sided sign test against 1/2 over those whose β falls or
    rises (ties left out), then each participant's Bayes factor (discrete only) and trend."""
    by_p = [r for r in rows if _has(r, "trend_p_falls")]
    usable = by_p or [r for r in rows if _has(r, "trend_log_ratio")]
    if by_p:
        falls = sum(r["trend_p_falls"] > 0.5 for r in usable)
        rises = sum(r["trend_p_rises"] > 0.5 for r in usable)
    else:
        falls = sum(r["trend_log_ratio"] < 0 for r in usable)
        rises = sum(r["trend_log_ratio"] > 0 for r in usable)
    n = len(usable)
    lines = ["## Expertise over the study (--expertise changing)", ""]
    if n:
        lines += [_improve_words(falls, rises, n, bool(by_p)), ""]
    lines += ["Per participant, episodes in task order: the log Bayes factor for a β that changes "
              "against one β (> 0 favours change; --method discrete only), P(changing), P(β falls from "
              "the first episode to the last) and E[log β_last − log β_first] (negative: improves; −0.69 "
              "is halving; with --method map the MAP λ̂).", "",
              "| participant | log BF | P(changing) | P(β falls) | E[log β_last/β_first] |",
              "|---|---|---|---|---|"]
    for r in usable:
        lines.append(f"| {r['participant']} | {_sig_or_blank(r['changing_log_bf'], 3)} | "
                     f"{_sig_or_blank(r['p_changing'])} | {_sig_or_blank(r['trend_p_falls'], 2)} | "
                     f"{r['trend_log_ratio']:+.2f} |")
    return "\n".join(lines) + "\n\n"


def misspecification_markdown(rows: Sequence[dict[str, Any]], check: str, share: str = "both") -> str:
    """``--check fast|full``: how many participants got each verdict, who the features do not explain,
    and what that means for their β̂ (empty with ``--check off``)."""
    from ..inference.misspecification import UNEXPLAINED, VERDICTS

    if check == "off":
        return ""
    lines = [f"## Low expertise or missing features? (--check {check})", ""]
    if share != "both":
        lines += ["Not available with --share beta: the checks simulate one θ for all of a participant's "
                  "tasks.", "", ""]
        return "\n".join(lines)
    by: dict[str, list[str]] = {v: [] for v in VERDICTS}
    for r in rows:
        by.setdefault(r.get(MISSPECIFICATION_COLUMN) or "not checked", []).append(str(r["participant"]))
    lines += ["| verdict | participants | who |", "|---|---|---|"]
    lines += [f"| {v} | {len(ps)} | {', '.join(ps)} |" for v, ps in by.items() if ps or v in VERDICTS]
    lines += ["", f"\"{UNEXPLAINED}\": the demonstrations have structure that the features do not describe, "
              "so the model reads it as noise and β̂ is an upper bound on the person's noise, not a measure "
              "of it. Each participant's reason and statistics are in their result.json "
              "(diagnostics.misspecification), drawn by `plot participants/ID/result.json --check --out "
              "check.png`; the rules are in "
              "docs/misspecification.md.", "", ""]
    return "\n".join(lines)


def _has(r: dict[str, Any], c: str) -> bool:
    v = r.get(c)
    return v is not None and not (isinstance(v, float) and math.isnan(v))


def study_markdown(
    rows: Sequence[dict[str, Any]],
    feature_names: Sequence[str],
    *,
    method: str,
    n_hypotheses: int | str | None,
    modes: dict[str, list],
    title: str,
    share: str = "both",
    warnings: dict[str, list[str]] | None = None,
    grid: dict[str, Any] | None = None,
    betas: Sequence[float] | None = None,
    heldout_unavailable: dict[str, str] | None = None,
    sections: str = "",
) -> str:
    """The study's summary: warnings counted, β and θ̂ per participant, every world's path counts,
    Tables V–VI where the maps are floor plans, the modes, the held-out check, what ingestion
    changed, ``sections`` (e.g. ``--group-by``'s) and each participant's warnings."""
    warnings = warnings or {}
    lines = _head_lines(rows, feature_names, method, n_hypotheses, title, share, warnings, grid, betas)
    lines += _estimate_lines(rows, feature_names)
    lines += _path_lines(rows, feature_names)
    lines += _plan_lines(rows)
    lines += _optimal_lines(rows)
    lines += _mode_lines(modes)
    lines += _heldout_unavailable_lines(heldout_unavailable)
    lines += _ingestion_lines(rows)
    if sections:
        lines += ["", sections.strip("\n")]
    lines += _warning_lines(warnings)
    return "\n".join(lines) + "\n"


def _head_lines(rows, feature_names, method, n_hypotheses, title, share, warnings, grid, betas) -> list[str]:
    """The title, the method and its hypotheses, the β grid and the count of warnings."""
    feats = ", ".join(feature_names)
    lines = [f"# {title}", ""]
    what = (f"{n_hypotheses} hypotheses; fewer for a participant whose constant features are kept at 0"
            if n_hypotheses else method)
    shared = ("one (θ, β) per participant over all their tasks" if share == "both"
              else "one β per participant, a θ per task (θ̂ per task in tasks.csv)")
    n_warn = sum(len(w) for w in warnings.values())
    lines += [f"Method: {method} ({what}); --share {share}: {shared}. Features: {feats}.", ""]
    if betas is not None:
        source = (f"chosen from the maps' optimal values Q* (--betas auto): {grid['rule']}" if grid
                  else "given by --betas")
        lines += [f"β grid: {', '.join(f'{b:g}' for b in betas)} ({source}).", ""]
    lines += [f"**Warnings: {n_warn}** for {sum(1 for w in warnings.values() if w)} of {len(rows)} "
              "participant(s) (listed under Warnings below).", ""]
    return lines


def _estimate_lines(rows: Sequence[dict[str, Any]], feature_names: Sequence[str]) -> list[str]:
    """``## Estimates``: β̂, its median, geometric mean and interval, θ̂, the groups and held-out."""
    lines = [
        "## Estimates",
        "",
        "β̂ is the posterior mean; the median, the geometric mean exp E[log β] and the 90% interval "
        "[q05, q95] beside it. P(high / medium / low) is the posterior mass of the paper's expertise "
        "groups, by absolute β (high < 0.212 ≤ medium < 2.24 ≤ low) whatever the grid; β is in reward "
        "units, so on maps whose rewards differ more per move the same person has a larger β. "
        "Held-out: log-likelihood per held-out action (0 is perfect, −1.39 a uniform choice of four "
        "moves) and its split.",
        "",
        "| participant | β̂ | median | geo. mean | 90% interval | θ̂ | P(high / medium / low) "
        "| held-out / action |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        theta = (", ".join(f"{f} {r[f'theta_{f}']:.2f}" for f in feature_names if _has(r, f"theta_{f}"))
                 or "per task")
        groups = " / ".join(_sig_or_blank(r[c], 2) for c in GROUP_COLUMNS) if _has(r, "p_high") else ""
        band = (f"[{_sig_or_blank(r['beta_q05'])}, {_sig_or_blank(r['beta_q95'])}]"
                if _has(r, "beta_q05") else "")
        held = (f"{r['heldout_log_likelihood_per_action']:.3f} ({r['heldout_split']})"
                if _has(r, "heldout_log_likelihood_per_action") else "n/a")
        lines.append(f"| {r['participant']} | {_sig_or_blank(r['beta_hat'])} | "
                     f"{_sig_or_blank(r['beta_median'])} | {_sig_or_blank(r['beta_geomean'])} | {band} | "
                     f"{theta} | {groups} | {held} |")
    return lines


def _path_lines(rows: Sequence[dict[str, Any]], feature_names: Sequence[str]) -> list[str]:
    """``## Observed paths``: every world's moves, goals, cost under θ̂ and feature sums."""
    lines = [
        "",
        "## Observed paths",
        "",
        "Every world: moves, episodes that reached a goal, their mean moves, the cost −Σ θ̂·φ under θ̂, "
        "and each feature's sum along the path.",
        "",
        "| participant | path length | reached goal | steps to goal | cost under θ̂ | "
        + " | ".join(f"Σ {f}" for f in feature_names) + " |",
        "|---" * (5 + len(feature_names)) + "|",
    ]
    for r in rows:
        lines.append(f"| {r['participant']} | {r['path_length']} | {r['goal_reached']}/{r['episodes']} | "
                     f"{_sig_or_blank(r['steps_to_goal'])} | {_sig_or_blank(r['cost_theta_hat'])} | "
                     + " | ".join(_sig_or_blank(r.get(f"feature_{f}", math.nan), 6) for f in feature_names)
                     + " |")
    return lines


def _plan_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Table V, the observed trajectories, for the rows on floor plans (none: no lines)."""
    plan_rows = [r for r in rows if _has(r, "path_cost")]
    if not plan_rows:
        return []
    lines = [
        "",
        "## Observed trajectories on floor plans (Table V)",
        "",
        "| participant | path length | path cost | wrong road direction "
        "| restricted moves | road usage | direction changes |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in plan_rows:
        lines.append(
            f"| {r['participant']} | {r['path_length']} | "
            f"{r['path_cost']} | {r['wrong_road_direction']} | {r['restricted_moves']} | "
            f"{r['road_cells']}/{r['path_length']} | {r['direction_changes']} |"
        )
    return lines


def _optimal_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Table VI: the optimal trajectories under θ̂ (``n/a`` where the map is not a floor plan)."""
    lines = [
        "",
        "## Optimal trajectories, β = 0.001 with θ̂ (Table VI)",
        "",
        "| participant | path length | path cost | wrong road direction | restricted moves | road usage "
        "| direction changes | reached a goal |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        road = f"{r['optimal_road_cells']}/{r['optimal_path_length']}"
        plan = ("path_cost", "wrong_road_direction", "restricted_moves")
        cells = ([str(r[f"optimal_{c}"]) for c in plan] + [road, str(r["optimal_direction_changes"])]
                 if _has(r, "optimal_path_cost") else ["n/a"] * 5)
        lines.append(f"| {r['participant']} | {r['optimal_path_length']} | " + " | ".join(cells)
                     + f" | {r['optimal_reached_goal']}/{r['episodes']} |")
    return lines


def _mode_lines(modes: dict[str, list]) -> list[str]:
    """The participants whose posterior has more than one mode, with each mode (none: no lines)."""
    several = {p: m for p, m in modes.items() if len(m) > 1}
    if not several:
        return []
    lines = ["", "## Participants whose posterior has several modes", ""]
    for p, ms in several.items():
        parts = [
            f"θ = [{', '.join(f'{x:.2f}' for x in m['theta'])}], β = {m['beta']:g} "
            f"(p = {m['probability']:.2f})"
            for m in ms
        ]
        lines.append(f"- {p}: " + "; ".join(parts))
    return lines


def _heldout_unavailable_lines(heldout_unavailable: dict[str, str] | None) -> list[str]:
    """The participants without a held-out check, grouped by the reason (none: no lines)."""
    unavailable = {p: why for p, why in (heldout_unavailable or {}).items() if why}
    if not unavailable:
        return []
    lines = ["", "## Held-out check not available", ""]
    by_reason: dict[str, list[str]] = {}
    for p, why in unavailable.items():
        by_reason.setdefault(why, []).append(p)
    for why, ps in by_reason.items():
        lines.append(f"- {', '.join(ps)}: {why}")
    return lines


def _ingestion_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """``## Ingestion``: the gaps filled and samples snapped per participant."""
    fixed = [r for r in rows if r["filled_gaps"] or r["snapped_samples"]]
    lines = ["", "## Ingestion", ""]
    if fixed:
        for r in fixed:
            lines.append(
                f"- {r['participant']}: filled gaps {r['filled_gaps']}, snapped samples "
                f"{r['snapped_samples']}"
            )
    else:
        lines.append("No gap was filled and no sample snapped.")
    return lines


def _warning_lines(warnings: dict[str, list[str]]) -> list[str]:
    """``## Warnings``: each participant's, one a line (``None.`` when there is none)."""
    lines = ["", "## Warnings", ""]
    if any(warnings.values()):
        for pid, ws in warnings.items():
            for w in ws:
                lines.append(f"- {pid}: {w}")
    else:
        lines.append("None.")
    return lines
