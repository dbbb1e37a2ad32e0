"""Sharing β across tasks, a θ per task: the objective, recovery, agreement with one task, NUTS."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.inference.gradient import map_estimate
from expertise_irl.inference.methods import get_method
from expertise_irl.inference.nuts import nuts_posterior
from expertise_irl.inference.priors import log_prior_jax
from expertise_irl.inference.shared_beta import (
    SharedBetaNUTS,
    _describe_nuts,
    _statistics,
    fit_shared_beta,
    map_shared_beta,
    nuts_shared_beta,
    shared_beta_log_likelihood,
    shared_beta_log_posterior,
)
from expertise_irl.inference.task_likelihood import tasks_log_likelihood
from expertise_irl.worlds.zones import load_bundled

# Two tasks that ask for different things (length first; "avoid" first), one person's β.
THETA_A = np.array([0.6, 0.1, 0.1, 0.1, 0.1])
THETA_B = np.array([0.1, 0.1, 0.6, 0.1, 0.1])
BETA = 0.3


@pytest.fixture(scope="module")
def corridor():
    return load_bundled("corridor").to_mdp()


@pytest.fixture(scope="module")
def two_tasks(corridor):
    crossroads = load_bundled("crossroads").to_mdp()
    a = simulate(corridor, THETA_A, BETA, 4, np.random.default_rng(1))
    b = simulate(crossroads, THETA_B, BETA, 4, np.random.default_rng(2))
    return [corridor, crossroads], [a, b]


def _cos(a, b) -> float:
    return float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))


@pytest.mark.parametrize("prior", ["log-uniform", "paper"])
def test_the_objective_is_the_sum_of_each_tasks_log_likelihood_at_its_theta(two_tasks, prior):
    mdps, trajs = two_tasks
    thetas = jnp.asarray([[0.3, 0.3, 0.2, 0.1, 0.1], [0.05, 0.15, 0.5, 0.2, 0.1]])
    beta = 0.7
    each = [float(tasks_log_likelihood(m, t, tol=1e-12)(thetas[i], beta)[0])
            for i, (m, t) in enumerate(zip(mdps, trajs, strict=True))]
    f = shared_beta_log_likelihood(mdps, trajs, tol=1e-12)
    assert float(f(thetas, beta)[0]) == pytest.approx(sum(each), rel=1e-12)
    assert [float(x) for x in f.per_task(thetas, beta)] == pytest.approx(each, rel=1e-12)
    # The log-posterior adds the prior once: β's part (each θ_t's is flat on the simplex).
    g = shared_beta_log_posterior(mdps, trajs, prior=prior, tol=1e-12)
    expected = sum(each) + float(log_prior_jax(prior)(thetas[0], beta))
    assert float(g(thetas, beta)) == pytest.approx(expected, rel=1e-12)
    assert float(g(thetas, 1e3)) == -math.inf  # outside every prior's β range


def test_the_tasks_must_pair_up_and_share_features(two_tasks):
    import dataclasses

    mdps, trajs = two_tasks
    with pytest.raises(InputError, match="one list of trajectories per MDP"):
        shared_beta_log_likelihood(mdps, trajs[:1])
    other = dataclasses.replace(mdps[1], feature_names=("a", "b", "c", "d", "e"))
    with pytest.raises(InputError, match="task 2 has features"):
        map_shared_beta([mdps[0], other], trajs, rng=np.random.default_rng(0))
    with pytest.raises(InputError, match="map or nuts"):
        fit_shared_beta("birl", mdps, trajs, get_method("birl").options_from({}), 0)
    with pytest.raises(InputError, match="takes NUTSOptions"):
        fit_shared_beta("nuts", mdps, trajs, get_method("map").options_from({}), 0)


@pytest.mark.slow
def test_sharing_beta_recovers_each_tasks_theta_where_one_theta_cannot(corridor):
    # 30 episodes a task on the same map, two different rewards, one β. Over simulation seeds 0-3
    # (30 and 60 episodes) shared-β MAP reached cos 0.95-1.0 on both tasks and one shared θ
    # 0.55-0.58 on task A, 0.97-0.98 on task B; the margins below leave room either way.
    a = simulate(corridor, THETA_A, BETA, 30, np.random.default_rng(10))
    b = simulate(corridor, THETA_B, BETA, 30, np.random.default_rng(20))
    shared = map_shared_beta([corridor, corridor], [a, b], n_starts=4, rng=np.random.default_rng(0))
    one = map_estimate([corridor, corridor], [a, b], n_starts=4, rng=np.random.default_rng(0))
    per_task = [_cos(shared.thetas[0], THETA_A), _cos(shared.thetas[1], THETA_B)]
    pooled = [_cos(one.theta, THETA_A), _cos(one.theta, THETA_B)]
    assert shared.thetas.shape == (2, 5) and np.allclose(shared.thetas.sum(axis=1), 1.0)
    assert min(per_task) > 0.93
    assert pooled[0] < 0.75  # one θ cannot serve a task that wants something else
    assert all(s > p for s, p in zip(per_task, pooled, strict=True))
    assert shared.log_posterior > one.log_posterior  # nested: one θ is shared-β with θ_A = θ_B
    assert abs(math.log(shared.beta / BETA)) < math.log(1.5)
    assert shared.starts.shape == (4, 2 * 5 + 1) and shared.optima.shape == (4,)


@pytest.mark.slow
def test_with_one_task_map_is_map_estimate(corridor):
    demos = simulate(corridor, THETA_A, 0.5, 6, np.random.default_rng(3))
    shared = map_shared_beta(corridor, demos, n_starts=3, rng=np.random.default_rng(4))
    single = map_estimate(corridor, demos, n_starts=3, rng=np.random.default_rng(4))
    # Same starts from the same generator, same objective: the same optimum.
    np.testing.assert_array_equal(shared.starts, single.starts)
    np.testing.assert_allclose(shared.thetas[0], single.theta, atol=1e-6)
    assert shared.beta == pytest.approx(single.beta, rel=1e-6)
    assert shared.log_posterior == pytest.approx(single.log_posterior, abs=1e-6)


@pytest.mark.slow  # two NUTS runs of 250 iterations × 2 chains: ~20 s
def test_with_one_task_nuts_agrees_with_nuts_posterior_within_monte_carlo_error(corridor):
    demos = simulate(corridor, THETA_A, 0.5, 6, np.random.default_rng(3))
    kwargs = dict(num_warmup=100, num_samples=150, num_chains=2)
    # Different seeds: independent runs of the two samplers, so only the posteriors can agree.
    shared = nuts_shared_beta(corridor, demos, seed=1, **kwargs)
    single = nuts_posterior(corridor, demos, seed=2, **kwargs)
    assert shared.theta.shape == (2, 150, 1, 5)
    # Each posterior mean has Monte-Carlo standard error sd/√ESS (bulk ESS of that parameter), so
    # the difference of two independent runs' means has sd √(sd₁²/ESS₁ + sd₂²/ESS₂); 4 of them
    # leave a 6e-5 chance per parameter (6 of them) of a false alarm. ESS here is ~150-300.
    pairs = [(shared.beta, single.beta, shared.ess["beta"], single.ess["beta"])]
    pairs += [(shared.theta[:, :, 0, k], single.theta[:, :, k], shared.ess["theta"][0][k],
               single.ess["theta"][k]) for k in range(5)]
    for x, y, ess_x, ess_y in pairs:
        assert ess_x > 50 and ess_y > 50
        se = math.sqrt(x.var() / ess_x + y.var() / ess_y)
        assert abs(x.mean() - y.mean()) < 4 * se


@pytest.mark.slow
def test_nuts_on_two_tasks_gives_draws_per_task_and_finite_summaries(two_tasks):
    mdps, trajs = two_tasks
    opts = get_method("nuts").options_from({"chains": 2, "warmup": 30, "samples": 30})
    out = fit_shared_beta("nuts", mdps, trajs, opts, 0)
    assert set(out) == {"theta_hat", "beta_hat", "map", "credible_intervals", "diagnostics", "draws",
                        "share", "run_time_s"}
    assert out["share"] == "beta"
    theta_hat = np.asarray(out["theta_hat"])
    assert theta_hat.shape == (2, 5) and np.allclose(theta_hat.sum(axis=1), 1.0)
    assert np.isfinite(out["beta_hat"]) and out["beta_hat"] > 0
    assert np.asarray(out["map"]["theta"]).shape == (2, 5) and np.isfinite(out["map"]["log_posterior"])
    ci = out["credible_intervals"]
    assert len(ci["beta"]) == 2 and np.asarray(ci["theta"]).shape == (2, 5, 2)
    diag = out["diagnostics"]
    for stat in ("r_hat", "ess_bulk"):
        assert np.isfinite(diag[stat]["beta"]) and np.asarray(diag[stat]["theta"], float).shape == (2, 5)
    assert diag["chains"] == 2 and diag["draws_per_chain"] == 30 and isinstance(diag["warnings"], list)
    chain, theta, beta = out["draws"]
    assert chain.shape == (60,) and theta.shape == (60, 2, 5) and beta.shape == (60,)
    assert np.all(np.isfinite(theta)) and np.all(beta > 0)


@pytest.mark.slow
def test_map_fields_mirror_the_map_methods(two_tasks):
    mdps, trajs = two_tasks
    opts = get_method("map").options_from({"starts": 2, "chains": 9})
    out = fit_shared_beta("map", mdps, trajs, opts, 0)
    single = get_method("map").run(mdps, trajs, opts, 0).fields
    assert set(out) == set(single) | {"share"}
    assert set(out["diagnostics"]) == set(single["diagnostics"])
    assert np.asarray(out["theta_hat"]).shape == (2, 5) and out["map"]["theta"] == out["theta_hat"]
    assert len(out["diagnostics"]["starts"]) == 2 and len(out["diagnostics"]["starts"][0]) == 11


def test_a_chain_stuck_in_one_tasks_theta_is_named_by_task():
    rng = np.random.default_rng(0)
    C, D, T, K = 2, 40, 2, 3
    theta = rng.dirichlet(np.ones(K), size=(C, D, T))
    beta = rng.lognormal(size=(C, D))
    theta[1, :, 1, :] = theta[1, -1, 1, :]  # chain 1 never moved in task 2's θ
    stats = _statistics(theta, beta, ("x", "y", "z"))
    assert sorted(stats["stuck"]) == [1 + K + k for k in range(K)]
    assert stats["ess_bulk"]["theta"][1] == [0.0] * K and stats["r_hat"]["theta"][1] == [None] * K
    assert stats["ess_bulk"]["theta"][0][0] > 0 and stats["r_hat"]["beta"] is not None
    why = stats["unavailable"]["r_hat.theta[1][0]"]
    assert why.startswith("chain 1 (of 0–1) did not move in θ[x, task 2]")
    r = SharedBetaNUTS(theta=theta, beta=beta, r_hat=stats["r_hat"], ess=stats["ess_bulk"], divergences=0,
                       log_density=np.zeros((C, D)), unavailable=stats["unavailable"], stuck=stats["stuck"],
                       feature_names=("x", "y", "z"))
    out = _describe_nuts(r, ("x", "y", "z"))
    assert out["credible_intervals"]["theta"][1] == [None] * K
    assert all(iv is not None for iv in out["credible_intervals"]["theta"][0])
    unavailable = out["diagnostics"]["unavailable"]
    assert "credible_intervals.theta[1][2]" in unavailable and "r_hat.theta[1][2]" in unavailable
    assert not any(".theta[5]" in k for k in unavailable)  # keys are per task, not flat
    assert out["diagnostics"]["warnings"][0].startswith("chain 1 (of 0–1) did not move in θ[x, task 2]")
