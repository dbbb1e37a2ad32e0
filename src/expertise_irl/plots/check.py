"""The figure of ``plot --check``: a result's misspecification checks.

Top: one panel per predictive statistic, the histogram of its replicated values (the posterior
predictive distribution) with the demonstrations' value as a vertical line and the p-value in the
title (red when Holm's rule rejects it; the figure's title says so). Bottom (with ``--check full``
results and a map): the richer reward's departure from θ̂·φ, r(s) for entering each state, on the
grid (blue: the person is drawn to it beyond the features, red: kept away), the demonstrations over
it and the largest departures circled.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import save_figure_atomic
from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from . import maps

REJECTED, PASSED = "#c0392b", "#222222"


def check_figure(doc: dict[str, Any], *, mdp: TabularMDP | None = None, trajs: Trajectories | None = None,
                 source: str | Path = "result"):
    """The :class:`~matplotlib.figure.Figure` of ``doc``'s ``diagnostics.misspecification``."""
    from matplotlib.figure import Figure

    diag = doc.get("diagnostics") or {}
    mis = diag.get("misspecification")
    if not mis:
        why = (diag.get("unavailable") or {}).get("misspecification")
        raise InputError(f"{source}: the result has no diagnostics.misspecification ("
                         + (why if why else "infer and study write it with --check fast or full, the default")
                         + ")")
    pred = mis.get("predictive") or {}
    stats = pred.get("statistics") or {}
    comp = mis.get("competitor")
    show_map = comp is not None and mdp is not None and mdp.state_xy is not None
    n = len(stats)
    cols = 4
    rows = -(-n // cols) if n else 0
    fig = Figure(figsize=(11, 2.3 * rows + (6.0 if show_map else 0) + 0.6))
    heights = [1.0] * rows + ([3.2] if show_map else [])
    gs = fig.add_gridspec(len(heights), cols, height_ratios=heights, hspace=0.75, wspace=0.3)
    for i, (name, s) in enumerate(stats.items()):
        ax = fig.add_subplot(gs[i // cols, i % cols])
        values = np.array([v for v in pred["replicated"][name] if v is not None], dtype=float)
        if values.size:
            ax.hist(values, bins=min(30, max(5, len(np.unique(values)))), color="#9db4c8", edgecolor="white")
        if s["observed"] is not None:
            ax.axvline(s["observed"], color=REJECTED if s["rejected"] else PASSED, lw=2)
        p = s["p_value"]
        ax.set_title(f"{name}\np = {p:.3g}" if p is not None else f"{name}\np: n/a", fontsize=9,
                     color=REJECTED if s["rejected"] else PASSED)
        ax.tick_params(labelsize=7)
        ax.set_yticks([])
        maps.tidy(ax)
    if show_map:
        _departure_map(fig.add_subplot(gs[rows, :]), comp, mdp, trajs)
    title = f"{mis['verdict']} — {mis['reason']}"
    if comp is not None:
        title += (f"\nheld-out gain of a per-state reward {comp['gain']:.3g} ± {comp['gain_se']:.2g} "
                  f"nats/action; β features {comp['beta_features']:.3g}, per-state {comp['beta_richer']:.3g}")
    if stats:
        alpha = (mis.get("thresholds") or {}).get("alpha", 0.05)
        title += (f"\nbars: {pred.get('replicates', 'the')} data sets simulated from the posterior; "
                  f"line: the demonstrations (red: rejected, Holm at family-wise level {alpha:g})")
    fig.suptitle(title, fontsize=10, wrap=True)
    return fig


def _departure_map(ax, comp: dict[str, Any], mdp: TabularMDP, trajs: Trajectories | None) -> None:
    dep = comp["departure"][0]
    xy = mdp.state_xy
    W, H = int(xy[:, 0].max()) + 1, int(xy[:, 1].max()) + 1
    grid = np.full((H, W), np.nan)
    for s, v in zip(dep["states"], dep["values"], strict=True):
        x, y = xy[s]
        grid[y, x] = v
    lim = float(np.nanmax(np.abs(grid))) if np.isfinite(grid).any() else 1.0
    lim = lim if lim > 0 else 1.0
    im = ax.imshow(grid, cmap="RdBu", vmin=-lim, vmax=lim, origin="upper")
    cb = ax.figure.colorbar(im, ax=ax, fraction=0.03, pad=0.01)
    cb.set_label("r(s): departure from θ̂·φ (reward units)", fontsize=8)
    goal = np.flatnonzero(mdp.terminal)
    ax.scatter(xy[goal, 0], xy[goal, 1], marker="*", s=160, color="gold", edgecolor="black", zorder=4,
               label="goal")
    if trajs is not None:
        for p in maps.paths_to_xy(trajs, mdp):
            ax.plot(p[:, 0], p[:, 1], color="black", lw=1, alpha=0.25)
    top = comp.get("top_states") or []
    if top:
        ax.scatter([xy[e["state"], 0] for e in top], [xy[e["state"], 1] for e in top], s=180,
                   facecolors="none", edgecolors="black", lw=1.5, zorder=5, label="largest departures")
    ax.set_title("where a per-state reward departs from θ̂·φ (red: kept away beyond the features)", fontsize=9)
    ax.set_xticks(range(W))
    ax.set_yticks(range(H))
    ax.tick_params(labelsize=7)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=2, fontsize=8, frameon=False)


def render_check_png(path: str | Path, doc: dict[str, Any], *, mdp: TabularMDP | None = None,
                     trajs: Trajectories | None = None, source: str | Path = "result") -> Path:
    """Save :func:`check_figure` to ``path`` (the format follows the suffix)."""
    fig = check_figure(doc, mdp=mdp, trajs=trajs, source=source)
    out = Path(path)
    save_figure_atomic(fig, out, dpi=maps.DPI, facecolor="white", bbox_inches="tight", pad_inches=0.08)
    fig.clear()
    return out
