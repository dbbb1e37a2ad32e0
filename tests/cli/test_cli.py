"""Command-line contracts of ``expertise-irl`` (README "Command line" and "File formats").

Most tests drive the typer app in-process with ``typer.testing.CliRunner``. In the
installed typer, ``result.stdout`` and ``result.stderr`` are separate and
``result.output`` is both interleaved, so an error test can check both that the
message went to stderr and that the user sees exactly one line in total. A few
tests run the real console script in a subprocess to prove that no traceback
reaches the user. Expensive artefacts (MDP archive, demonstrations, demo runs,
inference results) are made once per module.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, load, ok, snapshot

import expertise_irl
from expertise_irl import cli
from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, theta_grid
from expertise_irl.mdp import TabularMDP
from expertise_irl.worlds.zones import load_bundled

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
THETA_STAR = "0.5,0.5,0,0,0"
GRID_HEADER = "episode,step,x,y"
STATE_HEADER = "episode,step,state,action"
HYPOTHESIS_KEYS = {"theta", "beta", "log_likelihood", "log_posterior", "probability"}
TABLE_COLUMNS = "120"  # wide enough that the demo table never wraps
OLD_MTIME_NS = 1_000_000_000 * 1_000_000_000  # 2001-09-09: any rewrite moves the mtime


# ----------------------------------------------------------------------------- helpers


def cli_command() -> list[str]:
    """The installed console script (beside this interpreter), else an equivalent -c call."""
    script = Path(sys.executable).with_name("expertise-irl")
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "from expertise_irl.cli import main; main()"]


def run_cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    proc = subprocess.run(
        [*cli_command(), *(str(a) for a in args)],
        cwd=cwd, capture_output=True, text=True, encoding="utf-8", timeout=300, check=False,
        env={**os.environ, "COLUMNS": TABLE_COLUMNS},
    )
    assert "Traceback" not in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stdout, proc.stdout
    return proc


def csv_rows(path: Path) -> tuple[str, np.ndarray]:
    """Header line and ``[n, 4]`` int rows of a demonstrations CSV."""
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    return lines[0], np.array([[int(v) for v in ln.split(",")] for ln in lines[1:]], dtype=np.int64)


def age(path: Path) -> None:
    """Give ``path`` an old mtime, so that any later write to it is visible."""
    os.utime(path, ns=(OLD_MTIME_NS, OLD_MTIME_NS))


def table_cells(stdout: str, label: str, *, exact: bool = False) -> list[str]:
    """The ``true`` and ``inferred`` cells of the demo table row whose label is (or starts with) ``label``."""
    for line in stdout.splitlines():
        cells = [c.strip() for c in line.strip().strip("│").split("│")]
        if len(cells) == 3 and (cells[0] == label if exact else cells[0].startswith(label)):
            return cells[1:]
    raise AssertionError(f"no table row {label!r} in:\n{stdout}")


def check_hypotheses(doc: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hypotheses are well formed, probabilities a normalised posterior; returns (θ, β, p)."""
    hyps = doc["hypotheses"]
    assert hyps, "no hypotheses"
    for h in hyps:
        assert set(h) >= HYPOTHESIS_KEYS, h.keys()
    theta = np.array([h["theta"] for h in hyps])
    beta = np.array([h["beta"] for h in hyps])
    p = np.array([h["probability"] for h in hyps])
    lp = np.array([-np.inf if h["log_posterior"] is None else h["log_posterior"] for h in hyps])
    ll = np.array([-np.inf if h["log_likelihood"] is None else h["log_likelihood"] for h in hyps])
    assert np.all(p >= 0)
    assert p.sum() == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(theta.sum(axis=1), 1.0, atol=1e-12)  # unit l1
    assert np.all(theta >= 0) and np.all(beta > 0)
    # probability = softmax(log_posterior); with a uniform prior, log_posterior - log_likelihood
    # is the same for every possible hypothesis.
    np.testing.assert_allclose(p, np.exp(lp - np.logaddexp.reduce(lp)), rtol=1e-9, atol=1e-12)
    finite = np.isfinite(ll)
    assert finite.any()
    np.testing.assert_allclose(lp[finite] - ll[finite], (lp - ll)[finite][0], rtol=0, atol=1e-6)
    # Point estimates are posterior expectations.
    assert doc["beta_hat"] == pytest.approx(float(p @ beta), rel=1e-9)
    np.testing.assert_allclose(doc["theta_hat"], p @ theta, rtol=1e-9, atol=1e-12)
    assert doc["version"] == expertise_irl.__version__
    return theta, beta, p


def rows_as_set(a: np.ndarray) -> set[tuple[float, ...]]:
    return {tuple(r) for r in np.round(np.asarray(a, dtype=float), 9)}


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli")


@pytest.fixture(scope="module")
def corridor_npz(work) -> Path:
    path = work / "corridor.npz"
    ok(invoke("export-mdp", "corridor", "--out", path))
    return path


@pytest.fixture(scope="module")
def corridor_npz_no_xy(work, corridor_npz) -> Path:
    """The corridor archive without ``state_xy``: a generic tabular task."""
    path = work / "corridor-no-xy.npz"
    with np.load(corridor_npz) as z:
        arrays = {k: z[k] for k in z.files if k != "state_xy"}
    np.savez(path, **arrays)
    return path


@pytest.fixture(scope="module")
def corridor_csv(work) -> Path:
    """20 simulated episodes on the bundled corridor (grid CSV)."""
    path = work / "corridor-demos.csv"
    ok(invoke("simulate", "corridor", "--theta", THETA_STAR, "--beta", "0.5",
              "--episodes", 20, "--seed", 1, "--out", path))
    return path


@pytest.fixture(scope="module")
def demo_a(work):
    """``demo --map corridor --seed 0`` into a fresh directory: (dir, CliRunner result)."""
    out_dir = work / "demo-a"
    with pytest.MonkeyPatch.context() as mp:
        # rich sizes tables from COLUMNS or the real terminal; fix a width that never wraps the table
        mp.setattr(cli.out, "width", int(TABLE_COLUMNS))
        result = invoke("demo", "--map", "corridor", "--seed", 0, "--out", out_dir)
    ok(result)
    return out_dir, result


@pytest.fixture(scope="module")
def inferred(work, corridor_csv):
    """infer with --thetas 0,0.5,1 --betas 0.1,1,10, without and with --per-action."""
    args = ("infer", "corridor", "--demos", corridor_csv, "--thetas", "0,0.5,1", "--betas", "0.1,1,10")
    plain, traced = work / "infer-plain.json", work / "infer-per-action.json"
    ok(invoke(*args, "--out", plain))
    ok(invoke(*args, "--per-action", "--out", traced))
    return load(plain), load(traced)


# ----------------------------------------------------------------------------- demo
@pytest.mark.slow
def test_demo_writes_png_and_result(demo_a):
    out_dir, _ = demo_a
    names = sorted(p.name for p in out_dir.iterdir())
    assert names == ["demo-corridor-seed0.png", "result-corridor-seed0.json"]
    assert (out_dir / "demo-corridor-seed0.png").read_bytes()[:8] == PNG_SIGNATURE
    doc = load(out_dir / "result-corridor-seed0.json")
    for key in ("beta_hat", "theta_hat", "hypotheses", "settings", "version", "truth", "metrics"):
        assert key in doc, key
    theta, beta, p = check_hypotheses(doc)
    settings = doc["settings"]
    assert settings["seed"] == 0 and settings["map"] == "bundled:corridor"
    assert len(doc["hypotheses"]) == settings["k"] * len(BETA_PRESETS["paper-sim"])
    assert set(beta.tolist()) == set(BETA_PRESETS["paper-sim"])

    truth = doc["truth"]
    match = np.flatnonzero(np.all(np.isclose(theta, truth["theta"], atol=1e-9), axis=1)
                           & np.isclose(beta, truth["beta"]))
    assert match.size == 1, "the true hypothesis must be in the set exactly once"
    assert truth["probability"] == pytest.approx(p[match[0]], rel=1e-9)

    m = doc["metrics"]
    assert m["expertise_distance"] == pytest.approx(abs(truth["beta"] - doc["beta_hat"]), rel=1e-9)
    t, th = np.array(truth["theta"]), np.array(doc["theta_hat"])
    assert m["cosine_similarity"] == pytest.approx(t @ th / np.linalg.norm(t) / np.linalg.norm(th), rel=1e-9)
    assert np.isfinite(m["policy_regret"]) and m["policy_regret"] >= -1e-9


def test_demo_table_shows_truth_inference_and_metrics(demo_a):
    out_dir, result = demo_a
    doc = load(out_dir / "result-corridor-seed0.json")
    stdout = result.stdout
    truth, m = doc["truth"], doc["metrics"]
    assert table_cells(stdout, "expertise β", exact=True) == [f"{truth['beta']:g}", f"{doc['beta_hat']:.3g}"]
    for i, name in enumerate(doc["feature_names"]):
        assert table_cells(stdout, f"θ {name}", exact=True) == [
            f"{truth['theta'][i]:.3f}", f"{doc['theta_hat'][i]:.3f}"]
    assert table_cells(stdout, "P(θ*, β*)") == ["", f"{truth['probability']:.3f}"]
    assert table_cells(stdout, "expertise distance") == ["", f"{m['expertise_distance']:.3g}"]
    assert table_cells(stdout, "cosine similarity") == ["", f"{m['cosine_similarity']:.3f}"]
    assert table_cells(stdout, "policy regret") == ["", f"{m['policy_regret']:.3g}"]
    assert table_cells(stdout, "return regret") == ["", f"{m['return_regret']:.3g}"]
    assert str(out_dir / "demo-corridor-seed0.png") in stdout
    assert str(out_dir / "result-corridor-seed0.json") in stdout


@pytest.mark.slow
def test_demo_same_seed_same_result(work, demo_a):
    out_a, _ = demo_a
    out_b, out_c = work / "demo-b", work / "demo-c"
    ok(invoke("demo", "--map", "corridor", "--seed", 0, "--out", out_b))
    ok(invoke("demo", "--map", "corridor", "--seed", 1, "--out", out_c))
    a, b = (load(d / "result-corridor-seed0.json") for d in (out_a, out_b))
    c = load(out_c / "result-corridor-seed1.json")
    for doc in (a, b, c):
        assert doc.pop("run_time_s") >= 0
    assert a == b
    assert a != c  # the seed matters
    assert c["settings"]["seed"] == 1


def test_demo_refuses_to_overwrite_without_force(demo_a, tmp_path):
    out_dir = tmp_path / "demo"
    shutil.copytree(demo_a[0], out_dir)
    png, js = out_dir / "demo-corridor-seed0.png", out_dir / "result-corridor-seed0.json"
    for p in (png, js):
        age(p)
    before = {p: snapshot(p) for p in (png, js)}

    result = invoke("demo", "--map", "corridor", "--out", out_dir)
    line = assert_input_error(result, "already exists", "--force")
    assert str(png) in line or str(js) in line
    assert {p: snapshot(p) for p in (png, js)} == before

    ok(invoke("demo", "--map", "corridor", "--out", out_dir, "--force"))
    for p in (png, js):
        assert p.stat().st_mtime_ns != OLD_MTIME_NS, f"{p.name} was not rewritten"
    assert png.read_bytes()[:8] == PNG_SIGNATURE
    assert "beta_hat" in load(js)


def test_demo_checks_every_output_before_writing(demo_a, tmp_path):
    out_dir = tmp_path / "demo"
    out_dir.mkdir()
    shutil.copy(demo_a[0] / "result-corridor-seed0.json", out_dir / "result-corridor-seed0.json")
    before = snapshot(out_dir / "result-corridor-seed0.json")
    assert_input_error(invoke("demo", "--map", "corridor", "--out", out_dir),
                       "result-corridor-seed0.json", "already exists")
    assert not (out_dir / "demo-corridor-seed0.png").exists()
    assert snapshot(out_dir / "result-corridor-seed0.json") == before


@pytest.mark.slow
def test_demo_default_generated_map_end_to_end(tmp_path):
    """The README quick start: ``expertise-irl demo`` on a random map, as a real process."""
    proc = run_cli("demo", "--seed", 2, "--out", "demo-out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out_dir = tmp_path / "demo-out"
    assert (out_dir / "demo-seed2.png").read_bytes()[:8] == PNG_SIGNATURE
    doc = load(out_dir / "result-seed2.json")
    check_hypotheses(doc)
    assert doc["settings"]["map"].startswith("generated")
    assert doc["settings"]["episodes"] == 20
    for label in ("expertise β", "P(θ*, β*)", "expertise distance", "cosine similarity",
                  "policy regret"):
        assert label in proc.stdout, label
    assert table_cells(proc.stdout, "expertise β", exact=True)[0] == f"{doc['truth']['beta']:g}"


# ----------------------------------------------------------------------------- export-mdp
@pytest.mark.parametrize("name", ["corridor", "crossroads"])
def test_export_mdp_round_trips(name, corridor_npz, tmp_path):
    path = corridor_npz if name == "corridor" else tmp_path / f"{name}.npz"
    if name != "corridor":
        ok(invoke("export-mdp", name, "--out", path))
    got, want = TabularMDP.load(path), load_bundled(name).to_mdp()
    for field in ("next_state", "features", "terminal", "state_xy"):
        np.testing.assert_array_equal(getattr(got, field), getattr(want, field), err_msg=field)
    if want.start_states is None:
        assert got.start_states is None
    else:
        np.testing.assert_array_equal(got.start_states, want.start_states)
    assert got.gamma == want.gamma
    assert got.feature_names == want.feature_names


# ----------------------------------------------------------------------------- simulate
def test_simulate_map_writes_grid_csv(corridor_csv):
    header, rows = csv_rows(corridor_csv)
    assert header == GRID_HEADER
    ep = rows[:, 0]
    assert np.unique(ep).tolist() == list(range(20))
    grid = load_bundled("corridor").grid
    for e in range(20):
        r = rows[ep == e]
        assert r[:, 1].tolist() == list(range(len(r)))
        assert grid[r[0, 3], r[0, 2]] == "S", "episodes start on the map's start cell"
        assert np.all(np.abs(np.diff(r[:, 2])) + np.abs(np.diff(r[:, 3])) == 1), "cells must be 4-neighbours"
        assert np.all(grid[r[:, 3], r[:, 2]] != "#")
    # The file reads back as demonstrations of the map.
    assert read_demos_csv(corridor_csv, load_bundled("corridor").to_mdp()).n_episodes == 20


def test_simulate_is_reproducible_and_seeded(corridor_csv, tmp_path):
    common = ("simulate", "corridor", "--theta", THETA_STAR, "--beta", "0.5", "--episodes", 20)
    ok(invoke(*common, "--seed", 1, "--out", tmp_path / "again.csv"))
    ok(invoke(*common, "--seed", 2, "--out", tmp_path / "other.csv"))
    assert (tmp_path / "again.csv").read_bytes() == corridor_csv.read_bytes()
    assert (tmp_path / "other.csv").read_bytes() != corridor_csv.read_bytes()


def test_simulate_normalises_theta(corridor_csv, tmp_path):
    out = tmp_path / "unnormalised.csv"
    result = invoke("simulate", "corridor", "--theta", "1,1,0,0,0", "--beta", "0.5",
                    "--episodes", 20, "--seed", 1, "--out", out)
    ok(result)
    assert out.read_bytes() == corridor_csv.read_bytes()
    assert "[0.5, 0.5, 0.0, 0.0, 0.0]" in result.stdout  # θ* reported after normalising


def test_simulate_npz_formats(corridor_csv, corridor_npz, corridor_npz_no_xy, tmp_path):
    """write_demos_csv's documented "auto": grid when the MDP is a grid (an archive exported from
    a map carries state_xy), else the generic state format."""
    common = ("--theta", THETA_STAR, "--beta", "0.5", "--episodes", 20, "--seed", 1)
    with_xy, no_xy = tmp_path / "with-xy.csv", tmp_path / "no-xy.csv"
    ok(invoke("simulate", "--mdp", corridor_npz, *common, "--out", with_xy))
    ok(invoke("simulate", "--mdp", corridor_npz_no_xy, *common, "--out", no_xy))
    assert with_xy.read_bytes() == corridor_csv.read_bytes()  # same task, same seed, grid format
    header, rows = csv_rows(no_xy)
    assert header == STATE_HEADER
    assert np.unique(rows[:, 0]).tolist() == list(range(20))
    # The state CSV holds exactly the same (state, action) pairs as the grid CSV.
    mdp = load_bundled("corridor").to_mdp()
    grid_pairs = read_demos_csv(corridor_csv, mdp)
    state_pairs = read_demos_csv(no_xy, TabularMDP.load(corridor_npz_no_xy))
    for field in ("episode", "step", "state", "action"):
        np.testing.assert_array_equal(getattr(state_pairs, field), getattr(grid_pairs, field), err_msg=field)


# ----------------------------------------------------------------------------- infer
@pytest.mark.slow
def test_infer_result_document(inferred):
    doc, _ = inferred
    for key in ("beta_hat", "theta_hat", "hypotheses", "settings", "version"):
        assert key in doc, key
    assert "trace" not in doc
    theta, beta, _ = check_hypotheses(doc)
    settings = doc["settings"]
    assert settings["thetas"] == "0,0.5,1"
    assert settings["betas"] == "0.1,1,10"
    grid = theta_grid([0, 0.5, 1], 5)
    assert settings["n_theta"] == len(grid) == 211
    assert settings["n_beta"] == 3
    assert len(doc["hypotheses"]) == len(grid) * 3
    assert rows_as_set(theta) == rows_as_set(grid)
    assert sorted(set(beta.tolist())) == [0.1, 1.0, 10.0]
    assert doc["data"]["episodes"] == 20


@pytest.mark.slow
def test_infer_per_action_same_posterior_plus_trace(inferred, corridor_csv):
    plain, traced = inferred
    lp_plain = np.array([h["log_posterior"] for h in plain["hypotheses"]], dtype=float)
    lp_traced = np.array([h["log_posterior"] for h in traced["hypotheses"]], dtype=float)
    # The plain run is certified (hypotheses certainly below 1e-12 stop at a loose tolerance, every
    # probability within its stated bound); the traced one solves all to 1e-8 nats (each
    # log-likelihood within 2e-8 per action). The posteriors agree within the two bounds, and the
    # hypotheses that hold mass have the same log posterior.
    n = traced["data"]["actions"]
    bound = plain["settings"]["probability_error"] + np.expm1(4e-8 * n)
    assert plain["settings"]["probability_error"] <= 1e-6
    assert np.max(np.abs(np.exp(lp_plain) - np.exp(lp_traced))) <= bound
    held = np.exp(lp_plain) > 1e-9
    np.testing.assert_allclose(lp_traced[held], lp_plain[held], rtol=1e-8)
    assert traced["beta_hat"] == pytest.approx(plain["beta_hat"], rel=1e-8)
    assert traced["settings"]["per_action"] is True

    _, rows = csv_rows(corridor_csv)
    n_actions = len(rows) - len(np.unique(rows[:, 0]))  # grid CSV: one row per cell, incl. the last
    trace = traced["trace"]
    assert traced["data"]["actions"] == n_actions
    assert len(trace) == n_actions + 1  # the prior, then one entry per action
    prior = trace[0]
    assert prior["episode"] is None and prior["step"] is None
    assert prior["beta_hat"] == pytest.approx(np.mean([0.1, 1, 10]), rel=1e-9)
    np.testing.assert_allclose(prior["theta_hat"], theta_grid([0, 0.5, 1], 5).mean(axis=0), rtol=1e-9)
    assert trace[-1]["beta_hat"] == pytest.approx(plain["beta_hat"], rel=1e-8)
    np.testing.assert_allclose(trace[-1]["theta_hat"], plain["theta_hat"], rtol=1e-7, atol=1e-12)
    # Entries follow the (episode, step) order of the actions in the file.
    pairs = read_demos_csv(corridor_csv, load_bundled("corridor").to_mdp())
    assert [(t["episode"], t["step"]) for t in trace[1:]] == list(
        zip(pairs.episode.tolist(), pairs.step.tolist(), strict=True))


@pytest.mark.slow
def test_infer_sample_thetas(corridor_csv, tmp_path):
    def sample(seed: int) -> dict:
        out = tmp_path / f"sampled-{seed}-{len(list(tmp_path.iterdir()))}.json"
        ok(invoke("infer", "corridor", "--demos", corridor_csv, "--sample-thetas", 5, "--seed", seed,
                  "--out", out))
        return load(out)

    doc = sample(3)
    theta, _, _ = check_hypotheses(doc)
    assert doc["settings"]["n_theta"] == 5
    sampled = rows_as_set(theta)
    assert len(sampled) == 5
    assert sampled <= rows_as_set(theta_grid(THETA_PRESETS["paper-real"], 5))  # default --thetas
    assert len(doc["hypotheses"]) == 5 * len(BETA_PRESETS["paper-sim"])  # default --betas
    # --seed picks the sample: the same seed gives the same Θ_5, another seed another one.
    assert rows_as_set([h["theta"] for h in sample(3)["hypotheses"]]) == sampled
    assert rows_as_set([h["theta"] for h in sample(4)["hypotheses"]]) != sampled


@pytest.mark.slow
def test_infer_state_csv_on_generic_mdp(corridor_csv, corridor_npz_no_xy, tmp_path):
    """A task with no grid: simulate writes state CSV, infer --mdp reads it; same answer as the map."""
    demos = tmp_path / "state.csv"
    ok(invoke("simulate", "--mdp", corridor_npz_no_xy, "--theta", THETA_STAR, "--beta", "0.5",
              "--episodes", 20, "--seed", 1, "--out", demos))
    small = ("--thetas", "0,1", "--betas", "0.1,1")
    ok(invoke("infer", "--mdp", corridor_npz_no_xy, "--demos", demos, *small, "--out", tmp_path / "a.json"))
    ok(invoke("infer", "corridor", "--demos", corridor_csv, *small, "--out", tmp_path / "b.json"))
    a, b = load(tmp_path / "a.json"), load(tmp_path / "b.json")
    check_hypotheses(a)
    np.testing.assert_allclose([h["log_posterior"] for h in a["hypotheses"]],
                               [h["log_posterior"] for h in b["hypotheses"]], rtol=1e-10)


@pytest.mark.slow
def test_simulate_then_infer_recovers_truth(tmp_path):
    """β* = 0.09 on crossroads (no start cell, so episodes start all over the map). With the true
    θ* in the --thetas 0,0.5,1 grid and β* in paper-sim, 150 episodes put the MAP on the truth:
    measured with seeds 0..29, 150 episodes ranked it first every time (truth posterior >= 0.55),
    while 60 episodes did only 20 times in 30 (near-optimal paths rarely separate close θ)."""
    demos = tmp_path / "crossroads.csv"
    ok(invoke("simulate", "crossroads", "--theta", THETA_STAR, "--beta", "0.09",
              "--episodes", 150, "--seed", 1, "--out", demos))
    out = tmp_path / "result.json"
    ok(invoke("infer", "crossroads", "--demos", demos, "--thetas", "0,0.5,1", "--betas", "paper-sim",
              "--out", out))
    doc = load(out)
    theta, beta, p = check_hypotheses(doc)
    truth = np.flatnonzero(np.all(np.isclose(theta, [0.5, 0.5, 0, 0, 0]), axis=1) & np.isclose(beta, 0.09))
    assert truth.size == 1
    best = int(np.argmax(p))
    assert best == truth[0], f"MAP {theta[best]}, β={beta[best]} (p={p[best]:.3g}); truth p={p[truth[0]]:.3g}"
    assert doc["map"]["beta"] == pytest.approx(0.09)
    np.testing.assert_allclose(doc["map"]["theta"], [0.5, 0.5, 0, 0, 0], atol=1e-12)
    assert doc["expertise_group"] == "high"


@pytest.mark.slow
def test_pipeline_end_to_end(tmp_path):
    """export-mdp -> simulate --mdp -> infer --mdp through the installed console script."""
    assert run_cli("export-mdp", "corridor", "--out", "task.npz", cwd=tmp_path).returncode == 0
    proc = run_cli("simulate", "--mdp", "task.npz", "--theta", THETA_STAR, "--beta", "0.5",
                   "--episodes", 5, "--seed", 1, "--out", "demos.csv", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("infer", "--mdp", "task.npz", "--demos", "demos.csv", "--thetas", "0,1",
                   "--betas", "0.1,1", "--out", "result.json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    doc = load(tmp_path / "result.json")
    check_hypotheses(doc)
    assert doc["settings"]["n_hypotheses"] == len(theta_grid([0, 1], 5)) * 2
    assert "result.json" in proc.stdout


# ----------------------------------------------------------------------------- bad input
BAD_MAPS = {
    # name: (map text, fragments after the path prefix "{map}")
    "unknown-char": ("S..Q\n...G\n", [":1:4:", "unknown map character 'Q'"]),
    "ragged-rows": ("S...\n..G\n", [":2:", "same length"]),
    "no-goal": ("S...\n....\n", [":", "no goal"]),
    "one-cell-pocket": ("S....\n.###.\n.#.#.\n.###G\n", [":", "x=2, y=2"]),
    "two-cell-pocket": ("S......\n.####..\n.#..#..\n.####.G\n", [":", "x=2, y=2", "cannot reach"]),
    "empty-map": ("", [":", "empty"]),
}
MAP_COMMANDS = {
    "export-mdp": ("export-mdp", "{map}", "--out", "{out}"),
    "simulate": ("simulate", "{map}", "--theta", THETA_STAR, "--beta", "1", "--out", "{out}"),
    "infer": ("infer", "{map}", "--demos", "{demos}", "--out", "{out}"),
}


def fill(template, **paths) -> list[str]:
    return [str(a).format(**{k: str(v) for k, v in paths.items()}) for a in template]


@pytest.mark.parametrize("command", list(MAP_COMMANDS))
@pytest.mark.parametrize("case", list(BAD_MAPS))
def test_bad_map_file(case, command, corridor_csv, tmp_path):
    text, fragments = BAD_MAPS[case]
    map_path = tmp_path / "bad.txt"
    map_path.write_text(text, encoding="utf-8")
    out = tmp_path / "out.file"
    args = fill(MAP_COMMANDS[command], map=map_path, out=out, demos=corridor_csv)
    line = assert_input_error(invoke(*args), *fragments)
    assert line.startswith(f"error: {map_path}{fragments[0]}"), line
    assert not out.exists()


@pytest.mark.parametrize("command", list(MAP_COMMANDS))
def test_missing_map_file_and_unknown_bundled_name(command, corridor_csv, tmp_path):
    out = tmp_path / "out.file"
    missing = tmp_path / "no-such-map.txt"
    for spec, fragments in ((missing, [str(missing), "no such map file"]),
                            ("no-such-bundled-map", ["no-such-bundled-map", "corridor", "crossroads"])):
        args = fill(MAP_COMMANDS[command], map=spec, out=out, demos=corridor_csv)
        assert_input_error(invoke(*args), *fragments)
        assert not out.exists()


BAD_DEMOS = {
    # name: (CSV text, fragments after "{csv}")
    "wrong-columns": ("episode,step,a,b\n0,0,0,0\n", [":1:", "header", "episode,step,x,y"]),
    "non-numeric": (f"{GRID_HEADER}\n0,0,0,0\n0,1,one,0\n", [":3:", "'one'", "not a number"]),
    "markup-is-literal": (f"{GRID_HEADER}\n0,0,0,0\n0,1,[/x],0\n", [":3:", "'[/x]'"]),
    "leaves-map": (f"{GRID_HEADER}\n0,0,0,0\n0,1,-1,0\n", [":3:", "episode 0 step 1", "outside the map"]),
    "jumps": (f"{GRID_HEADER}\n0,0,0,0\n0,1,1,0\n0,2,3,0\n", [":4:", "episode 0 step 2", "jumps"]),
    "into-obstacle": (f"{GRID_HEADER}\n0,0,1,0\n0,1,1,1\n", [":3:", "episode 0 step 1", "obstacle"]),
    # state 0 is the top-left cell (x=0, y=0): "up" (action 0) leaves the map.
    "unavailable-action": (f"{STATE_HEADER}\n0,0,0,0\n", [":2:", "episode 0 step 0", "not available"]),
    # right (3) from state 0 leads to state 1, not state 5.
    "does-not-follow": (f"{STATE_HEADER}\n0,0,0,3\n0,1,5,3\n",
                        [":3:", "episode 0 step 1", "does not follow", "expected state 1"]),
    "empty-file": ("", [":", "empty"]),
    "header-only": (f"{GRID_HEADER}\n", [":", "no demonstrations"]),
}


@pytest.mark.parametrize("case", list(BAD_DEMOS))
def test_bad_demos_csv(case, tmp_path):
    text, fragments = BAD_DEMOS[case]
    demos = tmp_path / "demos.csv"
    demos.write_text(text, encoding="utf-8")
    out = tmp_path / "result.json"
    line = assert_input_error(invoke("infer", "corridor", "--demos", demos, "--out", out), *fragments)
    assert line.startswith(f"error: {demos}{fragments[0]}"), line
    assert not out.exists()


def test_missing_demos_file(tmp_path):
    demos, out = tmp_path / "nope.csv", tmp_path / "result.json"
    result = invoke("infer", "corridor", "--demos", demos, "--out", out)
    assert_input_error(result, str(demos), "no such file")
    assert not out.exists()


BAD_PARAMETERS = {
    # name: (simulate options, fragments)
    "negative-theta": (["--theta", "-0.5,1,0,0,0", "--beta", "1"], ["--theta", "non-negative"]),
    "theta-wrong-length": (["--theta", "1,0,0", "--beta", "1"], ["--theta", "3 values", "5 features"]),
    "theta-all-zero": (["--theta", "0,0,0,0,0", "--beta", "1"], ["--theta", "positive"]),
    "theta-not-numbers": (["--theta", "a,b,c,d,e", "--beta", "1"], ["--theta"]),
    "beta-zero": (["--theta", THETA_STAR, "--beta", "0"], ["--beta", "> 0"]),
    "beta-negative": (["--theta", THETA_STAR, "--beta", "-1"], ["--beta", "> 0"]),
}


@pytest.mark.parametrize("case", list(BAD_PARAMETERS))
def test_bad_simulate_parameters(case, tmp_path):
    options, fragments = BAD_PARAMETERS[case]
    out = tmp_path / "demos.csv"
    assert_input_error(invoke("simulate", "corridor", *options, "--out", out), *fragments)
    assert not out.exists()


@pytest.mark.parametrize(("options", "fragments"), [
    (["--betas", "0,1"], ["--betas", "> 0"]),
    (["--betas", "-1"], ["--betas", "> 0"]),
    (["--thetas", "abc"], ["--thetas", "'abc'"]),
    (["--betas", "abc"], ["--betas", "'abc'"]),
], ids=["betas-zero", "betas-negative", "thetas-abc", "betas-abc"])
def test_bad_hypothesis_specs(options, fragments, corridor_csv, tmp_path):
    out = tmp_path / "result.json"
    result = invoke("infer", "corridor", "--demos", corridor_csv, *options, "--out", out)
    assert_input_error(result, *fragments)
    assert not out.exists()


@pytest.mark.parametrize("command", ["simulate", "infer"])
def test_corrupt_npz(command, corridor_csv, tmp_path):
    npz, out = tmp_path / "corrupt.npz", tmp_path / "out.file"
    npz.write_bytes(np.random.default_rng(0).bytes(512))
    extra = (["--theta", THETA_STAR, "--beta", "1"] if command == "simulate"
             else ["--demos", str(corridor_csv)])
    assert_input_error(invoke(command, "--mdp", npz, *extra, "--out", out), str(npz))
    assert not out.exists()


@pytest.mark.parametrize("command", ["simulate", "infer"])
def test_map_and_mdp_both_or_neither(command, corridor_npz, corridor_csv, tmp_path):
    out = tmp_path / "out.file"
    extra = (["--theta", THETA_STAR, "--beta", "1"] if command == "simulate"
             else ["--demos", str(corridor_csv)])
    assert_input_error(invoke(command, "corridor", "--mdp", corridor_npz, *extra, "--out", out),
                       "exactly one", "MAP", "--mdp")
    assert_input_error(invoke(command, *extra, "--out", out), "exactly one", "MAP", "--mdp")
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize("command", ["export-mdp", "simulate", "infer"])
def test_existing_output_is_untouched_without_force(command, corridor_csv, tmp_path):
    out = tmp_path / "existing.out"
    out.write_bytes(b"precious\n")
    age(out)
    before = snapshot(out)
    args = {
        "export-mdp": ["export-mdp", "corridor"],
        "simulate": ["simulate", "corridor", "--theta", THETA_STAR, "--beta", "1", "--episodes", 2],
        "infer": ["infer", "corridor", "--demos", corridor_csv, "--thetas", "0,1", "--betas", "1"],
    }[command]
    assert_input_error(invoke(*args, "--out", out), str(out), "already exists", "--force")
    assert snapshot(out) == before
    ok(invoke(*args, "--out", out, "--force"))
    assert out.read_bytes() != b"precious\n"
    assert out.stat().st_mtime_ns != OLD_MTIME_NS


@pytest.mark.parametrize("spec", ["no-such-bundled-map", "bad-char-map"])
def test_demo_bad_map_is_one_line(spec, tmp_path):
    if spec == "bad-char-map":
        path = tmp_path / "bad.txt"
        path.write_text("S..Q\n...G\n", encoding="utf-8")
        spec = str(path)
    assert_input_error(invoke("demo", "--map", spec, "--out", tmp_path / "out"), spec)


@pytest.mark.parametrize("options", [["--episodes", "0"], ["--beta", "abc"]], ids=["episodes-0", "beta-abc"])
def test_parser_level_bad_values_are_one_line(options, tmp_path):
    base = {"--theta": THETA_STAR, "--beta": "1", "--episodes": "2"}
    base.update(dict(zip(options[::2], options[1::2], strict=True)))
    args = [a for kv in base.items() for a in kv]
    assert_input_error(invoke("simulate", "corridor", *args, "--out", tmp_path / "d.csv"), options[0])


# ----------------------------------------------------------------------------- bad input, real process
E2E_BAD = {
    "unknown-map-char": ("bad.txt", "S..Q\n...G\n",
                         ["export-mdp", "bad.txt", "--out", "x.npz"], ["bad.txt:1:4:"]),
    "corrupt-npz": ("corrupt.npz", None,
                    ["simulate", "--mdp", "corrupt.npz", "--theta", THETA_STAR, "--beta", "1",
                     "--out", "d.csv"],
                    ["corrupt.npz"]),
    "negative-theta": (None, None,
                       ["simulate", "corridor", "--theta", "-0.5,1,0,0,0", "--beta", "1", "--out", "d.csv"],
                       ["--theta"]),
    "demo-jumps": ("demos.csv", f"{GRID_HEADER}\n0,0,0,0\n0,1,2,0\n",
                   ["infer", "corridor", "--demos", "demos.csv", "--out", "r.json"],
                   ["demos.csv:3:", "jumps"]),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(E2E_BAD))
def test_bad_input_end_to_end_has_no_traceback(case, tmp_path):
    name, text, args, fragments = E2E_BAD[case]
    if name is not None and text is not None:
        (tmp_path / name).write_text(text, encoding="utf-8")
    elif name is not None:
        (tmp_path / name).write_bytes(np.random.default_rng(1).bytes(512))
    proc = run_cli(*args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert proc.stdout.strip() == ""
    for fragment in fragments:
        assert fragment in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ([name] if name else [])  # nothing written


# ----------------------------------------------------------------------------- review findings
@pytest.mark.parametrize("command", ["demo", "simulate", "infer"])
def test_negative_seed_is_a_one_line_error(command, corridor_csv, tmp_path):
    args = {
        "demo": ["demo", "--map", "corridor", "--out", tmp_path / "d"],
        "simulate": ["simulate", "corridor", "--theta", THETA_STAR, "--beta", "1",
                     "--out", tmp_path / "d.csv"],
        "infer": ["infer", "corridor", "--demos", corridor_csv, "--sample-thetas", "2", "--out",
                  tmp_path / "r.json"],
    }[command]
    assert_input_error(invoke(*args, "--seed", "-1"), "--seed")


def test_output_under_a_file_is_refused_before_any_work(corridor_csv, tmp_path):
    line = assert_input_error(invoke("infer", "corridor", "--demos", corridor_csv,
                                     "--out", corridor_csv / "r.json"), "is not a directory")
    assert str(corridor_csv) in line


def test_render_rejects_an_unknown_figure_format(tmp_path):
    assert_input_error(invoke("render", "corridor", "--out", tmp_path / "map.txt"), "map.txt", ".txt")
    assert not (tmp_path / "map.txt").exists()


@pytest.mark.parametrize("command", ["render", "export-mdp", "simulate", "infer"])
def test_a_map_whose_goal_cannot_be_reached_is_refused_alike(command, corridor_csv, tmp_path):
    walled = tmp_path / "walled.txt"
    walled.write_text("S..#.\n...#G\n...#.\n")
    out = tmp_path / {"render": "map.png", "export-mdp": "t.npz", "simulate": "d.csv",
                      "infer": "r.json"}[command]
    extra = {"simulate": ["--theta", THETA_STAR, "--beta", "1"],
             "infer": ["--demos", corridor_csv]}.get(command, [])
    assert_input_error(invoke(command, walled, *extra, "--out", out),
                       "walled.txt", "state 0 (cell x=0, y=0) cannot reach a terminal (goal) state")
    assert not out.exists()


def test_infer_leaves_a_users_tmp_file_alone(corridor_csv, tmp_path):
    precious = tmp_path / "r.json.tmp"
    precious.write_text("precious\n")
    ok(invoke("infer", "corridor", "--demos", corridor_csv, "--thetas", "0,1", "--betas", "1",
              "--out", tmp_path / "r.json"))
    assert precious.read_text() == "precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "r.json.tmp"]


def test_map_with_no_state_to_act_in(tmp_path):
    path = tmp_path / "onlygoal.txt"
    path.write_text("G\n")
    assert_input_error(invoke("export-mdp", path, "--out", tmp_path / "o.npz"),
                       str(path), "every state is terminal")


def test_tolerance_too_loose_is_refused(corridor_csv, tmp_path):
    assert_input_error(invoke("infer", "corridor", "--demos", corridor_csv, "--tol", "10",
                              "--out", tmp_path / "r.json"), "--tol")


def test_demos_path_that_is_a_directory(tmp_path):
    assert_input_error(invoke("infer", "corridor", "--demos", tmp_path, "--out", tmp_path / "r.json"),
                       str(tmp_path), "is a directory")


def test_bad_gamma_in_settings_names_the_toml(tmp_path):
    (tmp_path / "m.txt").write_text("S.G\n")
    (tmp_path / "m.toml").write_text("gamma = 1.5\n")
    assert_input_error(invoke("export-mdp", tmp_path / "m.txt", "--out", tmp_path / "o.npz"),
                       "m.toml", "gamma")


def test_infer_records_inputs_exactly(inferred, corridor_csv):
    plain, _ = inferred
    settings = plain["settings"]
    assert settings["goal_bonus"] == 10.0
    assert settings["demos_digest"].startswith("sha256:") and len(settings["demos_digest"]) == 71
    assert settings["mdp_digest"].startswith("sha256:")


# ----------------------------------------------------------------------------- continuous methods
@pytest.mark.slow
@pytest.mark.parametrize("method,extra", [
    ("map", ["--starts", "2"]),
    ("nuts", ["--chains", "2", "--warmup", "60", "--samples", "60"]),
    ("birl", ["--iterations", "150", "--variant", "simplex"]),
])
def test_infer_continuous_methods(method, extra, corridor_csv, tmp_path):
    out = tmp_path / f"{method}.json"
    ok(invoke("infer", "corridor", "--demos", corridor_csv, "--method", method, "--seed", "3",
              *extra, "--out", out))
    doc = load(out)
    assert doc["method"] == method and doc["settings"]["method"] == method
    K = len(doc["feature_names"])
    assert len(doc["theta_hat"]) == K and doc["beta_hat"] > 0
    assert set(doc["map"]) >= {"theta", "beta"} and len(doc["map"]["theta"]) == K
    assert doc["run_time_s"] > 0 and "version" in doc
    if method == "map":
        assert doc["theta_hat"] == doc["map"]["theta"]  # for map the estimate is the optimum
        assert sum(doc["theta_hat"]) == pytest.approx(1.0)
    else:
        ci = doc["credible_intervals"]
        assert ci["beta"][0] <= ci["beta"][1] and len(ci["theta"]) == K
        samples = doc["samples"]
        beta = np.array(samples["beta"])
        assert len(samples["theta"]) == len(beta) == len(samples["chain"])
        # The reported point estimate is the mean of the reported draws.
        assert doc["beta_hat"] == pytest.approx(beta.mean(), rel=1e-9)
        assert np.quantile(beta, 0.05) == pytest.approx(ci["beta"][0], rel=1e-9)
    diag = doc["diagnostics"]
    if method == "nuts":
        assert set(diag) >= {"r_hat", "ess_bulk", "divergences"}
    if method == "birl":
        assert 0 < diag["acceptance_rate"] < 1


@pytest.mark.slow
def test_infer_method_is_seeded(corridor_csv, tmp_path):
    docs = []
    for name in ("a", "b"):
        out = tmp_path / f"{name}.json"
        ok(invoke("infer", "corridor", "--demos", corridor_csv, "--method", "birl", "--iterations", "80",
                  "--seed", "7", "--out", out))
        doc = load(out)
        doc.pop("run_time_s")
        docs.append(doc)
    assert docs[0] == docs[1]


def test_infer_unknown_method(corridor_csv, tmp_path):
    assert_input_error(invoke("infer", "corridor", "--demos", corridor_csv, "--method", "magic",
                              "--out", tmp_path / "r.json"), "--method", "magic")
