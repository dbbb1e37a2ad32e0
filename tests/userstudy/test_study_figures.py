"""The study's figures: each participant's (layout rules, worlds, methods), the study overview,
and drawing them in parallel (same bytes however many workers; ``--figures``)."""

from __future__ import annotations

import itertools
from collections import deque
from pathlib import Path

import matplotlib as mpl
import numpy as np
import pytest
from matplotlib.text import Text

from expertise_irl.errors import InputError
from expertise_irl.mdp import TabularMDP
from expertise_irl.plots import userstudy as us
from expertise_irl.plots.study_overview import render_study_png, study_figure, study_order
from expertise_irl.userstudy.figures import draw_figures, select_figures
from expertise_irl.worlds.warehouse import load_floor_plan
from expertise_irl.worlds.zones import load_bundled

EXAMPLE = Path(__file__).resolve().parents[2] / "src" / "expertise_irl" / "userstudy" / "example"
WH_NAMES = ["length", "restricted", "road"]
ZONE_NAMES = ["length", "road", "avoid", "slow", "traffic"]


# ----------------------------------------------------------------------------- worlds
def shortest_path(mdp: TabularMDP, start: int) -> np.ndarray:
    """States from ``start`` to the nearest terminal state, both included (breadth first)."""
    prev, queue = {start: -1}, deque([start])
    while queue:
        s = queue.popleft()
        if mdp.terminal[s]:
            out = [s]
            while prev[out[-1]] >= 0:
                out.append(prev[out[-1]])
            return np.array(out[::-1])
        for t in mdp.next_state[s]:
            if t >= 0 and int(t) not in prev:
                prev[int(t)] = s
                queue.append(int(t))
    raise AssertionError("no terminal state reachable")


def wander(mdp: TabularMDP, start: int, steps: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = [start]
    for _ in range(steps):
        ok = mdp.next_state[out[-1]][mdp.next_state[out[-1]] >= 0]
        out.append(int(rng.choice(ok)))
        if mdp.terminal[out[-1]]:
            break
    return np.array(out)


def chain_mdp(layout: str | None) -> TabularMDP:
    """Six states in a row, right moves to the last (terminal); ``layout``: None, "sparse" (every
    10th cell) for ``state_xy``."""
    S = 6
    ns = np.array([[max(s - 1, 0), min(s + 1, S - 1)] for s in range(S)])
    feats = np.zeros((S, 2, 3))
    feats[..., 0] = -1.0
    xy = None if layout is None else np.array([[10 * s, 0] for s in range(S)])
    return TabularMDP(ns, feats, np.arange(S) == S - 1, feature_names=tuple(WH_NAMES), state_xy=xy,
                      start_states=np.array([0]))


def world(kind: str):
    """(world, mdp) of a task of ``kind``: floor plan, zone map, an MDP with a layout, one without."""
    if kind == "floorplan":
        plan = load_floor_plan(EXAMPLE / "spec-a.txt")
        return plan, plan.to_mdp()
    if kind == "zones":
        zm = load_bundled("corridor")
        return zm, zm.to_mdp()
    if kind == "layout":  # an archive: the MDP's state_xy, no map
        return None, load_bundled("crossroads").to_mdp()
    if kind == "sparse":
        return None, chain_mdp("sparse")
    if kind == "nolayout":
        return None, chain_mdp(None)
    raise ValueError(kind)


def panel(kind: str, i: int = 0, theta_hat=None, theta_marginal=None) -> dict:
    w, mdp = world(kind)
    start = int(mdp.start_states[0]) if mdp.start_states is not None else 0
    return {"world": w, "mdp": mdp, "title": f"{kind}-{i}.txt (P1-{i}.csv)",
            "observed": [wander(mdp, start, 25, seed=i), shortest_path(mdp, start)],
            "optimal": [shortest_path(mdp, start)], "theta_hat": theta_hat, "theta_marginal": theta_marginal}


# ------------------------------------------------------------------------------ docs
def theta_set(K: int) -> list[list[float]]:
    """Every θ with components in {0, 0.5, 1}."""
    vals = (0.0, 0.5, 1.0)
    return [[vals[d] for d in np.unravel_index(i, (3,) * K)] for i in range(3 ** K)]


def doc(method: str, share: str = "both", *, names=WH_NAMES, tasks: int = 3, warnings=(), modes=()) -> dict:
    rng = np.random.default_rng(7)
    K = len(names)
    d = {"feature_names": list(names), "method": method, "share": share, "modes": list(modes),
         "diagnostics": {"warnings": list(warnings)}}
    theta_hat = [0.6, 0.3, 0.8, 0.1, 0.5][:K]
    if method == "discrete":
        betas = [0.01, 0.09, 0.5, 1.0, 5.0, 10.0]
        pb = np.array([0.05, 0.2, 0.4, 0.2, 0.1, 0.05])
        d["marginals"] = {"beta": {"values": betas, "probabilities": pb.tolist()}}
        d["beta_hat"] = float(np.dot(betas, pb))
        d["beta_summary"] = {"mean": d["beta_hat"], "median": 0.5, "geomean": 0.4, "q05": 0.09, "q95": 5.0}
        if share == "both":
            t = theta_set(K)
            p = rng.random(len(t))
            d["marginals"]["theta"] = {"values": t, "probabilities": (p / p.sum()).tolist()}
    elif method == "nuts":
        b = np.exp(rng.normal(np.log(0.4), 0.7, 300))
        th = rng.dirichlet(np.ones(K) * 3, size=(300, tasks) if share == "beta" else 300)
        d["samples"] = {"beta": b.tolist(), "theta": th.tolist()}
        d["beta_hat"] = float(b.mean())
        d["beta_summary"] = {"mean": float(b.mean()), "median": float(np.median(b)), "geomean": None,
                             "q05": float(np.quantile(b, 0.05)), "q95": float(np.quantile(b, 0.95))}
        theta_hat = th.mean(axis=0).tolist() if share == "both" else theta_hat
    else:
        d["beta_hat"] = 0.42
        d["beta_summary"] = {"mean": 0.42, "median": None, "geomean": None, "q05": None, "q95": None}
    d["theta_hat"] = None if share == "beta" else theta_hat
    return d


def panels_for(d: dict, kinds: list[str]) -> list[dict]:
    """One panel per kind; under share beta each with its own θ̂ (and θ marginal for discrete)."""
    K = len(d["feature_names"])
    out = []
    for i, kind in enumerate(kinds):
        th = tm = None
        if d["share"] == "beta":
            th = [round(0.1 + 0.05 * i, 2)] + [0.5] * (K - 1)
            if d["method"] == "discrete":
                t = theta_set(K)
                tm = {"values": t, "probabilities": (np.ones(len(t)) / len(t)).tolist()}
        out.append(panel(kind, i, th, tm))
    return out


def by_gid(fig, gid: str) -> list:
    return fig.findobj(lambda a: a.get_gid() == gid)


def texts(fig) -> list[Text]:
    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


# ----------------------------------------------------------------------- layout rules
def check_layout_rules(fig) -> None:
    w, h = fig.get_size_inches()
    assert h / w <= us.MAX_ASPECT + 1e-9 and w / h <= us.MAX_ASPECT + 1e-9, (w, h)
    for ax in fig.axes:
        assert ax.get_position().width >= 1 / 3 - 1e-9, (ax.get_gid(), ax.get_position().width)


@pytest.mark.slow
@pytest.mark.parametrize("n", [1, 3, 12])
@pytest.mark.parametrize("kind", ["floorplan", "zones", "layout", "nolayout"])
def test_layout_rules_for_each_world(kind, n):
    names = ZONE_NAMES if kind == "zones" else WH_NAMES
    d = doc("discrete", names=names, tasks=n)
    fig = us.participant_figure("P1", panels_for(d, [kind] * n), d)
    check_layout_rules(fig)
    maps_drawn = [ax for ax in fig.axes if str(ax.get_gid()).startswith("task-")]
    if kind == "nolayout":  # no map panel, one line of text per task
        assert not maps_drawn
        assert len([t for t in texts(fig) if str(t.get_gid()).endswith("-text")]) == n
    else:
        assert len(maps_drawn) == n
        widths = {round(ax.get_position().width, 9) for ax in maps_drawn}
        assert widths == {round(1 / min(n, us.MAX_COLUMNS), 9)}


@pytest.mark.slow
@pytest.mark.parametrize("method,share", [("discrete", "both"), ("nuts", "beta"), ("map", "both")])
def test_fonts_and_beta_ticks_readable(method, share):
    d = doc(method, share, warnings=["a long warning " * 30, "second"], tasks=3)
    fig = us.participant_figure("P1", panels_for(d, ["floorplan", "zones", "nolayout"]), d)
    fig.canvas.draw()
    small = [(t.get_text()[:30], t.get_fontsize()) for t in texts(fig) if t.get_fontsize() < us.MIN_FONT]
    assert not small
    ax_b = by_gid(fig, "posterior-beta")[0]
    labels = [t for t in ax_b.get_xticklabels() if t.get_text()]
    assert 2 <= len(labels) <= us.MAX_BETA_TICKS
    boxes = sorted((t.get_window_extent() for t in labels), key=lambda b: b.x0)
    assert all(a.x1 <= b.x0 for a, b in itertools.pairwise(boxes))


def test_dense_beta_grid_gets_at_most_eight_labels():
    d = doc("discrete")
    betas = np.geomspace(0.001, 100, 30).tolist()
    d["marginals"]["beta"] = {"values": betas, "probabilities": (np.ones(30) / 30).tolist()}
    fig = us.participant_figure("P1", panels_for(d, ["zones"]), d)
    fig.canvas.draw()
    ax_b = by_gid(fig, "posterior-beta")[0]
    assert len(by_gid(fig, "beta-bar")) == 30
    labels = [t for t in ax_b.get_xticklabels() if t.get_text()]
    assert 2 <= len(labels) <= us.MAX_BETA_TICKS


# ------------------------------------------------------------------- what is drawn
@pytest.mark.parametrize("kind", ["floorplan", "zones", "layout", "sparse"])
def test_paths_are_drawn_on_the_cells_of_their_states(kind):
    d = doc("map")
    p = panel(kind)
    fig = us.participant_figure("P1", [p], d)
    cells = p["mdp"].state_xy if p["world"] is None else (
        p["world"].state_cells() if kind == "floorplan" else p["world"].cells)
    observed = by_gid(fig, "observed")[0].get_segments()
    optimal = by_gid(fig, "optimal")[0].get_segments()
    assert len(observed) == 2 and len(optimal) == 1
    np.testing.assert_allclose(observed[0], cells[p["observed"][0]])  # the first path is not offset
    np.testing.assert_allclose(optimal[0], cells[p["optimal"][0]])
    at_goal = sum(bool(p["mdp"].terminal[o[-1]]) for o in p["observed"])  # the shortest path's at least
    assert len(by_gid(fig, "observed-end-goal")[0].get_xdata()) == at_goal >= 1
    assert len(by_gid(fig, "observed-end-other")) == (at_goal < 2)
    check_layout_rules(fig)


def test_discrete_shared_theta():
    d = doc("discrete")
    fig = us.participant_figure("P1", panels_for(d, ["floorplan"] * 3), d)
    assert len(by_gid(fig, "beta-bar")) == 6
    assert len(by_gid(fig, "beta-interval")) == 1
    assert by_gid(fig, "beta-mean")[0].get_xdata()[0] == pytest.approx(d["beta_hat"])
    assert by_gid(fig, "beta-median")[0].get_xdata()[0] == pytest.approx(0.5)
    hats = [ln.get_xdata()[0] for ln in by_gid(fig, "theta-hat")]
    assert hats == pytest.approx(d["theta_hat"])
    for k in range(3):
        assert by_gid(fig, f"theta-bar-{k}") and by_gid(fig, f"theta-interval-{k}")
    title = by_gid(fig, "estimate")[0].get_text()
    assert "restricted 0.30" in title


def test_nuts_histograms_and_intervals():
    d = doc("nuts")
    fig = us.participant_figure("P1", panels_for(d, ["zones"]), d)
    assert by_gid(fig, "beta-hist") and not by_gid(fig, "beta-bar")
    band = by_gid(fig, "beta-interval")[0]
    summary = d["beta_summary"]
    assert (band.get_x(), band.get_x() + band.get_width()) == pytest.approx((summary["q05"], summary["q95"]))
    draws = np.asarray(d["samples"]["theta"])
    for k in range(3):
        seg = by_gid(fig, f"theta-interval-{k}")[0].get_xdata()
        assert seg == pytest.approx(np.quantile(draws[:, k], [0.05, 0.95]))


def test_map_point_estimate():
    d = doc("map")
    fig = us.participant_figure("P1", panels_for(d, ["floorplan"]), d)
    assert by_gid(fig, "beta-point")[0].get_xdata()[0] == pytest.approx(0.42)
    assert not by_gid(fig, "beta-interval") and not by_gid(fig, "beta-hist")
    assert [ln.get_xdata()[0] for ln in by_gid(fig, "theta-hat")] == pytest.approx(d["theta_hat"])


@pytest.mark.parametrize("method", ["discrete", "nuts", "map"])
def test_theta_per_task_under_shared_beta(method):
    d = doc(method, "beta", tasks=3)
    ps = panels_for(d, ["floorplan", "zones", "nolayout"])
    fig = us.participant_figure("P1", ps, d)
    check_layout_rules(fig)
    for i, p in enumerate(ps, start=1):
        assert list(by_gid(fig, f"theta-task-{i}")[0].get_xdata()) == pytest.approx(p["theta_hat"])
    shown = " ".join(t.get_text() for t in texts(fig))
    assert "this task's θ̂ = [0.15, 0.50, 0.50]" in shown  # task 2's own estimate, in its panel
    assert "θ̂ = [0.20, 0.50, 0.50]" in shown  # task 3's, in its line of text
    assert "θ estimated per task" in by_gid(fig, "estimate")[0].get_text()


def test_more_than_twelve_tasks_are_cut_with_a_caption():
    d = doc("discrete")
    fig = us.participant_figure("P1", panels_for(d, ["zones"] * 14), d)
    assert by_gid(fig, "tasks-caption")[0].get_text() == "12 of 14 tasks shown; all in tasks.csv"
    assert len([ax for ax in fig.axes if str(ax.get_gid()).startswith("task-")]) == us.MAX_TASKS
    check_layout_rules(fig)
    few = us.participant_figure("P1", panels_for(d, ["zones"] * 12), d)
    assert not by_gid(few, "tasks-caption")


def test_warnings_and_modes_are_printed():
    long = "the chain did not mix: " + "x" * 300
    modes = [{"theta": [1, 0, 0], "beta": 0.1, "probability": 0.5},
             {"theta": [0, 1, 0], "beta": 1, "probability": 0.4}]
    d = doc("discrete", warnings=[long, "second", "third"], modes=modes)
    fig = us.participant_figure("P1", panels_for(d, ["zones"]), d)
    assert by_gid(fig, "warnings")[0].get_text().startswith("3 warnings")
    first = by_gid(fig, "warning-0")[0].get_text()
    assert first.startswith("• the chain did not mix") and first.endswith("…") and len(first) < 200
    assert by_gid(fig, "warning-1")[0].get_text() == "• second" and not by_gid(fig, "warning-2")
    assert "2 separated modes" in by_gid(fig, "modes")[0].get_text()
    quiet = us.participant_figure("P1", panels_for(doc("discrete"), ["zones"]), doc("discrete"))
    assert not by_gid(quiet, "warnings") and not by_gid(quiet, "modes")


@pytest.mark.slow
def test_png_is_the_same_whatever_the_callers_rcparams(tmp_path):
    d = doc("nuts")
    ps = panels_for(d, ["zones"])
    a = us.participant_png_bytes("P1", ps, d)
    with mpl.rc_context({"font.size": 20, "axes.facecolor": "red", "lines.linewidth": 5}):
        b = us.participant_png_bytes("P1", ps, d)
    assert a == b and a.startswith(b"\x89PNG") and b"Matplotlib" not in a
    out = us.render_participant_png(tmp_path / "P1.png", "P1", ps, d)
    assert out.read_bytes() == a and [f.name for f in tmp_path.iterdir()] == ["P1.png"]


def test_light_panels_and_the_old_panel_contract_draw_the_same_figure():
    d = doc("discrete")
    ps = panels_for(d, ["floorplan", "layout"])
    full = us.participant_png_bytes("P1", ps, d)
    light = [us.light_panel(p) for p in ps]
    assert isinstance(light[0]["mdp"], us.TaskStates) and ps[0]["mdp"] is not light[0]["mdp"]
    assert us.participant_png_bytes("P1", light, d) == full
    plan = ps[0]["world"]  # the study's panels before: "plan" and [T, 2] cells, no MDP
    cells = plan.state_cells()
    old = {"plan": plan, "title": ps[0]["title"], "observed": [cells[s] for s in ps[0]["observed"]],
           "optimal": [cells[s] for s in ps[0]["optimal"]]}
    fig = us.participant_figure("P1", [old], d)
    np.testing.assert_allclose(by_gid(fig, "observed")[0].get_segments()[0], old["observed"][0])
    assert len(by_gid(fig, "observed-end-goal")[0].get_xdata()) >= 1


# ----------------------------------------------------------------- parallel drawing
@pytest.mark.slow
def test_draw_figures_same_bytes_with_two_workers(tmp_path):
    jobs = []
    for i, method in enumerate(["discrete", "nuts", "map"]):
        d = doc(method)
        jobs.append((f"P{i}.png", f"P{i}", panels_for(d, ["zones"]), d))
    one, two = tmp_path / "one", tmp_path / "two"
    one.mkdir()
    two.mkdir()
    progress = []
    got = draw_figures([(one / p, pid, ps, d) for p, pid, ps, d in jobs], workers=1,
                       on_progress=lambda done, total: progress.append((done, total)))
    assert got == [one / p for p, *_ in jobs] and progress == [(1, 3), (2, 3), (3, 3)]
    draw_figures([(two / p, pid, ps, d) for p, pid, ps, d in jobs], workers=2)
    for p, *_ in jobs:
        assert (one / p).read_bytes() == (two / p).read_bytes()
    assert sorted(f.name for f in two.iterdir()) == ["P0.png", "P1.png", "P2.png"]  # no temporary files
    assert draw_figures([], workers=2) == []


def test_draw_figures_rejects_zero_workers(tmp_path):
    d = doc("map")
    with pytest.raises(InputError):
        draw_figures([(tmp_path / "a.png", "a", panels_for(d, ["zones"]), d)], workers=0)


def test_select_figures():
    ids = ["P3", "P1", "P2"]
    assert select_figures(ids, "all") == ids
    assert select_figures(ids, " ALL ") == ids
    assert select_figures(ids, "none") == []
    assert select_figures(ids, "2") == ["P3", "P1"]
    assert select_figures(ids, 10) == ids
    for bad in ("0", "-1", "1.5", "x", "", "some"):
        with pytest.raises(InputError, match=r"^--figures must be all, none or a positive number, got "):
            select_figures(ids, bad)
    with pytest.raises(InputError) as e:
        select_figures(ids, "x")
    assert str(e.value) == "--figures must be all, none or a positive number, got 'x'"


# ------------------------------------------------------------------- study overview
def study_rows(n: int) -> list[dict]:
    rng = np.random.default_rng(3)
    rows = []
    for i in range(n):
        b = float(np.exp(rng.normal(np.log(0.5), 1.5)))
        missing = i % 10 == 0
        th = rng.dirichlet([2, 2, 2])
        nan = float("nan")
        rows.append({"participant": f"P{i:03d}", "beta_hat": nan if i == 5 else b, "beta_median": b * 0.9,
                     "beta_q05": nan if missing else b / 2, "beta_q95": nan if missing else b * 2,
                     **{f"theta_{f}": nan if i % 7 == 0 else float(v)
                        for f, v in zip(WH_NAMES, th, strict=True)}})
    return rows


def test_study_overview_rows_follow_beta_hat(tmp_path):
    rows = study_rows(120)
    fig = study_figure(rows, WH_NAMES, title="Study m.csv")
    x = by_gid(fig, "beta-hat")[0].get_xdata()
    y = by_gid(fig, "beta-hat")[0].get_ydata()
    assert list(y) == list(range(120))
    finite = x[np.isfinite(x)]
    assert len(finite) == 119 and np.all(np.diff(finite) >= 0) and np.isnan(x[-1])  # P005: no β̂, last
    ax = by_gid(fig, "study-beta")[0]
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels == [rows[i]["participant"] for i in study_order(rows)] and labels[-1] == "P005"
    assert min(t.get_fontsize() for t in ax.get_yticklabels()) >= 6
    heat = by_gid(fig, "theta-heatmap")[0].get_array()
    assert heat.shape == (120, 3)
    assert heat[0, 0] == pytest.approx(rows[study_order(rows)[0]]["theta_length"])
    out = render_study_png(tmp_path / "study.png", rows, WH_NAMES)
    assert out.read_bytes().startswith(b"\x89PNG")


@pytest.mark.slow
def test_study_overview_labels_every_kth_row_when_crowded():
    fig = study_figure(study_rows(600), WH_NAMES)
    ax = by_gid(fig, "study-beta")[0]
    labels = ax.get_yticklabels()
    assert 0 < len(labels) < 600 and min(t.get_fontsize() for t in labels) >= 6
    fig.canvas.draw()
    boxes = [t.get_window_extent() for t in labels]
    assert all(a.y0 >= b.y1 - 0.5 for a, b in itertools.pairwise(boxes))  # top to bottom, apart


def test_theta_panel_names_the_interval_bar_by_the_colour_it_is_drawn_in():
    # The 90% interval is a dark line at alpha 0.55 over white: it shows grey, and the title says so.
    d = doc("discrete")
    fig = us.participant_figure("P1", panels_for(d, ["floorplan"] * 3), d)
    seg = by_gid(fig, "theta-interval-0")[0]
    rgb = np.array(mpl.colors.to_rgb(seg.get_color()))
    shown = seg.get_alpha() * rgb + (1 - seg.get_alpha()) * np.ones(3)
    assert 0.3 < shown.mean() < 0.7  # neither black nor white
    titles = [ax.get_title() for ax in fig.get_axes() if ax.get_title().startswith("θ:")]
    assert titles and "grey bar = 90% interval" in titles[0]
