"""Certified elimination inside the sweeps (planning.screening): the one-sided bound of values
below the solution holds against an exact solve, a gate that eliminates nothing changes no result,
and every hypothesis a gate stops is certainly negligible."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.inference.certified import screening_gate, telescoped_log_likelihood
from expertise_irl.planning import kernels
from expertise_irl.planning.screening import GateArrays, gate_arrays, gate_check
from expertise_irl.planning.soft_vi import solve, solve_screened
from expertise_irl.planning.table_likelihood import log_likelihood
from expertise_irl.worlds.zones import parse_map

#: a small map with a road, a restricted block and starts on three sides of the goal
ROADS = """
S...x.s
S.xx...
..xx>>G
S......
"""


@pytest.fixture(scope="module")
def small():
    mdp = parse_map(ROADS, name="screening").to_mdp()
    rng = np.random.default_rng(7)
    # an off-grid person: θ from a Dirichlet, β log-uniform
    trajs = simulate(mdp, rng.dirichlet(np.ones(mdp.n_features)), float(np.exp(rng.uniform(-1, 1))), 6, rng,
                     max_steps=40)
    return mdp, trajs


def _gate(mdp, trajs, theta, beta, margin):
    """The library's gate for these demonstrations (``maxent``), with the elimination margin given."""
    return screening_gate(mdp, [trajs], theta, beta)._replace(margin=margin)


def _exact_ll(mdp, trajs, theta, beta, model="maxent"):
    sol = solve(mdp, theta, beta, tol=1e-12, model=model)
    return log_likelihood(np.asarray(sol.log_policy), trajs.state, trajs.action)


@pytest.mark.parametrize("model", ["maxent", "maxent-relative"])
def test_values_below_the_solution_bound_the_log_likelihood_from_one_side(small, model):
    """Plain sweeps from values far below the solution raise every value; the exact log-likelihood
    then lies in [LL − W₋·tol_h, LL + W₊·tol_h] (tol_h = γ/(1 − γ)·change), and W₊ (the ends of
    episodes that reached no goal) is a small part of Σ|w|."""
    mdp, trajs = small
    rng = np.random.default_rng(3)
    H = 8
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-2, 2, H))
    prep = kernels.prepared(mdp, "float64")
    weights = jnp.asarray(mdp.reward_weights(theta) / beta[:, None])
    v = np.full((H, prep.n_rows), -50.0 / (1 - mdp.gamma))
    v[:, -1] = 0.0  # the zero row
    v = jnp.asarray(v)
    g = _gate(mdp, trajs, theta, beta, -30.0)
    exact = _exact_ll(mdp, trajs, theta, beta, model)
    for _ in range(12):
        before = v
        v, d = jax_sweep(prep, weights, v, mdp.gamma, model)
        rose = np.asarray(jnp.min(v - before, axis=1)) >= 0
        assert rose.all()
        tol_h = mdp.gamma / (1 - mdp.gamma) * np.asarray(d)
        values = np.asarray(v)[:, prep.rows] * beta[:, None]
        ll, rounding = telescoped_log_likelihood(mdp, [trajs], theta, beta, values, model)
        slack = rounding + 1e-12 * g.factor  # the exact solve's own tolerance
        assert np.all(exact <= ll + g.positive * tol_h + slack)
        assert np.all(exact >= ll - (g.factor - g.positive) * tol_h - slack)
    assert g.positive <= 0.35 * g.factor


def jax_sweep(prep, weights, v, gamma, model):
    """One plain red-black sweep of every hypothesis (one lane each): ``(v [H, rows], change [H])``."""
    out, d = kernels.sweep(prep, weights.T, v.T, jnp.asarray(gamma), model)
    return out.T, d


def test_the_check_stops_only_lanes_below_the_best_by_the_margin():
    """gate_check on hand-made lanes: the best certain log mass is the largest lower bound of the
    busy lanes; a lane stops when its upper bound lies below it by more than the margin, with the
    one-sided bound where its values are below the solution."""
    g = GateArrays(jnp.asarray([0]), jnp.asarray([-1.0]), jnp.asarray([0.0, 0.0, 0.0, 0.0]),
                   jnp.asarray(10.0), jnp.asarray(1.0), jnp.asarray(-5.0), jnp.asarray(0.0), jnp.zeros(4))
    v = jnp.asarray([[0.0], [20.0], [6.4], [6.4]])  # LL = -v
    d = jnp.asarray([0.1, 0.1, 0.1, 0.1])
    lane_h = jnp.arange(4)
    stop, best, tol_h = gate_check(g, v, d, jnp.zeros(4), lane_h, jnp.ones(4, bool), -jnp.inf, 1.0,
                                   jnp.asarray([False, False, True, False]))
    np.testing.assert_allclose(np.asarray(tol_h), 0.1)
    assert float(best) == pytest.approx(-1.0)  # lane 0: 0 − 10·0.1
    # lane 1: −20 + 1 < −6 ; lane 2 (below): −6.4 + 1·0.1 < −6 ; lane 3 (two-sided): −6.4 + 1 > −6
    np.testing.assert_array_equal(np.asarray(stop), [False, True, True, False])
    idle = gate_check(g, v, d, jnp.zeros(4), lane_h, jnp.asarray([False, True, True, True]), -jnp.inf, 1.0,
                      jnp.zeros(4, bool))
    assert float(idle[1]) == pytest.approx(-6.4 - 1.0)  # an idle lane's bound is not counted
    # a lane below the solution sets the best with W₋·tol_h = (10 − 1)·0.1 below its sum
    below = gate_check(g, v, d, jnp.zeros(4), lane_h, jnp.asarray([False, False, True, False]), -jnp.inf,
                       1.0, jnp.asarray([False, False, True, False]))
    assert float(below[1]) == pytest.approx(-6.4 - 0.9)


@pytest.mark.parametrize("method", ["sweeps", "levels"])
def test_a_gate_that_eliminates_nothing_changes_no_result(small, method):
    mdp, trajs = small
    rng = np.random.default_rng(5)
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=12), np.exp(rng.uniform(-2, 2, 12))
    plain = solve(mdp, theta, beta, tol=1e-3, method=method)
    gated = solve_screened(mdp, theta, beta, _gate(mdp, trajs, theta, beta, -math.inf), tol=1e-3,
                           method=method)
    np.testing.assert_array_equal(gated.value, plain.value)
    np.testing.assert_array_equal(gated.iterations, plain.iterations)
    assert np.all(gated.stopped_tol == 0) and np.isfinite(gated.gate_best)


@pytest.mark.parametrize("method", ["sweeps", "levels"])
def test_every_hypothesis_a_gate_stops_is_certainly_negligible(small, method):
    """A set of 48 hypotheses off any grid: the gate stops at least half the negligible ones (in
    fewer sweeps than they need to converge), each stopped one's exact log-likelihood is within
    its reported tolerance's bound of its values' sum, and its exact posterior mass is below
    ``exp(margin)`` times the best one's."""
    mdp, trajs = small
    rng = np.random.default_rng(9)
    H = 48
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-3, 2, H))
    margin = math.log(1e-12 / H)
    gate = _gate(mdp, trajs, theta, beta, margin)
    sol = solve_screened(mdp, theta, beta, gate, tol=0.1, method=method)
    exact = _exact_ll(mdp, trajs, theta, beta)
    stopped, negligible = sol.stopped_tol > 0, exact < exact.max() + margin
    assert np.all(negligible[stopped])
    # the others of the 19 converge to the loose tol before their bounds part (on this small map)
    assert stopped.sum() >= negligible.sum() // 2 >= 8
    assert sol.gate_best <= exact.max()
    ll, rounding = telescoped_log_likelihood(mdp, [trajs], theta, beta, sol.value)
    err = gate.factor * sol.stopped_tol + rounding
    assert np.all(np.abs(ll - exact)[stopped] <= err[stopped])
    plain = solve(mdp, theta, beta, tol=0.1, method=method)
    assert np.all(sol.iterations[stopped] <= plain.iterations[stopped])
    assert sol.iterations.sum() < plain.iterations.sum()
    np.testing.assert_array_equal(sol.value[~stopped], plain.value[~stopped])


def test_gate_arrays_pad_the_support_with_zero_weights(small):
    mdp, trajs = small
    prep = kernels.prepared(mdp, "float64")
    theta, beta = np.full((3, mdp.n_features), 1.0 / mdp.n_features), np.array([0.5, 1.0, 2.0])
    gate = _gate(mdp, trajs, theta, beta, -30.0)
    g = gate_arrays(gate, prep.rows, np.array([2, 0, 1]), jnp.float64, prep.n_rows - 1)
    k = len(gate.states)
    assert g.rows.shape[0] >= max(k, 8) and g.rows.shape[0] & (g.rows.shape[0] - 1) == 0
    np.testing.assert_array_equal(np.asarray(g.weights)[k:], 0.0)
    np.testing.assert_array_equal(np.asarray(g.rows)[k:], prep.n_rows - 1)  # the zero row
    np.testing.assert_array_equal(np.asarray(g.base), gate.base[[2, 0, 1]])


def test_a_gated_pool_shrinks_straight_to_one_group_without_changing_any_answer(small, monkeypatch):
    """With a gate the pool's tail is short, so a pool with nothing left to hand out moves from 4
    lane groups straight to 1 (no size compiled in between); every hypothesis' sweeps and values
    are those of a pool that never shrinks."""
    mdp, trajs = small
    rng = np.random.default_rng(13)
    H = 24
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-2, 2, H))
    gate = _gate(mdp, trajs, theta, beta, math.log(1e-12 / H))
    opts = {"method": "sweeps", "lanes": 4, "chunk_size": 16, "tol": 1e-3}
    monkeypatch.setattr(kernels, "SHRINK_MIN_ROWS", 10**9)
    whole = solve_screened(mdp, theta, beta, gate, **opts)
    sizes = []
    repack = kernels._repack_pool

    def spy(carry, *, groups):
        sizes.append(groups)
        return repack(carry, groups=groups)

    monkeypatch.setattr(kernels, "_repack_pool", spy)
    monkeypatch.setattr(kernels, "SHRINK_MIN_ROWS", 0)
    shrunk = solve_screened(mdp, theta, beta, gate, **opts)
    assert sizes == [1]
    np.testing.assert_array_equal(shrunk.iterations, whole.iterations)
    np.testing.assert_array_equal(shrunk.stopped_tol, whole.stopped_tol)
    np.testing.assert_array_equal(shrunk.value, whole.value)


@pytest.mark.parametrize("method", ["sweeps", "levels"])
def test_values_above_the_solution_keep_the_two_sided_bound(small, method):
    """From a start above the solution (the pool's sweeps then lower values, so no lane counts as
    below it), every hypothesis the gate stops still has its exact log-likelihood within Σ|w|·tol_h
    of its values' sum, and is negligible."""
    mdp, trajs = small
    rng = np.random.default_rng(17)
    H = 32
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-3, 2, H))
    exact_sol = solve(mdp, theta, beta, tol=1e-12)
    start = exact_sol.value + 40.0 * beta[:, None] * ~mdp.terminal  # 40 nats above, terminals 0
    margin = math.log(1e-12 / H)
    gate = _gate(mdp, trajs, theta, beta, margin)
    sol = solve_screened(mdp, theta, beta, gate, tol=0.1, v_init=start, method=method)
    exact = log_likelihood(np.asarray(exact_sol.log_policy), trajs.state, trajs.action)
    stopped = sol.stopped_tol > 0
    assert stopped.any() and np.all(exact[stopped] < exact.max() + margin)
    ll, rounding = telescoped_log_likelihood(mdp, [trajs], theta, beta, sol.value)
    assert np.all(np.abs(ll - exact)[stopped] <= (gate.factor * sol.stopped_tol + rounding)[stopped])


def test_batches_and_progress_carry_the_best_bound_and_change_no_answer(small, monkeypatch):
    """The gate's best carries from batch to batch (progress batches of the pool, and the solver's
    memory batches): with 48 hypotheses in batches of 8 the stopped set, the values and the best
    bound are those of one batch."""
    from expertise_irl.planning import soft_vi

    mdp, trajs = small
    rng = np.random.default_rng(9)
    H = 48
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-3, 2, H))
    gate = _gate(mdp, trajs, theta, beta, math.log(1e-12 / H))
    one = solve_screened(mdp, theta, beta, gate, tol=0.1, method="sweeps", lanes=2, chunk_size=2)
    ticks = []
    batched = solve_screened(mdp, theta, beta, gate, tol=0.1, method="sweeps", lanes=2, chunk_size=2,
                             progress=lambda done, total: ticks.append(done))
    assert len(ticks) > 1 and ticks[-1] == H
    monkeypatch.setattr(soft_vi, "batch_limit", lambda mdp, memory=None: 8)
    small_batches = solve_screened(mdp, theta, beta, gate, tol=0.1, method="sweeps", lanes=2, chunk_size=2)
    for other in (batched, small_batches):
        assert other.gate_best == pytest.approx(one.gate_best, abs=1e-9)
        stopped = other.stopped_tol > 0
        exact = _exact_ll(mdp, trajs, theta, beta)
        assert stopped.any() and np.all(exact[stopped] < exact.max() + gate.margin)
        np.testing.assert_array_equal(other.value[~stopped & (one.stopped_tol == 0)],
                                      one.value[~stopped & (one.stopped_tol == 0)])


def test_where_newton_applies_the_gate_sweeps_to_one_nat_and_newton_finishes_the_rest(small, monkeypatch):
    """On a map counted as large the gated sweeps go to NEWTON_FROM; the hypotheses they did not
    stop finish by Newton's method (steps recorded) within the tolerance of an exact solve, and the
    stopped ones are negligible."""
    from expertise_irl.planning import soft_vi

    mdp, trajs = small
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_STATES", 1)
    monkeypatch.setattr(soft_vi, "NEWTON_MIN_GAMMA", 0.0)
    monkeypatch.setattr(soft_vi, "_backend", lambda: "cpu")
    rng = np.random.default_rng(19)
    H = 24
    theta, beta = rng.dirichlet(np.ones(mdp.n_features), size=H), np.exp(rng.uniform(-3, 2, H))
    gate = _gate(mdp, trajs, theta, beta, math.log(1e-12 / H))
    sol = solve_screened(mdp, theta, beta, gate, tol=1e-9)
    exact = solve(mdp, theta, beta, tol=1e-12, newton=False)
    stopped = sol.stopped_tol > 0
    assert stopped.any() and (~stopped).any()
    # (a hypothesis the sweeps brought close enough already takes no step)
    assert sol.newton_steps[~stopped].sum() >= 1 and np.all(sol.newton_steps[stopped] == 0)
    err = np.max(np.abs(sol.value - exact.value), axis=1) / beta
    assert np.all(err[~stopped] <= 1e-9 + 1e-12)
    ll = log_likelihood(np.asarray(exact.log_policy), trajs.state, trajs.action)
    assert np.all(ll[stopped] < ll.max() + gate.margin)
    with pytest.raises(TypeError, match="unexpected keywords"):
        solve_screened(mdp, theta, beta, gate, tol=1e-9, chunksize=4)
