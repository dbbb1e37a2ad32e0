"""Tests for experiments/demo.py: the ``demo`` job (simulate one person, infer, report)."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.experiments.demo import DEFAULT_EPISODES, DEFAULT_K, DEMO_BETAS, demo_outputs, run_demo
from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, expertise_group, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.metrics import cosine_similarity, policy_regret, return_regret

SUMMARY_KEYS = {
    "theta_true", "beta_true", "group_true", "theta_hat", "beta_hat", "group_hat",
    "truth_probability", "expertise_distance", "cosine_similarity", "policy_regret", "return_regret",
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
    mine = return_regret(run.mdp, run.theta_true, b.mean_theta)
    assert m["return_regret"] == pytest.approx(mine, abs=1e-12)
    assert m["return_regret"] >= 0.0


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


def test_the_default_person_is_an_expert_drawn_by_the_seed():
    """β* comes from the high group, by the seed; the inference still weighs all six β."""
    assert DEMO_BETAS == (0.01, 0.09)
    drawn = {run_demo(seed, map_spec="corridor", episodes=2, k=2).beta_true for seed in range(8)}
    assert drawn == set(DEMO_BETAS)


def test_the_first_figure_shows_the_method_working():
    """Seed 0, the README's figure: the person reaches the goal every time and is recovered."""
    r = run_demo(0)
    assert r.beta_true == 0.09
    assert r.outcomes() == ["goal"] * DEFAULT_EPISODES and r.cap_note() is None
    s = r.summary()
    assert s["group_hat"] == "high" and s["beta_hat"] == pytest.approx(0.09, abs=1e-6)
    assert s["cosine_similarity"] > 0.99 and s["truth_probability"] > 0.9


def test_beta_chooses_the_person_and_keeps_the_rest_of_the_seed():
    expert = run_demo(3, map_spec="corridor", episodes=3, k=4)
    novice = run_demo(3, map_spec="corridor", episodes=3, k=4, beta=10)
    assert novice.beta_true == 10.0
    np.testing.assert_array_equal(novice.theta_true, expert.theta_true)
    np.testing.assert_array_equal(novice.hypotheses.thetas, expert.hypotheses.thetas)
    assert run_demo(3, map_spec="corridor", episodes=3, k=4, beta=0.09 + 1e-12).beta_true == 0.09
    with pytest.raises(InputError, match=r"--beta 2: .*0\.01, 0\.09, 0\.5, 1, 5, 10"):
        run_demo(3, map_spec="corridor", beta=2)


def test_outputs_of_a_chosen_beta_sit_beside_the_default_ones(tmp_path):
    assert demo_outputs(tmp_path, 0) == (tmp_path / "demo-seed0.png", tmp_path / "result-seed0.json")
    assert demo_outputs(tmp_path, 0, "crossroads", 10) == (tmp_path / "demo-crossroads-seed0-beta10.png",
                                                           tmp_path / "result-crossroads-seed0-beta10.json")
    assert demo_outputs(tmp_path, 1, None, 0.5)[0].name == "demo-seed1-beta0.5.png"


def test_a_beta_outside_the_paper_s_is_refused_before_any_output(tmp_path):
    from cli_helpers import assert_input_error, invoke

    assert_input_error(invoke("demo", "--map", "corridor", "--beta", "2", "--out", tmp_path / "d"),
                       "--beta 2", "0.01, 0.09, 0.5, 1, 5, 10")
    assert not (tmp_path / "d").exists()
