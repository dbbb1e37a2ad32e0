"""One participant's figure of ``expertise-irl study``: their tasks and their posterior.

Top: the participant, the method, β̂ and θ̂ in words, several modes of the posterior when
there are, the count of the result's ``diagnostics.warnings`` with the first two shortened,
and one legend for every map. Middle: one map panel per task, up to three in a row, with the
observed path(s) (thin blue) over the optimal path(s) of θ̂ (wide orange: where the two
agree the blue line runs inside the orange one) and a summary above (the task's title; the
observed and the optimal paths: how many, their moves, how many reach a goal; under
``share == "beta"`` the task's own θ̂). Three kinds of task world are drawn:

- a warehouse floor plan (:class:`~expertise_irl.worlds.warehouse.WarehouseMap`),
- a zone map (:class:`~expertise_irl.worlds.zones.ZoneMap`),
- no map (``world=None``, an MDP archive): with ``mdp.state_xy`` its states are drawn as
  cells of a grid (or as dots when the layout is sparse) and the paths on them; without it
  the task gets no map panel, only a line of text summary.

Bottom: the posterior block, two panels side by side: β (bars of the marginal on the
discrete grid, a histogram of the NUTS draws, or the MAP point), on a log axis, with the
90% interval shaded and the mean (β̂) and median marked; and θ (one row per feature with its
marginal bars / histogram of draws, θ̂ and its 90% interval; or, when θ is estimated per
task (``doc["share"] == "beta"``), one row per task with θ̂ of each feature).

Layout rules (acceptance criteria, checked by ``tests/userstudy/test_study_figures.py``):

1. No panel (axes) is narrower than a third of the figure width: task panels are a third,
   a half or all of the width (three, two or one per row), the two posterior panels each
   more than a third.
2. The figure's aspect ratio (height / width and width / height) is at most 2:1 for up to
   :data:`MAX_TASKS` tasks; the figure is :data:`FIG_WIDTH` inches wide, its height follows
   the content (taller posterior panels when it would be too flat, smaller maps when it
   would be too tall).
3. Readable at the saved size (:data:`DPI`): no text below :data:`MIN_FONT` pt; at most
   :data:`MAX_BETA_TICKS` tick labels on the β axis, and they do not overlap.
4. More than :data:`MAX_TASKS` tasks: the first :data:`MAX_TASKS` are drawn and the figure
   says "12 of N tasks shown; all in tasks.csv".

Speed: the layout is computed here in inches (no constrained layout, no tight bounding box,
so the figure is drawn once), maps are one image each (``imshow``) and the paths of a task
are two line collections: about 0.4 s for a three-task floor-plan participant on a shared
two-core machine (the figure before this layout: about 1 s there). :func:`light_panel` strips a
panel's MDP to what is drawn, for sending panels to worker processes.

Panels as the study passed them before (``plan`` and ``[T, 2]`` cells instead of ``world``,
``mdp`` and state indices) are still drawn.

The PNG is the same bytes whichever process draws it: the figure is built and saved under
Matplotlib's default style (plus this module's settings) whatever the caller's rcParams, and
without the software version in its metadata.
"""

from __future__ import annotations

import io
import math
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib as mpl
import matplotlib.style
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle
from matplotlib.ticker import FixedLocator, FuncFormatter, MaxNLocator, NullLocator

from ..atomic import write_atomic
from ..worlds.grid import GOAL
from ..worlds.warehouse import WarehouseMap
from ..worlds.zones import ZoneMap
from . import maps
from .floorplan import GOAL_FILL, draw_floor_plan, floor_plan_legend_handles
from .results import theta_component_marginal

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..mdp import TabularMDP

#: Width of every participant figure (inches) and its resolution.
FIG_WIDTH = 12.0
DPI = 100
#: Tasks drawn at most (the rest are in tasks.csv); task panels per row at most.
MAX_TASKS = 12
MAX_COLUMNS = 3
#: Smallest font (points) anywhere in the figure; most β tick labels.
MIN_FONT = 8.0
MAX_BETA_TICKS = 8
#: Largest aspect ratio (either way) for up to MAX_TASKS tasks.
MAX_ASPECT = 2.0
OBSERVED_COLOR = "#1c4f9c"
OPTIMAL_COLOR = "#f08c00"
POST_COLOR = "#4c72b0"
BAND_COLOR = "#a5c0e6"
MEAN_COLOR = "#1a1a1a"
MEDIAN_COLOR = "#c2255c"
WARN_COLOR = "#b02a1a"
CAPTION_COLOR = "#a14a00"
LAYOUT_FREE = "#f4f4f2"
LAYOUT_VOID = "#d9d9d9"
FEATURE_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")
#: PNG metadata: no software version, so the bytes do not depend on the installation's
#: Matplotlib build (PNGs from Agg carry no timestamp).
PNG_METADATA: dict[str, Any] = {"Software": None}
_RC = {
    "font.size": 8.5, "axes.titlesize": 9.0, "axes.labelsize": 8.5, "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0, "legend.fontsize": 8.0, "legend.title_fontsize": 8.0,
    "figure.dpi": DPI, "savefig.dpi": DPI,
}
# Matplotlib's global state (rcParams, font caches) is not thread-safe: a Dask worker with
# several threads draws one figure at a time.
_DRAW_LOCK = threading.Lock()


@contextmanager
def figure_style() -> Iterator[None]:
    """Matplotlib's default style plus this module's font sizes, whatever the caller set."""
    with mpl.style.context("default"), mpl.rc_context(_RC):
        yield


# ---------------------------------------------------------------------------- tasks
@dataclass
class _Task:
    """What the figure needs of one task panel."""

    number: int  # 1-based, in the participant's order
    title: str
    world: WarehouseMap | ZoneMap | None
    layout: np.ndarray | None  # [S, 2] (x, y) cell of each state; None: nothing to draw
    observed: list[np.ndarray]  # [T, 2] cells per episode
    optimal: list[np.ndarray]
    observed_goal: list[bool | None]  # does each path end in a goal (None: unknown)
    optimal_goal: list[bool | None]
    theta_hat: list[float] | None
    theta_marginal: dict[str, Any] | None
    extent: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)  # x0, x1, y0, y1 (cell edges)
    terminal: np.ndarray | None = None  # [S] terminal states of the MDP


@dataclass(frozen=True)
class TaskStates:
    """What the figure reads of a task's MDP: ``state_xy`` (or None) and ``terminal``."""

    state_xy: np.ndarray | None
    terminal: np.ndarray


def light_panel(panel: dict[str, Any]) -> dict[str, Any]:
    """``panel`` with its MDP replaced by its :class:`TaskStates`: the same figure, from a panel a
    hundred times smaller to send to a worker (a floor plan's MDP is megabytes of features)."""
    mdp = panel.get("mdp")
    if mdp is None or isinstance(mdp, TaskStates):
        return dict(panel)
    return {**panel, "mdp": TaskStates(None if mdp.state_xy is None else np.asarray(mdp.state_xy),
                                       np.asarray(mdp.terminal, dtype=bool))}


def _layout_of(world, mdp: TabularMDP | TaskStates | None) -> np.ndarray | None:
    if mdp is not None and mdp.state_xy is not None:
        return np.asarray(mdp.state_xy, dtype=np.int64)
    if isinstance(world, WarehouseMap):
        return world.state_cells()
    if isinstance(world, ZoneMap):
        return world.cells
    return None


def _paths(raw, layout: np.ndarray | None, world, mdp: TabularMDP | TaskStates | None
           ) -> tuple[list[np.ndarray], list[bool | None]]:
    """Cells ``[T, 2]`` of each path and whether it ends in a goal.

    A path is given as state indices (1-D; indices outside the MDP are dropped) or, as the
    study's panels used to be, as ``[T, 2]`` cells.
    """
    cells, goal = [], []
    for p in raw or ():
        a = np.asarray(p)
        if a.ndim == 2 and a.shape[1] == 2:  # cells already
            c = a.astype(np.int64)
            if not len(c):
                continue
            cells.append(c)
            if world is not None and 0 <= c[-1, 1] < world.height and 0 <= c[-1, 0] < world.width:
                goal.append(bool(world.grid[c[-1, 1], c[-1, 0]] == GOAL))
            else:
                goal.append(None)
            continue
        s = a.astype(np.int64).ravel()
        n = len(mdp.terminal) if mdp is not None else (len(layout) if layout is not None else 0)
        s = s[(s >= 0) & (s < n)]
        if not len(s):
            continue
        cells.append(layout[s] if layout is not None else np.zeros((len(s), 2), dtype=np.int64))
        goal.append(bool(mdp.terminal[s[-1]]) if mdp is not None else None)
    return cells, goal


def _task(number: int, panel: dict[str, Any]) -> _Task:
    world = panel.get("world", panel.get("plan"))
    mdp = panel.get("mdp")
    if mdp is None and world is not None:
        mdp = world.to_mdp()
    layout = _layout_of(world, mdp)
    obs, obs_goal = _paths(panel.get("observed"), layout, world, mdp)
    opt, opt_goal = _paths(panel.get("optimal"), layout, world, mdp)
    t = _Task(number, str(panel.get("title", f"task {number}")), world, layout, obs, opt, obs_goal,
              opt_goal, panel.get("theta_hat"), panel.get("theta_marginal"),
              terminal=None if mdp is None else np.asarray(mdp.terminal, dtype=bool))
    if world is not None:
        t.extent = (-0.5, world.width - 0.5, -0.5, world.height - 0.5)
    elif layout is not None and len(layout):
        lo, hi = layout.min(axis=0), layout.max(axis=0)
        t.extent = (lo[0] - 0.5, hi[0] + 0.5, lo[1] - 0.5, hi[1] + 0.5)
    else:
        t.layout = None
    return t


def _span(counts: list[int]) -> str:
    lo, hi = min(counts), max(counts)
    return f"{lo}" if lo == hi else f"{lo}–{hi}"


def _path_summary(what: str, paths: list[np.ndarray], goal: list[bool | None]) -> str:
    """``"observed: 3 episodes, 34–40 moves, 2/3 reach a goal"``."""
    if not paths:
        return f"{what}: none"
    noun = "episode" if what == "observed" else "path"
    text = f"{what}: {len(paths)} {noun}{'s' if len(paths) != 1 else ''}, " \
           f"{_span([len(p) - 1 for p in paths])} moves"
    known = [g for g in goal if g is not None]
    if known:
        text += f", {sum(known)}/{len(known)} reach a goal"
    return text


def _fmt_vec(v) -> str:
    return "[" + ", ".join(f"{float(x):.2f}" for x in v) + "]"


def _short(text: str, n: int) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= n else text[: n - 1] + "…"


# --------------------------------------------------------------------------- layout
@dataclass
class _Layout:
    """Inches of every block, top to bottom."""

    header: float
    legend: float
    rows: list[tuple[float, float]]  # (title band, map box) per row of task panels
    text: float
    post_top: float
    post: float
    post_bottom: float
    columns: int

    @property
    def height(self) -> float:
        return (self.header + self.legend + sum(t + b + ROW_GAP for t, b in self.rows) + self.text
                + self.post_top + self.post + self.post_bottom + BOTTOM_PAD)


ROW_GAP = 0.12
BOTTOM_PAD = 0.1
HEADER_LINE = 0.21
TITLE_LINE = 0.155
LEGEND_ROW = 0.24
TEXT_LINE = 0.19
LEGEND_COLUMNS = 6


def _map_rows(mapped: list[_Task], columns: int, title_lines: int, cap: float) -> list[tuple[float, float]]:
    slot = FIG_WIDTH / max(columns, 1)
    rows = []
    for r in range(0, len(mapped), max(columns, 1)):
        need = 0.0
        for t in mapped[r:r + columns]:
            x0, x1, y0, y1 = t.extent
            need = max(need, (slot - 0.3) * (y1 - y0) / (x1 - x0) + 0.1)
        rows.append((0.1 + TITLE_LINE * title_lines, min(max(need, 1.2), cap)))
    return rows


# ------------------------------------------------------------------------ the figure
def participant_figure(participant: str, panels: Sequence[dict[str, Any]], doc: dict[str, Any]) -> Figure:
    """The :class:`~matplotlib.figure.Figure` of one participant (see the module docstring).

    ``panels``: one dict per task, in the participant's order: ``world`` (a floor plan, a zone
    map or None), ``mdp`` (the task's :class:`~expertise_irl.mdp.TabularMDP`), ``title``,
    ``observed`` and ``optimal`` (one array of visited state indices per episode, final state
    included), and under ``doc["share"] == "beta"`` the task's own ``theta_hat`` and (discrete)
    ``theta_marginal``. ``doc``: the participant's result document.
    """
    with figure_style():
        return _figure(str(participant), list(panels), doc)


def _figure(participant: str, panels: list[dict[str, Any]], doc: dict[str, Any]) -> Figure:
    names = [str(n) for n in doc["feature_names"]]
    per_task_theta = doc.get("share") == "beta" or doc.get("theta_hat") is None
    tasks = [_task(i + 1, p) for i, p in enumerate(panels[:MAX_TASKS])]
    mapped = [t for t in tasks if t.layout is not None]
    textonly = [t for t in tasks if t.layout is None]

    header = _header_lines(participant, doc, names, len(panels), per_task_theta)
    handles = _legend_handles(mapped, doc) if mapped else []
    columns = min(len(mapped), MAX_COLUMNS)
    title_lines = 4 if per_task_theta else 3
    rows_of_theta = len(tasks) if per_task_theta else len(names)
    post = max(2.2, 0.32 * rows_of_theta + 0.3) if per_task_theta else max(2.2, 0.55 * len(names) + 0.3)
    cap = min(0.7 * FIG_WIDTH / max(columns, 1), 5.5)
    for _ in range(20):  # smaller maps until the figure is at most twice as tall as wide
        lay = _Layout(
            header=0.12 + HEADER_LINE * len(header) + 0.05,
            legend=(LEGEND_ROW * math.ceil(len(handles) / LEGEND_COLUMNS) + 0.08) if handles else 0.0,
            rows=_map_rows(mapped, columns, title_lines, cap),
            text=(0.3 + TEXT_LINE * len(textonly)) if textonly else 0.0,
            post_top=0.55, post=post, post_bottom=1.0 if per_task_theta else 0.85, columns=columns)
        if lay.height <= MAX_ASPECT * FIG_WIDTH or cap <= 1.2:
            break
        cap = max(cap * 0.85, 1.2)
    lay.post += max(FIG_WIDTH / MAX_ASPECT - lay.height, 0.0)  # not flatter than 2:1
    H = lay.height
    fig = Figure(figsize=(FIG_WIDTH, H), dpi=DPI)
    FigureCanvasAgg(fig)

    def rect(x: float, top: float, w: float, h: float) -> list[float]:
        """Axes rectangle (figure fractions) of a box ``w`` × ``h`` inches, ``top`` from the top."""
        return [x / FIG_WIDTH, 1 - (top + h) / H, w / FIG_WIDTH, h / H]

    def text(y: float, s: str, **kw):
        return fig.text(0.5, 1 - y / H, s, ha="center", va="top", **kw)

    # header
    y = 0.12
    for i, (line, style) in enumerate(header):
        text(y, line, **style)
        y += HEADER_LINE + (0.03 if i == 0 else 0.0)
    y = lay.header
    if handles:
        leg = fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 1 - y / H),
                         ncol=min(len(handles), LEGEND_COLUMNS), frameon=False, fontsize=8,
                         handlelength=2.0, columnspacing=1.4, borderaxespad=0.0)
        leg.set_gid("legend")
        y += lay.legend
    # task panels
    slot = FIG_WIDTH / max(columns, 1)
    for r, (band, box) in enumerate(lay.rows):
        y += band
        for c, t in enumerate(mapped[r * columns:(r + 1) * columns]):
            ax = fig.add_axes(rect(c * slot, y, slot, box))
            ax.set_gid(f"task-{t.number}")
            _draw_task(ax, t, slot, box, per_task_theta)
        y += box + ROW_GAP
    if textonly:
        text(y + 0.05, "tasks without a state layout (no map to draw):", fontsize=8.5,
             fontweight="bold", gid="text-tasks-title")
        for i, t in enumerate(textonly):
            text(y + 0.05 + TEXT_LINE * (i + 1), _text_summary(t, per_task_theta), fontsize=8.5,
                 gid=f"task-{t.number}-text")
        y += lay.text
    # posterior block
    y += lay.post_top
    ax_b = fig.add_axes(rect(0.75, y, 0.42 * FIG_WIDTH, lay.post))
    ax_b.set_gid("posterior-beta")
    left = FIG_WIDTH / 2 + (0.95 if per_task_theta else 1.5)
    ax_t = fig.add_axes(rect(left, y, FIG_WIDTH - left - 0.3, lay.post))
    ax_t.set_gid("posterior-theta")
    legend_y = 1 - (y + lay.post + 0.5) / H
    _draw_beta(ax_b, doc, legend_y)
    if per_task_theta:
        _draw_theta_per_task(ax_t, doc, tasks, names, legend_y)
    else:
        _draw_theta(ax_t, doc, names)
    return fig


def _header_lines(participant: str, doc: dict[str, Any], names: list[str], n_tasks: int,
                  per_task_theta: bool) -> list[tuple[str, dict[str, Any]]]:
    """The header's lines, each with its text style."""
    method = doc["method"]
    samples = doc.get("samples") if isinstance(doc.get("samples"), dict) else {}
    what = {"discrete": "discrete posterior", "map": "MAP point estimate (no posterior)"}.get(
        method, f"{str(method).upper()} posterior")
    if samples.get("beta") is not None and method != "discrete":
        what += f" ({len(samples['beta'])} draws)"
    lines: list[tuple[str, dict[str, Any]]] = [
        (f"Participant {participant}: {what}, {n_tasks} task{'s' if n_tasks != 1 else ''}",
         {"fontsize": 11, "fontweight": "bold", "gid": "title"})]
    s = _beta_summary(doc)
    beta = f"β̂ = {float(doc['beta_hat']):.3g}"
    if s["q05"] is not None and s["q95"] is not None:
        beta += f" (90% interval {s['q05']:.3g} – {s['q95']:.3g})"
    if per_task_theta:
        theta = "θ estimated per task (in each task's panel)"
    else:
        theta = "θ̂ = " + ", ".join(f"{n} {float(v):.2f}"
                                   for n, v in zip(names, doc["theta_hat"], strict=False))
    lines.append((_short(f"{beta};  {theta}", 170), {"fontsize": 9.5, "gid": "estimate"}))
    modes = [m for m in doc.get("modes") or [] if isinstance(m, dict)]
    if len(modes) > 1:
        parts = [f"θ = {_fmt_vec(m.get('theta', []))}, β = {float(m.get('beta', float('nan'))):g}: "
                 f"p = {float(m.get('probability', float('nan'))):.2f}" for m in modes[:3]]
        more = f"; and {len(modes) - 3} more" if len(modes) > 3 else ""
        lines.append((_short(f"{len(modes)} separated modes: " + "; ".join(parts) + more, 170),
                      {"fontsize": 8.5, "gid": "modes"}))
    warnings = _warnings(doc)
    if warnings:
        n = len(warnings)
        lines.append((f"{n} warning{'s' if n != 1 else ''} (all in result.json, diagnostics.warnings)"
                      + (":" if n else ""), {"fontsize": 8.5, "color": WARN_COLOR, "fontweight": "bold",
                                              "gid": "warnings"}))
        for i, w in enumerate(warnings[:2]):
            lines.append((_short(f"• {w}", 165),
                          {"fontsize": 8.5, "color": WARN_COLOR, "gid": f"warning-{i}"}))
    if n_tasks > MAX_TASKS:
        lines.append((f"{MAX_TASKS} of {n_tasks} tasks shown; all in tasks.csv",
                      {"fontsize": 9, "fontweight": "bold", "color": CAPTION_COLOR, "gid": "tasks-caption"}))
    return lines


def _warnings(doc: dict[str, Any]) -> list[str]:
    diag = doc.get("diagnostics")
    warnings = diag.get("warnings") if isinstance(diag, dict) else None
    return [str(w) for w in warnings] if isinstance(warnings, list) else []


def _legend_handles(mapped: list[_Task], doc: dict[str, Any]) -> list:
    """One legend for every map: the paths, their ends, then the keys of the worlds drawn."""
    settings = doc.get("settings") if isinstance(doc.get("settings"), dict) else {}
    ob = settings.get("optimal_beta")
    opt = f"optimal path (θ̂, β = {float(ob):g})" if isinstance(ob, int | float) else "optimal path of θ̂"
    handles: list = [
        Line2D([], [], color=OBSERVED_COLOR, lw=1.4, label="observed path"),
        Line2D([], [], color=OPTIMAL_COLOR, lw=3.6, solid_capstyle="round", label=opt),
        Line2D([], [], ls="", marker="o", ms=5, mfc="white", mec=OBSERVED_COLOR, mew=1.2, label="path start"),
        Line2D([], [], ls="", marker="*", ms=8, mfc=OBSERVED_COLOR, mec="white", mew=0.5,
               label="observed end: at a goal"),
        Line2D([], [], ls="", marker="X", ms=6, mfc=OBSERVED_COLOR, mec="white", mew=0.5,
               label="observed end: elsewhere"),
    ]
    seen = {h.get_label() for h in handles}
    keys: list = []
    plan = next((t.world for t in mapped if isinstance(t.world, WarehouseMap)), None)
    zone = next((t.world for t in mapped if isinstance(t.world, ZoneMap)), None)
    if plan is not None:
        keys += floor_plan_legend_handles(plan)
    if zone is not None:
        keys += maps.map_legend_handles(zone)
    if any(t.world is None for t in mapped):
        keys += [Patch(fc=LAYOUT_FREE, ec="#7a7a7a", lw=0.5, label="state (from state_xy)"),
                 Line2D([], [], ls="", marker="o", ms=7, mfc=maps.GOAL_COLOR, mec="white",
                        label="terminal state")]
    for h in keys:
        if h.get_label() not in seen:
            seen.add(h.get_label())
            handles.append(h)
    return handles


# ----------------------------------------------------------------------------- maps
def _draw_task(ax: Axes, t: _Task, w_in: float, h_in: float, per_task_theta: bool) -> None:
    """Map, paths and the summary above, the map centred in a box ``w_in`` × ``h_in`` inches."""
    if isinstance(t.world, WarehouseMap):
        draw_floor_plan(ax, t.world, show_grid=False, legend=False)
    elif isinstance(t.world, ZoneMap):
        maps.draw_map(ax, t.world, show_grid=False, legend=False)
    else:
        _draw_layout(ax, t)
    x0, x1, y0, y1 = t.extent
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="#6b6b6b", lw=0.7, zorder=8))
    # square cells, the map centred in the box (limits set here, so the box never moves)
    scale = min((w_in - 0.3) / (x1 - x0), (h_in - 0.1) / (y1 - y0))  # inches per cell
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    ax.set_aspect("auto")
    ax.set_xlim(cx - w_in / scale / 2, cx + w_in / scale / 2)
    ax.set_ylim(cy + h_in / scale / 2, cy - h_in / scale / 2)  # row 0 on top
    ax.set_axis_off()
    if t.world is not None and scale * 72 < 9:  # small cells: goals drawn at a readable size on top
        g = np.argwhere(t.world.grid == GOAL)
        ax.plot(g[:, 1], g[:, 0], ls="", marker="o", ms=6.5, zorder=8, gid="goal-marker",
                mfc=GOAL_FILL if isinstance(t.world, WarehouseMap) else maps.GOAL_COLOR,
                mec="#7a5200" if isinstance(t.world, WarehouseMap) else "white", mew=0.8)
    jitter = 0.15 if scale * 72 >= 8 else 0.0  # too small cells: offsets would only blur
    _draw_paths(ax, t.optimal, t.optimal_goal, OPTIMAL_COLOR, "optimal", 3.4, jitter, ends=False)
    _draw_paths(ax, t.observed, t.observed_goal, OBSERVED_COLOR, "observed", 1.3, jitter, ends=True)
    lines = [(_short(f"task {t.number}: {t.title}", int(w_in / 0.072)), 8.5, "#1a1a1a", "bold"),
             (_path_summary("observed", t.observed, t.observed_goal), 8.0, OBSERVED_COLOR, "normal"),
             (_path_summary("optimal", t.optimal, t.optimal_goal), 8.0, "#9a5500", "normal")]
    if per_task_theta and t.theta_hat is not None:
        lines.append((f"this task's θ̂ = {_fmt_vec(t.theta_hat)}", 8.0, "#1a1a1a", "normal"))
    for j, (s, size, color, weight) in enumerate(lines):
        ax.annotate(s, (0.5, 1.0), xycoords="axes fraction", xytext=(0, 3 + 11.2 * (len(lines) - 1 - j)),
                    textcoords="offset points", ha="center", va="bottom", fontsize=size, color=color,
                    fontweight=weight, annotation_clip=False, gid=f"task-{t.number}-title-{j}")


def _draw_layout(ax: Axes, t: _Task) -> None:
    """States of an MDP archive from ``state_xy``: an image of the cells holding a state (dots
    when the layout is sparse or huge), terminal states as green discs."""
    from matplotlib.colors import to_rgb

    xy = t.layout
    x0, x1, y0, y1 = (round(v + 0.5) for v in t.extent)
    w, h = x1 - x0, y1 - y0
    cells = np.unique(xy, axis=0)
    if w * h <= 250_000 and len(cells) >= 0.2 * w * h:
        img = np.empty((h, w, 3))
        img[:] = to_rgb(LAYOUT_VOID)
        img[cells[:, 1] - y0, cells[:, 0] - x0] = to_rgb(LAYOUT_FREE)
        ax.imshow(img, extent=(x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5), origin="upper",
                  interpolation="nearest", zorder=0)
    else:
        ax.plot(cells[:, 0], cells[:, 1], ls="", marker=".", ms=2, color="#9a9a9a", zorder=1, gid="states")
    goals = xy[t.terminal] if t.terminal is not None and len(t.terminal) == len(xy) else xy[:0]
    if len(goals):
        goals = np.unique(goals, axis=0)
        ax.plot(goals[:, 0], goals[:, 1], ls="", marker="o", ms=6, mfc=maps.GOAL_COLOR, mec="white",
                mew=0.6, zorder=6, gid="goal")


def _draw_paths(ax: Axes, paths: list[np.ndarray], goal: list[bool | None], color: str, gid: str,
                width: float, jitter: float, *, ends: bool) -> None:
    """Paths as one line collection (gid ``gid``), start markers and, when ``ends``, end markers
    (★ at a goal, ✕ elsewhere)."""
    if not paths:
        return
    offsets = maps._jitter_offsets(len(paths), jitter)
    xy = [p.astype(float) + offsets[i] for i, p in enumerate(paths)]
    if not ends:  # the wide path gets a white edge, so it shows on any cell colour
        ax.add_collection(LineCollection(xy, colors="white", linewidths=width + 1.6, zorder=5,
                                         capstyle="round", joinstyle="round"))
    lc = LineCollection(xy, colors=color, linewidths=width, zorder=6 if not ends else 7, alpha=0.95,
                        capstyle="round", joinstyle="round")
    lc.set_gid(gid)
    ax.add_collection(lc)
    if ends:
        starts = np.array([p[0] for p in xy])
        ax.plot(starts[:, 0], starts[:, 1], ls="", marker="o", ms=5, mfc="white", mec=color, mew=1.2,
                zorder=9, gid=f"{gid}-start")
        for marker, hit in (("*", True), ("X", False)):
            pts = np.array([p[-1] for p, g in zip(xy, goal, strict=True)
                            if (g is True) == hit]).reshape(-1, 2)
            if len(pts):
                ax.plot(pts[:, 0], pts[:, 1], ls="", marker=marker, ms=9 if marker == "*" else 6.5,
                        mfc=color, mec="white", mew=0.5, zorder=9,
                        gid=f"{gid}-end-{'goal' if hit else 'other'}")


def _text_summary(t: _Task, per_task_theta: bool) -> str:
    s = (f"task {t.number}: {_short(t.title, 48)} — "
         f"{_path_summary('observed', t.observed, t.observed_goal)}; "
         f"{_path_summary('optimal', t.optimal, t.optimal_goal)}")
    if per_task_theta and t.theta_hat is not None:
        s += f"; θ̂ = {_fmt_vec(t.theta_hat)}"
    return _short(s, 175)


# ----------------------------------------------------------------------- posterior
def _weighted_quantile(values, probs, q: float) -> float:
    v, p = np.asarray(values, dtype=float), np.asarray(probs, dtype=float)
    order = np.argsort(v, kind="stable")
    cdf = np.cumsum(p[order]) / p.sum()
    return float(v[order][min(int(np.searchsorted(cdf, q - 1e-12)), len(v) - 1)])


def finite_or_none(x) -> float | None:
    """``x`` as a finite float; None when it is not a number (None, text, NaN, ±inf)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _beta_summary(doc: dict[str, Any]) -> dict[str, float | None]:
    """Mean (β̂), median, 5% and 95% quantiles of β: from ``beta_summary``, else computed from the
    marginal or the draws (None where neither says)."""
    given = doc.get("beta_summary") if isinstance(doc.get("beta_summary"), dict) else {}
    out = {k: finite_or_none(given.get(k)) for k in ("mean", "median", "q05", "q95")}
    if out["mean"] is None:
        out["mean"] = finite_or_none(doc.get("beta_hat"))
    marg = (doc.get("marginals") or {}).get("beta") if isinstance(doc.get("marginals"), dict) else None
    draws = (doc.get("samples") or {}).get("beta") if isinstance(doc.get("samples"), dict) else None
    for key, q in (("median", 0.5), ("q05", 0.05), ("q95", 0.95)):
        if out[key] is None:
            if marg:
                out[key] = _weighted_quantile(marg["values"], marg["probabilities"], q)
            elif draws is not None and len(draws):
                out[key] = float(np.quantile(np.asarray(draws, dtype=float), q))
    return out


def _beta_ticks(ax: Axes, lo: float, hi: float, log: bool, grid=None) -> None:
    """At most :data:`MAX_BETA_TICKS` labels: the grid's values (every k-th when there are more),
    else powers of ten, else a few rounded values when the range is under a decade or two."""
    if grid is not None:
        g = sorted(set(float(v) for v in grid))
        ticks = g[:: math.ceil(len(g) / MAX_BETA_TICKS)]
    elif log and hi / lo >= 30:  # powers of ten; 1-2-5 steps when that gives too few
        e0, e1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
        ticks = []
        for mult in ((1.0,), (1.0, 3.0), (1.0, 2.0, 5.0)):
            cand = [m * 10.0 ** e for e in range(e0, e1 + 1) for m in mult if lo <= m * 10.0 ** e <= hi]
            if len(cand) > MAX_BETA_TICKS:
                break
            ticks = cand
            if len(cand) >= 4:
                break
        if len(ticks) > MAX_BETA_TICKS or not ticks:
            pw = [10.0 ** e for e in range(e0, e1 + 1) if lo <= 10.0 ** e <= hi]
            ticks = pw[:: math.ceil(len(pw) / MAX_BETA_TICKS)] if pw else [float(f"{math.sqrt(lo * hi):.2g}")]
    else:
        raw = np.geomspace(lo, hi, 6)[1:-1] if log else np.linspace(lo, hi, 6)[1:-1]
        ticks = sorted({float(f"{v:.2g}") for v in raw})
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
    ax.xaxis.set_minor_locator(NullLocator())


def _draw_beta(ax: Axes, doc: dict[str, Any], legend_y: float) -> None:
    """β: bars of the marginal (discrete), a histogram of the draws (sampled) or the point (MAP);
    90% interval shaded (gid ``beta-interval``), mean and median lines (``beta-mean``,
    ``beta-median``)."""
    s = _beta_summary(doc)
    marg = (doc.get("marginals") or {}).get("beta") if isinstance(doc.get("marginals"), dict) else None
    samples = doc.get("samples") if isinstance(doc.get("samples"), dict) else {}
    draws = samples.get("beta")
    if marg:
        panel = _beta_bars(ax, marg)
    elif draws is not None and len(draws):
        panel = _beta_hist(ax, draws)
    else:
        panel = _beta_point(ax, float(doc["beta_hat"]))
    if panel.log:
        ax.set_xscale("log")
    ax.set_xlim(panel.lo, panel.hi)
    _beta_summary_marks(ax, s, panel.handles, lines=bool(marg or (draws is not None and len(draws))))
    _beta_ticks(ax, panel.lo, panel.hi, panel.log, panel.grid)
    ax.set_xlabel("β, expertise temperature (log scale; low = expert)" if panel.log else "β (low = expert)",
                  fontsize=8.5)
    ax.set_title(f"β: {panel.kind}", fontsize=9)
    maps.tidy(ax)
    ax.tick_params(labelsize=8)
    pos = ax.get_position()
    leg = ax.legend(handles=panel.handles, loc="upper center",
                    bbox_to_anchor=(pos.x0 + pos.width / 2, legend_y),
                    bbox_transform=ax.figure.transFigure, ncol=min(len(panel.handles), 3), frameon=False,
                    fontsize=8, handlelength=1.6, columnspacing=1.2, borderaxespad=0.0)
    leg.set_gid("beta-legend")


@dataclass
class _BetaPanel:
    """What the β panel's distribution set: its x range, whether it is on a log axis, the grid of
    a marginal (tick values), the words for the title and the legend handles so far."""

    lo: float
    hi: float
    log: bool
    kind: str
    handles: list
    grid: np.ndarray | None = None


def _beta_bars(ax: Axes, marg: dict[str, Any]) -> _BetaPanel:
    """The marginal posterior of β: one bar per grid value, 70% of its cell (in log space on a
    log axis), gid ``beta-bar``."""
    v = np.asarray(marg["values"], dtype=float)
    p = np.asarray(marg["probabilities"], dtype=float)
    order = np.argsort(v)
    v, p = v[order], p[order] / p.sum()
    log = bool((v > 0).all())
    if len(v) > 1:
        mids = np.sqrt(v[1:] * v[:-1]) if log else (v[1:] + v[:-1]) / 2
        first = v[0] ** 2 / mids[0] if log else 2 * v[0] - mids[0]
        last = v[-1] ** 2 / mids[-1] if log else 2 * v[-1] - mids[-1]
        edges = np.concatenate([[first], mids, [last]])
    else:
        edges = np.array([v[0] / 3, v[0] * 3]) if log else np.array([v[0] - 1, v[0] + 1])
    if log:
        le, re = np.log(edges[:-1]), np.log(edges[1:])
        left, right = np.exp(le + 0.15 * (re - le)), np.exp(re - 0.15 * (re - le))
    else:
        left, right = edges[:-1] + 0.15 * np.diff(edges), edges[1:] - 0.15 * np.diff(edges)
    bars = ax.bar(left, p, width=right - left, align="edge", color=POST_COLOR, edgecolor="#2f4b7c",
                  lw=0.5, zorder=2, label="marginal posterior")
    for b in bars:
        b.set_gid("beta-bar")
    handles: list = [Patch(fc=POST_COLOR, ec="#2f4b7c", label="marginal posterior P(β)")]
    ax.set_ylim(0, max(float(p.max()) * 1.18, 0.05))
    ax.set_ylabel("posterior probability", fontsize=8.5)
    return _BetaPanel(float(edges[0]), float(edges[-1]), log,
                      f"marginal posterior on {len(v)} grid values", handles, grid=v)


def _beta_hist(ax: Axes, draws) -> _BetaPanel:
    """A histogram of the finite draws of β (shares, gid ``beta-hist``); log bins when all are > 0."""
    x = np.asarray(draws, dtype=float)
    x = x[np.isfinite(x)]
    log = bool(len(x)) and bool((x > 0).all())
    nb = min(40, max(8, int(np.sqrt(len(x))) + 1))
    if not len(x):
        lo, hi = 1e-2, 1e1
    elif x.min() == x.max():
        lo, hi = (x[0] / 10, x[0] * 10) if log else (x[0] - 1, x[0] + 1)
        bins = np.array([x[0] / 1.04, x[0] * 1.04]) if log else np.array([x[0] - 0.02, x[0] + 0.02])
    else:
        bins = np.geomspace(x.min(), x.max(), nb + 1) if log else np.linspace(x.min(), x.max(), nb + 1)
        pad = 0.05 * np.ptp(x)
        lo, hi = (x.min() / 1.3, x.max() * 1.3) if log else (x.min() - pad, x.max() + pad)
    if len(x):
        h, _, patches = ax.hist(x, bins=bins, weights=np.full(len(x), 1 / len(x)), color=POST_COLOR,
                                alpha=0.9, edgecolor="white", lw=0.3, zorder=2)
        for b in patches:
            b.set_gid("beta-hist")
        ax.set_ylim(0, max(float(np.max(h)) * 1.18, 0.05))
    ax.set_ylabel("share of draws", fontsize=8.5)
    return _BetaPanel(lo, hi, log, "histogram of the draws", [Patch(fc=POST_COLOR, label=f"{len(x)} draws")])


def _beta_point(ax: Axes, b: float) -> _BetaPanel:
    """A point estimate of β (MAP): one diamond, gid ``beta-point``, and a note that there is no
    distribution."""
    log = b > 0
    lo, hi = (min(1e-2, b / 10), max(1e1, b * 10)) if log else (b - 1, b + 1)
    ax.plot([b], [0.5], ls="", marker="D", ms=9, color="#c0392b", zorder=4, gid="beta-point")
    handles: list = [Line2D([], [], ls="", marker="D", ms=7, color="#c0392b", label=f"β̂ = {b:.3g}")]
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    ax.text(0.5, 0.8, "point estimate: no posterior distribution", transform=ax.transAxes, ha="center",
            fontsize=8.5, color="#555555")
    return _BetaPanel(lo, hi, log, "MAP point estimate", handles)


def _beta_summary_marks(ax: Axes, s: dict[str, float | None], handles: list, *, lines: bool) -> None:
    """The 90% interval of ``s`` shaded and, when ``lines`` (a distribution is drawn), its mean and
    median as vertical lines; each appends its legend handle to ``handles``."""
    q05, q95 = s["q05"], s["q95"]
    if q05 is not None and q95 is not None and q95 >= q05:
        ax.axvspan(q05, q95, color=BAND_COLOR, alpha=0.5, lw=0, zorder=0, gid="beta-interval")
        handles.append(Patch(fc=BAND_COLOR, alpha=0.5, label=f"90% interval [{q05:.3g}, {q95:.3g}]"))
    if lines:
        if s["mean"] is not None:
            ax.axvline(s["mean"], color=MEAN_COLOR, lw=1.3, ls="--", zorder=3, gid="beta-mean")
            handles.append(Line2D([], [], color=MEAN_COLOR, lw=1.3, ls="--",
                                  label=f"mean β̂ = {s['mean']:.3g}"))
        if s["median"] is not None:
            ax.axvline(s["median"], color=MEDIAN_COLOR, lw=1.3, ls=":", zorder=3, gid="beta-median")
            handles.append(Line2D([], [], color=MEDIAN_COLOR, lw=1.3, ls=":",
                                  label=f"median {s['median']:.3g}"))


def _interval_of(values, probs) -> tuple[float, float, float]:
    """Mean, 5% and 95% quantiles of a discrete distribution."""
    v, p = np.asarray(values, dtype=float), np.asarray(probs, dtype=float)
    return (float(v @ p / p.sum()), _weighted_quantile(v, p, 0.05), _weighted_quantile(v, p, 0.95))


def _theta_range(ax: Axes, values: list[float]) -> None:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    lo, hi = min([0.0, *finite]), max([1.0, *finite])
    pad = 0.04 * (hi - lo)
    ax.set_xlim(lo - pad, hi + pad)
    ax.xaxis.set_major_locator(MaxNLocator(6))
    ax.set_xlabel("reward weight θ", fontsize=8.5)


def _draw_theta(ax: Axes, doc: dict[str, Any], names: list[str]) -> None:
    """θ shared by every task: one row per feature, its marginal (bars of the discrete marginal
    or a histogram of the draws, scaled to the row), θ̂ (◆, gid ``theta-hat``) and the 90%
    interval (a bar under it, gid ``theta-interval-i``)."""
    K = len(names)
    theta_hat = [float(v) for v in doc["theta_hat"]]
    marg = (doc.get("marginals") or {}).get("theta") if isinstance(doc.get("marginals"), dict) else None
    samples = doc.get("samples") if isinstance(doc.get("samples"), dict) else {}
    draws = np.asarray(samples["theta"], dtype=float) if samples.get("theta") is not None else None
    if draws is not None and (draws.ndim != 2 or draws.shape[1] != K):
        draws = None
    xs: list[float] = list(theta_hat)
    labels = []
    base = 0.3  # baseline of each row's bars, below the row's centre
    if draws is not None:
        finite = draws[np.isfinite(draws)]
        lo, hi = min(0.0, float(finite.min(initial=0.0))), max(1.0, float(finite.max(initial=1.0)))
        edges = np.linspace(lo, hi, 41)
        xs += [lo, hi]
    for k, name in enumerate(names):
        y = K - 1 - k
        interval = None
        if marg:
            v, p = theta_component_marginal(marg["values"], marg["probabilities"], k)
            gaps = np.diff(v)
            w = min(0.05, 0.7 * float(gaps.min())) if gaps.size else 0.05
            ax.bar(v, 0.62 * p / p.max(), width=w, bottom=y - base, color=POST_COLOR, edgecolor="#2f4b7c",
                   lw=0.4, zorder=2, gid=f"theta-bar-{k}")
            _, q05, q95 = _interval_of(v, p)
            interval = (q05, q95)
            xs += [float(v.min()), float(v.max())]
        elif draws is not None:
            col = draws[:, k][np.isfinite(draws[:, k])]
            if len(col):
                h, _ = np.histogram(col, bins=edges)
                ax.bar(edges[:-1], 0.62 * h / max(h.max(), 1), width=np.diff(edges), align="edge",
                       bottom=y - base, color=POST_COLOR, edgecolor="white", lw=0.3, zorder=2,
                       gid=f"theta-hist-{k}")
                interval = (float(np.quantile(col, 0.05)), float(np.quantile(col, 0.95)))
        if interval is not None:
            ax.plot(interval, [y - base - 0.08] * 2, color=MEAN_COLOR, lw=3.0, alpha=0.55,
                    solid_capstyle="butt", zorder=3, gid=f"theta-interval-{k}")
        at = y - base - 0.08 if (marg or draws is not None) else y
        ax.plot([theta_hat[k]], [at], ls="", marker="D", ms=7, color="#c0392b", mec="white",
                mew=0.6, zorder=4, gid="theta-hat")
        if k:
            ax.axhline(y + 0.5, color="#dddddd", lw=0.6, zorder=0)
        label = f"{_short(name, 16)}\nθ̂ = {theta_hat[k]:.2f}"
        if interval is not None:
            label += f" [{interval[0]:.2f}, {interval[1]:.2f}]"
        labels.append(label)
    ax.set_ylim(-0.5, K - 0.5)
    ax.set_yticks(range(K - 1, -1, -1), labels, fontsize=8)
    _theta_range(ax, xs)
    how = ("bars: marginal posterior of each θᵢ" if marg else "histogram of each θᵢ's draws"
           if draws is not None else "MAP point estimate: no posterior")
    distribution = bool(marg) or draws is not None
    ax.set_title(f"θ: ◆ = θ̂, grey bar = 90% interval\n{how} (scaled to its row)" if distribution
                 else f"θ: ◆ = θ̂\n{how}", fontsize=9)
    maps.tidy(ax)
    ax.tick_params(labelsize=8)
    ax.tick_params(axis="y", length=0)


def _draw_theta_per_task(ax: Axes, doc: dict[str, Any], tasks: list[_Task], names: list[str],
                         legend_y: float) -> None:
    """θ estimated per task: one row per task drawn, one marker per feature (gid
    ``theta-task-t``) with its 90% interval when there is one."""
    K = len(names)
    T = len(tasks)
    samples = doc.get("samples") if isinstance(doc.get("samples"), dict) else {}
    draws = np.asarray(samples["theta"], dtype=float) if samples.get("theta") is not None else None
    if draws is not None and (draws.ndim != 3 or draws.shape[2] != K):
        draws = None
    colors = [mpl.colormaps["tab10"](i % 10) for i in range(K)]
    step = min(0.8 / max(K, 1), 0.2)
    xs: list[float] = []
    drawn = False
    for i, t in enumerate(tasks):
        y = T - 1 - i
        j = t.number - 1  # the task's index among all the participant's tasks
        col = draws[:, j, :] if draws is not None and j < draws.shape[1] else None
        hat = t.theta_hat
        intervals: list[tuple[float, float] | None] = [None] * K
        if t.theta_marginal:
            m = t.theta_marginal
            for k in range(K):
                v, p = theta_component_marginal(m["values"], m["probabilities"], k)
                _, q05, q95 = _interval_of(v, p)
                intervals[k] = (q05, q95)
            if hat is None:
                hat = [_interval_of(*theta_component_marginal(m["values"], m["probabilities"], k))[0]
                       for k in range(K)]
        elif col is not None:
            intervals = [(float(np.quantile(col[:, k], 0.05)), float(np.quantile(col[:, k], 0.95)))
                         for k in range(K)]
            if hat is None:
                hat = col.mean(axis=0).tolist()
        if hat is None:
            continue
        pts = []
        for k in range(K):
            dy = (K - 1) / 2 * step - k * step
            if intervals[k] is not None:
                ax.plot(intervals[k], [y + dy] * 2, color=colors[k], lw=1.6, alpha=0.7, zorder=2)
                xs += list(intervals[k])
            pts.append((float(hat[k]), y + dy))
            ax.plot([float(hat[k])], [y + dy], ls="", marker=FEATURE_MARKERS[k % len(FEATURE_MARKERS)], ms=6,
                    color=colors[k], mec="white", mew=0.5, zorder=3)
            xs.append(float(hat[k]))
        ax.plot(*np.array(pts).T, ls="", marker="", gid=f"theta-task-{t.number}")
        drawn = True
        if i:
            ax.axhline(y + 0.5, color="#e2e2e2", lw=0.6, zorder=0)
    ax.set_ylim(-0.5, T - 0.5)
    ax.set_yticks(range(T - 1, -1, -1), [f"task {t.number}" for t in tasks], fontsize=8)
    _theta_range(ax, xs)
    ax.set_title("θ per task: marker = θ̂, line = 90% interval" if drawn else "θ per task: no estimate given",
                 fontsize=9)
    maps.tidy(ax)
    ax.tick_params(labelsize=8)
    ax.tick_params(axis="y", length=0)
    handles = [Line2D([], [], ls="-", lw=1.6, marker=FEATURE_MARKERS[k % len(FEATURE_MARKERS)], ms=6,
                      color=colors[k], label=_short(n, 16)) for k, n in enumerate(names)]
    pos = ax.get_position()
    leg = ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(pos.x0 + pos.width / 2, legend_y),
                    bbox_transform=ax.figure.transFigure, ncol=min(K, 5), frameon=False, fontsize=8,
                    columnspacing=1.0, borderaxespad=0.0, title="feature", title_fontsize=8)
    leg.set_gid("theta-legend")


# --------------------------------------------------------------------------- saving
def figure_png_bytes(fig: Figure) -> bytes:
    """The PNG of ``fig`` (white background, :data:`DPI`, no software version in it)."""
    buf = io.BytesIO()
    with figure_style():
        fig.savefig(buf, format="png", dpi=DPI, facecolor="white", metadata=PNG_METADATA)
    return buf.getvalue()


def participant_png_bytes(participant: str, panels: Sequence[dict[str, Any]], doc: dict[str, Any]) -> bytes:
    """The PNG of :func:`participant_figure` (what the figure workers ship back)."""
    with _DRAW_LOCK:
        return figure_png_bytes(participant_figure(participant, panels, doc))


def render_participant_png(path: str | Path, participant: str, panels: Sequence[dict[str, Any]],
                           doc: dict[str, Any]) -> Path:
    """Save the participant's figure (:func:`participant_figure`) as a PNG at ``path``, atomically."""
    return write_atomic(path, participant_png_bytes(participant, panels, doc))
