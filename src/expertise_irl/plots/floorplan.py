"""Figures for warehouse floor plans in the style of the paper's Figs. 10–11 (matplotlib, Agg).

Roads are green arrows in their travel direction, restricted areas red, obstacles dark,
goals gold discs, start cells grey squares; visited cells are blue dots. Drawing is in
image orientation as in :mod:`expertise_irl.plots.maps`: cell (col, row) is centred
on data coordinates (col, row), row 0 at the top, whatever ``y_up`` says about the
recordings (their samples are converted to these coordinates by :func:`to_plot_coords`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch

from ..errors import InputError
from ..worlds.grid import FREE, GOAL, OBSTACLE, ROAD_DIRECTIONS, START
from ..worlds.warehouse import RESTRICTED, WarehouseMap
from . import maps

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..demos.recordings import Discretised

CELL_COLORS: dict[str, str] = {
    FREE: "#f7f7f5", START: "#f7f7f5", GOAL: "#f7f7f5",
    OBSTACLE: "#2b2b2b", RESTRICTED: "#e4544a",
    **dict.fromkeys(ROAD_DIRECTIONS, "#e3f4e1"),
}
ROAD_COLOR = "#2f9e44"
GOAL_FILL = "#f2b01e"
PATH_COLOR = "#1c6fb3"
SAMPLE_COLOR = "#7a7a7a"
FILLED_COLOR = "#e8590c"
SNAPPED_COLOR = "#c2255c"


def to_plot_coords(plan: WarehouseMap, x, y) -> tuple[np.ndarray, np.ndarray]:
    """Data coordinates (col, row, continuous; cell centres on integers) of points in metres."""
    c = plan.cell_size
    px = np.asarray(x, dtype=float) / c - 0.5
    fy = np.asarray(y, dtype=float) / c
    py = (plan.height - fy if plan.y_up else fy) - 0.5
    return px, py


def draw_floor_plan(ax: Axes, plan: WarehouseMap, *, show_grid: bool = True,
                    legend: bool = True) -> Axes:
    """Draw a floor plan: cells, green road arrows (gid ``"road-arrows"``), goals, starts."""
    g = plan.grid
    maps.draw_cells(ax, g, CELL_COLORS, grid_lw=0.3 if show_grid and max(g.shape) <= 80 else None)
    maps.draw_road_arrows(ax, g, color=ROAD_COLOR, length=0.6, width=0.1)
    maps.draw_starts(ax, g, 0.6)
    for row, col in np.argwhere(g == GOAL):
        ax.add_patch(Circle((col, row), 0.4, fc=GOAL_FILL, ec="#7a5200", lw=0.8, zorder=2, gid="goal"))
    maps.frame_cells(ax, g)
    if legend:
        handles = floor_plan_legend_handles(plan)
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=len(handles),
                  frameon=False, fontsize=7.5, handlelength=1.2, columnspacing=1.0, borderaxespad=0.2)
    return ax


def floor_plan_legend_handles(plan: WarehouseMap) -> list:
    """Legend handles for what the floor plan holds."""
    g = plan.grid
    handles: list = []
    if (g == OBSTACLE).any():
        handles.append(Patch(fc=CELL_COLORS[OBSTACLE], ec="#7a7a7a", lw=0.5, label="obstacle"))
    if (g == RESTRICTED).any():
        handles.append(Patch(fc=CELL_COLORS[RESTRICTED], ec="#7a7a7a", lw=0.5, label="restricted"))
    if np.isin(g, tuple(ROAD_DIRECTIONS)).any():
        handles.append(Line2D([], [], ls="", marker=r"$\rightarrow$", ms=9, color=ROAD_COLOR,
                              label="road (direction)"))
    if (g == START).any():
        handles.append(Line2D([], [], ls="", marker="s", ms=6, mfc="none", mec="#6b6b6b", label="start"))
    handles.append(Line2D([], [], ls="", marker="o", ms=7, mfc=GOAL_FILL, mec="#7a5200", label="goal"))
    return handles


def draw_cell_path(ax: Axes, plan: WarehouseMap, cells: np.ndarray, *, color: str = PATH_COLOR,
                   gid: str = "path", size: float = 4.0) -> Axes:
    """A path of cells as blue dots on a thin line (the paper's Figs. 10–11)."""
    p = np.asarray(cells)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
        raise InputError(f"{gid}: expected a non-empty [T, 2] array of cells, got {p.shape}")
    off = (p[:, 0] < 0) | (p[:, 0] >= plan.width) | (p[:, 1] < 0) | (p[:, 1] >= plan.height)
    if off.any():
        raise InputError(f"{gid}, step {int(np.argmax(off))}: cell {tuple(p[np.argmax(off)].tolist())} "
                         "is off the map")
    ax.plot(p[:, 0], p[:, 1], color=color, lw=0.8, alpha=0.6, zorder=4)
    ax.plot(p[:, 0], p[:, 1], ls="", marker="o", ms=size, color=color, zorder=5, gid=gid)
    return ax


def render_floor_plan_png(plan: WarehouseMap, path: str | Path, *,
                          trajectories_xy: Sequence[np.ndarray] | None = None,
                          title: str | None = None) -> Path:
    """Save a PNG of the floor plan, optionally with paths of cells (one ``[T, 2]`` per episode)."""
    mw, mh = maps.map_size(plan, 10.0, 8.0)
    fig = maps.new_figure((max(mw + 0.3, 5.2), mh + 1.1))
    ax = fig.add_subplot()
    draw_floor_plan(ax, plan)
    for i, p in enumerate(trajectories_xy or ()):
        draw_cell_path(ax, plan, p, color=maps.PATH_COLORS[i % len(maps.PATH_COLORS)],
                       gid=f"path-{i}")
    ax.set_title(title if title is not None else plan.name, fontsize=10)
    return maps.save_figure(fig, path)


def render_discretised_png(path: str | Path, plan: WarehouseMap, result: Discretised, *,
                           title: str | None = None) -> Path:
    """Save :func:`discretised_figure` as a PNG (dpi 120)."""
    return maps.save_figure(discretised_figure(plan, result, title=title), path)


def discretised_figure(plan: WarehouseMap, result: Discretised, *, title: str | None = None):
    """Recorded samples against the cells they became, one panel per episode.

    Grey dots: every sample (gid ``samples-k``); hollow rings: the samples kept at the ticks
    (``kept-k``); crosses: snapped samples (``snapped-k``); blue dots: the visited cells
    (``cells-k``); orange dots: cells filled into gaps (``filled-k``).
    """
    eps = result.episodes
    cols = min(len(eps), 3)
    rows = -(-len(eps) // cols)
    mw, mh = maps.map_size(plan, 6.0, 5.0)
    fig = maps.new_figure((cols * (mw + 0.3), rows * (mh + 0.7) + 0.6))
    for k, ep in enumerate(eps):
        ax = fig.add_subplot(rows, cols, k + 1)
        draw_floor_plan(ax, plan, legend=False)
        px, py = to_plot_coords(plan, ep.samples_xy[:, 0], ep.samples_xy[:, 1])
        ax.plot(px, py, color=SAMPLE_COLOR, lw=0.5, alpha=0.7, zorder=4)
        ax.plot(px, py, ls="", marker=".", ms=2.5, color=SAMPLE_COLOR, zorder=4, gid=f"samples-{k}")
        ax.plot(px[ep.kept], py[ep.kept], ls="", marker="o", ms=5, mfc="none", mec="#333333",
                mew=0.6, zorder=6, gid=f"kept-{k}")
        if ep.snapped.any():
            ax.plot(px[ep.snapped], py[ep.snapped], ls="", marker="x", ms=5, color=SNAPPED_COLOR,
                    zorder=7, gid=f"snapped-{k}")
        draw_cell_path(ax, plan, ep.cells, gid=f"cells-{k}", size=3.5)
        if ep.filled.any():
            f = ep.cells[ep.filled]
            ax.plot(f[:, 0], f[:, 1], ls="", marker="o", ms=4.5, color=FILLED_COLOR, zorder=6,
                    gid=f"filled-{k}")
        ax.set_title(f"episode {ep.episode}: {len(ep.samples_xy)} samples → {ep.moves} moves; "
                     f"filled gaps {ep.filled_gaps}, snapped samples {ep.snapped_samples}", fontsize=8)
    handles = [
        Line2D([], [], ls="", marker=".", ms=6, color=SAMPLE_COLOR, label="sample"),
        Line2D([], [], ls="", marker="o", ms=6, mfc="none", mec="#333333",
               label=f"kept at {result.rate:g} Hz"),
        Line2D([], [], ls="", marker="o", ms=5, color=PATH_COLOR, label="cell of the path"),
        Line2D([], [], ls="", marker="o", ms=5, color=FILLED_COLOR, label="filled into a gap"),
        Line2D([], [], ls="", marker="x", ms=5, color=SNAPPED_COLOR, label="snapped sample"),
        *floor_plan_legend_handles(plan),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 5), frameon=False,
               fontsize=7.5)
    fig.suptitle(title if title is not None else plan.name, fontsize=10)
    return fig
