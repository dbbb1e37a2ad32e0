"""Newton's method (planning.newton) finishing soft value iteration: it reaches the solution from a
rough solve under both soft models and every β, and a solve that uses it keeps the guarantee on V/β."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.planning import newton, soft_vi
from expertise_irl.planning.newton import _Walk
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.floorplans import generate_floor_plan


@pytest.fixture(scope="module")
def plan():
    mdp = generate_floor_plan(16, seed=1).to_mdp()
    theta = np.random.default_rng(0).dirichlet(np.ones(mdp.n_features), size=6)
    return mdp, theta


@pytest.mark.parametrize("model", ["maxent", "maxent-relative"])
@pytest.mark.parametrize("beta", [1e-3, 1.0, 100.0])
def test_newton_reaches_the_solution_from_a_rough_solve(plan, model, beta):
    """From values within 0.1 nats, the chord and Newton steps land within 1e-9 nats of a solve to
    1e-12 (or at the values' floating-point floor) in a few steps; where the rough values were
    further off, they move by orders of magnitude towards the solution."""
    mdp, theta = plan
    b = np.full(len(theta), beta)
    rough = solve(mdp, theta, b, tol=0.1, model=model, newton=False)
    exact = solve(mdp, theta, b, tol=1e-12, model=model, newton=False).value
    values, steps = newton.newton_values(mdp, theta, b, rough.value, 1e-10, model=model)
    err = np.max(np.abs(values - exact), axis=1) / beta
    before = np.max(np.abs(rough.value - exact), axis=1) / beta
    floor = 64 * np.finfo(float).eps * np.max(np.abs(exact), axis=1) / beta / (1 - mdp.gamma)
    assert np.all(err <= np.maximum(1e-9, floor))
    assert np.all(steps <= 6)
    moved = before > 1e-6
    assert np.all(err[moved] <= 1e-3 * before[moved])


@pytest.mark.parametrize("model", ["maxent", "maxent-relative"])
def test_a_solve_that_finishes_by_newton_keeps_the_guarantee(plan, model):
    mdp, theta = plan
    b = np.array([0.1, 0.3, 1.0, 3.0, 10.0, 0.3])
    exact = solve(mdp, theta, b, tol=1e-12, model=model, newton=False)
    sol = solve(mdp, theta, b, tol=1e-9, model=model, newton=True)
    assert sol.newton_steps is not None and sol.newton_steps.shape == (6,) and sol.newton_steps.max() >= 1
    assert np.max(np.abs(sol.value - exact.value) / b[:, None]) <= 1e-9 + 1e-12
    fin = np.isfinite(exact.log_policy)
    np.testing.assert_array_equal(np.isfinite(sol.log_policy), fin)
    assert np.max(np.abs(sol.log_policy[fin] - exact.log_policy[fin])) <= 2.1e-9
    assert solve(mdp, theta, b, tol=1e-9, model=model, newton=False).newton_steps is None


def test_newton_is_used_by_default_only_where_it_applies(plan, monkeypatch):
    """Large maps on a CPU, soft models in float64, tolerances below NEWTON_BELOW; never for
    ``boltzmann`` (a hard max has no smooth Jacobian), on a GPU, or with ``newton=False``."""
    mdp, _ = plan
    uses = soft_vi._uses_newton
    monkeypatch.setattr(soft_vi, "_backend", lambda: "cpu")
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_STATES", mdp.n_states + 1)
    assert not uses(mdp, "maxent", "float64", 1e-8, None)  # a small map
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_GAMMA", mdp.gamma + 1e-3)
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_STATES", mdp.n_states)
    assert not uses(mdp, "maxent", "float64", 1e-8, None)  # sweeps contract fast enough
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_GAMMA", mdp.gamma)
    assert uses(mdp, "maxent", "float64", 1e-8, None) and uses(mdp, "maxent-relative", "float64", 1e-8, None)
    assert not uses(mdp, "boltzmann", "float64", 1e-8, None)
    assert not uses(mdp, "boltzmann", "float64", 1e-8, True)
    assert not uses(mdp, "maxent", "float32", 1e-8, None)
    assert not uses(mdp, "maxent", "float64", soft_vi.NEWTON_BELOW, None)
    assert not uses(mdp, "maxent", "float64", 1e-8, False)
    monkeypatch.setattr(soft_vi, "_backend", lambda: "gpu")
    assert not uses(mdp, "maxent", "float64", 1e-8, None) and uses(mdp, "maxent", "float64", 1e-8, True)
    sol = solve(mdp, np.array([[0.2, 0.3, 0.5]]), np.array([0.5]), model="boltzmann", newton=True)
    assert sol.newton_steps is None


def test_a_chord_that_gets_nowhere_leaves_the_sweeps_to_finish(plan, monkeypatch):
    """With no step allowed the values come back as they went in, and the solve still certifies
    its tolerance from them."""
    mdp, theta = plan
    b = np.full(len(theta), 0.3)
    rough = solve(mdp, theta, b, tol=0.1, newton=False)
    monkeypatch.setattr(newton, "MAX_STEPS", 0)
    values, steps = newton.newton_values(mdp, theta, b, rough.value, 1e-9)
    np.testing.assert_array_equal(values, rough.value)
    assert np.all(steps == 0)
    sol = solve(mdp, theta, b, tol=1e-9, newton=True)
    exact = solve(mdp, theta, b, tol=1e-12, newton=False)
    assert np.max(np.abs(sol.value - exact.value) / b[:, None]) <= 1e-9 + 1e-12
    with pytest.raises(ValueError, match="smooth backup"):
        newton.newton_values(mdp, theta, b, rough.value, 1e-9, model="boltzmann")


@pytest.mark.parametrize("model", ["maxent", "maxent-relative"])
def test_one_backup_certifies_values_that_are_close_enough_and_refuses_others(plan, model, monkeypatch):
    """newton_finish: from values solved to 1e-11, one backup certifies tol 1e-9 and they come back
    as the pool's last backup gives them (value and normalised log-policy, terminal rows −inf); a
    repeated hypothesis is worked on once and gets the same answer; values the chord cannot move
    (no step allowed) from 0.1 nats are refused, and come back as they went in."""
    mdp, theta = plan
    b = np.array([0.1, 1.0, 10.0, 1.0, 0.5, 2.0])
    th = theta.copy()
    th[3] = th[1]  # hypothesis 3 repeats hypothesis 1
    close = solve(mdp, th, b, tol=1e-11, model=model, newton=False)
    walks = []
    monkeypatch.setattr(newton, "_Walk", lambda *a: walks.append(a) or _Walk(*a))
    value, log_pi, steps = newton.newton_finish(mdp, th, b, close.value, 1e-9, model=model)
    assert len(walks) == 5  # the repeated hypothesis is worked on once
    assert log_pi is not None and np.all(steps == 0)
    assert np.max(np.abs(value - close.value) / b[:, None]) <= 1e-11
    fin = np.isfinite(close.log_policy)
    np.testing.assert_array_equal(np.isfinite(log_pi), fin)
    assert np.max(np.abs(log_pi[fin] - close.log_policy[fin])) <= 1e-10
    np.testing.assert_array_equal(value[3], value[1])
    np.testing.assert_array_equal(value[:, mdp.terminal], 0.0)
    rough = solve(mdp, th, b, tol=0.1, model=model, newton=False)
    monkeypatch.setattr(newton, "MAX_STEPS", 0)
    value, log_pi, _ = newton.newton_finish(mdp, th, b, rough.value, 1e-9, model=model)
    assert log_pi is None
    np.testing.assert_array_equal(value, rough.value)
