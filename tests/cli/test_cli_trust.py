"""What a new user meets: no crash loses a result, warnings that speak, inputs never overwritten,
options that do not apply refused, and commands that do not solve start without JAX."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, load, ok, snapshot

from expertise_irl.inference.priors import BETA_PRIOR_MEAN, BETA_PRIOR_SD, BETA_RANGE, PRIOR_TEXT, prior_text


@pytest.fixture(scope="module")
def one_episode(tmp_path_factory) -> Path:
    """A single simulated episode on the bundled corridor."""
    path = tmp_path_factory.mktemp("trust") / "one.csv"
    ok(invoke("simulate", "corridor", "--theta", "0.5,0.3,0.2,0,0", "--beta", "0.5", "--episodes", 1,
              "--seed", 2, "--out", path))
    return path


def strict_json(path: Path) -> dict:
    """The file parses as strict JSON: no NaN or Infinity anywhere."""
    def refuse(token):
        raise AssertionError(f"{path}: non-finite number {token} in the result")
    return json.loads(Path(path).read_text(encoding="utf-8"), parse_constant=refuse)


# ----------------------------------------------------------------------------- no crash loses a result
@pytest.mark.slow
@pytest.mark.parametrize("method,extra,unavailable", [
    ("nuts", ["--chains", "1", "--warmup", "1", "--samples", "1"], {"r_hat", "ess_bulk"}),
    ("birl", ["--iterations", "1"], {"r_hat", "ess_bulk"}),
    ("map", ["--starts", "1"], {"start_agreement"}),
    ("discrete", [], set()),
])
def test_smallest_runs_write_their_result(method, extra, unavailable, one_episode, tmp_path):
    out = tmp_path / f"{method}.json"
    result = invoke("infer", "corridor", "--demos", one_episode, "--method", method, *extra, "--out", out)
    ok(result)
    doc = strict_json(out)
    assert doc["method"] == method and doc["beta_hat"] > 0
    diag = doc["diagnostics"]
    assert isinstance(diag["warnings"], list)
    assert set(diag.get("unavailable", {})) == unavailable
    for name in unavailable - {"start_agreement"}:
        assert diag[name] is None  # null in the JSON, the reason beside it
        assert diag["unavailable"][name]
    # every warning of the result is also on stderr, none on stdout
    for w in diag["warnings"]:
        assert f"warning: {w}" in " ".join(result.stderr.split())
        assert w not in result.stdout
    if method in ("nuts", "birl"):
        assert any(w.startswith("convergence not checked") for w in diag["warnings"])


@pytest.mark.slow
def test_nuts_one_chain_is_not_reported_as_converged(one_episode, tmp_path):
    out = tmp_path / "nuts.json"
    ok(invoke("infer", "corridor", "--demos", one_episode, "--method", "nuts", "--chains", "1",
              "--warmup", "20", "--samples", "20", "--seed", "1", "--out", out))
    diag = strict_json(out)["diagnostics"]
    assert diag["r_hat"] is None and "2 chains" in diag["unavailable"]["r_hat"]
    assert diag["ess_bulk"] is not None  # 20 draws: ESS is computable
    assert any("--chains 2 or more" in w for w in diag["warnings"])


def test_short_birl_chain_warns(one_episode, tmp_path):
    """The issue's case: a 200-iteration walk far from converged reports its R-hat and ESS."""
    out = tmp_path / "birl.json"
    result = invoke("infer", "corridor", "--demos", one_episode, "--method", "birl", "--iterations", "60",
                    "--seed", "0", "--out", out)
    ok(result)
    diag = strict_json(out)["diagnostics"]
    assert diag["ess_bulk"]["beta"] < 100
    assert any(w.startswith("bulk ESS of ") for w in diag["warnings"])
    assert "warning: bulk ESS of " in result.stderr


# ----------------------------------------------------------------------------- the prior is stated
def test_prior_is_stated_in_help_output_and_result(one_episode, tmp_path):
    lo, hi = BETA_RANGE
    paper = f"Normal({BETA_PRIOR_MEAN:g}, {BETA_PRIOR_SD:g}) truncated to [{lo:g}, {hi:g}]"
    default = "log β uniform on [0.001, 100]"
    help_text = " ".join(invoke("infer", "--help").output.replace("│", " ").split())
    readme = " ".join((Path(__file__).parents[2] / "README.md").read_text(encoding="utf-8").split())
    for words in (paper, default):
        assert words in help_text and words in readme, words
    for prior, text in (("log-uniform", PRIOR_TEXT), ("paper", prior_text("paper"))):
        out = tmp_path / f"map-{prior}.json"
        result = invoke("infer", "corridor", "--demos", one_episode, "--method", "map", "--starts", "1",
                        "--prior", prior, "--out", out)
        ok(result)
        assert f"note: prior ({prior}): {text}" in " ".join(result.stderr.split())
        settings = load(out)["settings"]
        assert settings["prior"] == prior and settings["prior_text"] == text


# ----------------------------------------------------------------------------- inputs are never outputs
@pytest.mark.parametrize("command", ["infer-demos", "infer-map", "infer-toml", "simulate-mdp",
                                     "render-demos", "export-map"])
def test_out_that_is_an_input_is_refused_even_with_force(command, one_episode, tmp_path):
    demos = tmp_path / "demos.csv"
    demos.write_bytes(one_episode.read_bytes())
    mymap = tmp_path / "mymap.txt"
    mymap.write_text("S....\n.#..G\n", encoding="utf-8")
    toml = tmp_path / "mymap.toml"
    toml.write_text("goal_bonus = 5.0\n", encoding="utf-8")
    npz = tmp_path / "task.npz"
    ok(invoke("export-mdp", "corridor", "--out", npz))
    mdemos = tmp_path / "mdemos.csv"
    ok(invoke("simulate", mymap, "--theta", "1,0,0,0,0", "--beta", "0.1", "--out", mdemos))
    args, target = {
        "infer-demos": (["infer", "corridor", "--demos", demos, "--out", demos], demos),
        "infer-map": (["infer", mymap, "--demos", mdemos, "--out", mymap], mymap),
        "infer-toml": (["infer", mymap, "--demos", mdemos, "--out", toml], toml),
        "simulate-mdp": (["simulate", "--mdp", npz, "--theta", "1,0,0,0,0", "--beta", "1",
                          "--out", npz], npz),
        "render-demos": (["render", mymap, "--demos", mdemos, "--out", tmp_path / "." / "mdemos.csv"],
                         mdemos),
        "export-map": (["export-mdp", mymap, "--out", mymap], mymap),
    }[command]
    before = snapshot(target)
    assert_input_error(invoke(*args, "--force"), "is one of this command's inputs")
    assert snapshot(target) == before


def test_result_files_get_the_mode_of_other_outputs(one_episode, tmp_path):
    result, demos = tmp_path / "r.json", tmp_path / "d.csv"
    ok(invoke("infer", "corridor", "--demos", one_episode, "--out", result))
    ok(invoke("simulate", "corridor", "--theta", "1,0,0,0,0", "--beta", "1", "--out", demos))
    mode = stat.S_IMODE(os.stat(result).st_mode)
    assert mode == stat.S_IMODE(os.stat(demos).st_mode)
    assert mode & stat.S_IRGRP  # not private to the owner (mkstemp's 0600) under the usual umask


# ----------------------------------------------------------------------------- options that do not apply
@pytest.mark.parametrize("method,option,value,owner", [
    ("map", "--per-action", None, "discrete"),
    ("map", "--iterations", "10", "birl"),
    ("nuts", "--starts", "2", "map"),
    ("discrete", "--chains", "2", "nuts"),
    ("birl", "--betas", "0.1,1", "discrete"),
])
def test_options_of_another_method_are_refused(method, option, value, owner, one_episode, tmp_path):
    given = [option] if value is None else [option, value]
    out = tmp_path / "r.json"
    assert_input_error(invoke("infer", "corridor", "--demos", one_episode, "--method", method, *given,
                              "--out", out), f"{option} applies only to --method {owner}")
    assert not out.exists()


@pytest.mark.parametrize("extra,fragment", [
    (["--delta", "0.3"], "--delta must divide 1"),
    (["--delta", "-1"], "--delta must be"),
    (["--beta-step", "20"], "--beta-step 20 leaves a single β"),
    (["--variant", "cube"], "--variant must be one of"),
])
def test_birl_option_errors_name_the_flag(extra, fragment, one_episode, tmp_path):
    assert_input_error(invoke("infer", "corridor", "--demos", one_episode, "--method", "birl", *extra,
                              "--out", tmp_path / "r.json"), fragment)


# ----------------------------------------------------------------------------- rough edges
def test_notes_go_to_stderr(one_episode, tmp_path):
    result = invoke("infer", "corridor", "--demos", one_episode, "--sample-thetas", "500",
                    "--out", tmp_path / "r.json")
    ok(result)
    assert "note: --sample-thetas 500 exceeds" in result.stderr
    assert "directions of --thetas paper-real; using all of them" in result.stderr  # the default, by name
    assert "note:" not in result.stdout


@pytest.mark.slow
def test_demo_on_a_map_does_not_collide_with_the_random_map(tmp_path):
    ok(invoke("demo", "--seed", 0, "--episodes", 2, "--k", 2, "--out", tmp_path))
    ok(invoke("demo", "--map", "corridor", "--seed", 0, "--episodes", 2, "--k", 2, "--out", tmp_path))
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["demo-corridor-seed0.png", "demo-seed0.png", "result-corridor-seed0.json",
                     "result-seed0.json"]
    assert load(tmp_path / "result-corridor-seed0.json")["settings"]["map"] == "bundled:corridor"


@pytest.mark.parametrize("command", ["infer", "demo", "simulate", "render", "export-mdp"])
def test_flags_show_no_bool_metavar(command):
    text = invoke(command, "--help").output
    assert "<bool>" not in text
    assert "--no-force" not in text and "--force" in text


def test_seed_help_covers_every_method():
    text = " ".join(invoke("infer", "--help").output.replace("│", " ").split())
    assert "--sample-thetas, and the chains and starts of birl, map and nuts" in text


@pytest.mark.parametrize("module", ["expertise_irl", "expertise_irl.cli"])
def test_commands_that_do_not_solve_do_not_import_jax(module):
    heavy = ("jax", "numpyro", "matplotlib")
    code = f"import sys, {module}; print(sorted(m for m in {heavy!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_maps_and_help_do_not_import_jax():
    code = ("import sys\nfrom expertise_irl.cli import app\nfrom typer.testing import CliRunner\n"
            "r = CliRunner()\nassert r.invoke(app, ['maps']).exit_code == 0\n"
            "assert r.invoke(app, ['infer', '--help']).exit_code == 0\nprint('jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


# ----------------------------------------------------------------------------- API
def test_continuous_methods_are_importable_from_the_top_level():
    import expertise_irl as ei
    from expertise_irl.inference import birl, gradient, nuts

    assert ei.extended_birl is birl.extended_birl
    assert ei.map_estimate is gradient.map_estimate
    assert ei.nuts_posterior is nuts.nuts_posterior
    assert set(ei.__all__) <= set(dir(ei)) | {"__version__"}
    for name in ei.__all__:
        assert getattr(ei, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        ei.nope  # noqa: B018


def test_progress_callbacks_reach_the_end():
    import expertise_irl as ei

    mdp = ei.load_bundled("corridor").to_mdp()
    trajs = ei.simulate(mdp, np.array([0.6, 0.4, 0, 0, 0]), 0.5, 2, np.random.default_rng(0))
    seen = {"birl": [], "map": []}
    ei.extended_birl(mdp, trajs, n_iter=250, rng=0, progress=lambda d, t: seen["birl"].append((d, t)))
    ei.map_estimate(mdp, trajs, n_starts=2, rng=np.random.default_rng(0),
                    progress=lambda d, t: seen["map"].append((d, t)))
    assert seen["birl"][-1] == (250, 250) and 50 <= len(seen["birl"]) <= 126
    assert [d for d, _ in seen["birl"]] == sorted(d for d, _ in seen["birl"])
    assert seen["map"] == [(1, 2), (2, 2)]


def test_a_non_finite_statistic_becomes_null_with_a_reason():
    from expertise_irl.results import continuous_result

    out = {"beta_hat": 1.0, "theta_hat": [1.0, 0.0], "diagnostics": {"r_hat": {"beta": float("nan")},
                                                                     "warnings": []}}
    doc = continuous_result(out, method="nuts", feature_names=("length", "road"), settings={}, data={},
                            samples_path=None)
    assert doc["diagnostics"]["r_hat"]["beta"] is None
    assert "diagnostics.r_hat.beta" in doc["diagnostics"]["unavailable"]
    json.dumps(doc, allow_nan=False)  # strict JSON now

