"""The figure of ``plot --check``: a result's misspecification checks.

Top: one panel per predictive statistic, the histogram of its replicated values (the posterior
predictive distribution) with the demonstrations' value as a vertical line and the p-value in the
title (red when Holm's rule rejects it; the figure's title says so). Bottom (with ``--check full``
results and a map): the richer reward's departure from θ̂·φ, r(s) for entering each state, on the
grid (blue: the person is drawn to it beyond the features, red: kept away), the demonstrations over
it and the largest departures circled.

The figure reads a typed :class:`~expertise_irl.result.Result` (its
:class:`~expertise_irl.result.Diagnostics`); a result document is read with its ``from_json`` first.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import ListedColormap

from ..atomic import save_figure_atomic
from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..result import Diagnostics, Misspecification, Result
from ..worlds.grid import OBSTACLE
from . import maps

REJECTED, PASSED = "#c0392b", "#222222"


#: Characters per line of the figure's title (a long reason is wrapped, not allowed to widen the page).
TITLE_WIDTH = 120

def check_figure(result: Result | Mapping[str, Any], *, mdp: TabularMDP | None = None,
                 trajs: Trajectories | None = None, source: str | Path = "result"):
    """The :class:`~matplotlib.figure.Figure` of ``result``'s misspecification checks.

    ``result`` is a :class:`~expertise_irl.result.Result` or a result document (of which only
    ``diagnostics`` is read).
    """
    from matplotlib.figure import Figure

    diag = _diagnostics(result) or Diagnostics()
    mis = diag.misspecification
    if mis is None or not (mis.check or mis.verdict or mis.reason or mis.details):
        why = (diag.unavailable or {}).get("misspecification")
        raise InputError(f"{source}: the result has no diagnostics.misspecification ("
                         + (why if why else "infer and study write it with --check fast or full, the default")
                         + ")")
    pred = mis.details.get("predictive") or {}
    stats = pred.get("statistics") or {}
    comp = mis.details.get("competitor")
    show_map = comp is not None and mdp is not None and mdp.state_xy is not None
    rows, cols = panel_grid(len(stats))
    stat_w, map_w = 2.7 * cols, (6.5 if show_map else 0.0)
    fig = Figure(figsize=(max(stat_w + map_w, 6.0), max(2.4 * rows, 5.0 if show_map else 0.0) + 1.2),
                 layout="constrained")
    fig.get_layout_engine().set(w_pad=0.06, h_pad=0.06, hspace=0.06, wspace=0.04)
    if show_map and stats:
        left, right = fig.subfigures(1, 2, width_ratios=[stat_w, map_w], wspace=0.02)
    else:
        left = right = fig
    if stats:
        axes = left.subplots(rows, cols, squeeze=False).ravel()
        for ax in axes[len(stats):]:
            ax.remove()
        for ax, (name, st) in zip(axes, stats.items(), strict=False):
            _statistic_panel(ax, name, st, pred["replicated"][name], mdp)
    if show_map:
        _departure_map(right.subplots(), comp, mdp, trajs)
    fig.suptitle(_check_title(mis, comp, pred, bool(stats)), fontsize=10)
    return fig


def _diagnostics(result: Result | Mapping[str, Any]) -> Diagnostics | None:
    """``result``'s diagnostics, typed (a document's are read with :meth:`Diagnostics.from_json`)."""
    if isinstance(result, Result):
        return result.diagnostics
    diag = result.get("diagnostics")
    return Diagnostics.from_json(diag) if isinstance(diag, Mapping) else None


def panel_grid(n: int) -> tuple[int, int]:
    """``(rows, cols)`` for ``n`` statistic panels: 3 to 5 columns, the fewest empty slots, then the
    fewest rows (9 panels: 3 × 3, none empty)."""
    if n == 0:
        return 0, 0
    if n <= 3:
        return 1, n
    return min(((-(-n // c), c) for c in (3, 4, 5)), key=lambda rc: (rc[0] * rc[1] - n, rc[0]))


def statistic_unit(name: str, mdp: TabularMDP | None = None) -> str:
    """What a predictive statistic counts (its x axis; definitions in ``inference.predictive_checks``)."""
    if name == "path_length":
        return "moves per episode"
    if name == "steps_to_goal":
        return "moves per episode that reached a goal"
    if name.startswith("feature_"):
        return f"Σ φ_{name[len('feature_'):]} per episode"
    if name == "visit_discrepancy":
        return "total-variation distance of state visits (0–1)"
    if name == "agreement":
        return "share of moves that are the most probable action"
    return name


def _statistic_panel(ax, name: str, st: Mapping[str, Any], replicated, mdp) -> None:
    values = np.array([v for v in replicated if v is not None], dtype=float)
    if values.size:
        ax.hist(values, bins=min(30, max(5, len(np.unique(values)))), color="#9db4c8", edgecolor="white")
    if st["observed"] is not None:
        ax.axvline(st["observed"], color=REJECTED if st["rejected"] else PASSED, lw=2)
    p = st["p_value"]
    ax.set_title(f"{name}: p = {p:.3g}" if p is not None else f"{name}: p n/a", fontsize=9,
                 color=REJECTED if st["rejected"] else PASSED)
    ax.set_xlabel(statistic_unit(name, mdp), fontsize=7.5)
    ax.set_ylabel("replicated data sets", fontsize=7.5)
    ax.tick_params(labelsize=7)
    maps.tidy(ax)


def _check_title(mis: Misspecification, comp, pred: Mapping[str, Any], has_stats: bool) -> str:
    import textwrap

    title = "\n".join(textwrap.wrap(f"{mis.verdict} — {mis.reason}", TITLE_WIDTH))
    if comp is not None:
        title += (f"\nheld-out gain of a per-state reward {comp['gain']:.3g} ± {comp['gain_se']:.2g} "
                  f"nats/action; β features {comp['beta_features']:.3g}, per-state {comp['beta_richer']:.3g}")
    if has_stats:
        alpha = (mis.details.get("thresholds") or {}).get("alpha", 0.05)
        whose = " refined" if mis.details.get("first") else ""  # a coarse set: the checks of the refined set
        title += (f"\nbars: {pred.get('replicates', 'the')} data sets simulated from the{whose} posterior; "
                  f"line: the demonstrations (red: rejected, Holm at family-wise level {alpha:g})")
    return title


def _departure_map(ax, comp: Mapping[str, Any], mdp: TabularMDP, trajs: Trajectories | None) -> None:
    dep = comp["departure"][0]
    xy = mdp.state_xy
    W, H = int(xy[:, 0].max()) + 1, int(xy[:, 1].max()) + 1
    grid = np.full((H, W), np.nan)
    for s, v in zip(dep["states"], dep["values"], strict=True):
        x, y = xy[s]
        grid[y, x] = v
    lim = float(np.nanmax(np.abs(grid))) if np.isfinite(grid).any() else 1.0
    lim = lim if lim > 0 else 1.0
    blocked = np.ones((H, W), dtype=bool)  # a cell that is no state: an obstacle, drawn as the maps draw it
    blocked[xy[:, 1], xy[:, 0]] = False
    ax.imshow(np.where(blocked, 1.0, np.nan), cmap=ListedColormap([maps.ZONE_COLORS[OBSTACLE]]),
              vmin=0, vmax=1, origin="upper", interpolation="nearest")
    im = ax.imshow(np.where(blocked, np.nan, grid), cmap="RdBu", vmin=-lim, vmax=lim, origin="upper",
                   interpolation="nearest")
    cb = ax.figure.colorbar(im, ax=ax, fraction=0.04, pad=0.01)
    cb.ax.tick_params(labelsize=8)
    cb.set_label("r(s): departure from θ̂·φ (reward units)", fontsize=8)
    goal = np.flatnonzero(mdp.terminal)
    ax.scatter(xy[goal, 0], xy[goal, 1], marker="*", s=160, color="gold", edgecolor="black", zorder=4,
               label="goal")
    if trajs is not None:
        for p in maps.paths_to_xy(trajs, mdp):
            ax.plot(p[:, 0], p[:, 1], color="black", lw=1, alpha=0.25)
    if blocked.any():
        ax.scatter([], [], marker="s", s=60, color=maps.ZONE_COLORS[OBSTACLE], label="obstacle")
    top = comp.get("top_states") or []
    if top:
        ax.scatter([xy[e["state"], 0] for e in top], [xy[e["state"], 1] for e in top], s=180,
                   facecolors="none", edgecolors="black", lw=1.5, zorder=5, label="largest departures")
    ax.set_title("where a per-state reward departs from θ̂·φ\n"
                 "(blue: drawn to it, red: kept away, beyond the features)", fontsize=9)
    ax.set_xticks(range(W))
    ax.set_yticks(range(H))
    ax.tick_params(labelsize=7)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=3, fontsize=8, frameon=False)


def render_check_png(path: str | Path, result: Result | Mapping[str, Any], *, mdp: TabularMDP | None = None,
                     trajs: Trajectories | None = None, source: str | Path = "result") -> Path:
    """Save :func:`check_figure` to ``path`` (the format follows the suffix)."""
    fig = check_figure(result, mdp=mdp, trajs=trajs, source=source)
    out = Path(path)
    save_figure_atomic(fig, out, dpi=maps.DPI, facecolor="white", bbox_inches="tight", pad_inches=0.08)
    fig.clear()
    return out
