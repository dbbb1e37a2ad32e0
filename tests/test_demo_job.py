"""Tests for experiments/demo.py: the ``demo`` job (simulate one person, infer, report)."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.experiments.demo import DEFAULT_EPISODES, DEFAULT_K, run_demo
from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, expertise_group, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.metrics import cosine_similarity, policy_regret

SUMMARY_KEYS = {
    "theta_true", "beta_true", "group_true", "theta_hat", "beta_hat", "group_hat",
    "truth_probability", "expertise_distance", "cosine_similarity", "policy_regret",
}


@pytest.fixture(scope="module")
def run():
    return run_demo(3, map_spec="corridor")


def test_deterministic_for_a_seed(run):
    again = run_demo(3, map_spec="corridor")
    assert again.summary() == run.summary()
    for k in ("episode", "step", "state", "action"):
        np.testing.assert_array_equal(getattr(again.trajectories, k), getattr(run.trajectories, k))
    np.testing.assert_array_equal(again.hypotheses.thetas, run.hypotheses.thetas)
    np.testing.assert_array_equal(again.belief.log_likelihood, run.belief.log_likelihood)


def test_different_seeds_differ(run):
    other = run_demo(4, map_spec="corridor")
    assert not np.array_equal(other.hypotheses.thetas, run.hypotheses.thetas)
    assert other.summary() != run.summary()


def test_truth_is_in_the_hypothesis_set(run):
    hyp = run.hypotheses
    assert hyp.n_theta == DEFAULT_K
    np.testing.assert_array_equal(hyp.betas, BETA_PRESETS["paper-sim"])
    grid = theta_grid(THETA_PRESETS["paper-sim"], 5)
    for t in hyp.thetas:  # Θ_k is drawn from the paper's grid, without repeats
        assert np.any(np.all(np.isclose(grid, t, atol=1e-12), axis=1))
    assert len(np.unique(np.round(hyp.thetas, 12), axis=0)) == DEFAULT_K
    h = hyp.index(run.theta_true, run.beta_true)
    assert h is not None and h == run.truth_index
    np.testing.assert_array_equal(hyp.theta[h], run.theta_true)
    assert hyp.beta[h] == run.beta_true


def test_summary_keys_and_values(run):
    s = run.summary()
    assert set(s) == SUMMARY_KEYS
    b = run.belief
    assert s["theta_true"] == run.theta_true.tolist()
    assert s["beta_true"] == run.beta_true
    assert s["group_true"] == expertise_group(run.beta_true)
    assert s["theta_hat"] == b.mean_theta.tolist()
    assert s["beta_hat"] == b.mean_beta
    assert s["group_hat"] == expertise_group(b.mean_beta)
    assert s["truth_probability"] == b.probabilities[run.truth_index]
    assert 0.0 <= s["truth_probability"] <= 1.0


def test_metrics_consistent_with_belief(run):
    b = run.belief
    m = run.metrics
    assert m["expertise_distance"] == pytest.approx(abs(run.beta_true - b.mean_beta), abs=1e-15)
    assert m["cosine_similarity"] == pytest.approx(cosine_similarity(run.theta_true, b.mean_theta), abs=1e-15)
    assert m["policy_regret"] == pytest.approx(
        policy_regret(run.mdp, run.theta_true, run.beta_true, b.mean_theta), abs=1e-12)
    assert 0.0 < m["cosine_similarity"] <= 1.0 + 1e-12  # non-negative θ's
    assert m["policy_regret"] >= 0.0


def test_belief_is_the_posterior_of_the_demonstrations(run):
    t = run.trajectories
    assert t.n_episodes == DEFAULT_EPISODES
    assert run.belief.n_observed == len(t)
    assert np.all(run.mdp.initial_states()[0] == t.state[t.step == 0])  # corridor: one start
    fresh = DiscreteBelief.from_mdp(run.mdp, run.hypotheses).update(t)
    np.testing.assert_allclose(run.belief.probabilities, fresh.probabilities, rtol=0, atol=1e-12)


def test_options_and_progress():
    calls = []
    r = run_demo(5, map_spec="corridor", episodes=3, k=4, progress=lambda d, n: calls.append((d, n)))
    assert r.trajectories.n_episodes == 3
    assert len(r.hypotheses) == 4 * 6
    assert calls and calls[-1] == (24, 24)
    assert r.hypotheses.index(r.theta_true, r.beta_true) is not None
