"""One participant's figure in the style of the paper's Figs. 10–11.

A row per task: the specification with the observed path as blue dots (left) and the
optimal path of θ̂ at β = 0.001 (right); the bottom row holds the posterior marginals of β
and of each θ_i (bars for the discrete set, histograms of the draws for NUTS, a point for
MAP). When the posterior has several separated modes their list is printed under it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..worlds.warehouse import WarehouseMap
from . import maps
from .floorplan import PATH_COLOR, draw_cell_path, draw_floor_plan
from .results import draw_discrete_component, draw_point, draw_sampled, theta_component_marginal

OPTIMAL_COLOR = "#0b7261"


def _beta_bars(ax, values, probs, mean: float) -> None:
    x = np.arange(len(values))
    bars = ax.bar(x, probs, color="#6f8fbf", edgecolor="#2f4b7c", lw=0.5)
    for bar in bars:
        bar.set_gid("marginal")
    ax.set_xticks(x, [f"{v:g}" for v in values], fontsize=7)
    ax.set_ylim(0, max(float(np.max(probs)) * 1.15, 0.05))
    ax.set_title(rf"$\beta$: E = {mean:.3g}", fontsize=8.5)
    ax.set_ylabel("marginal prob.", fontsize=7.5)
    maps.tidy(ax)


def participant_figure(participant: str, panels: Sequence[dict[str, Any]], doc: dict[str, Any]):
    """The figure of one participant.

    ``panels``: one dict per task with ``plan`` (:class:`WarehouseMap`), ``title``,
    ``observed`` and ``optimal`` (lists of ``[T, 2]`` cell paths, one per episode).
    ``doc`` is the participant's result document.
    """
    names = doc["feature_names"]
    K = len(names)
    plan0: WarehouseMap = panels[0]["plan"]
    mw, mh = maps.map_size(plan0, 6.0, 4.0)
    width = max(2 * mw + 0.6, 2.1 * (K + 1))
    fig = maps.new_figure((width, len(panels) * (mh + 0.7) + 2.4))
    grid = fig.add_gridspec(len(panels) + 1, 2 * (K + 1), height_ratios=[mh + 0.5] * len(panels) + [1.6])
    for r, panel in enumerate(panels):
        plan = panel["plan"]
        for c, (key, color, label) in enumerate(
            (("observed", PATH_COLOR, "observed"), ("optimal", OPTIMAL_COLOR, "optimal (β = 0.001, θ̂)"))
        ):
            ax = fig.add_subplot(grid[r, c * (K + 1) : (c + 1) * (K + 1)])
            draw_floor_plan(ax, plan, show_grid=False, legend=(r == len(panels) - 1 and c == 0))
            for i, cells in enumerate(panel[key]):
                if len(cells):
                    draw_cell_path(ax, plan, cells, color=color, gid=f"{key}-{r}-{i}", size=2.5)
            ax.set_title(f"{panel['title']}: {label}", fontsize=8.5)
    bottom = [fig.add_subplot(grid[-1, 2 * i : 2 * i + 2]) for i in range(K + 1)]
    method = doc["method"]
    if method == "discrete":
        b = doc["marginals"]["beta"]
        _beta_bars(bottom[0], b["values"], b["probabilities"], doc["beta_hat"])
        t = doc["marginals"]["theta"]
        for i, name in enumerate(names):
            v, p = theta_component_marginal(t["values"], t["probabilities"], i)
            draw_discrete_component(bottom[i + 1], v, p, name, mean=doc["theta_hat"][i])
    elif isinstance(doc.get("samples"), dict):
        s = doc["samples"]
        ci = doc.get("credible_intervals") or {}  # null where a chain did not move: no band there
        draw_sampled(bottom[0], s["beta"], "β", mean=doc["beta_hat"],
                     withheld="beta" in ci and ci["beta"] is None)
        theta = np.asarray(s["theta"], dtype=float)
        for i, name in enumerate(names):
            draw_sampled(bottom[i + 1], theta[:, i], f"θ {name}", mean=doc["theta_hat"][i],
                         withheld=(ci.get("theta") or [0] * len(names))[i] is None)
    else:
        draw_point(bottom[0], doc["beta_hat"], "β", lo=1e-3, hi=1e2, log=True)
        for i, name in enumerate(names):
            draw_point(bottom[i + 1], doc["theta_hat"][i], f"θ {name}", lo=0.0, hi=1.0)
    theta_txt = ", ".join(f"{v:.2f}" for v in doc["theta_hat"])
    title = f"participant {participant}: β̂ = {doc['beta_hat']:.3g}, θ̂ = [{theta_txt}] ({method})"
    modes = doc.get("modes") or []
    if len(modes) > 1:
        title += "\nseveral modes: " + "; ".join(
            f"θ = [{', '.join(f'{x:.2f}' for x in m['theta'])}], β = {m['beta']:g}: "
            f"p = {m['probability']:.2f}"
            for m in modes
        )
    fig.suptitle(title, fontsize=9.5)
    return fig


def render_participant_png(path: str | Path, participant: str, panels, doc) -> Path:
    return maps.save_figure(participant_figure(participant, panels, doc), path)
