"""``plot --check``: a full page of statistic panels with units, and the per-state map as maps draw it."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb

from expertise_irl.plots import check, maps
from expertise_irl.worlds.grid import OBSTACLE
from expertise_irl.worlds.maps import load_bundled_world

NAMES = ["path_length", "steps_to_goal", "feature_length", "feature_road", "feature_avoid", "feature_slow",
         "feature_traffic", "visit_discrepancy", "agreement"]


def _doc(mdp):
    rng = np.random.default_rng(0)
    stats = {n: {"observed": 1.0, "p_value": 0.5, "rejected": False} for n in NAMES}
    replicated = {n: rng.normal(1.0, 0.3, 50).tolist() for n in NAMES}
    states = np.flatnonzero(~mdp.terminal)
    comp = {"departure": [{"states": states.tolist(), "values": rng.normal(0, 0.1, states.size).tolist()}],
            "top_states": [{"state": int(states[0])}], "gain": 0.0, "gain_se": 0.01, "beta_features": 0.5,
            "beta_richer": 0.5}
    mis = {"verdict": "features explain the behaviour", "reason": "no check rejected",
           "predictive": {"statistics": stats, "replicated": replicated, "replicates": 50},
           "competitor": comp, "thresholds": {"alpha": 0.05}}
    return {"diagnostics": {"misspecification": mis}}


def test_panels_fill_their_grid_and_say_what_they_count():
    assert check.panel_grid(9) == (3, 3)
    assert check.panel_grid(8) == (2, 4)
    assert check.panel_grid(7) == (2, 4)
    assert check.panel_grid(2) == (1, 2)
    mdp = load_bundled_world("crossroads").to_mdp()
    fig = check.check_figure(_doc(mdp), mdp=mdp)
    panels = [ax for ax in fig.get_axes() if ax.patches]  # the histograms
    assert len(panels) == len(NAMES)
    empty = [ax for ax in fig.get_axes() if not (ax.patches or ax.images or ax.collections)]
    assert all(ax.get_label() == "<colorbar>" for ax in empty), "an empty panel is left on the page"
    for ax in panels:
        assert ax.get_xlabel() and ax.get_ylabel() == "replicated data sets"
    assert check.statistic_unit("feature_road") == "Σ φ_road per episode"


@pytest.mark.slow
def test_obstacles_are_drawn_in_the_obstacle_colour_not_white():
    zone_map = load_bundled_world("crossroads")
    mdp = zone_map.to_mdp()
    fig = check.check_figure(_doc(mdp), mdp=mdp)
    FigureCanvasAgg(fig).draw()
    (ax,) = [a for a in fig.get_axes() if a.images]
    pixels = np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0
    states = set(map(tuple, mdp.state_xy.tolist()))
    blocked = [(x, y) for y in range(zone_map.height) for x in range(zone_map.width) if (x, y) not in states]
    assert blocked
    want = np.array(to_rgb(maps.ZONE_COLORS[OBSTACLE]))
    for x, y in blocked:
        px, py = ax.transData.transform((x, y))
        colour = pixels[round(fig.bbox.height - py), round(px)]
        assert np.abs(colour - want).max() < 0.1, (x, y, colour)
