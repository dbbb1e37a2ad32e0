"""Figures for zone maps, demonstrations and posteriors (matplotlib, Agg).

Colours follow the paper's Fig. 1: red = avoid, black = obstacle, yellow =
slow-down, purple = high traffic, light blue = road with a preferred direction
(an arrow in each road cell), green dot = goal. Maps are drawn in image
orientation: x = column to the right, y = row downwards, row 0 at the top, and
cell ``(x, y)`` is centred on data coordinates ``(x, y)``.

The ``draw_*`` functions draw onto a given :class:`~matplotlib.axes.Axes` and
return it. The ``render_*_png`` functions build a :class:`~matplotlib.figure.Figure`
directly (not through :mod:`matplotlib.pyplot`), so no figure is registered with
pyplot and nothing is left open after they return; they never change the
global backend.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Rectangle

from ..atomic import save_figure_atomic
from ..errors import InputError, plural
from ..worlds.grid import FREE, GOAL, OBSTACLE, ROAD_DIRECTIONS, START
from ..worlds.zones import AVOID, SLOW, TRAFFIC, ZoneMap

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..demos.trajectories import Trajectories
    from ..mdp import TabularMDP

#: Fill colour of each cell character (roads share one colour).
ZONE_COLORS: dict[str, str] = {
    FREE: "#fafafa",
    START: "#fafafa",
    GOAL: "#fafafa",
    OBSTACLE: "#1a1a1a",
    AVOID: "#e4544a",
    SLOW: "#f4d03f",
    TRAFFIC: "#9b72cf",
    **dict.fromkeys(ROAD_DIRECTIONS, "#9fd4f2"),
}
GOAL_COLOR = "#1e9e3a"
ARROW_COLOR = "#1d5a8c"
GRID_COLOR = "#cfcfcf"
#: Unit (dx, dy) of each road character, image orientation (y grows downwards).
ROAD_VECTORS: dict[str, tuple[int, int]] = {">": (1, 0), "<": (-1, 0), "^": (0, -1), "v": (0, 1)}
#: Default colours of demonstrations: dark, saturated, distinct from the zone fills.
PATH_COLORS = ("#0b2e59", "#d9480f", "#0b7261", "#7b1e62", "#3b3b3b", "#5c4d00", "#1c6fb3")
ROAD_ARROWS_GID = "road-arrows"
_LEGEND = (  # (characters, label) in legend order
    ((OBSTACLE,), "obstacle"),
    ((AVOID,), "avoid"),
    ((SLOW,), "slow-down"),
    ((TRAFFIC,), "high traffic"),
    (tuple(ROAD_DIRECTIONS), "road (→ direction)"),
)
DPI = 120


# --------------------------------------------------------------------------- map
#: Above this many βs the β marginal's ticks are rotated and only bars with mass are labelled.
CROWDED_BETAS = 8

def draw_map(ax: Axes, zone_map: ZoneMap, *, show_grid: bool = True, legend: bool = True) -> Axes:
    """Draw the cells of a zone map in the paper's colours.

    Parameters
    ----------
    ax : Axes
        Target axes; its limits are set to the grid, y inverted (row 0 on top).
    zone_map : ZoneMap
        The map to draw.
    show_grid : bool, default True
        Thin lines between cells.
    legend : bool, default True
        A compact legend, below the map, of the zone types present.

    Returns
    -------
    Axes
        ``ax``. Road arrows are one :class:`~matplotlib.quiver.Quiver` with gid
        ``"road-arrows"`` (``X, Y`` cell centres, ``U, V`` unit directions, V > 0 = down).
    """
    g = zone_map.grid
    draw_cells(ax, g, ZONE_COLORS, grid_lw=0.4 if show_grid else None)
    draw_road_arrows(ax, g, color=ARROW_COLOR, length=0.55, width=0.09)
    draw_starts(ax, g, 0.54)
    for y, x in np.argwhere(g == GOAL):
        ax.add_patch(Circle((x, y), 0.36, fc=GOAL_COLOR, ec="white", lw=0.8, zorder=6, gid="goal"))
    frame_cells(ax, g)
    for sp in ax.spines.values():
        sp.set_linewidth(0.6)
        sp.set_color("#7a7a7a")
    if legend:
        handles = map_legend_handles(zone_map)
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01),
                  ncol=min(len(handles), 4), frameon=False, fontsize=7.5, handlelength=1.2,
                  handleheight=1.0, columnspacing=1.0, borderaxespad=0.2)
    return ax


def draw_cells(ax: Axes, g: np.ndarray, colors: dict[str, str], *, grid_lw: float | None) -> None:
    """Fill each cell of ``g`` (``[rows, cols]`` characters) with its colour in ``colors`` and,
    unless ``grid_lw`` is None, draw lines that wide between cells."""
    h, w = g.shape
    rgb = np.zeros((h, w, 3))
    for ch, col in colors.items():
        rgb[g == ch] = to_rgb(col)
    ax.imshow(rgb, extent=(-0.5, w - 0.5, h - 0.5, -0.5), origin="upper",
              interpolation="nearest", zorder=0)
    if grid_lw is not None:
        ax.vlines(np.arange(w + 1) - 0.5, -0.5, h - 0.5, colors=GRID_COLOR, lw=grid_lw, zorder=1)
        ax.hlines(np.arange(h + 1) - 0.5, -0.5, w - 0.5, colors=GRID_COLOR, lw=grid_lw, zorder=1)


def draw_road_arrows(ax: Axes, g: np.ndarray, *, color: str, length: float, width: float) -> None:
    """An arrow ``length`` cells long along each road cell's direction: one quiver with gid
    :data:`ROAD_ARROWS_GID` (``X, Y`` cell centres, ``U, V`` unit directions, V > 0 = down)."""
    road = np.isin(g, tuple(ROAD_VECTORS))
    if road.any():
        ys, xs = np.nonzero(road)
        uv = np.array([ROAD_VECTORS[c] for c in g[ys, xs]], dtype=float)
        q = ax.quiver(xs, ys, uv[:, 0], uv[:, 1], angles="xy", scale_units="xy", scale=1 / length,
                      pivot="middle", color=color, width=width, units="xy",
                      headwidth=3.2, headlength=3.0, headaxislength=2.7, zorder=3)
        q.set_gid(ROAD_ARROWS_GID)


def draw_starts(ax: Axes, g: np.ndarray, side: float) -> None:
    """A grey square ``side`` cells wide (gid ``"start"``) on each start cell."""
    for y, x in np.argwhere(g == START):
        ax.add_patch(Rectangle((x - side / 2, y - side / 2), side, side, fill=False, ec="#6b6b6b",
                               lw=0.9, zorder=3, gid="start"))


def frame_cells(ax: Axes, g: np.ndarray) -> None:
    """Limits on the cells of ``g`` (row 0 on top), equal aspect, no ticks."""
    h, w = g.shape
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def map_legend_handles(zone_map: ZoneMap) -> list:
    """Legend handles for the zone types, start cells and goals present in ``zone_map``."""
    g = zone_map.grid
    handles: list = [
        Patch(fc=ZONE_COLORS[chars[0]], ec="#7a7a7a", lw=0.5, label=label)
        for chars, label in _LEGEND if np.isin(g, chars).any()
    ]
    if (g == START).any():
        handles.append(Line2D([], [], ls="", marker="s", ms=6, mfc="none", mec="#6b6b6b",
                              label="start"))
    handles.append(Line2D([], [], ls="", marker="o", ms=7, mfc=GOAL_COLOR, mec="white",
                          label="goal"))
    return handles


# ------------------------------------------------------------------ trajectories
def _jitter_offsets(n: int, radius: float) -> np.ndarray:
    """``[n, 2]`` deterministic offsets on a sunflower (Vogel) spiral; the first is 0."""
    i = np.arange(n)
    r = radius * np.sqrt(i / max(n - 1, 1))
    phi = i * np.pi * (3.0 - np.sqrt(5.0))  # golden angle
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def draw_trajectories(
    ax: Axes,
    zone_map: ZoneMap,
    paths_xy: Sequence[np.ndarray],
    *,
    color: str | Sequence[str] | None = None,
    alpha: float = 0.75,
    jitter: float = 0.2,
    linewidth: float = 1.4,
) -> Axes:
    """Draw demonstrations as polylines through cell centres, each with a start marker.

    Parameters
    ----------
    ax : Axes
        Axes holding the map (see :func:`draw_map`).
    zone_map : ZoneMap
        The map the paths live on; used to check that every point is a cell.
    paths_xy : sequence of ndarray
        One ``[T, 2]`` integer array of (x, y) cells per episode.
    color : str or sequence of str, optional
        One colour for all paths, or one per path; default cycles :data:`PATH_COLORS`.
    alpha : float, default 0.75
        Line opacity.
    jitter : float, default 0.2
        Largest offset (in cells) of an episode from the cell centres. Offsets are
        deterministic (a golden-angle spiral over the episode index), so overlapping
        paths stay distinguishable and the figure is reproducible.
    linewidth : float, default 1.4

    Returns
    -------
    Axes
        ``ax``; path ``i`` is the Line2D with gid ``"path-i"``.
    """
    n = len(paths_xy)
    if isinstance(color, str):
        colors = [color] * n
    elif color is None:
        colors = [PATH_COLORS[i % len(PATH_COLORS)] for i in range(n)]
    else:
        colors = list(color)
        if len(colors) != n:
            raise InputError(f"{len(colors)} colours for {n} paths")
    offsets = _jitter_offsets(n, jitter)
    for i, p in enumerate(paths_xy):
        p = np.asarray(p)
        if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] == 0:
            raise InputError(f"path {i}: expected a non-empty [T, 2] array of cells, got {p.shape}")
        off_grid = (p[:, 0] < 0) | (p[:, 0] >= zone_map.width) | (p[:, 1] < 0) | (
            p[:, 1] >= zone_map.height)
        if off_grid.any():
            t = int(np.argmax(off_grid))
            raise InputError(f"path {i}, step {t}: cell {tuple(p[t].tolist())} is off the map")
        xy = p.astype(float) + offsets[i]
        ax.plot(xy[:, 0], xy[:, 1], color=colors[i], alpha=alpha, lw=linewidth,
                solid_joinstyle="round", solid_capstyle="round", zorder=4, gid=f"path-{i}")
        ax.plot(xy[0, 0], xy[0, 1], ls="", marker="o", ms=4.5, mfc=colors[i], mec="white",
                mew=0.7, zorder=5, gid=f"start-{i}")
    return ax


def paths_to_xy(trajs: Trajectories, mdp: TabularMDP) -> list[np.ndarray]:
    """``[T_i + 1, 2]`` (x, y) cells visited in each episode, final state included.

    Raises :class:`InputError` if the MDP has no ``state_xy`` or an episode's last
    action is unavailable (so its final state is undefined).
    """
    if mdp.state_xy is None:
        raise InputError(f"{mdp.source}: the MDP has no grid coordinates (state_xy)")
    out = []
    for i, states in enumerate(trajs.paths(mdp)):
        states = np.asarray(states, dtype=np.int64)
        if (states < 0).any():
            raise InputError(f"episode {i}: its last action is unavailable, no final state")
        out.append(mdp.state_xy[states])
    return out


# --------------------------------------------------------------------- posteriors
def _check_probs(probs, n: int, what: str) -> np.ndarray:
    p = np.asarray(probs, dtype=float)
    if p.shape != (n,):
        raise InputError(f"{what}: expected {n} probabilities, got shape {p.shape}")
    if not np.all(np.isfinite(p)) or (p < 0).any() or p.sum() <= 0:
        raise InputError(f"{what}: probabilities must be finite, non-negative, not all 0")
    return p


def _compact(v: float) -> str:
    """A θ component in a top-θ label, at most two decimals without trailing zeros or the
    leading zero: ``0``, ``1``, ``.33``."""
    s = f"{v:.2f}".rstrip("0").rstrip(".")
    return s[1:] if s.startswith("0.") else s or "0"


def draw_beta_marginal(ax: Axes, betas, probs, *, beta_true: float | None = None) -> Axes:
    """Bar chart of the posterior marginal over β, one categorical bar per value.

    Parameters
    ----------
    ax : Axes
    betas : array_like, shape [B]
        The temperatures, drawn in the given order and labelled with ``%g``.
    probs : array_like, shape [B]
        Their probabilities.
    beta_true : float, optional
        The true β; its bar is highlighted (or noted in the title if not in ``betas``).

    Returns
    -------
    Axes
        ``ax``; the highlighted bar has gid ``"beta-true"``.
    """
    b = np.asarray(betas, dtype=float).ravel()
    p = _check_probs(probs, b.size, "draw_beta_marginal")
    x = np.arange(b.size)
    bars = ax.bar(x, p, color="#9aa7b8", edgecolor="#4a5568", lw=0.6, width=0.7)
    title = rf"posterior of $\beta$   (E[$\beta$] = {float(b @ p / p.sum()):.3g})"
    if beta_true is not None:
        hit = np.flatnonzero(np.isclose(b, beta_true, rtol=1e-9, atol=0))
        if hit.size:
            bars[hit[0]].set_color("#c0392b")
            bars[hit[0]].set_edgecolor("#6e1f17")
            bars[hit[0]].set_gid("beta-true")
            bars[hit[0]].set_label(rf"true $\beta^*$ = {beta_true:g}")
            ax.legend(loc="upper right", fontsize=7.5, frameon=False)
        else:
            title += rf",  $\beta^*$ = {beta_true:g} (not in set)"
    crowded = b.size > CROWDED_BETAS  # many βs (a fine grid, an adaptive set): label what has mass
    for xi, pi in zip(x, p, strict=True):
        if not crowded or pi >= 0.005:
            ax.annotate(f"{pi:.2f}", (xi, pi), xytext=(0, 2), textcoords="offset points",
                        ha="center", va="bottom", fontsize=7, color="#333")
    ax.set_xticks(x, [f"{v:.2g}" if crowded else f"{v:g}" for v in b])
    if crowded:
        ax.tick_params(axis="x", labelrotation=70, labelsize=6.5)
    ax.set_xlabel(r"expertise temperature $\beta$  (low = expert)", fontsize=8.5)
    ax.set_ylabel("probability", fontsize=8.5)
    # headroom above the tallest bar's label for the legend
    ax.set_ylim(0, max(1.0, float(p.max()) + 0.1) * (1.2 if beta_true is not None else 1.0))
    ax.set_yticks([t for t in (0, 0.2, 0.4, 0.6, 0.8, 1.0) if t <= ax.get_ylim()[1]])
    ax.set_title(title, fontsize=9.5)
    tidy(ax)
    return ax


def _aggregate(thetas: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sum the probabilities of identical θ rows (to 1e-9)."""
    keys = np.round(thetas, 9) + 0.0
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    return uniq, np.bincount(inv.ravel(), weights=p, minlength=len(uniq))


def draw_theta_summary(
    ax: Axes,
    thetas,
    probs,
    feature_names: Sequence[str],
    *,
    theta_true=None,
    top: int = 8,
    ax_top: Axes | None = None,
    absent: Sequence[bool] | None = None,
) -> tuple[Axes, Axes | None]:
    """Posterior mean E[θ] against θ* per feature, and the most probable θ vectors.

    Parameters
    ----------
    ax : Axes
        Receives grouped bars per feature: E[θ] (probability-weighted mean of ``thetas``)
        and, if given, θ*.
    thetas : array_like, shape [n, K]
        θ vectors (rows); identical rows are merged and their probabilities summed.
    probs : array_like, shape [n]
        Probability of each row (normalised here if it does not sum to 1).
    feature_names : sequence of str, length K
    theta_true : array_like, shape [K], optional
        True θ*; drawn as a second bar per feature, and its row starred in the top list.
    top : int, default 8
        How many most probable θ vectors to list (0: none).
    ax_top : Axes, optional
        Axes for that list; by default a new axes is split off below ``ax``.
    absent : sequence of bool, length K, optional
        Features that never occur on the map (e.g. no road cell): their tick label says
        "not on map" in grey and their bars are hatched, since no demonstration can
        tell anything about them.

    Returns
    -------
    (Axes, Axes or None)
        ``ax`` and the axes with the top-θ list (None when ``top == 0``).
    """
    th = np.atleast_2d(np.asarray(thetas, dtype=float))
    n, K = th.shape
    p = _check_probs(probs, n, "draw_theta_summary")
    p = p / p.sum()
    names = list(feature_names)
    if len(names) != K:
        raise InputError(f"{len(names)} feature names for {K} features")
    true = None if theta_true is None else np.asarray(theta_true, dtype=float).ravel()
    if true is not None and true.shape != (K,):
        raise InputError(f"theta_true must have {K} components, got {true.shape}")
    _draw_theta_means(ax, th, p, names, true, absent)
    if top <= 0:
        return ax, None
    if ax_top is None:
        from mpl_toolkits.axes_grid1 import make_axes_locatable

        ax_top = make_axes_locatable(ax).append_axes("bottom", size="90%", pad=0.45)
    _draw_top_thetas(ax_top, th, p, names, true, top)
    return ax, ax_top


def _draw_theta_means(ax: Axes, th: np.ndarray, p: np.ndarray, names: list[str], true: np.ndarray | None,
                      absent: Sequence[bool] | None) -> None:
    """Bars of E[θ] (and θ*) per feature; features ``absent`` from the map greyed and hatched."""
    K = th.shape[1]
    mean = p @ th
    x = np.arange(K)
    width = 0.38 if true is not None else 0.6
    shift = width / 2 if true is not None else 0.0
    ax.bar(x - shift, mean, width, color="#4c72b0", label=r"posterior mean E[$\theta$]", gid="mean")
    if true is not None:
        ax.bar(x + shift, true, width, color="#dd8452", label=r"true $\theta^*$", gid="true")
    gone = [False] * K if absent is None else [bool(a) for a in absent]
    if len(gone) != K:
        raise InputError(f"absent must have {K} entries, got {len(gone)}")
    ax.set_xticks(x, [f"{nm}\n(not on\nthe map)" if g else nm for nm, g in zip(names, gone, strict=True)],
                  fontsize=8)
    for xi, (tick, g) in enumerate(zip(ax.get_xticklabels(), gone, strict=True)):
        if g:
            tick.set_color("#8a8a8a")
            tick.set_fontsize(6.8)
            tick.set_gid("absent-feature")
            for bar in ax.patches:
                if abs(bar.get_x() + bar.get_width() / 2 - xi) < 0.5:
                    bar.set_hatch("////")
                    bar.set_alpha(0.5)
    ax.set_ylabel("weight", fontsize=8.5)
    ax.set_ylim(0, max(1.0, float(np.max(mean)), float(np.max(true)) if true is not None else 0) * 1.05)
    ax.set_title(r"reward weights $\theta$", fontsize=9.5)
    ax.legend(fontsize=7.5, frameon=False, loc="upper right")
    tidy(ax)


def _draw_top_thetas(ax_top: Axes, th: np.ndarray, p: np.ndarray, names: list[str], true: np.ndarray | None,
                     top: int) -> None:
    """The ``top`` most probable θ vectors as horizontal bars, θ*'s row starred."""
    uniq, pu = _aggregate(th, p)
    order = np.argsort(-pu, kind="stable")[:top]
    labels = ["(" + " ".join(_compact(v) for v in uniq[i]) + ")" for i in order]
    colors = ["#4c72b0"] * len(order)
    if true is not None:
        t_norm = true / true.sum() if true.sum() > 0 else true
        for j, i in enumerate(order):
            if np.allclose(uniq[i], true, atol=1e-6) or np.allclose(uniq[i], t_norm, atol=1e-6):
                labels[j] = "★ " + labels[j]
                colors[j] = "#dd8452"
    y = np.arange(len(order))
    ax_top.barh(y, pu[order], color=colors, height=0.7)
    for yi, v in zip(y, pu[order], strict=True):
        ax_top.annotate(f"{v:.2f}", (v, yi), xytext=(3, 0), textcoords="offset points",
                        va="center", fontsize=6.5, color="#333")
    ax_top.set_yticks(y, labels, fontsize=7, family="monospace")
    ax_top.invert_yaxis()
    ax_top.set_xlim(0, min(1.0, float(pu[order].max()) * 1.25 + 0.02))
    ax_top.set_xlabel("probability", fontsize=8.5)
    ax_top.set_title(rf"top {len(order)} $\theta$  ({', '.join(names)})", fontsize=8.5)
    tidy(ax_top)


def tidy(ax: Axes) -> None:
    ax.spines[["top", "right"]].set_visible(False)
    ax.tick_params(labelsize=7.5, length=2.5)


# ------------------------------------------------------------------------ figures
def new_figure(figsize: tuple[float, float]) -> Figure:
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def map_size(zone_map: ZoneMap, max_w: float, max_h: float) -> tuple[float, float]:
    """Inches for the map panel: ~0.42 in per cell (more for tiny maps), within ``max_w`` × ``max_h``."""
    w, h = zone_map.width, zone_map.height
    cell = min(max(0.42, 3.5 / max(w, h)), max_w / w, max_h / h)
    return cell * w, cell * h


def save_figure(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    save_figure_atomic(fig, path, dpi=DPI, facecolor="white", bbox_inches="tight", pad_inches=0.08)
    fig.clear()
    return path


def render_map_png(
    zone_map: ZoneMap,
    path: str | Path,
    *,
    trajectories_xy: Sequence[np.ndarray] | None = None,
    title: str | None = None,
) -> Path:
    """Save a PNG of the map, optionally with demonstrations on top.

    Parameters
    ----------
    zone_map : ZoneMap
    path : str or Path
        Output file (PNG, dpi 120).
    trajectories_xy : sequence of ndarray, optional
        ``[T, 2]`` cell paths (see :func:`paths_to_xy`).
    title : str, optional
        Defaults to the map's name.

    Returns
    -------
    Path
        ``path``.
    """
    mw, mh = map_size(zone_map, 9.0, 8.0)
    fig = new_figure((max(mw + 0.3, 5.2), mh + 1.1))
    ax = fig.add_subplot()
    draw_map(ax, zone_map)
    if trajectories_xy is not None:
        draw_trajectories(ax, zone_map, trajectories_xy)
    ax.set_title(title if title is not None else zone_map.name, fontsize=10)
    return save_figure(fig, path)


def render_summary_png(
    path: str | Path,
    zone_map: ZoneMap,
    paths_xy: Sequence[np.ndarray],
    betas,
    beta_probs,
    thetas,
    theta_probs,
    feature_names: Sequence[str],
    *,
    theta_true=None,
    beta_true: float | None = None,
    title: str | None = None,
    top: int = 8,
) -> Path:
    """One figure: map with demonstrations (left); β marginal and θ summary (right).

    Parameters
    ----------
    path : str or Path
        Output PNG (dpi 120).
    zone_map, paths_xy
        As for :func:`draw_map` and :func:`draw_trajectories`.
    betas, beta_probs
        As for :func:`draw_beta_marginal`.
    thetas, theta_probs, feature_names
        As for :func:`draw_theta_summary` (typically the θ marginal of the posterior).
    theta_true, beta_true : optional
        Ground truth, highlighted when given.
    title : str, optional
        Figure title.
    top : int, default 8
        Number of most probable θ vectors listed.

    Returns
    -------
    Path
        ``path``.
    """
    mw, mh = map_size(zone_map, 7.0, 5.8)
    fig = new_figure((mw + 5.4, max(mh + 1.3, 6.8)))
    gs = fig.add_gridspec(3, 2, width_ratios=[mw, 5.0], height_ratios=[1.0, 1.0, 1.1])
    ax_map = fig.add_subplot(gs[:, 0])
    draw_map(ax_map, zone_map)
    draw_trajectories(ax_map, zone_map, paths_xy)
    n = len(paths_xy)
    ax_map.set_title(f"{zone_map.name}: {n} demonstration{'s' if n != 1 else ''}", fontsize=9.5)
    draw_beta_marginal(fig.add_subplot(gs[0, 1]), betas, beta_probs, beta_true=beta_true)
    ax_theta = fig.add_subplot(gs[1, 1] if top > 0 else gs[1:, 1])
    draw_theta_summary(ax_theta, thetas, theta_probs, feature_names, theta_true=theta_true,
                       top=top, ax_top=fig.add_subplot(gs[2, 1]) if top > 0 else None)
    if title:
        fig.suptitle(title, fontsize=11)
    return save_figure(fig, path)


# ------------------------------------------------------------------ demo figure
#: Colours of the few episodes the demo figure draws one by one (the others go to the heat map).
EPISODE_COLORS = ("#e8590c", "#0b7285", "#ae3ec9")
VISITS_COLOR = "#1b2a49"
#: Episodes the demo figure draws one by one, and the moves of each drawn at most.
DEMO_EPISODES = 3
DEMO_MOVES = 60


def visit_counts(zone_map: ZoneMap, paths_xy: Sequence[np.ndarray]) -> np.ndarray:
    """``[height, width]`` number of times each cell is occupied, over every step of every path."""
    counts = np.zeros((zone_map.height, zone_map.width))
    for p in paths_xy:
        p = np.asarray(p, dtype=np.int64)
        np.add.at(counts, (p[:, 1], p[:, 0]), 1.0)
    return counts


def draw_visits(ax: Axes, zone_map: ZoneMap, paths_xy: Sequence[np.ndarray], *,
                color: str = VISITS_COLOR, max_radius: float = 0.38, alpha: float = 0.42):
    """Visitation heat map: a dot in each visited cell, its area proportional to the visits.

    Dots (not a shade over the cell) keep the zone colours visible underneath. The most
    visited cell gets radius ``max_radius`` (in cells). Returns the
    :class:`~matplotlib.collections.PatchCollection` of circles (gid ``"visits"``), one per
    visited cell, in the order of :func:`numpy.argwhere` over the counts.
    """
    from matplotlib.collections import PatchCollection

    counts = visit_counts(zone_map, paths_xy)
    top = counts.max() if counts.max() > 0 else 1.0
    cells = np.argwhere(counts > 0)
    circles = [Circle((x, y), max_radius * np.sqrt(counts[y, x] / top)) for y, x in cells]
    coll = PatchCollection(circles, facecolor=color, edgecolor="none", alpha=alpha, zorder=2)
    coll.set_gid("visits")
    ax.add_collection(coll)
    return coll


def visits_legend_handles(top: float, color: str = VISITS_COLOR, max_ms: float = 10.0,
                          alpha: float = 0.42) -> list:
    """Legend dots for 1 visit, a middle value and ``top`` visits (area ∝ visits)."""
    top = max(round(top), 1)
    values = sorted({1, round(top ** 0.5), top})
    return [Line2D([], [], ls="", marker="o", ms=max(max_ms * np.sqrt(v / top), 1.5), mfc=color,
                   mec="none", alpha=alpha, label=f"{v} visit{'s' if v != 1 else ''}")
            for v in values]


def draw_episodes(
    ax: Axes,
    zone_map: ZoneMap,
    paths_xy: Sequence[np.ndarray],
    outcomes: Sequence[str],
    *,
    labels: Sequence[str] | None = None,
    max_moves: int | None = DEMO_MOVES,
    colors: Sequence[str] = EPISODE_COLORS,
) -> list[Line2D]:
    """Draw a few episodes distinctly: path, start (●) and end (★ goal, ✕ step cap, ■ cut).

    A path longer than ``max_moves`` moves is drawn up to that move only, ending in an
    arrowhead (it goes on), and its end marker still shows where the episode stopped.

    Returns one legend handle per episode (gid ``"episode-i"`` on the drawn line).
    """
    handles = []
    offsets = _jitter_offsets(max(len(paths_xy), 1), 0.12)
    for i, (p, outcome) in enumerate(zip(paths_xy, outcomes, strict=True)):
        p = np.asarray(p)
        _check_path(zone_map, p, i)
        c = colors[i % len(colors)]
        moves = len(p) - 1
        shown = p if max_moves is None or moves <= max_moves else p[: max_moves + 1]
        xy = shown.astype(float) + offsets[i]
        ax.plot(xy[:, 0], xy[:, 1], color="white", lw=3.6, alpha=0.8, zorder=4,
                solid_joinstyle="round", solid_capstyle="round")
        ax.plot(xy[:, 0], xy[:, 1], color=c, lw=1.9, zorder=5, solid_joinstyle="round",
                        solid_capstyle="round", gid=f"episode-{i}")
        if len(shown) < len(p) and len(xy) >= 2:
            ax.annotate("", xy=xy[-1], xytext=xy[-2], zorder=6,
                        arrowprops={"arrowstyle": "-|>,head_length=0.5,head_width=0.3", "color": c,
                                    "lw": 1.9, "shrinkA": 0, "shrinkB": 0}, gid=f"episode-{i}-goes-on")
        ax.plot(*(p[0] + offsets[i]), ls="", marker="o", ms=7.5, mfc=c, mec="white", mew=1.2,
                zorder=7, gid=f"episode-{i}-start")
        end = p[-1] + offsets[i]
        marker = {"goal": "*", "cap": "X", "cut": "s"}[outcome]
        ax.plot(*end, ls="", marker=marker, ms=11 if marker == "*" else 8.5, mfc=c, mec="white",
                mew=1.0, zorder=7, gid=f"episode-{i}-end")
        what = {"goal": f"reached the goal in {plural(moves, 'move')}",
                "cap": f"stopped at the {moves}-step cap",
                "cut": f"ended after {plural(moves, 'move')}"}[outcome]
        if len(shown) < len(p):
            what += f" (first {max_moves} drawn)"
        label = labels[i] if labels is not None else f"episode {i}"
        handles.append(Line2D([], [], color=c, lw=1.9, label=f"{label}: {what}"))
    return handles


def _check_path(zone_map: ZoneMap, p: np.ndarray, i: int) -> None:
    """Raise :class:`InputError` unless ``p`` is a non-empty ``[T, 2]`` path of cells on the map."""
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] == 0:
        raise InputError(f"path {i}: expected a non-empty [T, 2] array of cells, got {p.shape}")
    off_grid = (p[:, 0] < 0) | (p[:, 0] >= zone_map.width) | (p[:, 1] < 0) | (p[:, 1] >= zone_map.height)
    if off_grid.any():
        t = int(np.argmax(off_grid))
        raise InputError(f"path {i}, step {t}: cell {tuple(p[t].tolist())} is off the map")


def episode_marker_handles(outcomes: Sequence[str]) -> list:
    """Legend handles of the start / end markers used by :func:`draw_episodes`."""
    grey = "#555555"
    handles = [Line2D([], [], ls="", marker="o", ms=7, mfc=grey, mec="white", label="episode start")]
    if "goal" in outcomes:
        handles.append(Line2D([], [], ls="", marker="*", ms=10, mfc=grey, mec="white",
                              label="episode end: goal"))
    if "cap" in outcomes:
        handles.append(Line2D([], [], ls="", marker="X", ms=8, mfc=grey, mec="white",
                              label="episode end: step cap"))
    if "cut" in outcomes:
        handles.append(Line2D([], [], ls="", marker="s", ms=7, mfc=grey, mec="white",
                              label="episode end: data stop"))
    return handles


def render_demo_png(path: str | Path, run, *, title: str | None = None,
                    n_episodes: int = DEMO_EPISODES, max_moves: int | None = DEMO_MOVES) -> Path:
    """Save the ``expertise-irl demo`` figure (:func:`demo_figure`) as a PNG (dpi 120)."""
    return save_figure(demo_figure(run, title=title, n_episodes=n_episodes, max_moves=max_moves), path)


def demo_figure(run, *, title: str | None = None, n_episodes: int = DEMO_EPISODES,
                max_moves: int | None = DEMO_MOVES) -> Figure:
    """The ``expertise-irl demo`` figure of a :class:`~expertise_irl.experiments.demo.DemoRun`.

    Left: the map with a heat map of where every episode went, ``n_episodes`` episodes
    drawn one by one (start and end marked), and a note when episodes hit the step cap.
    Right: the marginal posterior of β, E[θ] against θ* (features that never occur on
    the map are marked), and the most probable θ by marginal probability; the joint
    posterior probability of the truth is stated. How the episodes ended, the note on the
    step cap and the absent features are the run's (``run.outcomes()``, ``run.cap_note()``,
    ``run.absent_features()``).
    """
    zm, mdp, b = run.zone_map, run.mdp, run.belief
    paths = paths_to_xy(run.trajectories, mdp)
    outcomes = run.outcomes()
    ids = run.trajectories.episode_ids
    shown = min(n_episodes, len(paths))
    n = len(paths)
    n_goal = sum(o == "goal" for o in outcomes)

    mw, mh = map_size(zm, 6.6, 6.6)
    shown_ids = ", ".join(str(int(e)) for e in ids[:shown])
    notes = [f"Episode{'s' if shown != 1 else ''} {shown_ids} drawn "
             f"({shown} of {n}); every episode is in the visit dots."]
    note = run.cap_note()
    if note:
        notes.append(note)
    import textwrap

    width = max(60, int((mw + 0.4) * 16))
    text = "\n".join(textwrap.fill(t, width) for t in notes)
    heights = [mh, 0.78, 0.2 + 0.15 * shown, 0.1 + 0.135 * (text.count("\n") + 1)]
    fig_h = max(sum(heights) + 0.7, 7.6)
    heights.append(max(fig_h - 0.7 - sum(heights), 0.01))  # spare height goes below the notes
    fig = new_figure((mw + 5.8, fig_h))
    sf_left, sf_right = fig.subfigures(1, 2, width_ratios=[mw + 0.4, 5.4], wspace=0.02)
    left = sf_left.add_gridspec(5, 1, height_ratios=heights)
    ax_map = sf_left.add_subplot(left[0])
    draw_map(ax_map, zm, legend=False)
    draw_visits(ax_map, zm, paths)
    handles = draw_episodes(ax_map, zm, paths[:shown], outcomes[:shown],
                            labels=[f"episode {int(e)}" for e in ids[:shown]], max_moves=max_moves)
    ax_map.set_title(f"{zm.name}: where {n} episode{'s' if n != 1 else ''} went "
                     f"({n_goal} reached the goal)", fontsize=9.5)

    ax_leg, ax_eps, ax_note = (sf_left.add_subplot(left[i]) for i in (1, 2, 3))
    for a_ in (ax_leg, ax_eps, ax_note):
        a_.axis("off")
    top_visits = visit_counts(zm, paths).max()
    legend_handles = (map_legend_handles(zm) + episode_marker_handles(outcomes[:shown])
                      + visits_legend_handles(top_visits))
    leg = ax_leg.legend(handles=legend_handles, loc="center", ncol=4, frameon=False,
                        fontsize=7.3, handlelength=1.2, columnspacing=0.9, borderaxespad=0.0,
                        title="grey dots: visits per cell over all episodes (area ∝ visits)",
                        title_fontsize=7.3)
    leg.set_gid("demo-legend")
    ep_leg = ax_eps.legend(handles=handles, loc="center", frameon=False, fontsize=7.5,
                           handlelength=1.6, borderaxespad=0.0)
    ep_leg.set_gid("episode-legend")
    ax_note.text(0.5, 0.5, text, transform=ax_note.transAxes, ha="center", va="center",
                 fontsize=7.6, color="#333", gid="demo-note")

    gs = sf_right.add_gridspec(3, 1, height_ratios=[1.0, 1.0, 1.1])
    betas, pb = b.marginal_beta()
    thetas, pt = b.marginal_theta()
    ax_b = draw_beta_marginal(sf_right.add_subplot(gs[0]), betas, pb, beta_true=run.beta_true)
    ax_b.set_ylabel("marginal probability", fontsize=8.5)
    ax_b.set_title(rf"marginal posterior of $\beta$ (summed over $\theta$),  E[$\beta$] = {b.mean_beta:.3g}",
                   fontsize=9.5)
    _, ax_top = draw_theta_summary(sf_right.add_subplot(gs[1]), thetas, pt, mdp.feature_names,
                                      theta_true=run.theta_true, top=8,
                                      ax_top=sf_right.add_subplot(gs[2]), absent=run.absent_features())
    p_truth = float(b.probabilities[run.truth_index])
    ax_top.set_title(rf"most probable $\theta$: marginal P($\theta$) (summed over $\beta$)"
                     "\n" rf"joint P($\theta^*$, $\beta^*$) = {p_truth:.3f}  (★ = $\theta^*$)", fontsize=8.5)
    ax_top.set_xlabel("marginal probability", fontsize=8.5)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig
