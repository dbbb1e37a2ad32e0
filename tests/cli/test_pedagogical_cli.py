"""``--model pedagogical`` on the command line: ``simulate --lambda`` and ``infer --lambdas``, and what
they refuse (exit 2, one line naming the flag)."""

from __future__ import annotations

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, load, ok

from expertise_irl import infer
from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.demos.simulation import simulate_teacher
from expertise_irl.hypotheses import HypothesisSet, resolve_betas, resolve_thetas
from expertise_irl.worlds.maps import resolve_world

#: A small observer's set and λ grid, so that the commands solve little.
OBSERVER = ("--observer-thetas", "0,1", "--observer-betas", "0.1,1")
SET = ("--thetas", "0,1", "--betas", "0.1,1")
THETA = "0.4,0.3,0.1,0.1,0.1"


@pytest.fixture(scope="module")
def teacher_csv(tmp_path_factory):
    out = tmp_path_factory.mktemp("teach") / "t.csv"
    res = invoke("simulate", "crossroads", "--theta", THETA, "--beta", "0.2", "--model", "pedagogical",
                 "--lambda", "0.5", *OBSERVER, "--episodes", "6", "--max-steps", "80", "--seed", "3",
                 "--out", out)
    ok(res)
    assert "model pedagogical, λ=0.5, observer 0,1 Θ × 0.1,1 B: 62 hypotheses" in res.stdout
    return out


def test_simulate_writes_the_teachers_episodes(teacher_csv):
    """The CSV holds :func:`simulate_teacher`'s episodes for the same seed, θ*, β*, λ and observer."""
    mdp = resolve_world("crossroads").to_mdp()
    hyp = HypothesisSet(resolve_thetas("0,1", mdp.n_features), resolve_betas("0.1,1"))
    want = simulate_teacher(mdp, np.array([0.4, 0.3, 0.1, 0.1, 0.1]), 0.2, 0.5, 6, np.random.default_rng(3),
                            observer=hyp, max_steps=80)
    got = read_demos_csv(teacher_csv, mdp)
    np.testing.assert_array_equal(got.state, want.state)
    np.testing.assert_array_equal(got.action, want.action)


def test_infer_reads_teaching_and_says_so(teacher_csv, tmp_path):
    """The result's ``teaching`` is the Python API's for the same inputs, and one line tells its reading
    with λ̂ and its interval."""
    out = tmp_path / "r.json"
    res = invoke("infer", "crossroads", "--demos", teacher_csv, "--model", "pedagogical", *SET,
                 "--lambdas", "0,0.1,1", "--check", "off", "--out", out)
    ok(res)
    doc = load(out)
    want = infer("crossroads", teacher_csv, model="pedagogical", thetas="0,1", betas="0.1,1",
                 lambdas="0,0.1,1", check="off")
    assert doc["teaching"] == want.teaching.to_json()
    assert doc["settings"]["model"] == "pedagogical" and doc["settings"]["lambdas"] == [0.0, 0.1, 1.0]
    t = want.teaching
    line = [ln for ln in res.stdout.splitlines() if ln.startswith("teaching: ")]
    assert line == [f"teaching: {t.reading}; λ̂ = {t.lambda_hat:.3g}, 90% credible interval "
                    f"[{t.lambda_interval[0]:.3g}, {t.lambda_interval[1]:.3g}]"]


@pytest.mark.parametrize(("args", "fragments"), [
    (("--model", "pedagogical", "--lambdas", "0.1,1"), ("--lambdas", "must hold 0")),
    (("--model", "pedagogical", "--lambdas", "0,x"), ("--lambdas", "comma-separated numbers")),
    (("--lambdas", "0,0.1"), ("--lambdas", "--model pedagogical")),
    (("--model", "pedagogical", "--method", "map"), ("--model pedagogical", "--method discrete")),
    (("--model", "pedagogical", "--per-action"), ("--per-action", "--model pedagogical")),
    (("--model", "pedagogical", "--expertise", "changing"), ("--expertise changing", "--model pedagogical")),
    (("--model", "pedagogical", "--check", "full"), ("--check full", "--model pedagogical")),
])
def test_infer_refuses_in_one_line(teacher_csv, tmp_path, args, fragments):
    out = tmp_path / "r.json"
    assert_input_error(invoke("infer", "crossroads", "--demos", teacher_csv, *args, "--out", out), *fragments)
    assert not out.exists()


@pytest.mark.parametrize(("args", "fragments"), [
    (("--lambda", "0.3"), ("--lambda applies only to --model pedagogical",)),
    (("--observer-betas", "0.1"), ("--observer-betas applies only to --model pedagogical",)),
    (("--model", "pedagogical", "--lambda", "-1"), ("--lambda must be a number from 0 to 1000",)),
    (("--model", "pedagogical", "--observer-thetas", "x"), ("--observer-thetas",)),
    (("--model", "softmax"), ("--model must be one of", "pedagogical")),
])
def test_simulate_refuses_in_one_line(tmp_path, args, fragments):
    out = tmp_path / "d.csv"
    res = invoke("simulate", "crossroads", "--theta", THETA, "--beta", "0.2", *args, "--out", out)
    assert_input_error(res, *fragments)
    assert not out.exists()


def test_commands_that_solve_a_model_refuse_pedagogical(tmp_path):
    assert_input_error(invoke("demo", "--model", "pedagogical", "--out", tmp_path),
                       "--model pedagogical has no Bellman backup")
