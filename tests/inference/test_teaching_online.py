"""TeachingOnlineEstimator: after every action, the batch teaching posterior of the same pairs
(its λ × hypothesis log-likelihoods, its λ-marginal belief and its record); undo and restore;
what it refuses."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference import pedagogical as P
from expertise_irl.inference.teaching_online import TeachingOnlineEstimator
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.zones import load_bundled

# Both sides add the same float64 log-probabilities, in another order (here one pair at a time,
# there counts × log-policies summed over the states): the log-likelihoods of the unlikely
# hypotheses reach some thousand nats, whose round-off (~1e-16 relative) stays below 1e-9 absolute,
# and the record's probabilities and means are far closer.
TOL = 1e-9
LAMBDAS = (0.0, 0.03, 0.3, 1.0)


@pytest.fixture(scope="module")
def setup():
    mdp = load_bundled("crossroads").to_mdp()
    hyp = HypothesisSet(theta_grid((0.0, 0.5, 1.0), 5)[::12], BETA_PRESETS["paper-sim"])  # 20 × 6
    lp = np.asarray(solve(mdp, hyp.theta, hyp.beta, tol=1e-8).log_policy)
    teacher = P.teacher_log_policy(mdp, hyp.theta[5], 0.5, 0.3, P.observer(hyp, lp))
    trajs = simulate(mdp, hyp.theta[5], 0.5, 3, np.random.default_rng(4), max_steps=40, log_policy=teacher)
    return mdp, hyp, lp, trajs


def head(trajs: Trajectories, n: int) -> Trajectories:
    return Trajectories(trajs.episode[:n], trajs.step[:n], trajs.state[:n], trajs.action[:n])


def pair(trajs: Trajectories, i: int) -> Trajectories:
    return Trajectories(*(x[i:i + 1] for x in (trajs.episode, trajs.step, trajs.state, trajs.action)))


def assert_batch(est: TeachingOnlineEstimator, lp, hyp, trajs) -> None:
    """The estimator equals the batch teaching posterior of ``trajs`` (the pairs it observed)."""
    post = P.teaching_posterior(lp, hyp, trajs, lambdas=LAMBDAS)
    np.testing.assert_allclose(est.posterior().log_likelihood, post.log_likelihood, rtol=0, atol=TOL)
    want = post.belief(lp)
    assert est.estimate.beta_hat == pytest.approx(want.mean_beta, abs=TOL)
    np.testing.assert_allclose(est.estimate.theta_hat, want.mean_theta, atol=TOL)
    assert est.estimate.entropy == pytest.approx(want.entropy, abs=TOL)
    got, ref = est.record(), post.record(lp)
    assert got.keys() == ref.keys() and got["verdict"] == ref["verdict"] and got["reading"] == ref["reading"]
    for k in ("log_bayes_factor", "p_teaching", "lambda_hat", "lambda_interval", "lambda_probabilities",
              "beta_hat_maxent", "theta_hat_maxent"):
        np.testing.assert_allclose(got[k], ref[k], rtol=0, atol=TOL, err_msg=k)


def test_every_action_gives_the_batch_teaching_posterior(setup):
    mdp, hyp, lp, trajs = setup
    assert trajs.n_episodes == 3 and len(trajs) >= 10
    est = TeachingOnlineEstimator(mdp, hyp, lp, lambdas=LAMBDAS)
    assert est.record()["verdict"] == "undecided" and est.estimate.beta_hat == pytest.approx(hyp.betas.mean())
    for n in range(1, len(trajs) + 1):
        e = est.feed(pair(trajs, n - 1))
        assert e.n_observed == n
        if n % 3 == 0 or n == len(trajs):
            assert_batch(est, lp, hyp, head(trajs, n))
    # λ > 0 changes the estimate: it is not the maxent posterior of the same pairs
    maxent = P.teaching_posterior(lp, hyp, trajs, lambdas=LAMBDAS).belief(lp, doer=True)
    assert abs(est.estimate.beta_hat - maxent.mean_beta) > 1e-6


def test_undo_and_restore_give_the_batch_posterior_of_what_remains(setup, tmp_path):
    mdp, hyp, lp, trajs = setup
    est = TeachingOnlineEstimator(mdp, hyp, lp, lambdas=LAMBDAS)
    est.feed(trajs)
    snap = est.snapshot()
    est.undo()
    est.undo()
    assert_batch(est, lp, hyp, head(trajs, len(trajs) - 2))
    est.save(tmp_path / "snap.json")
    other = TeachingOnlineEstimator(mdp, hyp, lp, lambdas=LAMBDAS)
    other.feed(head(trajs, 3))
    other.restore(snap)  # starts from nothing, not from the three pairs it held
    assert_batch(other, lp, hyp, trajs)
    other.restore(tmp_path / "snap.json")
    assert_batch(other, lp, hyp, head(trajs, len(trajs) - 2))
    kept = other.posterior().log_likelihood
    with pytest.raises(InputError, match="snapshot"):
        other.restore({"episode": [0], "step": [0], "state": [0], "action": [0], "episode_open": True,
                       "n_hypotheses": 1, "n_states": mdp.n_states, "n_actions": mdp.n_actions})
    np.testing.assert_array_equal(other.posterior().log_likelihood, kept)  # a refused restore changes nothing


def test_refuses_other_models_bad_grids_and_impossible_pairs(setup):
    mdp, hyp, lp, _ = setup
    with pytest.raises(InputError, match="--lambdas"):
        TeachingOnlineEstimator(mdp, hyp, lp, lambdas=(0.1, 1.0))  # no doer
    with pytest.raises(InputError, match="boltzmann"):
        TeachingOnlineEstimator.from_mdp(mdp, hyp, model="boltzmann")
    s = int(np.flatnonzero(~mdp.terminal & (mdp.next_state >= 0).all(axis=1))[0])
    table = lp.copy()
    table[:, s, 0] = -np.inf  # no hypothesis takes action 0 there
    table[:, s, 1:] = np.log(1 / 3)
    est = TeachingOnlineEstimator(mdp, hyp, table, lambdas=LAMBDAS)
    with pytest.raises(InputError, match="impossible under every hypothesis"):
        est.observe(s, 0)
    assert est.n_observed == 0 and not est.posterior().log_likelihood.any()
