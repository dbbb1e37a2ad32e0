"""The tables of a study: ``study.csv`` / ``study.md`` (one row per participant) and
``tasks.csv`` (one row per manifest row), and the modes of a discrete posterior."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..inference.belief import DiscreteBelief
from .paths import COUNTS

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


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow([_fmt(r[c]) for c in columns])
    tmp.replace(path)


#: The columns that close a row of ``study.csv`` and of ``tasks.csv``: groups, Table V-VI counts, ingestion.
_SUMMARY_COLUMNS = (
    *GROUP_COLUMNS,
    *COUNTS,
    *(f"optimal_{c}" for c in COUNTS),
    "optimal_reached_goal",
    "filled_gaps",
    "snapped_samples",
)


def study_columns(feature_names: Sequence[str], models: Sequence[str] = ()) -> list[str]:
    cols = ["participant", "tasks", "episodes", "beta_hat", *(f"theta_{f}" for f in feature_names),
            *_SUMMARY_COLUMNS]
    if models:
        cols += [f"log_evidence_{m}" for m in models] + ["best_model"]
    return cols


def task_columns(feature_names: Sequence[str]) -> list[str]:
    return ["participant", "task", "line", "map", "recording", "demos", "episodes", "beta_hat",
            *(f"theta_{f}" for f in feature_names), *_SUMMARY_COLUMNS]


def _num(x: float, digits: int = 3) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}g}"


def study_markdown(
    rows: Sequence[dict[str, Any]],
    feature_names: Sequence[str],
    *,
    method: str,
    n_hypotheses: int | None,
    modes: dict[str, list],
    title: str,
) -> str:
    """Tables V and VI of the study, the modes, and what ingestion changed."""
    feats = ", ".join(feature_names)
    lines = [f"# {title}", ""]
    what = f"{n_hypotheses} hypotheses" if n_hypotheses else method
    lines += [
        f"Method: {method} ({what}). θ̂ in the order [{feats}].",
        "",
        "## Observed trajectories (Table V)",
        "",
        "| participant | β̂ | θ̂ | P(high / medium / low) | path length | path cost | wrong road direction "
        "| restricted moves | road usage | direction changes |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        theta = "[" + ", ".join(f"{r[f'theta_{f}']:.2f}" for f in feature_names) + "]"
        groups = " / ".join(_num(r[c], 2) for c in GROUP_COLUMNS) if not math.isnan(r["p_high"]) else ""
        lines.append(
            f"| {r['participant']} | {r['beta_hat']:.3g} | {theta} | {groups} | {r['path_length']} | "
            f"{r['path_cost']} | {r['wrong_road_direction']} | {r['restricted_moves']} | "
            f"{r['road_cells']}/{r['path_length']} | {r['direction_changes']} |"
        )
    lines += [
        "",
        "## Optimal trajectories, β = 0.001 with θ̂ (Table VI)",
        "",
        "| participant | path length | path cost | wrong road direction | restricted moves | road usage "
        "| direction changes | reached a goal |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['participant']} | {r['optimal_path_length']} | {r['optimal_path_cost']} | "
            f"{r['optimal_wrong_road_direction']} | {r['optimal_restricted_moves']} | "
            f"{r['optimal_road_cells']}/{r['optimal_path_length']} | "
            f"{r['optimal_direction_changes']} | {r['optimal_reached_goal']}/{r['episodes']} |"
        )
    several = {p: m for p, m in modes.items() if len(m) > 1}
    if several:
        lines += ["", "## Participants whose posterior has several modes", ""]
        for p, ms in several.items():
            parts = [
                f"θ = [{', '.join(f'{x:.2f}' for x in m['theta'])}], β = {m['beta']:g} "
                f"(p = {m['probability']:.2f})"
                for m in ms
            ]
            lines.append(f"- {p}: " + "; ".join(parts))
    fixed = [r for r in rows if r["filled_gaps"] or r["snapped_samples"]]
    lines += ["", "## Ingestion", ""]
    if fixed:
        for r in fixed:
            lines.append(
                f"- {r['participant']}: filled gaps {r['filled_gaps']}, snapped samples "
                f"{r['snapped_samples']}"
            )
    else:
        lines.append("No gap was filled and no sample snapped.")
    return "\n".join(lines) + "\n"
