"""Large worlds: generated floor plans, the solver's greedy path jumps and its memory-sized pool."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.hypotheses import resolve_betas, resolve_thetas
from expertise_irl.mdp import TabularMDP
from expertise_irl.planning import kernels, soft_vi
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.floorplans import LARGE_GAMMA, floor_plan_text, generate_floor_plan
from expertise_irl.worlds.warehouse import parse_floor_plan


def test_generated_floor_plans_are_reproducible_and_reach_the_goal():
    a, b = generate_floor_plan(40, seed=3), generate_floor_plan(40, seed=3)
    np.testing.assert_array_equal(a.grid, b.grid)
    assert not np.array_equal(a.grid, generate_floor_plan(40, seed=4).grid)
    mdp = a.to_mdp()  # validation: every state reaches a goal
    assert mdp.gamma == LARGE_GAMMA and mdp.start_states is not None
    assert 0.95 * 2 * 40 * 40 <= mdp.n_states <= 2 * 40 * 40
    assert {"x", "#", ">", "<", "^", "v", "G", "S"} <= set(a.grid.ravel().tolist())
    again = parse_floor_plan(floor_plan_text(a), gamma=a.gamma)  # the text round-trips
    np.testing.assert_array_equal(again.grid, a.grid)
    with pytest.raises(InputError, match="size must be a whole number >= 8"):
        generate_floor_plan(5)


def _ring(n: int, gamma: float = 0.99) -> TabularMDP:
    """n states in a ring (action 0: to the next, feature +1) with an exit to a terminal state
    from each (action 1, feature -50): a person of small β circles for ever."""
    nxt = np.full((n + 1, 2), -1)
    nxt[:n, 0] = (np.arange(n) + 1) % n
    nxt[:n, 1] = n
    feats = np.zeros((n + 1, 2, 1))
    feats[:n, 0, 0] = 1.0 + 0.1 * (np.arange(n) % 3)  # uneven, so values differ round the ring
    feats[:n, 1, 0] = -50.0
    return TabularMDP(next_state=nxt, features=feats, terminal=np.arange(n + 1) == n, gamma=gamma)


def test_a_jump_sums_a_loop_that_sweeps_need_thousands_of_sweeps_for():
    n, gamma, beta = 40, 0.99, 0.05
    mdp = _ring(n, gamma)
    r = mdp.features[:n, 0, 0] / beta
    # the greedy walk's values round the ring: v(s) = Σ_k γ^k r(s+k) over the whole future
    exact = np.array([sum(gamma ** k * r[(s + k) % n] for k in range(n)) for s in range(n)])
    exact /= 1 - gamma ** n
    prep = kernels.prepared(mdp, "float64")
    import jax.numpy as jnp

    w = jnp.asarray(mdp.reward_weights(np.ones((4, 1))) / beta)
    v, jumps = kernels.jump_start(prep, w, jnp.zeros((4, prep.n_rows)), jnp.asarray(gamma),
                                  jnp.asarray(1e-10), groups=1, lanes=4)
    got = np.asarray(v)[0, prep.rows[:n]]
    # the exit's probability is e^-1000 of the ring's: the soft values are the greedy walk's to
    # far below 1e-9 relative, so a few jumps land on them
    assert np.max(np.abs(got - exact) / np.abs(exact)) < 1e-12
    assert int(jumps[0]) <= 3
    sweeps = solve(mdp, np.ones((1, 1)), beta, method="sweeps", over_relax=False)
    jumped = solve(mdp, np.ones((1, 1)), beta, method="jumps", over_relax=False)
    assert sweeps.iterations[0] > 1000  # γ² per sweep from 1e3 nats to 1e-10
    assert jumped.iterations[0] <= 40
    assert np.max(np.abs(jumped.value - sweeps.value)) / beta <= 2e-8


@pytest.fixture(scope="module")
def plan_mdp():
    return generate_floor_plan(24, seed=1).to_mdp()


@pytest.fixture(scope="module")
def real_set(plan_mdp):
    th = resolve_thetas("paper-real", plan_mdp.n_features)[::3]
    be = resolve_betas("paper-real")[[0, 2, 4]]  # 0.1, 1, 10
    return np.repeat(th, len(be), axis=0), np.tile(be, len(th))


@pytest.mark.slow
@pytest.mark.parametrize("method", ["jumps", "levels"])
def test_jumps_and_levels_agree_with_sweeps_within_the_tolerance_and_save_sweeps(plan_mdp, real_set, method):
    theta, beta = real_set
    sweeps = solve(plan_mdp, theta, beta, method="sweeps")
    jumps = solve(plan_mdp, theta, beta, method=method)
    # each is within tol = 1e-8 nats of the fixed point on V/β (certified by the pool's plain
    # sweep), so within 2e-8 of each other; log-policies within twice that
    assert np.max(np.abs(jumps.value - sweeps.value) / beta[:, None]) <= 2e-8
    fin = np.isfinite(sweeps.log_policy)
    np.testing.assert_array_equal(np.isfinite(jumps.log_policy), fin)
    assert np.max(np.abs(jumps.log_policy[fin] - sweeps.log_policy[fin])) <= 4e-8
    if method == "jumps":
        low = beta <= 0.1  # near-greedy people: the jumps' case
        assert jumps.iterations[low].mean() < 0.5 * sweeps.iterations[low].mean()


@pytest.mark.slow
@pytest.mark.parametrize("method", ["jumps", "levels"])
def test_jumped_and_level_solutions_are_the_same_whatever_the_lane_width(plan_mdp, real_set, method):
    theta, beta = real_set[0][::2], real_set[1][::2]
    sols = {lanes: solve(plan_mdp, theta, beta, method=method, lanes=lanes) for lanes in (4, 8)}
    # each hypothesis' jumps and sweeps depend on its own lane only
    np.testing.assert_array_equal(sols[4].iterations, sols[8].iterations)
    assert np.max(np.abs(sols[4].value - sols[8].value) / beta[:, None]) <= 2e-8


def test_method_choice_and_its_errors(monkeypatch):
    small = _ring(6)
    a = solve(small, np.ones((1, 1)), 0.5)  # default: sweeps
    b = solve(small, np.ones((1, 1)), 0.5, method="sweeps")
    np.testing.assert_array_equal(a.value, b.value)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    monkeypatch.setenv(soft_vi.SOLVER_ENV, "jumps")
    c = solve(small, np.ones((1, 1)), 0.5)
    d = solve(small, np.ones((1, 1)), 0.5, method="jumps")
    np.testing.assert_array_equal(c.iterations, d.iterations)
    assert not np.array_equal(c.iterations, a.iterations)  # the variable did choose the jumps
    monkeypatch.setenv(soft_vi.SOLVER_ENV, "fast")
    with pytest.raises(InputError, match="EXPERTISE_IRL_SOLVER='fast': must be one of sweeps, jumps, levels"):
        solve(small, np.ones((1, 1)), 0.5)
    with pytest.raises(InputError, match="method must be one of sweeps, jumps, levels, got 'lu'"):
        solve(small, np.ones((1, 1)), 0.5, method="lu")


@pytest.mark.slow
def test_large_maps_default_to_level_order(plan_mdp, monkeypatch):
    monkeypatch.delenv(soft_vi.SOLVER_ENV, raising=False)
    theta, beta = [[1.0, 0, 0], [0, 0, 1.0]], [0.1, 0.3]
    assert soft_vi.default_method(plan_mdp) == "sweeps"  # 1,138 states
    small = solve(plan_mdp, theta, beta)
    np.testing.assert_array_equal(small.iterations, solve(plan_mdp, theta, beta, method="sweeps").iterations)
    monkeypatch.setattr(soft_vi, "LEVELS_MIN_STATES", plan_mdp.n_states)  # this plan counts as large
    assert soft_vi.default_method(plan_mdp) == "levels" and soft_vi.default_method() == "sweeps"
    large = solve(plan_mdp, theta, beta)
    np.testing.assert_array_equal(large.iterations, solve(plan_mdp, theta, beta, method="levels").iterations)
    assert not np.array_equal(large.iterations, small.iterations)
    monkeypatch.setenv(soft_vi.SOLVER_ENV, "sweeps")  # the variable still decides
    assert soft_vi.default_method(plan_mdp) == "sweeps"


def test_a_gpu_keeps_the_plain_sweeps_on_large_maps(plan_mdp, monkeypatch):
    monkeypatch.delenv(soft_vi.SOLVER_ENV, raising=False)
    monkeypatch.setattr(soft_vi, "LEVELS_MIN_STATES", plan_mdp.n_states)  # this plan counts as large
    assert soft_vi.default_method(plan_mdp) == "levels"
    monkeypatch.setattr(soft_vi, "_backend", lambda: "gpu")
    assert soft_vi.default_method(plan_mdp) == "sweeps"
    monkeypatch.setenv(soft_vi.SOLVER_ENV, "levels")  # the variable still decides
    assert soft_vi.default_method(plan_mdp) == "levels"


def test_the_pool_shrinks_to_the_memory_it_has():
    mdp = generate_floor_plan(30).to_mdp()
    S = mdp.n_states
    roomy = kernels.default_chunk_size(mdp, lanes=4, memory=64 * 2**30)
    assert roomy == kernels.default_chunk_size(mdp, lanes=4, memory=10**15)  # memory not binding
    # room for 10 lanes' copies in the memory's share: 8 lanes (two groups of 4)
    tight = int(10 * kernels.LANE_COPIES * S * 8 / kernels.MEMORY_SHARE)
    assert kernels.default_chunk_size(mdp, lanes=4, memory=tight) == 8
    assert kernels.default_chunk_size(mdp, lanes=4, memory=1) == 4  # never below one group
    assert kernels.available_memory() > 0


def test_a_set_too_large_for_memory_is_solved_in_batches_with_the_same_answer(monkeypatch):
    """The level phase's ``[H, rows]`` copies are counted: with the memory's share room for fewer
    hypotheses than asked, the solve runs in batches (seen by the calls), each hypothesis' values,
    policy and sweeps as in one pass, and progress counts up to H."""
    mdp = generate_floor_plan(16, seed=1).to_mdp()
    rng = np.random.default_rng(3)
    theta = rng.dirichlet(np.ones(3), size=11)
    beta = np.exp(rng.uniform(np.log(0.1), np.log(3.0), size=11))
    one = solve(mdp, theta, beta, method="levels")
    assert soft_vi.batch_limit(mdp, memory=10**15) > 11
    monkeypatch.setattr(soft_vi, "MIN_BATCH", 4)
    monkeypatch.setattr(kernels, "available_memory", lambda: 1)
    assert soft_vi.batch_limit(mdp) == 4
    calls, ticks = [], []
    inner = soft_vi._solve_all
    monkeypatch.setattr(soft_vi, "_solve_all",
                        lambda m, th, b, **kw: calls.append(len(b)) or inner(m, th, b, **kw))
    batched = solve(mdp, theta, beta, method="levels", progress=lambda d, t: ticks.append((d, t)))
    assert calls == [4, 4, 3]
    np.testing.assert_allclose(batched.value, one.value, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(batched.iterations, one.iterations)
    assert np.array_equal(np.isfinite(batched.log_policy), np.isfinite(one.log_policy))
    fin = np.isfinite(one.log_policy)
    np.testing.assert_allclose(batched.log_policy[fin], one.log_policy[fin], rtol=0, atol=1e-12)
    assert ticks[-1] == (11, 11) and all(t == 11 for _, t in ticks)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["jumps", "levels"])
@pytest.mark.parametrize("model", ["maxent-relative", "boltzmann"])
def test_jumps_and_levels_meet_the_same_guarantee_under_the_other_models(model, method):
    mdp = generate_floor_plan(16, seed=1).to_mdp()
    theta = np.array([[0, 0, 1.0], [1, 0, 0], [0.4, 0.2, 0.4]])
    beta = np.array([0.1, 0.3, 1.0])
    sweeps = solve(mdp, theta, beta, model=model, method="sweeps")
    jumps = solve(mdp, theta, beta, model=model, method=method)
    assert np.max(np.abs(jumps.value - sweeps.value) / beta[:, None]) <= 2e-8  # each within 1e-8
    if method == "jumps":  # the road-loving person of β = 0.1 circles a two-state loop:
        # sweeps need ~1/(1-γ²) per nat, jumps do not (levels do: a two-state loop is one move
        # towards the goal and one away, which a symmetric sweep crosses once, as two sweeps do)
        assert jumps.iterations[0] < 0.2 * sweeps.iterations[0]


def test_level_order_carries_values_round_a_long_loop_in_one_pass():
    # a one-way ring of n states whose only exit is at state 0: the distances to the goal fall
    # from n to 1 round the ring, so the outward pass updates every state after its successor
    n, gamma, beta = 60, 0.99, 0.05
    ring = _ring(n, gamma)
    nxt = ring.next_state.copy()
    nxt[1:n, 1] = -1  # exits elsewhere closed
    mdp = TabularMDP(next_state=nxt, features=ring.features, terminal=ring.terminal, gamma=gamma)
    sweeps = solve(mdp, np.ones((1, 1)), beta, method="sweeps", over_relax=False)
    levels = solve(mdp, np.ones((1, 1)), beta, method="levels")
    assert sweeps.iterations[0] > 1000  # γ² per sweep
    # γ^n = 0.55 per pass: ~50 passes from ~1e3 nats to the threshold 1e-10, then the pool's check
    assert levels.iterations[0] <= 130
    assert np.max(np.abs(levels.value - sweeps.value)) / beta <= 2e-8


def test_level_order_follows_the_distance_to_the_goal():
    from expertise_irl.planning import level_order

    mdp = generate_floor_plan(16, seed=1).to_mdp()
    dist = kernels.goal_distance(mdp)
    assert np.all(dist[mdp.terminal] == 0) and np.all(dist[~mdp.terminal] > 0)
    # a move lowers the distance by at most one, and the distance is one more than the best move's
    nxt = np.where(mdp.available, np.maximum(mdp.next_state, 0), 0)
    best = np.where(mdp.available, dist[nxt], np.iinfo(np.int64).max).min(axis=1)
    np.testing.assert_array_equal(dist[~mdp.terminal], best[~mdp.terminal] + 1)
    prep = kernels.prepared(mdp, "float64")
    lv = level_order.level_blocks(mdp, prep, block=8)
    rows = np.asarray(lv.rows)
    level_of_row = np.full(prep.n_rows, -1)
    level_of_row[prep.rows[~mdp.terminal]] = dist[~mdp.terminal]
    per_block = level_of_row[rows]
    assert np.all(per_block == per_block[:, :1])  # a block holds one level
    assert np.all(np.diff(per_block[:, 0]) >= 0)  # blocks in order of distance
    live = prep.rows[~mdp.terminal]
    np.testing.assert_array_equal(np.unique(rows), np.sort(live))  # every live state, no other row


def _backup_np(model: str, q: np.ndarray, n_actions: np.ndarray) -> np.ndarray:
    """The Bellman backup of scaled Q-values ``[S, A]`` (``-inf`` where unavailable)."""
    from scipy.special import logsumexp

    if model == "boltzmann":
        return q.max(axis=1)
    return logsumexp(q, axis=1) - (np.log(n_actions) if model == "maxent-relative" else 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("model", ["maxent", "maxent-relative", "boltzmann"])
def test_the_level_start_is_the_walk_towards_the_goal_and_a_lower_bound(model):
    import jax.numpy as jnp

    from expertise_irl.planning import level_order

    mdp = generate_floor_plan(16, seed=1).to_mdp()
    S, g = mdp.n_states, mdp.gamma
    theta = np.array([[1.0, 0, 0], [0.4, 0.2, 0.4], [0, 0, 1.0]])
    beta = np.array([0.1, 1.0, 0.3])
    w = mdp.reward_weights(theta) / beta[:, None]
    prep = kernels.prepared(mdp, "float64")
    lv = level_order.levels_of(mdp, prep, "float64")
    v = np.asarray(level_order.approach_start(lv, jnp.asarray(w), jnp.zeros((3, prep.n_rows)), jnp.asarray(g),
                                              lanes=2, model=model))[:, prep.rows]  # 3 on lanes of 2
    dist, live = kernels.goal_distance(mdp), ~mdp.terminal
    nxt = np.where(mdp.available, np.maximum(mdp.next_state, 0), 0)
    n_actions = mdp.available.sum(axis=1)
    toward = mdp.available & (dist[nxt] == dist[:, None] - 1)
    basis = mdp.reward_basis()
    gaps = []
    for h in range(3):
        r = np.where(mdp.available, basis @ w[h], -np.inf)
        # level by level, the same backup restricted to the moves towards the goal
        u = np.zeros(S)
        for k in range(1, dist.max() + 1):
            s = np.flatnonzero((dist == k) & live)
            u[s] = _backup_np(model, np.where(toward[s], r[s] + g * u[nxt[s]], -np.inf), n_actions[s])
        np.testing.assert_allclose(v[h], u, rtol=0, atol=1e-9)
        tv = np.zeros(S)
        tv[live] = _backup_np(model, (r + g * v[h][nxt])[live], n_actions[live])
        assert np.all(v[h] <= tv + 1e-9)  # v ≤ T v: the sweeps rise from it
        gaps.append(np.max(tv - v[h]))
        exact = solve(mdp, theta[h], beta[h], model=model, method="sweeps").value[0] / beta[h]
        assert np.all(v[h] <= exact + 1e-7)
    # a length-only person's walk towards the goal is nearly their solution already; the road-lover
    # circles loops that the walk towards the goal never takes
    assert gaps[0] < 1e-2 and gaps[2] > 1.0


def test_a_cold_level_solve_starts_from_the_walk_towards_the_goal():
    # far from the goal a length-only person's values are ~ -1/((1-γ)β) = -1,000 nats; from zero
    # the sweeps come down at γ per move, from the walk towards the goal they start within a few nats
    mdp = generate_floor_plan(40, seed=0).to_mdp()
    cold = solve(mdp, [1.0, 0, 0], 0.1, method="levels")
    zero = solve(mdp, [1.0, 0, 0], 0.1, method="levels", v_init=np.zeros((1, mdp.n_states)))
    assert 2 * cold.iterations[0] < zero.iterations[0]  # 15 against 72 sweeps
    np.testing.assert_allclose(cold.value / 0.1, zero.value / 0.1, rtol=0, atol=2e-8)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["sweeps", "levels"])
def test_a_pool_with_nothing_left_to_hand_out_shrinks_without_changing_any_answer(plan_mdp, real_set,
                                                                                  monkeypatch, method):
    from expertise_irl.planning import level_order

    theta, beta = real_set
    opts = {"method": method, "lanes": 4, "chunk_size": 16}  # 4 lane groups
    monkeypatch.setattr(kernels, "SHRINK_MIN_ROWS", 10**9)
    whole = solve(plan_mdp, theta, beta, **opts)
    shrunk_to = []

    def spy_on(mod, name):
        repack = getattr(mod, name)

        def spy(carry, *, groups):
            shrunk_to.append((name, groups))
            return repack(carry, groups=groups)

        monkeypatch.setattr(mod, name, spy)

    spy_on(kernels, "_repack_pool")
    spy_on(level_order, "_level_repack")
    monkeypatch.setattr(kernels, "SHRINK_MIN_ROWS", 0)
    shrunk = solve(plan_mdp, theta, beta, **opts)
    # 4 groups -> 2 -> 1 in the sweep pool (and in the level pool before it); a size that the busy
    # lanes already fit in half of is skipped (after the level pool, 4 -> 1 with levels)
    pool = [g for name, g in shrunk_to if name == "_repack_pool"]
    assert pool[-1] == 1 and pool == sorted(pool, reverse=True) and len(set(pool)) == len(pool)
    assert method == "levels" or pool == [2, 1]
    assert method == "sweeps" or ("_level_repack", 1) in shrunk_to
    # each lane's sweeps depend on its own hypothesis only, wherever it sits
    np.testing.assert_array_equal(shrunk.iterations, whole.iterations)
    assert np.max(np.abs(shrunk.value - whole.value) / beta[:, None]) <= 1e-9


@pytest.mark.slow
def test_a_few_hypotheses_on_a_large_map_take_narrower_lanes(plan_mdp, monkeypatch):
    seen = []
    pool = kernels.solve_pool

    def spy(*args, lanes, **kw):
        seen.append(lanes)
        return pool(*args, lanes=lanes, **kw)

    monkeypatch.setattr(kernels, "solve_pool", spy)
    monkeypatch.setattr(soft_vi, "lane_width", lambda dtype, measure: 4)
    kw = {"newton": False}  # one pool per solve (Newton's finish runs the pool twice)
    wide = solve(plan_mdp, [[0.4, 0.2, 0.4]] * 3, [0.3, 1.0, 3.0], **kw)
    monkeypatch.setattr(kernels, "SHRINK_MIN_ROWS", 0)  # this plan counts as large
    narrow = solve(plan_mdp, [[0.4, 0.2, 0.4]] * 3, [0.3, 1.0, 3.0], **kw)
    one = solve(plan_mdp, [0.4, 0.2, 0.4], 0.3, **kw)
    assert seen == [4, 2, 1]  # 3 hypotheses: 2 lanes (two groups); 1 hypothesis: 1 lane
    np.testing.assert_array_equal(narrow.iterations, wide.iterations)
    assert np.max(np.abs(narrow.value - wide.value) / np.array([0.3, 1.0, 3.0])[:, None]) <= 2e-8
    assert np.max(np.abs(one.value[0] - wide.value[0])) / 0.3 <= 2e-8
