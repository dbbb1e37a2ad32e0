"""Figures: PNG output, road arrows, trajectories, posterior panels, no figure leaks."""

from __future__ import annotations

import re
import struct

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.inference.identifiability import absent_features
from expertise_irl.plots import maps as render
from expertise_irl.worlds.zones import FEATURE_NAMES, load_bundled, parse_map

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
UP, DOWN, LEFT, RIGHT = range(4)

SMALL = parse_map("S>>vx\n.#.v.\nts.G<\n", name="small")


def png_size(path) -> tuple[int, int]:
    """(width, height) in pixels from the IHDR chunk."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def new_ax():
    return Figure().add_subplot()


def demo_paths():
    return [
        np.array([[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2]]),
        np.array([[0, 0], [0, 1], [0, 2], [1, 2], [2, 2], [3, 2]]),
        np.array([[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2]]),  # same as the first
    ]


def posterior():
    betas = np.array([0.01, 0.09, 0.5, 1.0, 5.0, 10.0])
    beta_probs = np.array([0.05, 0.6, 0.2, 0.1, 0.03, 0.02])
    rng = np.random.default_rng(0)
    thetas = rng.dirichlet(np.ones(5), size=40)
    theta_probs = rng.dirichlet(np.ones(40))
    return betas, beta_probs, thetas, theta_probs


# ------------------------------------------------------------------------- PNGs
def test_render_map_png_writes_a_png_and_leaks_no_figure(tmp_path):
    before = plt.get_fignums()
    out = render.render_map_png(load_bundled("crossroads"), tmp_path / "map.png", title="x")
    assert out == tmp_path / "map.png"
    w, h = png_size(out)
    assert out.stat().st_size > 5_000
    assert w > h > 100  # crossroads is 16 × 12 cells: a landscape picture
    out2 = render.render_map_png(SMALL, tmp_path / "demo.png", trajectories_xy=demo_paths())
    assert png_size(out2)[0] > 100 and out2.stat().st_size > 5_000
    assert out2.read_bytes() != render.render_map_png(SMALL, tmp_path / "c.png").read_bytes()
    assert plt.get_fignums() == before


def test_render_summary_png_writes_a_png_and_leaks_no_figure(tmp_path):
    betas, bp, thetas, tp = posterior()
    before = plt.get_fignums()
    out = render.render_summary_png(
        tmp_path / "summary.png", load_bundled("crossroads"), demo_paths(), betas, bp,
        thetas, tp, FEATURE_NAMES, theta_true=thetas[3], beta_true=0.09, title="demo",
    )
    w, h = png_size(out)
    assert out.stat().st_size > 20_000
    assert w > h > 400  # map on the left, posterior panels on the right
    out2 = render.render_summary_png(tmp_path / "s2.png", SMALL, demo_paths()[:1], betas, bp,
                                     thetas, tp, FEATURE_NAMES, top=0)
    assert png_size(out2)[0] > 400
    assert plt.get_fignums() == before


# -------------------------------------------------------------------------- map
def test_road_arrows_point_along_the_road():
    ax = render.draw_map(new_ax(), SMALL)
    (q,) = [c for c in ax.collections if c.get_gid() == render.ROAD_ARROWS_GID]
    arrows = {(int(x), int(y)): (u, v) for (x, y), u, v in zip(q.XY, q.U, q.V, strict=True)}
    expected = {(1, 0): (1, 0), (2, 0): (1, 0), (3, 0): (0, 1), (3, 1): (0, 1), (4, 2): (-1, 0)}
    assert arrows == expected  # one arrow per road cell; y grows downwards
    # On screen, 'v' must point down and '>' right: check through the data transform.
    tr = ax.transData.transform
    (x0, y0), (x1, y1) = tr([(3, 0), (3, 1)])
    assert y1 < y0 and x1 == pytest.approx(x0)  # display y grows upwards
    (x0, y0), (x1, y1) = tr([(1, 0), (2, 0)])
    assert x1 > x0
    assert ax.get_ylim()[0] > ax.get_ylim()[1]  # row 0 at the top


@pytest.mark.parametrize(("ch", "uv"), [(">", (1, 0)), ("<", (-1, 0)), ("^", (0, -1)),
                                         ("v", (0, 1))])
def test_each_road_character_gets_its_direction(ch, uv):
    ax = render.draw_map(new_ax(), parse_map(f"{ch}G\n"))
    (q,) = [c for c in ax.collections if c.get_gid() == render.ROAD_ARROWS_GID]
    assert q.XY.tolist() == [[0.0, 0.0]]
    assert (float(q.U[0]), float(q.V[0])) == uv


def test_draw_map_cells_goal_start_and_legend():
    ax = render.draw_map(new_ax(), SMALL)
    (img,) = ax.images
    rgb = np.asarray(img.get_array())
    assert rgb.shape == (3, 5, 3)
    colors = {ch: np.array(matplotlib.colors.to_rgb(c)) for ch, c in render.ZONE_COLORS.items()}
    np.testing.assert_allclose(rgb[1, 1], colors["#"])  # obstacle
    np.testing.assert_allclose(rgb[0, 4], colors["x"])  # avoid
    np.testing.assert_allclose(rgb[2, 0], colors["t"])  # traffic
    np.testing.assert_allclose(rgb[2, 1], colors["s"])  # slow
    np.testing.assert_allclose(rgb[0, 1], colors[">"])  # road
    goals = [p for p in ax.patches if p.get_gid() == "goal"]
    assert len(goals) == 1 and isinstance(goals[0], Circle)
    assert goals[0].center == (3, 2)
    starts = [p for p in ax.patches if p.get_gid() == "start"]
    assert len(starts) == 1
    assert starts[0].get_x() + starts[0].get_width() / 2 == pytest.approx(0.0)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["obstacle", "avoid", "slow-down", "high traffic", "road (→ direction)",
                      "start", "goal"]
    assert ax.get_xticks().size == 0 and ax.get_yticks().size == 0
    assert ax.get_aspect() == 1.0


def test_legend_lists_only_zone_types_present():
    ax = render.draw_map(new_ax(), parse_map(".xG\n...\n"), show_grid=False)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["avoid", "goal"]
    assert not [c for c in ax.collections if c.get_gid() == render.ROAD_ARROWS_GID]
    assert render.draw_map(new_ax(), SMALL, legend=False).get_legend() is None


# ----------------------------------------------------------------- trajectories
def lines_by_gid(ax, prefix):
    return [ln for ln in ax.lines if (ln.get_gid() or "").startswith(prefix)]


def test_trajectories_follow_cell_centres_with_small_deterministic_jitter():
    paths = demo_paths()
    ax = render.draw_trajectories(render.draw_map(new_ax(), SMALL), SMALL, paths, jitter=0.2)
    lines = lines_by_gid(ax, "path-")
    assert len(lines) == 3
    offsets = []
    for ln, p in zip(lines, paths, strict=True):
        xy = np.column_stack([ln.get_xdata(), ln.get_ydata()])
        off = xy - p
        assert np.allclose(off, off[0])  # one rigid shift per episode
        assert np.hypot(*off[0]) <= 0.2 + 1e-12
        offsets.append(off[0])
    assert np.allclose(offsets[0], 0.0)
    assert not np.allclose(offsets[0], offsets[2])  # identical paths drawn apart
    starts = lines_by_gid(ax, "start-")
    assert len(starts) == 3
    for s, p, off in zip(starts, paths, offsets, strict=True):
        np.testing.assert_allclose([s.get_xdata()[0], s.get_ydata()[0]], p[0] + off)
        assert s.get_marker() == "o"
    again = render.draw_trajectories(new_ax(), SMALL, paths, jitter=0.2)
    for a, b in zip(lines, lines_by_gid(again, "path-"), strict=True):
        np.testing.assert_array_equal(a.get_xydata(), b.get_xydata())


def test_trajectory_colours():
    paths = demo_paths()
    ax = render.draw_trajectories(new_ax(), SMALL, paths, color="red")
    assert {ln.get_color() for ln in lines_by_gid(ax, "path-")} == {"red"}
    ax = render.draw_trajectories(new_ax(), SMALL, paths)
    assert len({ln.get_color() for ln in lines_by_gid(ax, "path-")}) == 3
    with pytest.raises(InputError, match="2 colours for 3 paths"):
        render.draw_trajectories(new_ax(), SMALL, paths, color=["r", "g"])


def test_trajectories_off_the_map_are_rejected():
    with pytest.raises(InputError, match=r"path 0, step 1: cell \(5, 0\) is off the map"):
        render.draw_trajectories(new_ax(), SMALL, [np.array([[4, 0], [5, 0]])])
    with pytest.raises(InputError, match="path 0"):
        render.draw_trajectories(new_ax(), SMALL, [np.zeros((0, 2), dtype=int)])


def test_paths_to_xy_includes_the_final_state():
    zm = parse_map("S..\n.#G\n")
    mdp = zm.to_mdp()
    idx = zm.state_index()
    s = [idx[0, 0], idx[0, 1], idx[0, 2], idx[0, 0], idx[1, 0]]
    trajs = Trajectories(episode=[0, 0, 0, 1, 1], step=[0, 1, 2, 0, 1], state=s,
                         action=[RIGHT, RIGHT, DOWN, DOWN, UP])
    xy = render.paths_to_xy(trajs, mdp)
    assert [p.tolist() for p in xy] == [
        [[0, 0], [1, 0], [2, 0], [2, 1]],
        [[0, 0], [0, 1], [0, 0]],
    ]


def test_paths_to_xy_rejects_an_unavailable_last_action():
    zm = parse_map("S..\n.#G\n")
    mdp = zm.to_mdp()
    trajs = Trajectories(episode=[0], step=[0], state=[0], action=[UP])  # off the grid
    with pytest.raises(InputError, match="episode 0"):
        render.paths_to_xy(trajs, mdp)


# -------------------------------------------------------------------- posterior
def test_beta_marginal_bars_and_true_value():
    betas, bp, _, _ = posterior()
    ax = render.draw_beta_marginal(new_ax(), betas, bp, beta_true=0.5)
    bars = ax.patches
    np.testing.assert_allclose([b.get_height() for b in bars], bp)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0.01", "0.09", "0.5", "1", "5", "10"]
    (hit,) = [b for b in bars if b.get_gid() == "beta-true"]
    assert hit is bars[2]
    assert hit.get_facecolor() != bars[0].get_facecolor()
    assert "E[" in ax.get_title()
    ax = render.draw_beta_marginal(new_ax(), betas, bp, beta_true=2.0)
    assert "not in set" in ax.get_title()
    assert not [b for b in ax.patches if b.get_gid() == "beta-true"]
    with pytest.raises(InputError, match="expected 6 probabilities"):
        render.draw_beta_marginal(new_ax(), betas, bp[:3])


def test_a_fine_beta_grid_labels_only_the_bars_with_mass_and_turns_its_ticks():
    betas = np.logspace(-2, 1, 16)
    bp = np.zeros(16)
    bp[[7, 8]] = [0.19, 0.81]
    ax = render.draw_beta_marginal(new_ax(), betas, bp)
    assert sorted(t.get_text() for t in ax.texts) == ["0.19", "0.81"]
    ticks = ax.get_xticklabels()
    assert [t.get_text() for t in ticks][:3] == ["0.01", "0.016", "0.025"]
    assert all(t.get_rotation() == 70 for t in ticks)
    few = render.draw_beta_marginal(new_ax(), betas[:6], np.full(6, 1 / 6))
    assert len(few.texts) == 6 and all(t.get_rotation() == 0 for t in few.get_xticklabels())


def test_theta_summary_mean_true_and_top_list():
    thetas = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 0.0], [1.0, 0.0, 0.0]])
    probs = np.array([0.2, 0.5, 0.1, 0.2])  # rows 0 and 3 are the same θ: 0.4 in total
    names = ["length", "road", "avoid"]
    fig = Figure()
    ax, ax_top = render.draw_theta_summary(fig.add_subplot(), thetas, probs, names,
                                           theta_true=[0.5, 0.5, 0.0], top=2)
    mean = [b.get_height() for b in ax.patches if b.get_gid() == "mean"]
    true = [b.get_height() for b in ax.patches if b.get_gid() == "true"]
    np.testing.assert_allclose(mean, probs @ thetas)
    np.testing.assert_allclose(true, [0.5, 0.5, 0.0])
    assert [t.get_text() for t in ax.get_xticklabels()] == names
    assert ax_top is not None and ax_top is not ax
    np.testing.assert_allclose([b.get_width() for b in ax_top.patches], [0.5, 0.4])
    assert [t.get_text() for t in ax_top.get_yticklabels()] == ["(0 1 0)", "(1 0 0)"]
    # θ* (0.5, 0.5, 0) is third most probable: shown and starred when top = 3.
    _, ax3 = render.draw_theta_summary(new_ax(), thetas, probs, names,
                                       theta_true=[0.5, 0.5, 0.0], top=3)
    assert [t.get_text() for t in ax3.get_yticklabels()][2] == "★ (.5 .5 0)"


def test_theta_summary_without_truth_or_top_list():
    thetas = np.eye(3)
    ax, ax_top = render.draw_theta_summary(new_ax(), thetas, [1, 1, 2], ["a", "b", "c"], top=0)
    assert ax_top is None
    np.testing.assert_allclose([b.get_height() for b in ax.patches], [0.25, 0.25, 0.5])
    with pytest.raises(InputError, match="2 feature names for 3 features"):
        render.draw_theta_summary(new_ax(), thetas, [1, 1, 1], ["a", "b"])
    with pytest.raises(InputError, match="theta_true must have 3 components"):
        render.draw_theta_summary(new_ax(), thetas, [1, 1, 1], "abc", theta_true=[1, 0])


# ------------------------------------------------------------------- demo figure
@pytest.fixture(scope="module")
def wandering_run():
    """Seed 0 with --beta 10: a generated map without roads; every episode runs to the cap."""
    from expertise_irl.experiments.demo import run_demo

    return run_demo(0, episodes=5, beta=10)  # a novice who wanders until the step cap


@pytest.fixture(scope="module")
def expert_run():
    """Seed 3: β* = 0.01; every episode reaches the goal."""
    from expertise_irl.experiments.demo import run_demo

    return run_demo(3, episodes=6)


def _map_axes(fig):
    (ax,) = [ax for ax in fig.get_axes() if [c for c in ax.collections if c.get_gid() == "visits"]]
    return ax


def _texts(fig) -> str:
    return "\n".join(t.get_text() for ax in fig.get_axes() for t in ax.texts)


def test_demo_figure_draws_a_few_episodes_and_says_why_they_hit_the_cap(wandering_run):
    run = wandering_run
    fig = render.demo_figure(run, title="t")
    ax = _map_axes(fig)
    paths = render.paths_to_xy(run.trajectories, run.mdp)
    n = len(paths)
    drawn = [ln for ln in ax.lines if re.fullmatch(r"episode-\d+", ln.get_gid() or "")]
    assert len(drawn) == min(render.DEMO_EPISODES, n) < n
    for i, ln in enumerate(drawn):
        xy = ln.get_xydata()
        assert len(xy) <= render.DEMO_MOVES + 1  # a 500-step walk is cut for drawing
        off = xy - paths[i][: len(xy)]
        assert np.allclose(off, off[0]) and np.hypot(*off[0]) <= 0.2
        (start,) = [m for m in ax.lines if m.get_gid() == f"episode-{i}-start"]
        (end,) = [m for m in ax.lines if m.get_gid() == f"episode-{i}-end"]
        np.testing.assert_allclose(start.get_xydata()[0], paths[i][0] + off[0])
        np.testing.assert_allclose(end.get_xydata()[0], paths[i][-1] + off[0])  # where it stopped
        assert end.get_marker() == "X"
    # Independently: episodes of max_steps actions whose last state is not a goal.
    capped = sum(len(s) == run.max_steps and not run.mdp.terminal[p[-1]]
                 for (s, _), p in zip(run.trajectories.episodes(), run.trajectories.paths(run.mdp),
                                      strict=True))
    assert capped == n  # seed 0 wanders: the premise of this test
    text = _texts(fig)
    assert f"{capped} of {n} episodes hit the {run.max_steps}-step cap" in text
    assert "randomness" in text and "entropy" in text
    labels = [t.get_text() for a in fig.get_axes() if a.get_legend() for t in a.get_legend().get_texts()]
    assert "episode start" in labels and "episode end: step cap" in labels
    assert sum("episode 0: stopped at the 500-step cap" in lb for lb in labels) == 1


def test_demo_figure_visit_dots_cover_every_episode(wandering_run):
    run = wandering_run
    ax = _map_axes(render.demo_figure(run))
    (dots,) = [c for c in ax.collections if c.get_gid() == "visits"]
    counts = np.zeros((run.zone_map.height, run.zone_map.width))
    for p in render.paths_to_xy(run.trajectories, run.mdp):
        for x, y in p:
            counts[y, x] += 1
    cells = np.argwhere(counts > 0)
    circles = dots.get_paths()
    assert len(circles) == len(cells)
    radii = np.array([np.ptp(c.vertices[:, 0]) / 2 for c in circles])
    np.testing.assert_allclose(radii, 0.38 * np.sqrt(counts[cells[:, 0], cells[:, 1]] / counts.max()),
                               rtol=1e-6)
    assert dots.get_zorder() < min(ln.get_zorder() for ln in ax.lines)  # under the paths
    (img,) = ax.images  # the zones, drawn once, under the dots
    assert img.get_zorder() < dots.get_zorder()


def test_demo_figure_labels_joint_and_marginal_and_absent_features(wandering_run):
    run = wandering_run
    fig = render.demo_figure(run)
    titles = [ax.get_title() for ax in fig.get_axes()]
    assert any(t.startswith("marginal posterior of") for t in titles)
    (top,) = [t for t in titles if "joint" in t]
    assert "marginal P(" in top
    p_truth = float(run.belief.probabilities[run.truth_index])
    assert f"= {p_truth:.3f}" in top
    assert not np.isin(run.zone_map.grid, list(">v<^")).any()  # no road on this map
    marked = [t.get_text() for ax in fig.get_axes() for t in ax.get_xticklabels()
              if t.get_gid() == "absent-feature"]
    assert marked == ["road\n(not on\nthe map)"]
    assert absent_features(run.mdp) == run.absent_features() == [False, True, False, False, False]


@pytest.mark.slow
def test_demo_figure_of_an_expert_reports_no_cap(expert_run, tmp_path):
    run = expert_run
    fig = render.demo_figure(run)
    ax = _map_axes(fig)
    ends = [m for m in ax.lines if re.fullmatch(r"episode-\d+-end", m.get_gid() or "")]
    assert len(ends) == render.DEMO_EPISODES and {m.get_marker() for m in ends} == {"*"}
    assert "cap" not in _texts(fig)
    assert "reached the goal" in ax.get_title()
    before = plt.get_fignums()
    out = render.render_demo_png(tmp_path / "d.png", run, title="x")
    assert out.read_bytes()[:8] == PNG_SIGNATURE and plt.get_fignums() == before
