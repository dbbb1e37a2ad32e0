"""``study --population``'s figure: the population of β over the participants, and of θ.

Left: one row per participant, sorted by their independent β̂ (most expert on top), on a log β
axis: the independent 90% interval (light line, ○ at β̂) and the pooled one under the population
(dark line, ● at β̂, drawn just below); behind them, per group, the fitted population of β (the
density of log β, Normal(μ, σ²), averaged over the posterior's draws of (μ, σ)), scaled to the
panel's height. Right: the population mean of θ over the set, per feature,
with its 90% interval.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..atomic import write_atomic
from ..inference.posterior import beta_quantile
from .userstudy import figure_png_bytes, figure_style

INDEPENDENT = "#9bb5d9"
POOLED = "#1c4f9c"
GROUP_COLORS = ("#c2255c", "#2b8a3e", "#e67700", "#5f3dc4", "#0b7285", "#862e9c")


def _interval(betas: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
    return (float(beta_quantile(betas, p, 0.05)), float(p @ betas), float(beta_quantile(betas, p, 0.95)))


def population_figure(result: dict[str, Any], feature_names: Sequence[str], *,
                      title: str | None = None) -> Figure:
    """The figure of a :func:`~expertise_irl.userstudy.population.run_population` result."""
    data, post = result["data"], result["posterior"]
    betas = data.hypotheses.betas
    ind = [_interval(betas, result["independent"][i].sum(axis=0)) for i in range(data.n)]
    pooled = [_interval(betas, result["shrunk"][i].sum(axis=0)) for i in range(data.n)]
    order = sorted(range(data.n), key=lambda i: (ind[i][1], i))
    n = data.n
    height = min(24.0, max(4.0, 0.22 * n + 1.8))
    with figure_style():
        fig = Figure(figsize=(11.0, height))
        FigureCanvasAgg(fig)
        ax, ax_t = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 1.2]})
        # the population of β behind the rows: the density of log β averaged over the draws
        grid = np.exp(np.linspace(np.log(betas.min()) - 0.5, np.log(betas.max()) + 0.5, 400))
        lg = np.log(grid)
        curves = []
        for k in range(data.n_groups):
            mu, sd = post.mu[..., k].reshape(-1), post.sigma[..., k].reshape(-1)
            pick = np.linspace(0, len(mu) - 1, min(400, len(mu))).astype(int)
            dens = np.exp(-0.5 * ((lg[None, :] - mu[pick, None]) / sd[pick, None]) ** 2) / sd[pick, None]
            curves.append(dens.mean(axis=0))
        top = max(c.max() for c in curves)
        for k, (g, c) in enumerate(zip(data.group_names, curves, strict=True)):
            color = GROUP_COLORS[k % len(GROUP_COLORS)]
            label = "population of β" + ("" if data.n_groups == 1 else f": {g}")
            y = -0.5 + 0.85 * n * c / top
            ax.fill_between(grid, -0.5, y, color=color, alpha=0.12, lw=0, gid=f"population-fill-{k}")
            ax.plot(grid, y, color=color, lw=1.5, label=label, gid=f"population-{k}")
        for row, i in enumerate(order):
            y = n - 1 - row
            lo, m, hi = ind[i]
            ax.plot([lo, hi], [y + 0.15, y + 0.15], color=INDEPENDENT, lw=2, solid_capstyle="butt",
                    gid="independent" if row == 0 else None, label="independent 90%" if row == 0 else None)
            ax.plot([m], [y + 0.15], "o", mfc="white", mec=INDEPENDENT, ms=4)
            lo, m, hi = pooled[i]
            ax.plot([lo, hi], [y - 0.15, y - 0.15], color=POOLED, lw=2, solid_capstyle="butt",
                    gid="pooled" if row == 0 else None, label="pooled 90%" if row == 0 else None)
            ax.plot([m], [y - 0.15], "o", color=POOLED, ms=4)
        ax.set_xscale("log")
        ax.set_xlim(grid[0], grid[-1])
        ax.set_ylim(-0.8, n - 0.2)
        step = max(1, n // 40)
        ticks = [n - 1 - r for r in range(0, n, step)]
        ax.set_yticks(ticks, [data.participants[order[r]] for r in range(0, n, step)])
        ax.set_xlabel("β (lower: more expert)")
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
        ax.set_title("β: each participant alone and pooled, over the population")
        # θ's population mean
        doc = result["document"]["theta_population_mean"]
        means = np.array([doc[f]["mean"] for f in feature_names])
        err = np.array([[doc[f]["mean"] - doc[f]["q05"] for f in feature_names],
                        [doc[f]["q95"] - doc[f]["mean"] for f in feature_names]])
        ypos = np.arange(len(feature_names))[::-1]
        ax_t.barh(ypos, means, xerr=np.maximum(err, 0), color=POOLED, alpha=0.8, gid="theta-mean")
        ax_t.set_yticks(ypos, list(feature_names))
        ax_t.set_xlim(0, 1)
        ax_t.set_xlabel("θ, population mean (90%)")
        ax_t.set_title("θ population mean")
        if title:
            fig.suptitle(title)
        fig.tight_layout()
    return fig


def render_population_png(path: str | Path, result: dict[str, Any], feature_names: Sequence[str], *,
                          title: str | None = None) -> Path:
    """Save :func:`population_figure` as a PNG at ``path`` (atomically)."""
    return write_atomic(path, figure_png_bytes(population_figure(result, feature_names, title=title)))
