"""Observation models: each against a slow reference, the limits that must hold, its gradient,
and the simulator; one backup serves the batched solver and the differentiable likelihood."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from reference_solver import random_mdp, reference

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.inference.task_likelihood import pair_counts
from expertise_irl.mdp import TabularMDP
from expertise_irl.models import BACKUP_MODELS, MODELS, check_model
from expertise_irl.planning.differentiable import make_log_likelihood
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.zones import load_bundled

BETAS = np.array([0.05, 0.3, 1.0, 5.0])
NEW = ("maxent-relative", "boltzmann")


def lp_error(a, b) -> float:
    fa, fb = np.isfinite(a), np.isfinite(b)
    np.testing.assert_array_equal(fa, fb)
    return float(np.max(np.abs(a[fa] - b[fb]), initial=0.0))


@pytest.fixture(scope="module")
def crossroads():
    return load_bundled("crossroads").to_mdp()


@pytest.mark.slow
@pytest.mark.parametrize("model", BACKUP_MODELS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_solve_matches_reference(model, seed):
    """Values, Q and log-policies within 1e-8 (scaled units) of the slow reference, every β at once."""
    rng = np.random.default_rng(seed)
    mdp = random_mdp(rng, 12, 3, 3, gamma=0.9)
    theta = rng.dirichlet(np.ones(3))
    sol = solve(mdp, np.tile(theta, (len(BETAS), 1)), BETAS, tol=1e-11, model=model)
    assert sol.model == model
    for h, beta in enumerate(BETAS):
        ref = reference(mdp, theta, beta, model)
        assert lp_error(sol.log_policy[h], ref.log_policy) <= 1e-8, (model, beta)
        assert np.max(np.abs(sol.value[h] - ref.value)) / beta <= 1e-8, (model, beta)
        assert lp_error(sol.q[h] / beta, ref.q / beta) <= 1e-8, (model, beta)
        np.testing.assert_allclose(sol.policy[h].sum(-1)[~mdp.terminal], 1.0, atol=1e-12)


@pytest.mark.parametrize("model", NEW)
def test_solve_matches_reference_on_a_map(model, crossroads):
    theta = np.array([0.4, 0.3, 0.1, 0.1, 0.1])
    betas = np.array([0.09, 1.0, 10.0])
    sol = solve(crossroads, np.tile(theta, (3, 1)), betas, tol=1e-11, model=model)
    for h, beta in enumerate(betas):
        ref = reference(crossroads, theta, beta, model)
        assert lp_error(sol.log_policy[h], ref.log_policy) <= 1e-8
        assert np.max(np.abs(sol.value[h] - ref.value)) / beta <= 1e-8


def full_action_mdp(rng, S=10, A=3, K=2, gamma=0.9) -> TabularMDP:
    """Every non-terminal state has all A actions; one absorbing goal reachable from everywhere."""
    nxt = rng.integers(0, S, size=(S, A))
    nxt[1:, 0] = np.arange(S - 1)  # action 0 walks towards the goal (state 0)
    terminal = np.zeros(S, dtype=bool)
    terminal[0] = True
    feats = rng.uniform(-1, 0, size=(S, A, K))
    return TabularMDP(nxt, feats, terminal, gamma=gamma)


def test_relative_equals_maxent_with_a_step_cost():
    """With |A(s)| = A everywhere, maxent-relative = maxent with β·log A taken off every move."""
    rng = np.random.default_rng(5)
    mdp = full_action_mdp(rng)
    A = mdp.n_actions
    theta, beta = np.array([0.7, 0.3]), 2.0
    step = np.concatenate([mdp.features, -np.ones((*mdp.features.shape[:2], 1))], axis=-1)
    costed = TabularMDP(mdp.next_state, step, mdp.terminal, gamma=mdp.gamma)
    rel = solve(mdp, theta, beta, tol=1e-12, model="maxent-relative")
    ment = solve(costed, np.append(theta, beta * np.log(A)), beta, tol=1e-12)
    np.testing.assert_allclose(rel.value, ment.value, atol=1e-9)
    assert lp_error(rel.log_policy, ment.log_policy) <= 1e-9
    # Without the step cost the policies differ: random moves are paid under maxent only.
    plain = solve(mdp, theta, beta, tol=1e-12)
    assert lp_error(rel.log_policy, plain.log_policy) > 1e-3


def test_relative_finishes_where_maxent_wanders(crossroads):
    """The issue's case: θ = (.4, .3, .1, .1, .1), β = 1 on crossroads."""
    theta = np.array([0.4, 0.3, 0.1, 0.1, 0.1])
    done = {}
    for model in ("maxent", "maxent-relative"):
        t = simulate(crossroads, theta, 1.0, 20, np.random.default_rng(0), model=model, max_steps=500)
        lengths = np.bincount(t.episode)
        done[model] = int(np.sum(lengths < 500))
    assert done["maxent"] == 0
    assert done["maxent-relative"] == 20


def test_boltzmann_goes_greedy_as_beta_goes_to_zero(crossroads):
    from reference_solver import hard_value_iteration

    theta = np.array([0.5, 0.2, 0.1, 0.1, 0.1])
    hard = hard_value_iteration(crossroads, theta, tie_atol=1e-9)
    A = crossroads.n_actions
    for beta in (1e-2, 1e-3):
        sol = solve(crossroads, theta, beta, tol=1e-10, model="boltzmann")
        pi = sol.policy[0]
        for s in np.flatnonzero(~crossroads.terminal):
            greedy = sorted(hard.greedy[s])
            others = [a for a in np.flatnonzero(crossroads.available[s]) if a not in hard.greedy[s]]
            # off-greedy mass <= (A - 1) exp(-gap / β): it vanishes as β -> 0
            gap = min((hard.value[s] - hard.q[s, a] for a in others), default=np.inf)
            assert 1 - pi[s, greedy].sum() <= (A - 1) * np.exp(-gap / beta) * (1 + 1e-6) + 1e-12, s
        np.testing.assert_allclose(sol.value[0], hard.value, atol=1e-8)


def test_boltzmann_solves_each_theta_once(crossroads):
    """Two θ × four β: every β of a θ starts from the same hard values (same hard sweep count)."""
    thetas = np.array([[0.5, 0.5, 0, 0, 0], [0.2, 0.2, 0.2, 0.2, 0.2]])
    th = np.repeat(thetas, len(BETAS), axis=0)
    be = np.tile(BETAS, 2)
    sol = solve(crossroads, th, be, model="boltzmann")
    alone = [solve(crossroads, t, b, model="boltzmann") for t, b in zip(th, be, strict=True)]
    for h, single in enumerate(alone):
        assert lp_error(sol.log_policy[h], single.log_policy[0]) <= 2e-8
    # the hard values are identical in reward units for every β of one θ
    for i in range(2):
        v = sol.value[i * len(BETAS):(i + 1) * len(BETAS)]
        np.testing.assert_allclose(v, np.broadcast_to(v[0], v.shape), atol=1e-7 * np.abs(v).max())


@pytest.mark.parametrize("model", BACKUP_MODELS)
def test_gradient_matches_finite_differences(model, crossroads):
    rng = np.random.default_rng(3)
    theta0 = np.array([0.4, 0.3, 0.1, 0.1, 0.1])
    trajs = simulate(crossroads, theta0, 0.5, 5, rng, model="maxent-relative", max_steps=80)
    f = make_log_likelihood(crossroads, pair_counts(crossroads, trajs), tol=1e-12, model=model)
    theta, beta = np.array([0.3, 0.3, 0.2, 0.1, 0.1]), 0.8
    g_theta, g_beta = jax.grad(lambda t, b: f(t, b)[0], argnums=(0, 1))(theta, beta)
    eps = 1e-5
    for k in range(5):
        e = np.zeros(5)
        e[k] = eps
        fd = (float(f(theta + e, beta)[0]) - float(f(theta - e, beta)[0])) / (2 * eps)
        assert float(g_theta[k]) == pytest.approx(fd, rel=1e-5, abs=1e-6), (model, k)
    fd_b = (float(f(theta, beta + eps)[0]) - float(f(theta, beta - eps)[0])) / (2 * eps)
    assert float(g_beta) == pytest.approx(fd_b, rel=1e-5, abs=1e-6)


@pytest.mark.parametrize("model", BACKUP_MODELS)
def test_likelihood_equals_the_batched_solver(model, crossroads):
    """The differentiable path and the lane pool share one backup: same log-likelihood."""
    trajs = simulate(crossroads, np.array([0.6, 0.1, 0.1, 0.1, 0.1]), 0.3, 4, np.random.default_rng(1),
                     model=model, max_steps=60)
    f = make_log_likelihood(crossroads, pair_counts(crossroads, trajs), tol=1e-11, model=model)
    theta, beta = np.array([0.2, 0.4, 0.2, 0.1, 0.1]), 0.7
    sol = solve(crossroads, theta, beta, tol=1e-11, model=model)
    batch = float(sol.log_policy[0][trajs.state, trajs.action].sum())
    ll, v = f(theta, beta)
    assert float(ll) == pytest.approx(batch, abs=1e-7)
    np.testing.assert_allclose(np.asarray(v) * beta, sol.value[0], atol=1e-7)
    ll_warm, _ = f(theta, beta, v)  # a warm start reaches the same fixed point
    assert float(ll_warm) == pytest.approx(batch, abs=1e-7)


@pytest.mark.parametrize("model", BACKUP_MODELS)
def test_simulator_uses_the_models_policy(model, crossroads):
    theta, beta = np.array([0.4, 0.3, 0.1, 0.1, 0.1]), 1.0
    lp = solve(crossroads, theta, beta, model=model).log_policy[0]
    a = simulate(crossroads, theta, beta, 5, np.random.default_rng(9), model=model, max_steps=50)
    b = simulate(crossroads, None, None, 5, np.random.default_rng(9), log_policy=lp, max_steps=50)
    np.testing.assert_array_equal(a.action, b.action)
    # First actions from one start state: frequencies follow π within 5 binomial sd.
    s0 = int(np.flatnonzero(~crossroads.terminal)[40])
    t = simulate(crossroads, theta, beta, 4000, np.random.default_rng(2), model=model, starts=[s0],
                 max_steps=1)
    freq = np.bincount(t.action, minlength=crossroads.n_actions) / 4000
    p = np.exp(lp[s0])
    assert np.all(np.abs(freq - p) <= 5 * np.sqrt(p * (1 - p) / 4000) + 1e-12)


def test_unknown_model_is_refused(crossroads):
    with pytest.raises(InputError, match="model must be one of maxent, maxent-relative, boltzmann"):
        solve(crossroads, np.ones(5) / 5, 1.0, model="softmax")
    with pytest.raises(InputError, match="model must be one of"):
        make_log_likelihood(crossroads, np.zeros((crossroads.n_states, crossroads.n_actions)), model="x")


def test_pedagogical_is_a_model_that_no_solver_takes(crossroads):
    """Known (check_model with solvable=False), but every solver path refuses it in one line naming the
    field, before any work: it has no backup of its own."""
    assert set(MODELS) - set(BACKUP_MODELS) == {"pedagogical"}
    assert check_model("pedagogical", solvable=False) == "pedagogical"
    with pytest.raises(InputError, match=r"^model pedagogical has no Bellman backup"):
        solve(crossroads, np.ones(5) / 5, 1.0, model="pedagogical")
    with pytest.raises(InputError, match=r"^model pedagogical has no Bellman backup"):
        make_log_likelihood(crossroads, np.zeros((crossroads.n_states, crossroads.n_actions)),
                            model="pedagogical")
    with pytest.raises(InputError, match=r"^model pedagogical has no Bellman backup"):
        simulate(crossroads, np.ones(5) / 5, 1.0, 1, 0, model="pedagogical")
    with pytest.raises(InputError, match=r"^models pedagogical"):
        check_model("pedagogical", "models")


def test_a_solve_that_does_not_converge_is_nan_not_wrong(crossroads):
    trajs = simulate(crossroads, np.array([0.6, 0.1, 0.1, 0.1, 0.1]), 0.5, 2, np.random.default_rng(0),
                     max_steps=40)
    counts = pair_counts(crossroads, trajs)
    f = make_log_likelihood(crossroads, counts, max_iter=10)
    assert np.isnan(float(f(np.ones(5) / 5, 0.5)[0]))
    # The adjoint converges as fast as the forward solve (the constant zero row must not be an
    # eigenvalue-1 direction): with a cap a little above the forward's sweeps, the gradient is finite.
    g = jax.grad(lambda t, b: make_log_likelihood(crossroads, counts, max_iter=2000)(t, b)[0],
                 argnums=(0, 1))(np.ones(5) / 5, 0.5)
    assert np.all(np.isfinite(np.asarray(g[0]))) and np.isfinite(float(g[1]))
