"""Figures in the paper's form, drawn with matplotlib's Agg canvas (no pyplot, no global state).

Each helper draws onto an axes; :func:`save` writes ``figures/<name>.png`` and ``.pdf``.
Regret spans many orders of magnitude, so it is drawn on a log axis (:data:`LOG_FLOOR`: values
below it, numerically zero, are drawn at it and the captions say so).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...atomic import save_figure_atomic
from .stats import mean_ci

#: How captions name the intervals drawn.
CI_TEXT = "95% confidence intervals (Student t, clipped to the metric's range)"
#: Regret values below this are drawn at it on log axes (regrets of 1e-17 are rounding noise).
LOG_FLOOR = 1e-6
GREEN, ORANGE, BLUE, PURPLE, GREY, RED = "#2a9d3f", "#f28e2b", "#4e79a7", "#9467bd", "#7f7f7f", "#d62728"
CONDITION_COLORS = {"full": GREEN, "fixed_theta": ORANGE, "fixed_beta": ORANGE}
CONDITION_LABELS = {"full": "Full set", "fixed_theta": "Fixed θ set", "fixed_beta": "Fixed β set"}
GROUP_COLORS = {"high": BLUE, "medium": ORANGE, "low": RED}
METHOD_COLORS = {"discrete": GREEN, "birl_box": ORANGE, "birl_simplex": BLUE, "map": PURPLE, "nuts": GREY}
METHOD_LABELS = {"discrete": "discrete set", "birl_box": "Algorithm 1 (box)",
                 "birl_simplex": "Algorithm 1 (simplex)", "map": "MAP (gradient)", "nuts": "NUTS"}


def new_figure(ncols: int = 1, *, width: float = 4.2, height: float = 3.6, nrows: int = 1,
               sharey: bool = False):
    """A figure with ``nrows × ncols`` axes (flattened), on the Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width * ncols, height * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, sharey=sharey, squeeze=False).ravel()
    return fig, list(axes)


def episodes_axis(ax) -> None:
    """An x axis of episode counts: labelled "episodes seen", ticks on whole numbers only."""
    from matplotlib.ticker import MaxNLocator

    ax.set_xlabel("episodes seen")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def save(fig, folder: Path, name: str) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    png, pdf = folder / f"{name}.png", folder / f"{name}.pdf"
    save_figure_atomic(fig, png, dpi=130, metadata={"Software": None})
    save_figure_atomic(fig, pdf, metadata={"CreationDate": None, "Producer": None, "Creator": None})
    return [png, pdf]


def log10_floor(values) -> np.ndarray:
    x = np.asarray(values, dtype=np.float64)
    return np.log10(np.maximum(x[np.isfinite(x)], LOG_FLOOR))


def set_log_ticks(ax, axis: str = "y") -> None:
    """Label an axis that holds log10 values as powers of ten."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    a = ax.yaxis if axis == "y" else ax.xaxis
    a.set_major_locator(MaxNLocator(integer=True))
    a.set_major_formatter(FuncFormatter(lambda v, _: f"$10^{{{round(v)}}}$"))


def _violin(ax, values, pos: float, color: str, width: float) -> None:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return
    if len(v) < 3 or np.ptp(v) == 0:  # no density to draw: a bar at the value(s)
        ax.hlines(v, pos - width / 3, pos + width / 3, color=color, lw=2)
    else:
        parts = ax.violinplot([v], positions=[pos], widths=width, showextrema=False)
        for body in parts["bodies"]:
            body.set_facecolor(color)
            body.set_edgecolor("black")
            body.set_linewidth(0.6)
            body.set_alpha(0.75)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    ax.vlines(pos, q1, q3, color="black", lw=3)
    ax.scatter([pos], [med], color="white", edgecolor="black", zorder=3, s=14)


def violins(ax, groups: list[str], hues: list[str], values, colors: dict[str, str], labels: dict[str, str],
            *, log: bool = False, legend: bool = True) -> None:
    """Side-by-side violins: one slot per group, one violin per hue; ``values(group, hue)`` -> array.

    Each violin shows the density, the quartiles (black bar) and the median (white dot).
    """
    width = 0.8 / len(hues)
    for i, g in enumerate(groups):
        for j, h in enumerate(hues):
            v = values(g, h)
            _violin(ax, log10_floor(v) if log else v, i + (j - (len(hues) - 1) / 2) * width,
                    colors[h], width * 0.9)
    ax.set_xticks(range(len(groups)), groups)
    ax.set_xlim(-0.6, len(groups) - 0.4)
    if log:
        set_log_ticks(ax)
    if legend:
        ax.legend(handles=patches(hues, colors, labels), fontsize=8, loc="best")
    ax.grid(axis="y", alpha=0.3)


def patches(hues, colors, labels):
    from matplotlib.patches import Patch

    return [Patch(facecolor=colors[h], edgecolor="black", label=labels[h]) for h in hues]


def figure_legend(fig, handles) -> None:
    """One legend for the whole figure, in a row below the panels."""
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=9, frameon=False)


def ci_bars(ax, categories: list[str], series: dict[str, dict], colors: dict[str, str],
            labels: dict[str, str], *, log: bool = False, dodge: bool = True,
            bounds: tuple[float, float] = (-np.inf, np.inf)) -> None:
    """Bars of means with 95% CIs: ``series[hue][category]`` -> values; one bar per (category, hue).

    ``dodge=False`` puts every hue at its category's centre (for hues that each fill one category).
    Error bars are clipped to ``bounds``, the range the metric can take.
    """
    hues = list(series)
    width = 0.8 / max(len(hues), 1) if dodge else 0.6
    for j, h in enumerate(hues):
        xs, ms, err = [], [], [[], []]
        for i, c in enumerate(categories):
            v = series[h].get(c)
            if v is None or len(v) == 0:
                continue
            ci = mean_ci(v)
            xs.append(i + (j - (len(hues) - 1) / 2) * width if dodge else i)
            ms.append(ci.mean)
            half = 0.0 if not np.isfinite(ci.half) else ci.half
            floor = max(bounds[0], LOG_FLOOR) if log else bounds[0]  # a log axis cannot show <= 0
            err[0].append(max(min(half, ci.mean - floor), 0.0))
            err[1].append(max(min(half, bounds[1] - ci.mean), 0.0))
        ax.bar(xs, ms, width * 0.9, yerr=err, color=colors[h], edgecolor="black", lw=0.6,
               capsize=3, label=labels[h])
    ax.set_xticks(range(len(categories)), categories)
    if log:
        ax.set_yscale("log")
    if len(hues) > 1 and dodge:
        ax.legend(fontsize=8, loc="best")
    ax.grid(axis="y", alpha=0.3)


def bands(ax, frame, x: str, y: str, hue: str, order: list[str], colors: dict[str, str],
          labels: dict[str, str], *, log: bool = False, legend: bool = True,
          bounds: tuple[float, float] = (-np.inf, np.inf)) -> None:
    """Mean of ``y`` against ``x`` for each ``hue`` with a shaded 95% CI band (clipped to ``bounds``)."""
    for h in order:
        sub = frame[frame[hue] == h]
        if not len(sub):
            continue
        xs, ms, lo, hi = [], [], [], []
        for xv, g in sub.groupby(x, sort=True):
            ci = mean_ci(g[y])
            xs.append(xv)
            ms.append(ci.mean)
            lo.append(ci.low if np.isfinite(ci.low) else ci.mean)
            hi.append(ci.high if np.isfinite(ci.high) else ci.mean)
        ms, lo, hi = (np.asarray(a, dtype=np.float64) for a in (ms, lo, hi))
        lo, hi = np.maximum(lo, bounds[0]), np.minimum(hi, bounds[1])
        if log:
            ms, lo, hi = (np.maximum(a, LOG_FLOOR) for a in (ms, lo, hi))
        ax.plot(xs, ms, color=colors[h], label=labels[h], marker="o", ms=3, lw=1.5)
        ax.fill_between(xs, lo, hi, color=colors[h], alpha=0.2, lw=0)
    if log:
        ax.set_yscale("log")
    if legend:
        ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)


def lines(order, colors, labels):
    """Legend handles for :func:`bands` series."""
    from matplotlib.lines import Line2D

    return [Line2D([], [], color=colors[h], marker="o", ms=3, lw=1.5, label=labels[h]) for h in order]


def needs_log(values, span: float = 100.0) -> bool:
    """True when the positive values span more than ``span`` (a log axis then reads better)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v) & (v > LOG_FLOOR)]
    return len(v) > 1 and v.max() / v.min() > span
