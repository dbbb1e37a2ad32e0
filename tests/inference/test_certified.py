"""Certified log-likelihoods (inference.certified): the bounds hold against exact solves, and the
two-stage posterior equals a full-precision one within its stated error."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, resolve_thetas
from expertise_irl.inference.certified import (
    certified_log_likelihoods,
    data_tolerance,
    error_weight,
    state_weights,
    telescoped_log_likelihood,
)
from expertise_irl.planning.soft_vi import solve
from expertise_irl.planning.table_likelihood import log_likelihood
from expertise_irl.worlds.zones import load_bundled, parse_map

SMALL = """
S....s
S.xx..
S.xx.G
..>>>.
"""


@pytest.fixture(scope="module")
def small():
    mdp = parse_map(SMALL, name="certified").to_mdp()
    rng = np.random.default_rng(4)
    return mdp, simulate(mdp, rng.dirichlet(np.ones(mdp.n_features)), 0.7, 8, rng, max_steps=60)


@pytest.mark.parametrize("model", ["maxent", "maxent-relative", "boltzmann"])
@pytest.mark.parametrize("beta", [1e-3, 1.0, 100.0])
def test_the_bounds_hold_against_an_exact_solve(small, model, beta):
    """Solved to a loose 1e-3 nats, every hypothesis' log-likelihood lies within its certified
    interval around the exact one (solved to 1e-12): tol·Σ|w| for the models whose sum telescopes
    (far narrower than the table's 2·tol per action), 2·tol per action for ``boltzmann``."""
    mdp, trajs = small
    rng = np.random.default_rng(int(beta * 1000) % 97)
    theta = rng.dirichlet(np.ones(mdp.n_features), size=6)
    b = np.full(6, beta)
    c = certified_log_likelihoods([(mdp, [trajs])], theta, b, tol=1e-3, screen_tol=1e-3, model=model)
    exact = log_likelihood(np.asarray(solve(mdp, theta, b, tol=1e-12, model=model).log_policy),
                           trajs.state, trajs.action)
    finite = np.isfinite(exact)
    assert finite.any()
    np.testing.assert_array_equal(np.isfinite(c.log_likelihood), finite)
    assert np.all(np.abs(c.log_likelihood[finite] - exact[finite]) <= c.error[finite])
    n = len(trajs.state)
    if model == "boltzmann":
        assert c.error_weight == 2 * n
    else:
        assert c.error_weight == pytest.approx(np.abs(state_weights(mdp, [trajs])).sum())
        assert c.error_weight < 0.1 * 2 * n
    assert np.all(c.error >= 1e-3 * c.error_weight - 1e-12)


@pytest.mark.parametrize("model", ["maxent", "maxent-relative"])
@pytest.mark.parametrize("beta", [1e-3, 1.0, 100.0])
def test_the_telescoped_sum_is_exact_at_the_solution_and_moves_by_at_most_its_weights(small, model, beta):
    """At the exact values the telescoped log-likelihood equals the log-policy table's sum; values
    off by at most δ move it by at most δ·Σ|w|, and by exactly that when every state's error takes
    its weight's sign (the bound is attained, so it cannot be narrowed)."""
    mdp, trajs = small
    rng = np.random.default_rng(int(beta * 1000) % 89)
    theta = rng.dirichlet(np.ones(mdp.n_features), size=4)
    b = np.full(4, beta)
    sol = solve(mdp, theta, b, tol=1e-12, model=model)
    v = np.asarray(sol.value)
    table = log_likelihood(np.asarray(sol.log_policy), trajs.state, trajs.action)
    tele, rounding = telescoped_log_likelihood(mdp, [trajs], theta, b, v, model)
    finite = np.isfinite(table)
    assert finite.any() and np.all(rounding < 1e-6 * np.maximum(1.0, np.abs(tele)))
    F = error_weight(mdp, [trajs], model)
    atol = 4e-11 * F + rounding[finite].max()
    np.testing.assert_allclose(tele[finite], table[finite], rtol=1e-9, atol=atol)
    w = state_weights(mdp, [trajs])
    delta = 0.05
    worst, _ = telescoped_log_likelihood(mdp, [trajs], theta, b, v + delta * np.sign(w) * b[:, None], model)
    np.testing.assert_allclose(worst - tele, delta * F, rtol=1e-9)
    e = rng.uniform(-delta, delta, size=v.shape) * ~mdp.terminal
    moved, _ = telescoped_log_likelihood(mdp, [trajs], theta, b, v + e * b[:, None], model)
    assert np.all(np.abs(moved - tele) <= delta * F * (1 + 1e-9))


@pytest.fixture(scope="module")
def readme_person():
    mdp = load_bundled("crossroads").to_mdp()
    trajs = simulate(mdp, np.array([0.5, 0.5, 0, 0, 0]), 0.5, 20, np.random.default_rng(1))
    hyp = HypothesisSet(resolve_thetas("paper-real", mdp.n_features), BETA_PRESETS["paper-sim"])
    return mdp, trajs, hyp


def _posterior(ll):
    p = np.exp(ll - ll[np.isfinite(ll)].max())
    return p / p.sum()


def test_the_two_stage_posterior_equals_a_full_precision_one_within_its_bound(readme_person):
    """The README's person (947 actions) on paper-real Θ × paper-sim B (1,266 hypotheses): most
    hypotheses are eliminated at the screen, every probability is within the reported bound
    (≤ 1e-6) of a solve to 1e-10 nats without elimination, and fewer sweeps are spent than on
    one solve of the whole set to the default 1e-8."""
    mdp, trajs, hyp = readme_person
    c = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta)
    full = solve(mdp, hyp.theta, hyp.beta, tol=1e-10)
    exact = _posterior(log_likelihood(np.asarray(full.log_policy), trajs.state, trajs.action))
    mine = _posterior(c.log_likelihood)
    assert c.probability_error <= 1e-6
    assert np.max(np.abs(mine - exact)) <= c.probability_error
    assert c.eliminated.mean() > 0.5
    assert exact[c.eliminated].sum() < 1e-12
    assert c.tol == pytest.approx(data_tolerance(len(trajs.state), error_weight=c.error_weight))
    assert c.screen_tols == (c.screen_tol,) and c.screen_tol > c.tol
    plain = solve(mdp, hyp.theta, hyp.beta).iterations.sum()
    assert c.sweeps.sum() < plain
    rec = c.record()
    assert rec["eliminated"] == int(c.eliminated.sum()) and rec["probability_error"] <= 1e-6


def test_a_given_tolerance_is_kept_and_bad_settings_are_refused(readme_person):
    mdp, trajs, hyp = readme_person
    c = certified_log_likelihoods([(mdp, [trajs])], hyp.theta[:8], hyp.beta[:8], tol=1e-6)
    assert c.tol == 1e-6 and c.screen_tol >= 1e-6
    with pytest.raises(InputError, match="elimination < probability_error"):
        data_tolerance(100, probability_error=1e-13)


def test_several_screening_stages_keep_the_bound(readme_person, monkeypatch):
    """With three screening widths (30, 3, 1 nats) the survivors of each stage go on to the next:
    fewer hypotheses at each stage, every probability still within the bound of a full solve."""
    from expertise_irl.inference import certified

    mdp, trajs, hyp = readme_person
    monkeypatch.setattr(certified, "SCREEN_WIDTHS", (30.0, 3.0, 1.0))
    c = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta)
    assert len(c.screen_tols) == 3
    np.testing.assert_allclose(np.array(c.screen_tols) * c.error_weight, [30.0, 3.0, 1.0])
    full = solve(mdp, hyp.theta, hyp.beta, tol=1e-10)
    exact = _posterior(log_likelihood(np.asarray(full.log_policy), trajs.state, trajs.action))
    assert np.max(np.abs(_posterior(c.log_likelihood) - exact)) <= c.probability_error <= 1e-6
    assert exact[c.eliminated].sum() < 1e-12
    one = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta, screen_tol=c.screen_tols[0])
    assert c.sweeps[c.eliminated & one.eliminated].sum() == one.sweeps[c.eliminated & one.eliminated].sum()


def test_the_survivors_finish_by_newton_on_a_large_map_with_the_same_bound(small, monkeypatch):
    """Where the map counts as large, the finish takes Newton steps (recorded) and every
    log-likelihood still lies within its certified interval around the exact one."""
    from expertise_irl.planning import soft_vi

    mdp, trajs = small
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_STATES", 1)
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_GAMMA", 0.0)
    monkeypatch.setattr(soft_vi, "_backend", lambda: "cpu")
    rng = np.random.default_rng(11)
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=12), np.exp(rng.uniform(-2, 1, 12))
    c = certified_log_likelihoods([(mdp, [trajs])], theta, beta)
    exact = log_likelihood(np.asarray(solve(mdp, theta, beta, tol=1e-12, newton=False).log_policy),
                           trajs.state, trajs.action)
    finite = np.isfinite(exact)
    assert np.all(np.abs(c.log_likelihood[finite] - exact[finite]) <= c.error[finite])
    assert c.newton_steps[~c.eliminated].min() >= 1 and c.record()["newton_steps"] >= 1


def test_demonstrations_without_moves_still_get_a_useful_tolerance(small):
    """No observed action: every log-likelihood is 0 with no error, and the values are solved to the
    tolerance of one action's bound, not to an unbounded one."""
    from expertise_irl.demos.trajectories import Trajectories

    mdp, _ = small
    none = np.zeros(0, np.int64)
    empty = Trajectories(none, none, none, none)
    theta = np.full((1, mdp.n_features), 1.0 / mdp.n_features)
    c = certified_log_likelihoods([(mdp, [empty])], theta, np.array([1.0]))
    assert c.error_weight == 0 and np.all(c.log_likelihood == 0) and np.all(c.error <= 1e-12)
    assert c.tol == pytest.approx(data_tolerance(0, error_weight=2.0)) and c.tol < 1e-6


@pytest.mark.parametrize("method", ["sweeps", "levels"])
def test_eliminating_in_the_sweeps_keeps_the_bound_and_saves_sweeps(readme_person, method, monkeypatch):
    """The first stage's sweeps stop most hypotheses as soon as their elimination is certain
    (planning.screening): every probability stays within the bound of a full-precision solve,
    every hypothesis stopped there is negligible, and fewer sweeps are spent than without."""
    from expertise_irl.inference import certified

    mdp, trajs, hyp = readme_person
    c = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta, method=method)
    full = solve(mdp, hyp.theta, hyp.beta, tol=1e-10)
    exact_ll = log_likelihood(np.asarray(full.log_policy), trajs.state, trajs.action)
    exact = _posterior(exact_ll)
    assert np.max(np.abs(_posterior(c.log_likelihood) - exact)) <= c.probability_error <= 1e-6
    stopped = c.stopped_tol > 0
    assert c.record()["eliminated_in_sweeps"] == stopped.sum() >= c.eliminated.sum() // 2
    assert np.all(c.eliminated[stopped])
    assert np.all(exact_ll[stopped] < exact_ll.max() + np.log(1e-12 / len(hyp.beta)))
    monkeypatch.setattr(certified._Stages, "gate", lambda self, *args: None)
    off = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta, method=method)
    assert off.record()["eliminated_in_sweeps"] == 0
    assert c.sweeps.sum() < off.sweeps.sum()


def test_a_prior_that_favours_a_poor_hypothesis_keeps_it(small):
    """The gate counts the log prior weights: a hypothesis over 100 nats below the best one in
    likelihood, given a prior weight that brings it to 10 nats below (elimination needs 32), is not
    eliminated, and the posterior with that prior matches a full-precision one."""
    mdp, trajs = small
    rng = np.random.default_rng(21)
    H = 32
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-3, 2, H))
    exact_ll = log_likelihood(np.asarray(solve(mdp, theta, beta, tol=1e-12).log_policy), trajs.state,
                              trajs.action)
    poor = int(np.argsort(exact_ll)[H // 4])
    assert exact_ll.max() - exact_ll[poor] > 100
    prior = np.zeros(H)
    prior[poor] = exact_ll.max() - exact_ll[poor] - 10.0
    c = certified_log_likelihoods([(mdp, [trajs])], theta, beta, log_prior=prior)
    assert not c.eliminated[poor] and c.eliminated.any()
    exact = _posterior(exact_ll + prior)
    assert np.max(np.abs(_posterior(c.log_likelihood + prior) - exact)) <= c.probability_error
