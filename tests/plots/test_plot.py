"""``expertise-irl plot`` and the figure of a result: what each panel shows, and the CLI contract.

Results of every method are made once per module on the bundled corridor with tiny
options, as in ``test_cli.py``.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from expertise_irl.cli import app
from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import HypothesisSet, expertise_group
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.plots import results as rp
from expertise_irl.results import check_result
from expertise_irl.worlds.zones import load_bundled

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
METHOD_ARGS = {
    "discrete": ("--thetas", "0,1", "--betas", "0.1,1,10", "--per-action"),
    "birl": ("--method", "birl", "--iterations", "50"),
    "map": ("--method", "map", "--starts", "1"),
}
METHODS = ("discrete", "birl", "map", "nuts")
FEATURES = ("length", "road", "avoid", "slow", "traffic")


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def ok(result) -> None:
    assert result.exit_code == 0, f"exit {result.exit_code}\n{result.output}\n{result.exception!r}"
    assert "Traceback" not in result.output


def one_line_error(result, *fragments: str) -> str:
    assert result.exit_code == 2, f"exit {result.exit_code}\n{result.output}\n{result.exception!r}"
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: ") and lines[0] in result.stderr
    for f in fragments:
        assert f in lines[0], f"{f!r} not in {lines[0]!r}"
    return lines[0]


def by_gid(ax, gid: str, kind: str = "lines") -> list:
    return [a for a in getattr(ax, kind) if a.get_gid() == gid]


def find_axes(fig, pred):
    return [ax for ax in fig.get_axes() if pred(ax)]


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("plot")


@pytest.fixture(scope="module")
def demos(work) -> Path:
    path = work / "demos.csv"
    ok(invoke("simulate", "corridor", "--theta", "0.5,0.5,0,0,0", "--beta", "0.5",
              "--episodes", 4, "--seed", 1, "--out", path))
    return path


def sampler_result(path: Path, n_draws: int, *, seed: int = 0) -> Path:
    """A ``nuts`` result written by the real result writer from synthetic draws (two chains).

    NUTS itself takes minutes even with tiny options on a shared 2-core machine; the figure
    only reads the result document, so its format is what matters here. Beyond
    ``INLINE_DRAWS`` draws the writer puts them in a CSV beside the JSON, as ``infer`` does.
    """
    from expertise_irl.inference.gradient import credible_intervals
    from expertise_irl.results import continuous_result, samples_path_for, write_json

    rng = np.random.default_rng(seed)
    chain = np.repeat([0, 1], n_draws // 2 + 1)[:n_draws]
    beta = rng.lognormal(np.log(0.5), 0.3, n_draws)
    theta = rng.dirichlet([5, 5, 1, 1, 1], n_draws)
    best = int(np.argmax(beta))
    out = {"beta_hat": float(beta.mean()), "theta_hat": theta.mean(axis=0).tolist(),
           "map": {"theta": theta[best].tolist(), "beta": float(beta[best]), "log_posterior": -1.0},
           "credible_intervals": credible_intervals(theta, beta, 0.9),
           "diagnostics": {"r_hat": {"beta": 1.0}, "divergences": 0}, "run_time_s": 0.1,
           "draws": (chain, theta, beta)}
    doc = continuous_result(out, method="nuts", feature_names=FEATURES, settings={"method": "nuts"},
                            data={"episodes": 4, "actions": 40},
                            samples_path=samples_path_for(path))
    write_json(path, doc)
    return path


@pytest.fixture(scope="module")
def results(work, demos) -> dict[str, Path]:
    out = {}
    for method, args in METHOD_ARGS.items():
        path = work / f"{method}.json"
        ok(invoke("infer", "corridor", "--demos", demos, *args, "--out", path))
        out[method] = path
    out["nuts"] = sampler_result(work / "nuts.json", 60)
    return out


def load(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


# ------------------------------------------------------------------ Trace extension
def test_trace_groups_and_band_match_streaming_updates():
    rng = np.random.default_rng(3)
    thetas = np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])
    betas = np.array([0.01, 0.09, 0.5, 1.0, 5.0, 10.0])
    hyp = HypothesisSet(thetas, betas)
    S, A = 4, 3
    logits = rng.normal(size=(len(hyp), S, A)) * 2
    log_policy = logits - np.logaddexp.reduce(logits, axis=2, keepdims=True)
    prior = DiscreteBelief.from_log_policy(hyp, log_policy)
    trajs = Trajectories(episode=[0] * 5 + [1] * 4, step=[*range(5), *range(4)],
                         state=rng.integers(S, size=9), action=rng.integers(A, size=9))
    tr = prior.trace(trajs)
    assert tr.group_probabilities.shape == (10, 3) and tr.beta_low.shape == (10,)
    b = prior
    for i in range(10):
        if i:
            b = b.update_action(int(trajs.state[i - 1]), int(trajs.action[i - 1]))
        g = b.group_probabilities()
        np.testing.assert_allclose(tr.group_probabilities[i], [g[k] for k in ("high", "medium", "low")],
                                   atol=1e-12)
        assert tr.groups_at(i) == pytest.approx(g, abs=1e-12)
        grid, pb = b.marginal_beta()
        cdf = np.cumsum(pb)
        assert tr.beta_low[i] == grid[np.flatnonzero(cdf >= 0.05 - 1e-12)[0]]
        assert tr.beta_high[i] == grid[np.flatnonzero(cdf >= 0.95 - 1e-12)[0]]
        assert pb[(grid >= tr.beta_low[i]) & (grid <= tr.beta_high[i])].sum() >= 0.9 - 1e-12
    # Uniform prior over six β values: 5% quantile is the smallest, 95% the largest.
    assert (tr.beta_low[0], tr.beta_high[0]) == (0.01, 10.0)
    np.testing.assert_allclose(tr.group_probabilities[0], [1 / 3] * 3)


def test_result_trace_entries_carry_groups_and_band(results):
    doc = load(results["discrete"])
    trace = doc["trace"]
    assert len(trace) == doc["data"]["actions"] + 1
    for e in trace:
        assert set(e) >= {"episode", "step", "beta_hat", "theta_hat", "entropy",
                          "group_probabilities", "beta_band"}
        assert set(e["group_probabilities"]) == {"high", "medium", "low"}
        assert sum(e["group_probabilities"].values()) == pytest.approx(1.0, abs=1e-9)
        lo, hi = e["beta_band"]
        assert lo <= hi and {lo, hi} <= set(doc["marginals"]["beta"]["values"])
    last = trace[-1]
    assert last["group_probabilities"] == pytest.approx(doc["group_probabilities"], abs=1e-9)
    assert last["beta_hat"] == pytest.approx(doc["beta_hat"], rel=1e-9)


# ------------------------------------------------------------------- figure content
def test_discrete_bars_are_the_marginals(results):
    doc = load(results["discrete"])
    fig = rp.result_figure(doc, source=results["discrete"])
    m = doc["marginals"]
    (ax_b,) = find_axes(fig, lambda ax: ax.get_title().startswith(r"$\beta$: marginal"))
    np.testing.assert_allclose([b.get_height() for b in ax_b.patches], m["beta"]["probabilities"])
    tv, tp = np.array(m["theta"]["values"]), np.array(m["theta"]["probabilities"])
    for i, name in enumerate(doc["feature_names"]):
        (ax,) = find_axes(fig, lambda a, n=name: a.get_title().startswith(rf"$\theta$ {n}:"))
        bars = [p for p in ax.patches if p.get_gid() == "marginal"]
        x = np.array([b.get_x() + b.get_width() / 2 for b in bars])
        h = np.array([b.get_height() for b in bars])
        for v in np.unique(np.round(tv[:, i], 9)):  # P(θ_i = v), summed by hand
            want = tp[np.isclose(tv[:, i], v, atol=1e-9)].sum() / tp.sum()
            (j,) = np.flatnonzero(np.isclose(x, v, atol=1e-9))
            assert h[j] == pytest.approx(want, abs=1e-12)
        assert h.sum() == pytest.approx(1.0)
        (mean,) = by_gid(ax, "mean")
        assert mean.get_xdata()[0] == pytest.approx(doc["theta_hat"][i])


def test_trace_panel_is_the_json_trace_with_episode_boundaries(results, demos):
    doc = load(results["discrete"])
    fig = rp.result_figure(doc, source=results["discrete"])
    trajs = read_demos_csv(demos, load_bundled("corridor").to_mdp())
    lengths = [len(s) for s, _ in trajs.episodes()]
    (ax_b,) = [ax for ax in fig.get_axes() if by_gid(ax, "trace-beta")]
    (line,) = by_gid(ax_b, "trace-beta")
    np.testing.assert_array_equal(line.get_xdata(), np.arange(len(doc["trace"])))
    np.testing.assert_allclose(line.get_ydata(), [e["beta_hat"] for e in doc["trace"]])
    want = np.cumsum(lengths)[:-1]
    trace_axes = [ax for ax in fig.get_axes() if by_gid(ax, "episode-boundary")]
    assert len(trace_axes) == 3
    for ax in trace_axes:
        got = sorted(ln.get_xdata()[0] for ln in by_gid(ax, "episode-boundary"))
        np.testing.assert_array_equal(got, want)
    (ax_g,) = [ax for ax in fig.get_axes() if by_gid(ax, "trace-group-high")]
    for g in ("high", "medium", "low"):
        (ln,) = by_gid(ax_g, f"trace-group-{g}")
        np.testing.assert_allclose(ln.get_ydata(), [e["group_probabilities"][g] for e in doc["trace"]])
    (ax_e,) = [ax for ax in fig.get_axes() if by_gid(ax, "trace-entropy")]
    np.testing.assert_allclose(by_gid(ax_e, "trace-entropy")[0].get_ydata(),
                               [e["entropy"] for e in doc["trace"]])
    band = by_gid(ax_b, "trace-band", "collections")
    assert len(band) == 1


def test_trace_arrays_boundaries():
    steps = [None, 0, 1, 2, 0, 1, 0]  # episodes of 3, 2 and 1 actions
    trace = [{"episode": None if s is None else 0, "step": s, "beta_hat": 1.0, "entropy": 1.0}
             for s in steps]
    t = rp.trace_arrays(trace)
    assert t["boundaries"].tolist() == [3, 5]
    assert t["band"] is None and t["groups"] is None  # an older result: drawn without them


def test_sampled_histograms_and_intervals(results):
    for method in ("birl", "nuts"):
        doc = load(results[method])
        fig = rp.result_figure(doc, source=results[method])
        _, beta, _ = rp.load_samples(doc, results[method])
        assert len(beta) == len(doc["samples"]["beta"])
        (ax_b,) = find_axes(fig, lambda a: a.get_title().startswith(r"$\beta$: 90%"))
        counts = sum(p.get_height() * p.get_width() for p in ax_b.patches if p.get_gid() != "interval")
        assert counts == pytest.approx(1.0, rel=1e-9)  # a density histogram of the draws
        lo, hi = doc["credible_intervals"]["beta"]
        assert f"[{lo:.3g}, {hi:.3g}]" in ax_b.get_title()
        (span,) = by_gid(ax_b, "interval", "patches")
        assert (span.get_x(), span.get_x() + span.get_width()) == pytest.approx((lo, hi))
        for i, name in enumerate(doc["feature_names"]):
            (ax,) = find_axes(fig, lambda a, n=name: a.get_title().startswith(rf"$\theta$ {n}: 90%"))
            (mean,) = by_gid(ax, "mean")
            assert mean.get_xdata()[0] == pytest.approx(doc["theta_hat"][i])


def test_map_result_is_a_marked_point(results):
    doc = load(results["map"])
    fig = rp.result_figure(doc, source=results["map"])
    points = [ln for ax in fig.get_axes() for ln in by_gid(ax, "point")]
    assert len(points) == len(doc["feature_names"]) + 1
    xs = sorted(float(p.get_xdata()[0]) for p in points)
    assert xs == pytest.approx(sorted([doc["beta_hat"], *doc["theta_hat"]]))
    assert "point" in fig.get_suptitle()


@pytest.mark.slow
def test_samples_csv_beside_the_result_is_found(tmp_path, monkeypatch):
    from expertise_irl.results import INLINE_DRAWS

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    monkeypatch.chdir(run_dir)  # infer --out big.json, run here: the JSON names the CSV relatively
    sampler_result(Path("big.json"), INLINE_DRAWS + 2)
    doc = load(run_dir / "big.json")
    assert doc["samples"] == "big.samples.csv"
    moved = tmp_path / "elsewhere"
    shutil.move(run_dir, moved)
    monkeypatch.chdir(tmp_path)  # not found as given: looked up beside the JSON
    chain, beta, theta = rp.load_samples(doc, moved / "big.json")
    assert len(beta) == INLINE_DRAWS + 2 and theta.shape == (INLINE_DRAWS + 2, 5)
    assert set(chain.tolist()) == {0, 1}
    fig = rp.result_figure(doc, source=moved / "big.json")
    (ax_b,) = find_axes(fig, lambda a: a.get_title().startswith(r"$\beta$: 90%"))
    lo, hi = np.quantile(beta, [0.05, 0.95])
    assert f"[{lo:.3g}, {hi:.3g}]" in ax_b.get_title()
    ok(invoke("plot", moved / "big.json", "--out", tmp_path / "r.png"))
    (moved / "big.samples.csv").unlink()
    one_line_error(invoke("plot", moved / "big.json", "--out", tmp_path / "r2.png"),
                   str(moved / "big.json"), "big.samples.csv")


# ------------------------------------------------------------------------------ CLI
@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_every_method_plots(method, results, demos, tmp_path):
    out = tmp_path / f"{method}.png"
    r = invoke("plot", results[method], "--map", "corridor", "--demos", demos, "--out", out)
    ok(r)
    assert out.read_bytes()[:8] == PNG_SIGNATURE
    assert str(out) in r.stdout
    bare = tmp_path / f"{method}-bare.png"
    ok(invoke("plot", results[method], "--out", bare))
    assert bare.read_bytes()[:8] == PNG_SIGNATURE


@pytest.mark.slow
def test_plot_on_an_mdp_archive(results, demos, work, tmp_path):
    npz = work / "corridor.npz"
    if not npz.exists():
        ok(invoke("export-mdp", "corridor", "--out", npz))
    out = tmp_path / "npz.png"
    ok(invoke("plot", results["discrete"], "--mdp", npz, "--demos", demos, "--out", out))
    assert out.read_bytes()[:8] == PNG_SIGNATURE
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files if k != "state_xy"}
    bare = tmp_path / "no-xy.npz"
    np.savez(bare, **arrays)
    one_line_error(invoke("plot", results["discrete"], "--mdp", bare, "--out", tmp_path / "x.png"),
                   str(bare), "state_xy")


def map_panel(fig):
    """The drawn figure's map axes (equal aspect); its own, its legend's and its panel's extents in pixels."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    [ax] = find_axes(fig, lambda a: a.get_aspect() == 1.0)
    return (ax, ax.get_window_extent(renderer), ax.get_legend().get_window_extent(renderer),
            ax.get_figure(root=False).bbox)


@pytest.fixture(scope="module")
def crossroads_task(work):
    """The README's task: crossroads as an MDP archive, and the person of its simulate command
    (long episodes, so the legend's labels are long: "… (first 60 drawn)")."""
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.mdp import TabularMDP

    npz = work / "crossroads.npz"
    ok(invoke("export-mdp", "crossroads", "--out", npz))
    mdp = TabularMDP.load(npz)
    return mdp, simulate(mdp, np.array([0.5, 0.5, 0, 0, 0]), 0.5, 20, np.random.default_rng(1))


@pytest.mark.slow
@pytest.mark.parametrize("world", ["corridor", "crossroads"])
@pytest.mark.parametrize("source", ["mdp", "map"])
@pytest.mark.parametrize("method", METHODS)
def test_the_map_panel_fills_its_space_and_holds_its_legend(method, source, world, results, demos, work,
                                                            crossroads_task):
    """On an MDP archive as on a map, the map is as wide as its panel (not a thumbnail squeezed
    by a legend wider than the panel) and the legend lies inside the panel."""
    from expertise_irl.mdp import TabularMDP

    if world == "crossroads":
        mdp, trajs = crossroads_task
    else:
        npz = work / "corridor.npz"
        if not npz.exists():
            ok(invoke("export-mdp", "corridor", "--out", npz))
        mdp = TabularMDP.load(npz)
        trajs = read_demos_csv(demos, mdp)
    zone_map = load_bundled(world) if source == "map" else None
    fig = rp.result_figure(load(results[method]), source=results[method], mdp=mdp, zone_map=zone_map,
                           trajs=trajs)
    ax, box, legend, panel = map_panel(fig)
    assert box.width >= 0.85 * panel.width, (box.width, panel.width)
    assert box.height >= 0.3 * box.width  # corridor is 11 × 5 cells, crossroads 16 × 12
    assert panel.x0 - 2 <= legend.x0 and legend.x1 <= panel.x1 + 2, (legend, panel)
    assert panel.y0 - 8 <= legend.y0 and legend.y1 <= box.y0, (legend, panel, box)
    assert fig.bbox.contains(legend.x0, legend.y0) and fig.bbox.contains(legend.x1, legend.y1)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "goal" in labels and any(t.startswith("episode 0: ") for t in labels)


def test_bad_inputs_are_one_line_errors_naming_the_file(results, demos, tmp_path):
    out = tmp_path / "fig.png"
    not_json = tmp_path / "notes.json"
    not_json.write_text("hello\n", encoding="utf-8")
    one_line_error(invoke("plot", not_json, "--out", out), str(not_json), "not a result JSON")
    not_result = tmp_path / "other.json"
    not_result.write_text('{"a": 1}\n', encoding="utf-8")
    one_line_error(invoke("plot", not_result, "--out", out), str(not_result), "not an expertise-irl result")
    broken = tmp_path / "broken.json"
    doc = load(results["discrete"])
    del doc["marginals"]
    broken.write_text(json.dumps(doc), encoding="utf-8")
    one_line_error(invoke("plot", broken, "--out", out), str(broken), "marginals")
    renamed = tmp_path / "renamed.json"
    doc = load(results["discrete"])
    doc["feature_names"] = ["a", "b", "c", "d", "e"]
    renamed.write_text(json.dumps(doc), encoding="utf-8")
    one_line_error(invoke("plot", renamed, "--map", "corridor", "--out", out), "corridor",
                   str(renamed), "do not match")
    crossroads_demos = tmp_path / "x.csv"
    ok(invoke("simulate", "crossroads", "--theta", "1,0,0,0,0", "--beta", "0.5", "--episodes", 1,
              "--out", crossroads_demos))
    one_line_error(invoke("plot", results["discrete"], "--map", "corridor", "--demos",
                          crossroads_demos, "--out", out), str(crossroads_demos))
    one_line_error(invoke("plot", results["discrete"], "--demos", demos, "--out", out), str(demos),
                   "--map or --mdp")
    one_line_error(invoke("plot", results["discrete"], "--out", tmp_path / "fig.xyz"), "fig.xyz", ".xyz")
    one_line_error(invoke("plot", tmp_path / "missing.json", "--out", out), "missing.json")
    assert not out.exists()


def test_out_is_refused_when_it_exists_or_is_an_input(results, demos, tmp_path):
    out = tmp_path / "fig.png"
    out.write_bytes(b"keep")
    one_line_error(invoke("plot", results["map"], "--out", out), str(out), "--force")
    assert out.read_bytes() == b"keep"
    ok(invoke("plot", results["map"], "--out", out, "--force"))
    assert out.read_bytes()[:8] == PNG_SIGNATURE
    # The result or the demonstrations as --out: refused even with --force, under another spelling.
    copy = tmp_path / "copy.json"
    shutil.copy(results["map"], copy)
    before = copy.read_bytes()
    alias = tmp_path / "sub" / ".." / "copy.json"
    (tmp_path / "sub").mkdir()
    one_line_error(invoke("plot", copy, "--out", alias, "--force"), "one of the inputs")
    assert copy.read_bytes() == before
    demos_copy = tmp_path / "d.csv"
    shutil.copy(demos, demos_copy)
    one_line_error(invoke("plot", copy, "--map", "corridor", "--demos", demos_copy,
                          "--out", demos_copy, "--force"), "one of the inputs")
    assert demos_copy.read_bytes() == demos.read_bytes()


def test_check_result_unit():
    with pytest.raises(InputError, match=r"r\.json: unknown method 'magic'"):
        check_result({"method": "magic"}, "r.json")
    with pytest.raises(InputError, match="theta_hat"):
        check_result({"method": "map", "feature_names": ["a"], "beta_hat": 1.0,
                      "theta_hat": [1, 2]}, "r.json")
    check_result({"method": "map", "feature_names": ["a"], "beta_hat": 1.0, "theta_hat": [1]}, "r.json")
    assert expertise_group(0.5) == "medium"


def test_diagnostics_warnings_are_on_the_figure(results):
    doc = load(results["map"])
    doc.setdefault("diagnostics", {})["warnings"] = ["starts disagree: 2 optima", "x" * 300]
    fig = rp.result_figure(doc, source=results["map"])
    texts = [t for sf in fig.subfigs for t in sf.texts if t.get_gid() == "warnings"]
    assert len(texts) == 1
    lines = texts[0].get_text().splitlines()
    assert lines[0] == "warning: starts disagree: 2 optima"
    assert lines[1].endswith("…") and len(lines[1]) < 200
    doc["diagnostics"]["warnings"] = []
    fig = rp.result_figure(doc, source=results["map"])
    assert not [t for sf in fig.subfigs for t in sf.texts if t.get_gid() == "warnings"]
    assert not [t for t in fig.texts if t.get_gid() == "warnings"]


def test_a_floor_plan_is_drawn_as_a_floor_plan():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    from expertise_irl.demos.simulation import simulate
    from expertise_irl.plots import maps as render
    from expertise_irl.plots.floorplan import ROAD_COLOR
    from expertise_irl.worlds.warehouse import parse_floor_plan

    plan = parse_floor_plan("S>>>v\n..xxv\n....G\n")
    mdp = plan.to_mdp()
    trajs = simulate(mdp, np.array([0.6, 0.2, 0.2]), 0.1, 2, np.random.default_rng(0))
    fig, ax = plt.subplots()
    handles = rp.draw_demos_on_map(ax, mdp, plan, trajs)
    arrows = [c for c in ax.collections if c.get_gid() == render.ROAD_ARROWS_GID]
    assert len(arrows) == 1 and to_hex(arrows[0].get_facecolor()[0]) == ROAD_COLOR  # green, not zone blue
    assert len(arrows[0].get_offsets()) == 5  # the five road cells (>>>v, v)
    assert any(h.get_label() == "restricted" for h in handles)
    plt.close(fig)


def test_no_band_where_the_chain_did_not_move(results, tmp_path):
    """A result that withholds an interval (null: the chain did not move there) gets no shaded band,
    though the draws would give one, and neither does a parameter whose draws are all one value
    (a result written before intervals were withheld: its [v, v] is no posterior's)."""
    doc = load(results["birl"])
    doc["credible_intervals"]["beta"] = None
    doc["credible_intervals"]["theta"][0] = None
    frozen = np.asarray(doc["samples"]["theta"], dtype=float)
    frozen[:, 1] = 0.25
    doc["samples"]["theta"] = frozen.tolist()
    doc["credible_intervals"]["theta"][1] = [0.25, 0.25]
    fig = rp.result_figure(doc, source=results["birl"])
    for name in (r"$\beta$", rf"$\theta$ {FEATURES[0]}", rf"$\theta$ {FEATURES[1]}"):
        (ax,) = find_axes(fig, lambda a, n=name: a.get_title().startswith(f"{n}: "))
        assert ax.get_title() == f"{name}: no 90% interval (stuck chain)"
        assert by_gid(ax, "interval", "patches") == [] and len(by_gid(ax, "hist", "patches")) > 0
    (ax,) = find_axes(fig, lambda a: a.get_title().startswith(rf"$\theta$ {FEATURES[2]}: 90% ["))
    assert len(by_gid(ax, "interval", "patches")) == 1  # the others keep theirs
