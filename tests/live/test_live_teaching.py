"""``live --model pedagogical``: a simulated teacher driven through the session on the bundled
crossroads map ends with the batch teaching posterior of its pairs in ``result.json``; a restart
replays to the same record; the command's options and what it refuses."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok

from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.inference import pedagogical as P
from expertise_irl.inference.methods import DiscreteOptions
from expertise_irl.live.session import open_session
from expertise_irl.mdp import ACTION_NAMES
from expertise_irl.worlds.maps import resolve_world

# The session adds each pair's [λ, h] log-likelihood row as it comes; the batch posterior sums
# counts × log-policies over the states: the same float64 terms in another order. The
# log-likelihoods reach some thousand nats (round-off ~1e-13), so every entry of the record, a
# probability, a mean or a log Bayes factor, agrees far below 1e-9.
TOL = 1e-9
SETTINGS = {"command": "live", "mdp_digest": "sha256:crossroads", "model": "pedagogical"}


def drive_teacher(session, teacher, rng, n_moves=None) -> None:
    """One episode of the teacher from the session's start, move by move through ``handle``
    (``n_moves``: stop after that many, mid-episode)."""
    tr = simulate(session.mdp, None, None, 1, rng, starts=[session.position], max_steps=400,
                  log_policy=teacher)
    actions = tr.action.tolist()[:n_moves]
    for i, a in enumerate(actions):
        (r,) = session.handle({"type": "move", "action": ACTION_NAMES[a]})
        assert r["type"] == "state", r
        assert r["teaching"]["verdict"] in ("teaching", "doing", "undecided")
        assert r["event"] == ("episode_done" if n_moves is None and i + 1 == len(actions) else "moved")


def batch_record(session, demos):
    """The batch teaching posterior of the recorded pairs and its record, from the session's one
    maxent solve of the set."""
    lp = np.asarray(session.estimator.belief().log_policy)
    post = P.teaching_posterior(lp, session.estimator.hypotheses, demos, lambdas=P.LAMBDAS)
    return post, post.record(lp), lp


def assert_record(got: dict, want: dict) -> None:
    assert got.keys() == want.keys()
    assert (got["verdict"], got["reading"]) == (want["verdict"], want["reading"])
    for k in ("log_bayes_factor", "p_teaching", "lambda_hat", "lambda_interval", "lambda_map",
              "lambda_probabilities", "lambda_prior", "lambdas", "beta_hat_maxent", "theta_hat_maxent"):
        np.testing.assert_allclose(got[k], want[k], rtol=0, atol=TOL, err_msg=k)


@pytest.mark.slow
def test_a_teacher_driven_live_ends_with_the_batch_teaching_posterior_and_resumes(tmp_path):
    """Two episodes and a third cut short: result.json's teaching record is the batch posterior of
    the recorded pairs, the page's estimate is its λ-marginal belief, a restart replays both, and
    ``infer --model pedagogical`` on the recording gives the same record."""
    zone_map = resolve_world("crossroads")
    mdp = zone_map.to_mdp()
    hyp = DiscreteOptions(refine=False).hypotheses(mdp.n_features)  # paper-real Θ × paper-sim B
    session = open_session(zone_map, hyp, tmp_path, settings=SETTINGS, model="pedagogical", n_samples=8)
    assert session.teaching and session.start.how == "active"
    lp = np.asarray(session.estimator.belief().log_policy)
    theta = hyp.theta[int(np.argmax(hyp.theta[:, 0] - hyp.theta[:, 1]))]  # off the middle of the set
    teacher = P.teacher_log_policy(mdp, theta, 0.5, 0.3, P.observer(hyp, lp))
    rng = np.random.default_rng(11)
    for episode in range(2):
        drive_teacher(session, teacher, rng)
        doc = json.loads((tmp_path / "result.json").read_text())  # rebuilt after every episode
        demos = read_demos_csv(tmp_path / "demos.csv", mdp)
        assert demos.n_episodes == episode + 1 and doc["data"]["actions"] == len(demos)
        post, want, _ = batch_record(session, demos)
        assert_record(doc["teaching"], want)
        belief = post.belief(lp)  # the estimate shown is the λ-marginal posterior over the set
        assert doc["beta_hat"] == pytest.approx(belief.mean_beta, abs=TOL)
        assert session.estimator.estimate.entropy == pytest.approx(belief.entropy, abs=TOL)
        assert doc["settings"] == SETTINGS
    drive_teacher(session, teacher, rng, n_moves=3)  # stopped mid-episode
    demos = read_demos_csv(tmp_path / "demos.csv", mdp)
    _, want, _ = batch_record(session, demos)
    assert_record(session.estimator.record(), want)
    shown = (list(session.history_beta), list(session.history_entropy), session.position)
    del session
    again = open_session(zone_map, hyp, tmp_path, settings=SETTINGS, model="pedagogical", n_samples=8)
    assert again.start.how == "resumed" and again.position == shown[2]
    assert_record(again.estimator.record(), want)
    assert_record(json.loads((tmp_path / "result.json").read_text())["teaching"], want)
    np.testing.assert_allclose(again.history_beta, shown[0], rtol=0, atol=1e-12)  # what the page showed
    np.testing.assert_allclose(again.history_entropy, shown[1], rtol=0, atol=1e-12)
    inferred = tmp_path / "infer.json"  # the batch command on the same recording
    ok(invoke("infer", "crossroads", "--demos", tmp_path / "demos.csv", "--model", "pedagogical",
              "--no-refine", "--out", inferred))
    assert_record(json.loads(inferred.read_text())["teaching"], want)


def test_pedagogical_takes_a_fixed_set_and_one_beta(tmp_path):
    zone_map = resolve_world("corridor")
    hyp = DiscreteOptions(refine=False).hypotheses(zone_map.to_mdp().n_features)
    for kw, word in (({"refine": DiscreteOptions()}, "refine"), ({"expertise": "changing"}, "expertise"),
                     ({"model": "boltzmann"}, "model")):
        with pytest.raises(InputError, match=word):
            open_session(zone_map, hyp, tmp_path / "x", **{"model": "pedagogical", **kw})
    with pytest.raises(InputError, match="lambdas"):
        open_session(zone_map, hyp, tmp_path / "x", lambdas="0,1")  # maxent has no λ
    assert not (tmp_path / "x").exists()  # refused before anything is written


# ------------------------------------------------------------------------- the command
@pytest.mark.parametrize("args, fragments", [
    (("--model", "pedagogical", "--refine"), ("--refine", "--model pedagogical")),
    (("--model", "pedagogical", "--expertise", "changing"), ("--expertise", "--model pedagogical")),
    (("--model", "boltzmann"), ("--model", "maxent, pedagogical")),
    (("--lambdas", "0,1"), ("--lambdas", "--model pedagogical")),
    (("--model", "pedagogical", "--lambdas", "0.1,1"), ("--lambdas",)),
    (("--model", "pedagogical", "--lambdas", "0,x"), ("--lambdas",)),
])
def test_live_command_refuses_in_one_line(tmp_path, args, fragments):
    assert_input_error(invoke("live", "corridor", *args, "--out", tmp_path / "rec", "--port", 0), *fragments)
    assert not (tmp_path / "rec").exists()


def test_live_command_with_the_teaching_model(tmp_path, monkeypatch):
    """No set named: the fixed default set, never refined; the settings name the model and the λ grid
    (sorted); result.json carries the teaching record from the start."""
    import expertise_irl.live.server as server

    monkeypatch.setattr(server, "serve", lambda session, sock, on_ready: (
        on_ready(server.url_of(sock)), sock.close()))
    out = tmp_path / "teaching"
    r = invoke("live", "corridor", "--model", "pedagogical", "--lambdas", "0.5,0", "--out", out, "--port", 0)
    ok(r)
    assert "teaching model over 2 values of λ" in r.stdout and "refined" not in r.stdout
    doc = json.loads((out / "result.json").read_text())
    s = doc["settings"]
    assert (s["hypotheses"], s["thetas"], s["betas"]) == ("fixed", "paper-real", "paper-sim")
    assert s["model"] == "pedagogical" and s["lambdas"] == [0.0, 0.5]
    assert doc["teaching"]["verdict"] == "undecided" and doc["teaching"]["lambdas"] == [0.0, 0.5]
    assert doc["teaching"]["log_bayes_factor"] == 0.0  # no action yet
    r = invoke("live", "corridor", "--thetas", "0,1", "--out", tmp_path / "maxent", "--port", 0)
    ok(r)
    doc = json.loads((tmp_path / "maxent" / "result.json").read_text())
    assert doc["settings"]["model"] == "maxent" and "teaching" not in doc and "lambdas" not in doc["settings"]
