"""Tests for metrics.py: the paper's three metrics (Sec. V-E), on hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.mdp import TabularMDP
from expertise_irl.metrics import (
    cosine_similarity,
    expertise_distance,
    greedy_policy,
    policy_regret,
    policy_values,
    regret_from_values,
    return_regret,
    return_regret_table,
    uniform_policy,
)
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.zones import load_bundled

# solve()'s default tol bounds the error of V/β by 1e-8 nats, so V is within β·1e-8 of the
# exact value; with |V| = O(1) every regret below is exact to ~1e-7 or better.
SOLVE_ABS = 1e-7


# --------------------------------------------------------------- expertise distance
@pytest.mark.parametrize(("b_true", "b_hat", "expected"), [
    (0.5, 1.25, 0.75),
    (1.25, 0.5, 0.75),  # symmetric
    (5.0, 5.0, 0.0),
    (0.01, 10.0, 9.99),
    (np.float64(2.0), np.array(0.5), 1.5),  # numpy scalars / 0-d arrays
])
def test_expertise_distance(b_true, b_hat, expected):
    d = expertise_distance(b_true, b_hat)
    assert type(d) is float
    assert d == pytest.approx(expected, abs=1e-15)


# ---------------------------------------------------------------- cosine similarity
def test_cosine_equal_vectors_is_one():
    v = np.array([0.2, 0.3, 0.0, 0.4, 0.1])
    assert cosine_similarity(v, v) == pytest.approx(1.0, abs=1e-15)


def test_cosine_orthogonal_is_zero():
    assert cosine_similarity([1.0, 0.0, 0.0], [0.0, 0.5, 0.5]) == 0.0
    assert cosine_similarity([1.0, 1.0], [1.0, -1.0]) == pytest.approx(0.0, abs=1e-16)


def test_cosine_opposite_is_minus_one():
    assert cosine_similarity([1.0, 2.0], [-2.0, -4.0]) == pytest.approx(-1.0, abs=1e-15)


def test_cosine_worked_examples():
    # (3, 4)·(4, 3) = 24; both norms 5 → 24 / 25.
    assert cosine_similarity([3.0, 4.0], [4.0, 3.0]) == pytest.approx(0.96, abs=1e-15)
    # (1, 0)·(1, 1) = 1; norms 1 and √2 → 1/√2.
    assert cosine_similarity([1.0, 0.0], [1.0, 1.0]) == pytest.approx(1 / math.sqrt(2), abs=1e-15)
    # Unit-l1 θ's as the estimators produce them: (1,0,0,0,0)·(.5,.5,0,0,0) / (1 · √.5) = √.5.
    assert cosine_similarity([1, 0, 0, 0, 0], [0.5, 0.5, 0, 0, 0]) == pytest.approx(math.sqrt(0.5), abs=1e-15)


def test_cosine_is_scale_invariant():
    a = np.array([0.1, 0.7, 0.2])
    b = np.array([0.3, 0.3, 0.4])
    c = cosine_similarity(a, b)
    assert c < 0.99  # not trivially 1
    for s, t in [(2.0, 1.0), (1.0, 1e-6), (1e6, 3.0)]:
        assert cosine_similarity(s * a, t * b) == pytest.approx(c, rel=1e-14)


@pytest.mark.parametrize(("a", "b"), [
    ([0.0, 0.0], [1.0, 0.0]),
    ([1.0, 0.0], [0.0, 0.0]),
])
def test_cosine_zero_vector_raises(a, b):
    with pytest.raises(InputError, match="zero vector"):
        cosine_similarity(a, b)


@pytest.mark.parametrize(("a", "b"), [
    ([1.0, 0.0], [1.0, 0.0, 0.0]),  # lengths differ
    ([[1.0, 0.0]], [[1.0, 0.0]]),  # not 1-D
    (1.0, 1.0),  # scalars
])
def test_cosine_shape_mismatch_raises(a, b):
    with pytest.raises(InputError, match="1-D"):
        cosine_similarity(a, b)


# --------------------------------------------------------------- regret from values
def test_regret_from_values_hand_computed_excludes_terminals():
    v_true = np.array([-2.0, -4.0, 0.0, -1.0])
    v_hat = np.array([-3.0, -4.0, 5.0, -1.0])  # the terminal entry must be ignored
    terminal = np.array([False, False, True, False])
    # Non-terminal |differences| 1, 0, 0 → mean 1/3; scale max|V*| = 4 → 1/12.
    assert regret_from_values(v_true, v_hat, terminal) == pytest.approx(1 / 12, abs=1e-16)
    # Counting the terminal state would have given mean(1, 0, 5, 0) / 4 = 3/8.
    assert regret_from_values(v_true, v_hat, [0, 0, 1, 0]) == pytest.approx(1 / 12, abs=1e-16)


def test_regret_from_values_normalises_by_max_abs_value_for_negative_values():
    # All values negative: the paper's max_s V = −1 would make the regret negative;
    # max_s |V| = 4 keeps it positive. |diffs| 2, 2 → mean 2; 2 / 4 = 0.5.
    v_true = np.array([-1.0, -4.0])
    v_hat = np.array([-3.0, -2.0])
    r = regret_from_values(v_true, v_hat, [False, False])
    assert r == pytest.approx(0.5, abs=1e-16)
    # Mixed signs: the scale is the largest magnitude (|−4| here, not max V = 3).
    assert regret_from_values([3.0, -4.0], [3.0, -3.0], [False, False]) == pytest.approx(0.5 / 4, abs=1e-16)


def test_regret_from_values_zero_true_values_raise():
    with pytest.raises(InputError, match="zero everywhere"):
        regret_from_values(np.zeros(3), np.ones(3), np.zeros(3, bool))
    # Non-zero only at a terminal state still counts as zero everywhere that matters.
    with pytest.raises(InputError, match="zero everywhere"):
        regret_from_values([0.0, 7.0], [1.0, 1.0], [False, True])


def test_regret_from_values_all_terminal_raises_input_error():
    with pytest.raises(InputError):
        regret_from_values([0.0, 0.0], [0.0, 0.0], [True, True])


# ------------------------------------------------------------------- policy regret
@pytest.fixture(scope="module")
def chain():
    """s0 → s1 → s2 (terminal), one action each: V does not depend on β.
    φ(s0) = (−1, 0), φ(s1) = (−1, −1), γ = 0.5."""
    return TabularMDP(np.array([[1], [2], [-1]]),
                      np.array([[[-1.0, 0.0]], [[-1.0, -1.0]], [[0.0, 0.0]]]),
                      np.array([False, False, True]), gamma=0.5)


@pytest.fixture(scope="module")
def fork():
    """One decision: s0 has two actions into the terminal s1, φ = (−1, 0) and (0, −1), γ = 0.5.
    V(s0) = β log(exp(−θ₁/β) + exp(−θ₂/β))."""
    return TabularMDP(np.array([[1, 1], [-1, -1]]),
                      np.array([[[-1.0, 0.0], [0.0, -1.0]], [[0.0, 0.0], [0.0, 0.0]]]),
                      np.array([False, True]), gamma=0.5)


@pytest.mark.parametrize("beta", [0.3, 3.0])
def test_policy_regret_hand_computed_chain(chain, beta):
    # θ* = (1, 0): V(s1) = −1, V(s0) = −1 + 0.5·(−1) = −1.5.
    # θ̂ = (.5, .5): V(s1) = −1,   V(s0) = −0.5 + 0.5·(−1) = −1.
    # Regret = mean(|−1.5 + 1|, 0) / 1.5 = 0.25 / 1.5 = 1/6, for any β.
    assert policy_regret(chain, [1.0, 0.0], beta, [0.5, 0.5]) == pytest.approx(1 / 6, abs=SOLVE_ABS)


def test_policy_regret_hand_computed_fork(fork):
    beta = 1.0

    def v(t1, t2):
        return beta * math.log(math.exp(-t1 / beta) + math.exp(-t2 / beta))

    v_true = v(1.0, 0.0)  # log(1 + e^-1) ≈ 0.3133
    expected = abs(v_true - v(0.5, 0.5)) / abs(v_true)
    assert policy_regret(fork, [1.0, 0.0], beta, [0.5, 0.5]) == pytest.approx(expected, abs=SOLVE_ABS)
    # The mirror-image preference has the same soft value here: zero regret, though θ̂ ≠ θ*.
    assert policy_regret(fork, [1.0, 0.0], beta, [0.0, 1.0]) == pytest.approx(0.0, abs=SOLVE_ABS)


@pytest.fixture(scope="module")
def corridor():
    return load_bundled("corridor").to_mdp()


THETA_STAR = np.array([0.4, 0.1, 0.3, 0.1, 0.1])
THETA_HAT = np.array([0.2, 0.2, 0.2, 0.2, 0.2])


@pytest.mark.parametrize("beta", [0.09, 1.0])
def test_policy_regret_zero_for_truth_positive_otherwise(corridor, beta):
    assert policy_regret(corridor, THETA_STAR, beta, THETA_STAR) == pytest.approx(0.0, abs=1e-12)
    # Measured 0.24 at both β; well clear of the solver error.
    assert policy_regret(corridor, THETA_STAR, beta, THETA_HAT) > 0.1


@pytest.mark.parametrize("beta", [0.09, 1.0])
def test_policy_regret_uses_theta_hat_as_given(corridor, beta):
    """Not invariant to the scale of θ̂ alone: V_{θ̂,β*} is evaluated at the true β*, and
    (θ̂, β*) and (2θ̂, β*) are different policies with different values. The documented
    behaviour is Eq. 17 on the soft values of θ̂ exactly as passed (callers pass unit-l1
    θ̂, as every estimator produces), which we check against solve() directly."""
    r1 = policy_regret(corridor, THETA_STAR, beta, THETA_HAT)
    r2 = policy_regret(corridor, THETA_STAR, beta, 2 * THETA_HAT)
    assert abs(r1 - r2) > 0.02  # measured 0.24 vs 0.20 (β = 0.09), 0.24 vs 0.05 (β = 1)
    # θ̂ = 2θ* has regret > 0 although it is the same direction.
    assert policy_regret(corridor, THETA_STAR, beta, 2 * THETA_STAR) > 0.1
    sol = solve(corridor, np.stack([THETA_STAR, 2 * THETA_HAT]), [beta, beta])
    expected = regret_from_values(sol.value[0], sol.value[1], corridor.terminal)
    assert r2 == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("c", [0.5, 3.0])
def test_policy_regret_invariant_to_joint_rescaling(corridor, c):
    """(θ, β) → (cθ, cβ) scales every soft value by c, so the normalised regret is unchanged
    when θ*, β* and θ̂ are rescaled together (scale invariance)."""
    r = policy_regret(corridor, THETA_STAR, 0.5, THETA_HAT)
    assert policy_regret(corridor, c * THETA_STAR, c * 0.5, c * THETA_HAT) == pytest.approx(r, abs=SOLVE_ABS)


# ------------------------------------------------------------------- return regret
def test_return_regret_hand_computed_on_the_fork(fork):
    """θ* = (0.8, 0.2): the best action pays −0.2, the other −0.8, acting at random −0.5."""
    t = np.array([0.8, 0.2])
    assert return_regret(fork, t, [0.99, 0.01]) == 0.0  # the same policy, another reward
    assert return_regret(fork, t, [0.3, 0.7]) == pytest.approx(0.6 / 0.3, abs=1e-12)  # the wrong action
    assert return_regret(fork, t, [0.5, 0.5]) == pytest.approx(1.0, abs=1e-12)  # a tie: acting at random
    assert return_regret(fork, t, [0.0, 0.0]) == pytest.approx(1.0, abs=1e-12)


def test_return_regret_ranks_policies_where_eq17_does_not(fork):
    """(0.2, 0.8) mirrors θ*: the same soft values (Eq. 17 = 0) but the wrong action; (0.99, 0.01)
    takes θ*'s action but has other soft values (Eq. 17 > 0). Only the return regret ranks them
    by what acting on them earns."""
    t, beta = np.array([0.8, 0.2]), 0.3
    right, mirror = np.array([0.99, 0.01]), np.array([0.2, 0.8])
    assert policy_regret(fork, t, beta, mirror) == pytest.approx(0.0, abs=SOLVE_ABS)
    assert policy_regret(fork, t, beta, right) > 0.1
    assert return_regret(fork, t, right) == 0.0 < return_regret(fork, t, mirror)


def test_return_regret_is_zero_for_the_truth_and_free_of_scale():
    mdp = load_bundled("crossroads").to_mdp()
    t = np.array([0.5, 0.3, 0.1, 0.05, 0.05])
    other = np.array([0.2, 0.2, 0.2, 0.2, 0.2])
    assert return_regret(mdp, t, t) == 0.0
    r = return_regret(mdp, t, other)
    assert 0.0 < r < 1.0
    assert return_regret(mdp, 3 * t, 7 * other) == pytest.approx(r, rel=1e-9)
    table = return_regret_table(mdp, t, np.stack([t, other, np.zeros(5)]))
    np.testing.assert_allclose(table, [0.0, r, 1.0], atol=1e-9)


def test_policy_values_solve_the_policy_bellman_equation():
    """The exact values of a stochastic policy satisfy V = r_π + γ P_π V at every state (and are
    0 at terminals); an iterative evaluation agrees."""
    mdp = load_bundled("crossroads").to_mdp()
    rng = np.random.default_rng(3)
    theta = rng.dirichlet(np.ones(mdp.n_features))
    pi = np.where(mdp.available, rng.random(mdp.available.shape), 0.0)
    pi /= np.maximum(pi.sum(axis=1, keepdims=True), 1e-300)
    v = policy_values(mdp, theta, pi)
    r = np.where(mdp.available, mdp.reward(theta), 0.0)
    nxt = np.where(mdp.available, mdp.next_state, 0)
    backup = (pi * (r + mdp.gamma * v[nxt])).sum(axis=1)
    np.testing.assert_allclose(v[~mdp.terminal], backup[~mdp.terminal], atol=1e-10)
    assert np.all(v[mdp.terminal] == 0.0)
    it = np.zeros(mdp.n_states)
    for _ in range(2000):
        it = (pi * (r + mdp.gamma * it[nxt])).sum(axis=1)
    np.testing.assert_allclose(v, it, atol=1e-9)


def test_greedy_and_uniform_policies_are_distributions_over_available_actions():
    mdp = load_bundled("crossroads").to_mdp()
    for pi in (greedy_policy(mdp, [0.2, 0.2, 0.2, 0.2, 0.2]), uniform_policy(mdp)):
        live = ~mdp.terminal
        np.testing.assert_allclose(pi[live].sum(axis=1), 1.0)
        assert np.all(pi[~mdp.available] == 0.0)


def test_return_regret_refuses_bad_input(fork):
    with pytest.raises(InputError, match="2 components"):
        return_regret(fork, [1.0, 0.0], [1.0, 0.0, 0.0])
    with pytest.raises(InputError, match="every policy earns the same"):
        return_regret(fork, [0.5, 0.5], [1.0, 0.0])
