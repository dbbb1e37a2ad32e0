"""The study at a glance: every participant's β and θ̂ in one figure (from ``study.csv``).

One row per participant, sorted by β̂ (most expert on top; participants without an estimate
last): on the left their 90% interval of β (a line, where ``beta_q05`` / ``beta_q95`` are
numbers), β̂ (●) and the median (|) on a log axis, with the expertise groups' boundaries
dashed; on the right θ̂, one column per feature, as a heat map in the same row order (grey
where θ̂ is not a number, e.g. θ estimated per task). Rows get a fixed height, so the figure
grows with the study; with many participants the rows get thinner and only every k-th is
labelled, labels never below 6 pt. Tick labels of β are on top and at the bottom.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

from ..atomic import write_atomic
from ..hypotheses import GROUP_BOUNDARIES, GROUP_NAMES
from . import maps
from .userstudy import DPI, figure_png_bytes, figure_style, finite_or_none

#: Row height (inches) for small studies, and the plot height a large study is squeezed into
#: before rows get thinner than :data:`MIN_ROW`.
ROW = 0.2
TARGET_HEIGHT = 24.0
MIN_ROW = 0.05
MIN_LABEL_FONT = 6.0
HAT_COLOR = "#1c4f9c"
INTERVAL_COLOR = "#7aa0d4"
MEDIAN_COLOR = "#c2255c"


def _finite_or_nan(x: Any) -> float:
    """``x`` as a finite float; NaN (not drawn) when it is not a number."""
    v = finite_or_none(x)
    return math.nan if v is None else v


def study_order(rows: Sequence[dict[str, Any]]) -> list[int]:
    """Indices of ``rows`` by β̂, smallest (most expert) first; rows without a β̂ last, in order."""
    keys = [_finite_or_nan(r.get("beta_hat")) for r in rows]
    return sorted(range(len(rows)),
                  key=lambda i: (math.isnan(keys[i]), 0.0 if math.isnan(keys[i]) else keys[i], i))


def _row_geometry(n: int) -> tuple[float, float, int]:
    """Row height (inches), label font (points) and label step for ``n`` participants."""
    row = ROW if n * ROW <= TARGET_HEIGHT else max(TARGET_HEIGHT / n, MIN_ROW)
    font = max(MIN_LABEL_FONT, min(8.5, 0.75 * row * 72))
    step = max(1, math.ceil(1.15 * font / (row * 72)))
    return row, font, step


def _log_ticks(lo: float, hi: float) -> list[float]:
    e0, e1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    ticks: list[float] = []
    for mult in ((1.0,), (1.0, 3.0), (1.0, 2.0, 5.0)):
        cand = [m * 10.0 ** e for e in range(e0, e1 + 1) for m in mult if lo <= m * 10.0 ** e <= hi]
        if len(cand) > 8:
            break
        ticks = cand
        if len(cand) >= 4:
            break
    return ticks or [float(f"{math.sqrt(lo * hi):.2g}")]


def study_figure(rows: Sequence[dict[str, Any]], feature_names: Sequence[str], *,
                 title: str | None = None) -> Figure:
    """The :class:`~matplotlib.figure.Figure` of the module docstring.

    ``rows``: the ``study.csv`` rows (``participant``, ``beta_hat``, ``beta_median``,
    ``beta_q05``, ``beta_q95``, ``theta_<feature>``; missing or non-numbers are not drawn).
    The β̂ markers are the Line2D with gid ``"beta-hat"``, top row first.
    """
    with figure_style():
        return _figure(list(rows), [str(f) for f in feature_names], title)


def _figure(rows: list[dict[str, Any]], names: list[str], title: str | None) -> Figure:
    order = study_order(rows)
    n, K = len(rows), len(names)
    ids = [str(rows[i].get("participant", "")) for i in order]
    col = {k: np.array([_finite_or_nan(rows[i].get(k)) for i in order])
           for k in ("beta_hat", "beta_median", "beta_q05", "beta_q95")}
    theta = np.array([[_finite_or_nan(rows[i].get(f"theta_{f}")) for f in names]
                      for i in order]).reshape(n, K)
    row, font, step = _row_geometry(max(n, 1))
    label_w = min(max(len(s) for s in ids) if ids else 4, 24) * font * 0.62 / 72 + 0.25
    top, bottom = 1.25, 0.75  # title, legend and top ticks; bottom ticks and label
    plot_h = max(n * row, 1.5)
    beta_w, gap, heat_w = 6.0, 0.35, max(1.6, 0.6 * K)
    W = label_w + beta_w + gap + heat_w + 0.3
    H = top + plot_h + bottom
    fig = Figure(figsize=(W, H), dpi=DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_axes([label_w / W, bottom / H, beta_w / W, plot_h / H])
    ax.set_gid("study-beta")
    axh = fig.add_axes([(label_w + beta_w + gap) / W, bottom / H, heat_w / W, plot_h / H], sharey=ax)
    axh.set_gid("study-theta")
    lo, hi = _beta_limits(col, n)
    _draw_beta_rows(ax, col, row)
    _beta_axis(ax, lo, hi)
    _row_labels(ax, ids, step, font)
    _draw_theta_heatmap(fig, axh, theta, names, row,
                        [(label_w + beta_w + gap) / W, 1 - 0.42 / H, heat_w / W, 0.1 / H])
    _header(fig, n, int(np.isfinite(col["beta_hat"]).sum()), title, step, label_w / W, H)
    return fig


def _beta_limits(col: dict[str, np.ndarray], n: int) -> tuple[float, float]:
    """The β axis: every positive value of ``col`` with room on both sides, a decade at least."""
    vals = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in col.values()]) if n else np.array([])
    lo, hi = (float(vals.min()) / 1.6, float(vals.max()) * 1.6) if vals.size else (1e-2, 1e1)
    if hi / lo < 10:
        mid = math.sqrt(lo * hi)
        lo, hi = mid / math.sqrt(10), mid * math.sqrt(10)
    return lo, hi


def _draw_beta_rows(ax, col: dict[str, np.ndarray], row: float) -> None:
    """Per row (``row`` inches high): the 90% interval, the median (|) and β̂ (●)."""
    y = np.arange(len(col["beta_hat"]))
    q05, q95 = col["beta_q05"], col["beta_q95"]
    ok = np.isfinite(q05) & np.isfinite(q95) & (q05 > 0)
    lw = max(1.0, min(4.0, 0.45 * row * 72))
    ax.hlines(y[ok], q05[ok], q95[ok], color=INTERVAL_COLOR, lw=lw, zorder=2, gid="beta-interval")
    med = np.isfinite(col["beta_median"]) & (col["beta_median"] > 0)
    ms = max(3.0, min(6.0, 0.55 * row * 72))
    thin = row * 72 < 8  # thin rows: markers without white edges, medians no taller than a row
    ax.plot(col["beta_median"][med], y[med], ls="", marker="|", ms=ms * (1.0 if thin else 1.5),
            mew=0.8 if thin else 1.2, color=MEDIAN_COLOR, zorder=3, gid="beta-median")
    hat = np.where(col["beta_hat"] > 0, col["beta_hat"], np.nan)
    ax.plot(hat, y, ls="", marker="o", ms=ms, color=HAT_COLOR, mec="none" if thin else "white", mew=0.4,
            zorder=4, gid="beta-hat")


def _beta_axis(ax, lo: float, hi: float) -> None:
    """The log β axis from ``lo`` to ``hi``: ticks top and bottom, the groups' boundaries and names."""
    ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    ticks = _log_ticks(lo, hi)
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.tick_params(axis="x", labelsize=8, top=True, labeltop=True)
    for b in GROUP_BOUNDARIES:
        if lo < b < hi:
            ax.axvline(b, color="#868e96", lw=0.8, ls="--", zorder=1, gid="group-boundary")
    bounds = (0.0, *GROUP_BOUNDARIES, math.inf)  # each group's β range, clipped to the axis
    for g, a, c in zip(GROUP_NAMES, bounds[:-1], bounds[1:], strict=True):
        if c <= lo or a >= hi:
            continue
        a, c = max(a, lo), min(c, hi)
        ax.annotate(f"{g} expertise", (math.sqrt(a * c), 1.0), xycoords=("data", "axes fraction"),
                    xytext=(0, 22), textcoords="offset points", ha="center", va="bottom", fontsize=8,
                    color="#5c5f66", annotation_clip=False)
    ax.set_xlabel("β (log scale; low = expert)", fontsize=8.5)


def _row_labels(ax, ids: list[str], step: int, font: float) -> None:
    """Rows top down, every ``step``-th labelled with its participant; a light grid when few."""
    n = len(ids)
    ax.set_ylim(n - 0.5, -0.5)  # first (most expert) on top
    shown = list(range(0, n, step))
    ax.yaxis.set_major_locator(FixedLocator(shown))
    ax.set_yticklabels([ids[i] for i in shown], fontsize=font)
    ax.tick_params(axis="y", length=2 if step == 1 else 3, labelsize=font)
    if n <= 150:
        ax.grid(axis="y", color="#eeeeee", lw=0.5, zorder=0)
    maps.tidy(ax)
    ax.tick_params(axis="x", labelsize=8)


def _draw_theta_heatmap(fig: Figure, axh, theta: np.ndarray, names: list[str], row: float,
                        cbar_rect: list[float]) -> None:
    """θ̂ as a heat map (``[rows, K]``; grey where not a number), values written in tall rows,
    and its colour bar at ``cbar_rect``."""
    n, K = theta.shape
    cmap = mpl.colormaps["viridis"].with_extremes(bad="#d0d0d0")
    finite = theta[np.isfinite(theta)]
    vmin, vmax = min(0.0, float(finite.min(initial=0.0))), max(1.0, float(finite.max(initial=1.0)))
    im = axh.imshow(np.ma.masked_invalid(theta), aspect="auto", cmap=cmap, vmin=vmin, vmax=vmax,
                    interpolation="nearest", extent=(-0.5, K - 0.5, n - 0.5, -0.5))
    im.set_gid("theta-heatmap")
    if row * 72 >= 13 and K:
        for (i, k), v in np.ndenumerate(theta):
            if np.isfinite(v):
                axh.text(k, i, f"{v:.2f}", ha="center", va="center", fontsize=8,
                         color="white" if (v - vmin) / (vmax - vmin or 1) < 0.6 else "black")
    axh.set_xticks(range(K), names, fontsize=8, rotation=30 if K > 3 else 0,
                   ha="right" if K > 3 else "center")
    axh.tick_params(axis="y", left=False, labelleft=False)
    axh.tick_params(axis="x", top=True, labeltop=True, bottom=True, labelbottom=True, labelsize=8)
    if K > 3:
        for lab in axh.get_xticklabels():
            lab.set_rotation_mode("anchor")
    axh.set_ylim(n - 0.5, -0.5)
    cax = fig.add_axes(cbar_rect)
    cb = fig.colorbar(im, cax=cax, orientation="horizontal")
    cb.ax.tick_params(labelsize=8, length=2)
    cb.ax.xaxis.set_major_locator(FixedLocator(np.linspace(vmin, vmax, 3)))
    cb.ax.set_title("θ̂ (grey: none)", fontsize=8.5, pad=3)


def _header(fig: Figure, n: int, n_est: int, title: str | None, step: int, x: float, H: float) -> None:
    """The title (participants, those without β̂), the legend below it at figure fraction ``x``,
    and, when not every row is labelled, a note at the bottom (``H``: figure height, inches)."""
    head = title or "Study overview"
    fig.text(x, 1 - 0.12 / H, f"{head}: {n} participant{'s' if n != 1 else ''}"
             + (f" ({n - n_est} without β̂)" if n_est < n else ""), fontsize=11, fontweight="bold", va="top")
    handles = [Line2D([], [], ls="", marker="o", ms=6, color=HAT_COLOR, label="β̂ (mean)"),
               Line2D([], [], ls="", marker="|", ms=8, mew=1.2, color=MEDIAN_COLOR, label="median"),
               Line2D([], [], color=INTERVAL_COLOR, lw=3, label="90% interval"),
               Line2D([], [], color="#868e96", lw=0.8, ls="--", label="expertise group boundary")]
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(x, 1 - 0.4 / H), ncol=4,
               frameon=False, fontsize=8, borderaxespad=0.0, columnspacing=1.2)
    if step > 1:
        fig.text(x, 0.1 / H, f"{n} rows in β̂ order; one label every {step} rows", fontsize=8,
                 color="#555555", va="bottom")


def render_study_png(path: str | Path, rows: Sequence[dict[str, Any]], feature_names: Sequence[str], *,
                     title: str | None = None) -> Path:
    """Save :func:`study_figure` as a PNG at ``path`` (atomically; same bytes on every run)."""
    return write_atomic(path, figure_png_bytes(study_figure(rows, feature_names, title=title)))
