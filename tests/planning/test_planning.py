"""Batched soft value iteration (planning.solve) against the slow reference and known limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st
from reference_solver import hard_value_iteration, random_mdp, soft_value_iteration
from scipy.optimize import brentq

from expertise_irl.errors import ArgumentError, InputError
from expertise_irl.mdp import TabularMDP
from expertise_irl.planning.kernels import CHECK_EVERY
from expertise_irl.planning.soft_vi import ConvergenceError, solve
from expertise_irl.planning.table_likelihood import log_likelihood, pair_log_likelihoods
from expertise_irl.worlds.zones import parse_map

BETAS = np.array([1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0])
GAMMAS = (0.5, 0.9, 0.95, 0.99)
EPS = float(np.finfo(np.float64).eps)
# Derandomised: every run draws the same examples (fixed seeds, reproducible failures).
PROPERTY = settings(max_examples=25, deadline=None, derandomize=True)


def random_theta(rng: np.random.Generator, k: int) -> np.ndarray:
    """Non-negative θ on the unit l1 simplex, some components exactly 0."""
    theta = rng.uniform(0.0, 1.0, k) * (rng.random(k) < 0.7)
    theta[rng.integers(k)] += 0.5  # at least one positive component
    return theta / theta.sum()


# Shapes come from a small menu so that JAX compiles each (S, A, K, H = 6) only once.
STATES = (5, 12, 25)
ACTIONS = (2, 5)
FEATURES = (1, 4)


@st.composite
def mdp_cases(draw):
    """(mdp, theta): a random valid MDP (1–2 terminals, ~30% unavailable actions) and θ.

    γ = 0.99 cases are kept to S <= 12 because the reference needs ~4,000 sweeps there.
    """
    gamma = draw(st.sampled_from(GAMMAS))
    S = draw(st.sampled_from(STATES[:2] if gamma == 0.99 else STATES))
    A = draw(st.sampled_from(ACTIONS))
    K = draw(st.sampled_from(FEATURES))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    mdp = random_mdp(rng, S, A, K, gamma, n_terminal=int(rng.integers(1, 3)))
    return mdp, random_theta(rng, K)


def assert_rows_sum_to_one(sol, mdp):
    """Σ_a π(a|s) = 1 on non-terminal rows. log π = q − v is rounded at the scale of the
    scaled value v = V/β (~ eps·|v|), so that sets the tolerance (|v| ≈ 1e5 at β = 1e-3)."""
    nonterm = ~mdp.terminal
    v_scale = np.abs(sol.value) / sol.beta[:, None]
    err = np.abs(sol.policy.sum(-1) - 1.0)[:, nonterm]
    assert np.all(err <= 1e-13 + 8 * EPS * v_scale[:, nonterm]), err.max()


def finite_max(x: np.ndarray) -> float:
    return float(np.max(np.abs(x[np.isfinite(x)]), initial=0.0))


def lp_error(a: np.ndarray, b: np.ndarray) -> float:
    """Max |a - b| over entries where both are finite; -inf patterns must agree."""
    fa, fb = np.isfinite(a), np.isfinite(b)
    np.testing.assert_array_equal(fa, fb)
    return finite_max(a[fa] - b[fb])


# --------------------------------------------------------------------------- reference match
@pytest.mark.slow
@PROPERTY
@given(mdp_cases())
def test_solve_matches_reference(case):
    """All six paper-range β in one batch vs. the extended-precision reference, tol=1e-12.

    Required accuracy: 1e-8 on log π and on V/β (absolute), 1e-8 relative on V. ``solve``
    documents that its tolerance is floored at the floating-point resolution of the scaled
    values: it stops once a backup changes v = V/β by <= 8·eps·max|v|, which bounds the
    remaining error by 8·eps·max|v|·γ/(1−γ). That floor is allowed on top of 1e-8; it only
    matters at γ = 0.99 with β <= 1e-2.
    """
    mdp, theta = case
    g = mdp.gamma
    event(f"gamma={g}")  # see pytest --hypothesis-show-statistics
    sol = solve(mdp, np.tile(theta, (len(BETAS), 1)), BETAS, tol=1e-12)
    for h, beta in enumerate(BETAS):
        ref = soft_value_iteration(mdp, theta, beta, extended=True)
        v_max = np.abs(ref.value).max() / beta
        floor = 8 * EPS * v_max * g / (1 - g)
        err_lp = lp_error(sol.log_policy[h], ref.log_policy)
        err_v = np.abs(sol.value[h] - ref.value).max() / beta
        err_q = lp_error(sol.q[h] / beta, ref.q / beta)
        rel_v = np.max(np.abs(sol.value[h] - ref.value) / np.maximum(np.abs(ref.value), 1e-300))
        # log π = q − v and Q = V + β log π each combine two errors in v
        assert err_lp <= 1e-8 + 2 * floor, (beta, g, err_lp, floor)
        assert err_v <= 1e-8 + floor, (beta, g, err_v, floor)
        assert err_q <= 1e-8 + 2 * floor, (beta, g, err_q, floor)
        assert rel_v <= 1e-8, (beta, g, rel_v)
        assert np.all(sol.value[h][mdp.terminal] == 0.0)
    np.testing.assert_array_equal(sol.beta, BETAS)


def test_reference_solver_closed_forms():
    """The reference itself, on cases with closed forms: a one-step choice (V is a plain
    log-sum-exp) and a self-loop (V solves a scalar fixed-point equation)."""
    beta, gamma = 0.3, 0.9
    one_step = TabularMDP(np.array([[-1, -1], [0, 0]]), np.array([[[0.0], [0.0]], [[0.2], [-0.5]]]),
                          np.array([True, False]), gamma=gamma)
    ref = soft_value_iteration(one_step, [1.0], beta)
    expected_v = beta * math.log(math.exp(0.2 / beta) + math.exp(-0.5 / beta))
    assert ref.value[1] == pytest.approx(expected_v, abs=1e-15)
    np.testing.assert_allclose(ref.log_policy[1], (np.array([0.2, -0.5]) - expected_v) / beta,
                               atol=1e-14)
    assert ref.value[0] == 0.0 and np.all(ref.log_policy[0] == -np.inf)
    hard = hard_value_iteration(one_step, [1.0])
    assert hard.greedy[1] == {0} and hard.value[1] == 0.2

    loop = TabularMDP(np.array([[-1, -1], [0, 1]]), np.array([[[0.0], [0.0]], [[-1.0], [0.05]]]),
                      np.array([True, False]), gamma=gamma)

    def residual(v):
        return beta * math.log(math.exp(-1.0 / beta) + math.exp((0.05 + gamma * v) / beta)) - v

    v_star = brentq(residual, -10.0, 10.0, xtol=1e-15, rtol=4 * EPS)
    for extended in (False, True):
        ref = soft_value_iteration(loop, [1.0], beta, extended=extended)
        assert ref.value[1] == pytest.approx(v_star, abs=1e-13)
    sol = solve(loop, [1.0], beta, tol=1e-12)
    assert sol.value[0, 1] == pytest.approx(v_star, abs=1e-11)
    assert hard_value_iteration(loop, [1.0]).value[1] == pytest.approx(0.05 / (1 - gamma))


def test_accuracy_at_the_float64_limit():
    """γ = 0.99, β = 1e-3, |V| ≈ 70 (|V/β| ≈ 7e4): even a plain float64 reference is only
    good to ~1e-8 here; solve must stay within its documented floor (see above)."""
    rng = np.random.default_rng(0)
    mdp = random_mdp(rng, 22, 4, 3, 0.99)
    theta = rng.uniform(0.0, 1.0, 3)
    theta /= theta.sum()
    beta = 1e-3
    exact = soft_value_iteration(mdp, theta, beta, extended=True)
    sol = solve(mdp, theta, beta, tol=1e-12)
    v_max = np.abs(exact.value).max() / beta
    assert v_max > 3e4
    floor = 8 * EPS * v_max * 0.99 / 0.01
    assert lp_error(sol.log_policy[0], exact.log_policy) <= 1e-8 + 2 * floor
    assert np.abs(sol.value[0] - exact.value).max() / beta <= 1e-8 + floor
    np.testing.assert_allclose(sol.value[0], exact.value, rtol=1e-11)


# --------------------------------------------------------------------------- policy sanity
@pytest.mark.slow
@PROPERTY
@given(mdp_cases())
def test_policies_normalised_and_masked(case):
    mdp, theta = case
    sol = solve(mdp, np.tile(theta, (len(BETAS), 1)), BETAS)
    avail = mdp.available
    assert np.all(np.isfinite(sol.value))
    assert np.all(sol.value[:, mdp.terminal] == 0.0)
    assert np.all(np.isfinite(sol.log_policy[:, avail]))
    assert np.all(sol.log_policy[:, ~avail] == -np.inf)
    assert np.all(sol.policy[:, ~avail] == 0.0)
    assert np.all(sol.policy[:, mdp.terminal] == 0.0)
    assert_rows_sum_to_one(sol, mdp)
    assert np.all(sol.log_policy[:, avail] <= 1e-10)


def test_policies_finite_at_extreme_beta_and_gamma():
    """β = 1e-3 and 100 on a zone map with γ = 0.99 and a large goal bonus."""
    zmap = parse_map(ZONE_TEXT, goal_bonus=100.0, gamma=0.99)
    mdp = zmap.to_mdp()
    theta = np.array([[1.0, 1.0, 1.0, 1.0, 1.0], [5.0, 0.0, 0.0, 0.0, 0.0]])
    sol = solve(mdp, np.repeat(theta, 2, axis=0), np.array([1e-3, 100.0, 1e-3, 100.0]))
    assert np.all(np.isfinite(sol.value))
    assert np.all(np.isfinite(sol.log_policy[:, mdp.available]))
    assert_rows_sum_to_one(sol, mdp)


def test_policy_rows_sum_to_one_to_machine_precision():
    mdp = parse_map(ZONE_TEXT, goal_bonus=100.0, gamma=0.99).to_mdp()
    sol = solve(mdp, [[1.0, 1.0, 1.0, 1.0, 1.0]], 1e-3)
    err = np.abs(sol.policy.sum(-1) - 1.0)[:, ~mdp.terminal]
    assert err.max() <= 1e-14 * mdp.n_actions


# --------------------------------------------------------------------------- β → 0 limit
def _hard_gap(hard, mdp):
    """Per non-terminal state: hard-Q gap between the greedy set and the best other action."""
    gaps = np.full(mdp.n_states, np.inf)
    for s in np.flatnonzero(~mdp.terminal):
        others = [hard.q[s, a] for a in np.flatnonzero(mdp.available[s]) if a not in hard.greedy[s]]
        if others:
            gaps[s] = hard.value[s] - max(others)
    return gaps


def _greedy_mass(policy, greedy):
    return np.array([policy[s, sorted(g)].sum() if g else 1.0 for s, g in enumerate(greedy)])


@pytest.mark.slow
@PROPERTY
@given(mdp_cases())
def test_small_beta_mass_bound(case):
    """At β = 1e-3, mass off the hard-greedy set obeys the soft/hard bound at every state.

    0 <= V_soft − V_hard <= β log A / (1−γ), so a non-greedy action with hard gap g has
    π <= exp(−(g − δ)/β) with δ = γ β log A / (1−γ).
    """
    mdp, theta = case
    beta = BETAS[0]
    sol = solve(mdp, np.tile(theta, (len(BETAS), 1)), BETAS, tol=1e-10)  # shape shared
    hard = hard_value_iteration(mdp, theta)
    delta = mdp.gamma * beta * math.log(mdp.n_actions) / (1 - mdp.gamma)
    gap = _hard_gap(hard, mdp)
    off = 1.0 - _greedy_mass(sol.policy[0], hard.greedy)
    bound = (mdp.n_actions - 1) * np.exp(-np.maximum(gap - delta, 0.0) / beta)
    nonterm = ~mdp.terminal
    assert np.all(off[nonterm] <= bound[nonterm] + 1e-12)
    # V_soft is within [V_hard, V_hard + β log A / (1−γ)]
    assert np.all(sol.value[0] >= hard.value - 1e-9)
    assert np.all(sol.value[0] <= hard.value + beta * math.log(mdp.n_actions) / (1 - mdp.gamma) + 1e-9)


@pytest.mark.parametrize("seed", [0, 2, 11, 25])
def test_small_beta_is_greedy_on_clear_gap(seed):
    rng = np.random.default_rng(seed)
    mdp = random_mdp(rng, 12, 3, 2, 0.9)
    theta = rng.uniform(0, 1, 2)
    theta /= theta.sum()
    hard = hard_value_iteration(mdp, theta)
    gap = _hard_gap(hard, mdp)
    assert gap[~mdp.terminal].min() > 0.1  # premise: a clear gap everywhere
    sol = solve(mdp, theta, 1e-3)
    mass = _greedy_mass(sol.policy[0], hard.greedy)
    assert np.all(mass[~mdp.terminal] >= 1 - 1e-6)
    assert all(len(g) == 1 for g, t in zip(hard.greedy, mdp.terminal, strict=True) if not t)


SYMMETRIC_GRID = """
.....
.....
.....
.....
....G
"""


def test_small_beta_splits_exact_ties_equally():
    """Open 5×5 grid, goal in a corner, θ = length only: on the diagonal, right and down
    lead to mirror-image states, so the hard tie must be split exactly in half."""
    mdp = parse_map(SYMMETRIC_GRID).to_mdp()
    theta = np.array([1.0, 0, 0, 0, 0])
    hard = hard_value_iteration(mdp, theta)
    sol = solve(mdp, theta, 1e-3, tol=1e-10)
    pi = sol.policy[0]
    gap = _hard_gap(hard, mdp)
    delta = mdp.gamma * 1e-3 * math.log(4) / (1 - mdp.gamma)
    assert gap[~mdp.terminal].min() > delta + 0.05  # premise: ties exact, others clearly worse
    mass = _greedy_mass(pi, hard.greedy)
    assert np.all(mass[~mdp.terminal] >= 1 - 1e-6)
    down, right = 1, 3
    xy = mdp.state_xy
    diagonal = [s for s in range(mdp.n_states) if xy[s, 0] == xy[s, 1] and not mdp.terminal[s]]
    assert len(diagonal) == 4
    for s in diagonal:
        assert hard.greedy[s] == {down, right}
        assert pi[s, down] == pytest.approx(0.5, abs=1e-6)
        assert pi[s, right] == pytest.approx(pi[s, down], abs=1e-9)


# --------------------------------------------------------------------------- scale invariance
@pytest.mark.parametrize("c", [1e-2, 7.0, 1e2])
def test_scale_invariance(c):
    rng = np.random.default_rng(3)
    mdp = random_mdp(rng, 12, 3, 2, 0.95)
    theta = rng.uniform(0, 2, (3, 2))
    beta = np.array([0.05, 1.0, 20.0])
    a = solve(mdp, theta, beta, tol=1e-12)
    b = solve(mdp, c * theta, c * beta, tol=1e-12)
    assert lp_error(a.log_policy, b.log_policy) < 1e-10
    np.testing.assert_allclose(b.value, c * a.value, rtol=1e-10, atol=1e-12 * c)


# --------------------------------------------------------------------------- batching
@pytest.fixture(scope="module")
def batch_case():
    rng = np.random.default_rng(1)
    mdp = random_mdp(rng, 15, 4, 3, 0.95)
    theta = np.stack([random_theta(rng, 3) for _ in range(8)])
    beta = np.array([1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 0.5, 3.0])
    return mdp, theta, beta, solve(mdp, theta, beta)


def test_batch_equals_each_alone(batch_case):
    mdp, theta, beta, full = batch_case
    assert len(set(full.iterations.tolist())) > 1  # hypotheses stop on their own
    for h in range(len(beta)):
        one = solve(mdp, theta[h], beta[h])
        assert one.iterations[0] == full.iterations[h]
        np.testing.assert_allclose(one.value[0], full.value[h], rtol=1e-13, atol=0)
        assert lp_error(one.log_policy[0], full.log_policy[h]) <= 1e-13


@pytest.mark.parametrize("chunk", [1, 3, 5])  # H = 8: partial last chunks
def test_chunking_is_invisible(batch_case, chunk):
    mdp, theta, beta, full = batch_case
    calls = []
    sol = solve(mdp, theta, beta, chunk_size=chunk, progress=lambda d, t: calls.append((d, t)))
    np.testing.assert_array_equal(sol.iterations, full.iterations)
    np.testing.assert_allclose(sol.value, full.value, rtol=1e-13, atol=0)
    assert lp_error(sol.log_policy, full.log_policy) <= 1e-13
    H = len(beta)
    done = [d for d, _ in calls]
    assert calls and all(t == H for _, t in calls)
    assert done == sorted(done) and done[-1] == H  # monotone, ends complete


def test_warm_start_at_solution(batch_case):
    mdp, theta, beta, full = batch_case
    warm = solve(mdp, theta, beta, v_init=full.value)
    # Started within ~tol of the fixed point, the residual only has to shrink from ~tol to the
    # stopping threshold, not from the scale of V: a small fraction of a cold start's sweeps.
    # Convergence is checked every CHECK_EVERY sweeps, so counts come in those steps.
    assert np.all(warm.iterations <= 2 * CHECK_EVERY)
    assert np.all(3 * warm.iterations < full.iterations)
    # tol = 1e-8 nats on V/β for each solve
    assert np.max(np.abs(warm.value - full.value) / beta[:, None]) <= 2e-8
    assert lp_error(warm.log_policy, full.log_policy) <= 4e-8


def test_float32_agrees_with_float64():
    """γ = 0.9: float32's stopping floor (8·eps32 on the change) bounds the relative error
    of V by 8 · 1.2e-7 · γ/(1−γ) ≈ 9e-6, and probabilities are accurate to about the same."""
    rng = np.random.default_rng(2)
    mdp = random_mdp(rng, 15, 4, 3, 0.9)
    theta = np.tile(random_theta(rng, 3), (len(BETAS), 1))
    a = solve(mdp, theta, BETAS)
    b = solve(mdp, theta, BETAS, dtype="float32")
    assert b.value.dtype == np.float64 and b.log_policy.dtype == np.float64
    assert np.abs(a.policy - b.policy).max() < 1e-4
    assert np.max(np.abs(a.value - b.value) / np.abs(a.value).max(-1, keepdims=True)) < 1e-4
    np.testing.assert_array_equal(np.isfinite(a.log_policy), np.isfinite(b.log_policy))


def test_float32_documented_accuracy():
    rng = np.random.default_rng(2)
    mdp = random_mdp(rng, 15, 4, 3, 0.95)
    theta = np.tile(random_theta(rng, 3), (len(BETAS), 1))
    a = solve(mdp, theta, BETAS)
    b = solve(mdp, theta, BETAS, dtype="float32")
    assert np.max(np.abs(a.value - b.value) / np.abs(a.value).max(-1, keepdims=True)) < 1e-4


# --------------------------------------------------------------------------- errors
def test_max_iter_too_small_names_hypothesis_and_beta(batch_case):
    mdp, theta, beta, full = batch_case
    order = np.argsort(full.iterations, kind="stable")[-3:]  # the three slowest, slowest last
    its = full.iterations[order]
    assert its[1] < its[2]
    th, be = theta[order], beta[order]
    max_iter = int(its[1])
    ok = solve(mdp, th[:2], be[:2], max_iter=max_iter)  # the first two converge in time
    np.testing.assert_array_equal(ok.iterations, its[:2])
    with pytest.raises(ConvergenceError) as exc:
        solve(mdp, th, be, max_iter=max_iter, chunk_size=2)  # culprit in the second chunk
    msg = str(exc.value)
    assert "hypothesis 2 " in msg
    assert f"beta={be[2]:g}" in msg
    assert str(max_iter) in msg
    assert not isinstance(exc.value, InputError)


@pytest.mark.parametrize(("theta", "beta", "match"), [
    ([0.5, 0.5, 0.0], 0.0, "beta"),
    ([0.5, 0.5, 0.0], -1.0, "beta"),
    ([0.5, 0.5, 0.0], np.nan, "beta"),
    ([0.5, 0.5, 0.0], np.inf, "beta"),
    ([[0.5, 0.5, 0.0]] * 2, [1.0, 0.0], "beta"),
    ([np.nan, 0.5, 0.0], 1.0, "theta"),
    ([np.inf, 0.5, 0.0], 1.0, "theta"),
])
def test_bad_hypotheses_raise_input_error(batch_case, theta, beta, match):
    mdp = batch_case[0]
    with pytest.raises(InputError, match=match):
        solve(mdp, theta, beta)


@pytest.mark.parametrize(("theta", "beta", "kwargs", "match"), [
    ([0.5, 0.5], 1.0, {}, "K = 3"),
    ([[0.5, 0.5, 0.0, 0.0]], 1.0, {}, "K = 3"),
    ([[0.5, 0.5, 0.0]] * 2, [1.0, 2.0, 3.0], {}, "beta must have shape"),
    ([0.5, 0.5, 0.0], 1.0, {"v_init": np.zeros((2, 15))}, "v_init must have shape"),
    ([0.5, 0.5, 0.0], 1.0, {"v_init": np.full((1, 15), np.nan)}, "v_init must be finite"),
])
def test_arrays_of_the_wrong_shape_are_programming_errors(batch_case, theta, beta, kwargs, match):
    """The package builds these arrays itself: a wrong one is a bug, not the user's input."""
    with pytest.raises(ArgumentError, match=match) as err:
        solve(batch_case[0], theta, beta, **kwargs)
    assert not isinstance(err.value, InputError)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"tol": 0.0}, "tol"),
    ({"tol": np.nan}, "tol"),
    ({"dtype": "float16"}, "dtype"),
])
def test_bad_options_raise_input_error(batch_case, kwargs, match):
    mdp = batch_case[0]
    with pytest.raises(InputError, match=match):
        solve(mdp, [0.5, 0.5, 0.0], 1.0, **kwargs)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_overflowing_reward_is_input_error(batch_case):
    mdp = batch_case[0]
    with pytest.raises(InputError, match=r"theta|beta|overflow"):
        solve(mdp, [1e306, 0.0, 0.0], 1e-3)


# --------------------------------------------------------------------------- likelihood
def test_log_likelihood_matches_reference():
    rng = np.random.default_rng(4)
    mdp = random_mdp(rng, 12, 3, 2, 0.95)
    s_idx, a_idx = np.nonzero(mdp.available)
    pick = rng.integers(len(s_idx), size=30)
    states, actions = s_idx[pick], a_idx[pick]
    thetas = np.stack([random_theta(rng, 2) for _ in range(3)])
    betas = np.array([0.05, 2.0])
    H_theta = np.repeat(thetas, 2, axis=0)
    H_beta = np.tile(betas, 3)
    sol = solve(mdp, H_theta, H_beta, tol=1e-12)
    ll = log_likelihood(sol.log_policy, states, actions)
    pairs = pair_log_likelihoods(sol.log_policy, states.tolist(), actions.tolist())
    assert ll.shape == (6,) and pairs.shape == (6, 30)
    for h in range(6):
        ref = soft_value_iteration(mdp, H_theta[h], H_beta[h])
        expected = sum(ref.log_policy[s, a] for s, a in zip(states, actions, strict=True))
        assert ll[h] == pytest.approx(expected, abs=1e-7)
        np.testing.assert_allclose(pairs[h], ref.log_policy[states, actions], atol=1e-8, rtol=0)
    assert np.all(ll < 0)
    # an action the MDP cannot take makes the trajectory impossible under every hypothesis
    s_bad, a_bad = np.argwhere(~mdp.available & ~mdp.terminal[:, None])[0]
    ll_bad = log_likelihood(sol.log_policy, [*states, s_bad], [*actions, a_bad])
    assert np.all(ll_bad == -np.inf)


ZONE_TEXT = """
S....xx....
.###.xx.##.
.#>>>>>>>>.
.#...ss...G
.....ss..tt
"""


def _large_set(rng, mdp, n):
    theta = np.stack([random_theta(rng, mdp.n_features) for _ in range(n)])
    beta = rng.choice(BETAS, size=n)
    return theta, beta


@pytest.mark.slow
def test_float32_start_meets_the_same_guarantee():
    """A set large enough for the float32 first phase: every hypothesis is within the
    tolerance of the extended-precision reference, as a cold float64 solve is (the float64
    phase stops on the same contraction bound from any start)."""
    from expertise_irl.planning.soft_vi import FLOAT32_START_MIN

    rng = np.random.default_rng(5)
    mdp = random_mdp(rng, 12, 4, 3, 0.95)
    theta, beta = _large_set(rng, mdp, FLOAT32_START_MIN)
    mixed = solve(mdp, theta, beta, float32_start=True)
    cold = solve(mdp, theta, beta)
    g = mdp.gamma
    for h in rng.choice(len(beta), size=12, replace=False):
        ref = soft_value_iteration(mdp, theta[h], beta[h], extended=True)
        floor = 8 * EPS * np.abs(ref.value).max() / beta[h] * g / (1 - g)
        assert np.abs(mixed.value[h] - ref.value).max() / beta[h] <= 1e-8 + floor
        assert lp_error(mixed.log_policy[h], ref.log_policy) <= 2e-8 + 2 * floor
    # Both phases' sweeps are counted, and the float32 phase did run: the counts differ.
    assert not np.array_equal(mixed.iterations, cold.iterations)
    np.testing.assert_array_equal(np.isfinite(mixed.log_policy), np.isfinite(cold.log_policy))


def test_float32_start_falls_back_where_float32_overflows():
    """Weights θ/β beyond float32's range (β = 1e-39): the float32 phase cannot converge, so a
    cold float64 solve decides, and the result is a cold float64 solve's."""
    from expertise_irl.errors import ConvergenceError
    from expertise_irl.planning.soft_vi import FLOAT32_START_MIN

    rng = np.random.default_rng(6)
    mdp = random_mdp(rng, 10, 3, 2, 0.9)
    theta, beta = _large_set(rng, mdp, FLOAT32_START_MIN)
    beta[:4] = 1e-39
    with pytest.raises(ConvergenceError):  # the case is real: float32 overflows there
        solve(mdp, theta, beta, dtype="float32")
    mixed = solve(mdp, theta, beta, float32_start=True)
    cold = solve(mdp, theta, beta)
    assert np.all(np.isfinite(mixed.value))
    np.testing.assert_array_equal(mixed.value, cold.value)
    np.testing.assert_array_equal(mixed.iterations, cold.iterations)


@pytest.mark.slow
def test_over_relaxation_meets_the_guarantee_in_fewer_sweeps():
    """On a grid (red-black ordering), the wandering hypotheses (large β) switch to SOR and the
    near-deterministic ones mostly stay plain: every one is within the tolerance of the
    extended-precision reference, and the set needs far fewer sweeps than plain sweeps do."""
    rng = np.random.default_rng(11)
    mdp = parse_map(ZONE_TEXT).to_mdp()
    theta = np.stack([random_theta(rng, mdp.n_features) for _ in range(24)])
    beta = np.repeat([0.01, 0.5, 10.0], 8)
    sor = solve(mdp, theta, beta)
    plain = solve(mdp, theta, beta, over_relax=False)
    g = mdp.gamma
    for h in range(len(beta)):
        ref = soft_value_iteration(mdp, theta[h], beta[h], extended=True)
        floor = 8 * EPS * np.abs(ref.value).max() / beta[h] * g / (1 - g)
        for sol in (sor, plain):
            assert np.abs(sol.value[h] - ref.value).max() / beta[h] <= 1e-8 + floor
            assert lp_error(sol.log_policy[h], ref.log_policy) <= 2e-8 + 2 * floor
    wander = beta >= 0.5
    # Plain red-black sweeps contract by about γ² each on these; SOR by about ω − 1 ≈ 0.6.
    assert sor.iterations[wander].sum() < 0.6 * plain.iterations[wander].sum()
    # A lane that tried SOR and fell back pays at most its trial (two checks) over plain.
    assert np.all(sor.iterations <= plain.iterations + 2 * CHECK_EVERY)


def test_log_likelihood_counts_each_pair_once_across_row_blocks():
    """Several blocks of rows (H = 600 is not a multiple of the block), repeated pairs and
    impossible ones: the weighted sum equals the plain sum of every pair's log-probability."""
    rng = np.random.default_rng(8)
    H, S, A = 600, 7, 3
    table = np.log(rng.dirichlet(np.ones(A), size=(H, S)))
    table[rng.random((H, S, A)) < 0.02] = -np.inf
    states, actions = rng.integers(0, S, 400), rng.integers(0, A, 400)
    plain = pair_log_likelihoods(table, states, actions).sum(axis=1)
    fast = log_likelihood(table, states, actions)
    fin = np.isfinite(plain)
    assert 0 < fin.sum() < H  # both kinds of rows occur
    np.testing.assert_array_equal(np.isfinite(fast), fin)
    assert not np.isnan(fast).any()
    np.testing.assert_allclose(fast[fin], plain[fin], rtol=1e-12, atol=0)


def test_log_likelihood_names_a_pair_outside_the_table():
    table = np.log(np.full((3, 4, 2), 0.5))
    assert log_likelihood(table, [0, 3], [1, 1]) == pytest.approx(2 * math.log(0.5))
    message = r"pair 1: \(state 0, action 2\) is outside the MDP \(4 states, 2 actions\)"
    with pytest.raises(InputError, match=message):
        log_likelihood(table, [0, 0], [1, 2])  # would otherwise read state 1's action 0
    with pytest.raises(InputError, match=r"pair 0: \(state 4, action 0\)"):
        log_likelihood(table, [4] * 100, [0] * 100)


def test_boltzmann_sweeps_plainly():
    """Over-relaxation is not used for hard values (its trials fail there): the counts are a
    plain solve's."""
    rng = np.random.default_rng(12)
    mdp = parse_map(ZONE_TEXT).to_mdp()
    theta = np.stack([random_theta(rng, mdp.n_features) for _ in range(12)])
    beta = np.repeat([0.01, 1.0, 10.0], 4)
    a = solve(mdp, theta, beta, model="boltzmann")
    b = solve(mdp, theta, beta, model="boltzmann", over_relax=False)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    np.testing.assert_array_equal(a.value, b.value)
