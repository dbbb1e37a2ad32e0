"""NUTS driver: warm starts, Laplace starts, chains in threads, several tasks per person."""

from __future__ import annotations

import dataclasses
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.inference import nuts_kernel
from expertise_irl.inference.gradient import map_estimate
from expertise_irl.inference.methods import BIRLOptions, get_method
from expertise_irl.inference.nuts import nuts_posterior
from expertise_irl.inference.nuts_kernel import _laplace_start
from expertise_irl.inference.task_likelihood import pair_counts, tasks_log_likelihood
from expertise_irl.planning.differentiable import make_log_likelihood
from expertise_irl.worlds.zones import load_bundled

THETA = np.array([0.5, 0.3, 0.1, 0.05, 0.05])


@pytest.fixture(scope="module")
def corridor():
    return load_bundled("corridor").to_mdp()


@pytest.fixture(scope="module")
def corridor_demos(corridor):
    return simulate(corridor, THETA, 0.5, 6, np.random.default_rng(3))


@pytest.mark.slow
@pytest.mark.parametrize("model", ["maxent", "maxent-relative", "boltzmann"])
def test_a_warm_start_changes_neither_the_value_nor_the_gradient(corridor, corridor_demos, model):
    f = make_log_likelihood(corridor, pair_counts(corridor, corridor_demos), tol=1e-12, model=model)
    theta, beta = jnp.asarray(THETA), 0.5
    start = f.start_at(jnp.asarray([0.4, 0.4, 0.1, 0.05, 0.05]), 0.6)  # a nearby hypothesis

    def value_and_grad(start):
        return jax.value_and_grad(lambda t, b: f(t, b, start=start)[0], argnums=(0, 1))(theta, beta)

    (cold, (gt_cold, gb_cold)), (warm, (gt_warm, gb_warm)) = value_and_grad(None), value_and_grad(start)
    # Both solves stop within 1e-12 of the same fixed point (in V/β); what is left is rounding.
    assert abs(float(warm - cold)) < 1e-8 * max(1.0, abs(float(cold)))
    np.testing.assert_allclose(np.asarray(gt_warm), np.asarray(gt_cold), rtol=1e-7, atol=1e-8)
    assert abs(float(gb_warm - gb_cold)) < 1e-7 * max(1.0, abs(float(gb_cold)))


@pytest.mark.slow
def test_the_warm_start_is_the_solution_there(corridor, corridor_demos):
    f = make_log_likelihood(corridor, pair_counts(corridor, corridor_demos), tol=1e-12)
    start = f.start_at(jnp.asarray(THETA), 0.5)
    _, v = f(jnp.asarray(THETA), 0.5)
    np.testing.assert_allclose(np.asarray(start.v[np.asarray(f._state_rows), 0]), np.asarray(v), atol=1e-10)
    assert float(jnp.max(jnp.abs(start.lam))) > 0  # the adjoint of a non-zero gradient


def test_the_laplace_start_of_a_gaussian_is_its_covariance():
    a = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]])
    mode = np.array([0.3, -1.0, 2.0])
    potential = jax.jit(jax.value_and_grad(lambda x: 0.5 * (x - mode) @ jnp.asarray(a) @ (x - mode)))
    x, cov = _laplace_start(potential, np.zeros(3), np.random.default_rng(0), dense_mass=True)
    np.testing.assert_allclose(cov, np.linalg.inv(a), rtol=1e-6)
    # The start is one draw from N(mode, A⁻¹): its Mahalanobis distance² is χ²₃ (< 16.3 w.p. 0.999).
    assert (x - mode) @ a @ (x - mode) < 16.3
    _, diag = _laplace_start(potential, np.zeros(3), np.random.default_rng(0), dense_mass=False)
    np.testing.assert_allclose(diag, np.diag(np.linalg.inv(a)), rtol=1e-6)


def test_a_laplace_start_that_fails_keeps_the_chains_start():
    potential = jax.jit(jax.value_and_grad(lambda x: -jnp.sum(x ** 2)))  # no mode: unbounded below
    x0 = np.array([0.5, -0.5])
    x, cov = _laplace_start(potential, x0, np.random.default_rng(0), dense_mass=True)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(cov, np.eye(2))


@pytest.mark.slow
def test_draws_do_not_depend_on_how_many_chains_run_at_once(corridor, corridor_demos, monkeypatch):
    kwargs = dict(num_warmup=30, num_samples=20, num_chains=3, seed=5)
    together = nuts_posterior(corridor, corridor_demos, **kwargs)
    monkeypatch.setattr(nuts_kernel.os, "cpu_count", lambda: 1)
    one_at_a_time = nuts_posterior(corridor, corridor_demos, **kwargs)
    np.testing.assert_array_equal(together.beta, one_at_a_time.beta)
    np.testing.assert_array_equal(together.theta, one_at_a_time.theta)
    assert together.beta.shape == (3, 20)
    assert len({float(b[0]) for b in together.beta}) == 3  # three chains, not one repeated


@pytest.mark.slow
def test_progress_counts_every_chains_iterations(corridor, corridor_demos):
    seen = []
    nuts_posterior(corridor, corridor_demos, num_warmup=30, num_samples=30, num_chains=2, seed=0,
                   progress=lambda d, t: seen.append((d, t)))
    assert seen[-1] == (120, 120)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


@pytest.mark.slow
def test_two_tasks_sum_their_log_likelihoods(corridor):
    crossroads = load_bundled("crossroads").to_mdp()
    a = simulate(corridor, THETA, 0.5, 3, np.random.default_rng(1))
    b = simulate(crossroads, THETA, 0.5, 3, np.random.default_rng(2))
    joint = tasks_log_likelihood([corridor, crossroads], [a, b], tol=1e-12)
    fa = make_log_likelihood(corridor, pair_counts(corridor, a), tol=1e-12)
    fb = make_log_likelihood(crossroads, pair_counts(crossroads, b), tol=1e-12)
    theta = jnp.asarray([0.3, 0.3, 0.2, 0.1, 0.1])
    expected = float(fa(theta, 0.7)[0] + fb(theta, 0.7)[0])
    assert float(joint(theta, 0.7)[0]) == pytest.approx(expected, rel=1e-12)
    # MAP on both tasks maximises the summed log-posterior: no start of either alone beats it.
    both = map_estimate([corridor, crossroads], [a, b], n_starts=2, rng=np.random.default_rng(0))
    only_a = map_estimate(corridor, a, n_starts=2, rng=np.random.default_rng(0))
    joint_at = lambda t, bt: float(joint(jnp.asarray(t), bt)[0])  # noqa: E731
    assert joint_at(both.theta, both.beta) >= joint_at(only_a.theta, only_a.beta) - 1e-6


def test_tasks_must_share_features_and_pair_up(corridor, corridor_demos):
    other = dataclasses.replace(corridor, feature_names=("a", "b", "c", "d", "e"))
    with pytest.raises(InputError, match="one list of trajectories per MDP"):
        tasks_log_likelihood([corridor, corridor], [corridor_demos])
    with pytest.raises(InputError, match="task 2 has features a, b, c, d, e"):
        tasks_log_likelihood([corridor, other], [corridor_demos, corridor_demos])
    with pytest.raises(InputError, match=r"birl .* takes one task"):
        get_method("birl").run([corridor], [corridor_demos], BIRLOptions(iterations=10), 0)


def test_counts_passed_in_replace_the_ones_built_in(corridor, corridor_demos):
    other = simulate(corridor, np.array([0.1, 0.1, 0.6, 0.1, 0.1]), 2.0, 4, np.random.default_rng(9))
    f = make_log_likelihood(corridor, pair_counts(corridor, corridor_demos), tol=1e-12)
    g = make_log_likelihood(corridor, pair_counts(corridor, other), tol=1e-12)
    theta = jnp.asarray([0.3, 0.3, 0.2, 0.1, 0.1])
    assert float(f(theta, 0.8)[0]) != pytest.approx(float(g(theta, 0.8)[0]))
    assert float(f(theta, 0.8, counts=g.counts)[0]) == pytest.approx(float(g(theta, 0.8)[0]), rel=1e-12)
    grad = jax.grad(lambda t, n: f(t, 0.8, counts=n)[0])
    np.testing.assert_allclose(np.asarray(grad(theta, g.counts)),
                               np.asarray(jax.grad(lambda t: g(t, 0.8)[0])(theta)), rtol=1e-9)


def test_a_target_acceptance_outside_0_1_is_refused(corridor, corridor_demos):
    with pytest.raises(InputError, match=r"target_accept must be in \(0, 1\), got 1.2"):
        nuts_posterior(corridor, corridor_demos, num_warmup=5, num_samples=5, target_accept=1.2)


@pytest.mark.slow
def test_repeated_runs_keep_no_compiled_code(corridor, corridor_demos):
    # A process that runs NUTS for every participant of a study must not run out of memory maps
    # (each run once left ~400 behind: about 150 runs exhausted Linux's default 65,530).
    def maps() -> int:
        with open("/proc/self/maps") as fh:
            return sum(1 for _ in fh)

    if not os.path.exists("/proc/self/maps"):
        pytest.skip("needs /proc")

    def run(seed: int):
        return nuts_posterior(corridor, corridor_demos, num_warmup=10, num_samples=10, num_chains=2,
                              seed=seed)

    run(0), run(1)
    before = maps()
    for s in range(2, 6):
        run(s)
    assert maps() - before < 100  # 4 runs: leaking ~400 each would add ~1,600


@pytest.mark.slow
def test_a_chain_stuck_at_one_value_is_no_posterior(corridor, corridor_demos, monkeypatch):
    """Chain 1 made to repeat one draw (as a chain whose every proposal is rejected does): every
    parameter gets ESS 0 and R-hat null with the reason, the document withholds the 90% intervals,
    and the first warning names the chain."""
    from expertise_irl.inference import nuts_kernel as kernel_module
    from expertise_irl.inference.methods import NUTSOptions, document

    real = kernel_module.run_chains

    def second_chain_stuck(*args, **kwargs):
        chains = real(*args, **kwargs)
        th, be, *rest = chains[1]
        chains[1] = (np.repeat(th[-1:], len(th), axis=0), np.repeat(be[-1:], len(be)), *rest)
        return chains

    monkeypatch.setattr(kernel_module, "run_chains", second_chain_stuck)
    run = get_method("nuts").run(corridor, corridor_demos, NUTSOptions(chains=2, warmup=30, samples=30), 0)
    assert run.result.stuck.keys() == set(range(1 + corridor.n_features))
    doc = document(run, feature_names=corridor.feature_names, settings={}, data={})
    diag = doc["diagnostics"]
    assert doc["credible_intervals"] == {"beta": None, "theta": [None] * corridor.n_features}
    assert diag["ess_bulk"] == {"beta": 0.0, "theta": [0.0] * corridor.n_features}
    assert diag["r_hat"] == {"beta": None, "theta": [None] * corridor.n_features}
    assert diag["unavailable"]["r_hat.beta"].startswith("chain 1 (of 0–1) did not move in β (always ")
    why = diag["unavailable"]["credible_intervals.theta[0]"]
    assert why.startswith("chain 1 (of 0–1) did not move in θ[")
    assert diag["warnings"][0].startswith("chain 1 (of 0–1) did not move in β, θ[")
    assert "every draw after warm-up has β = " in diag["warnings"][0] and "--warmup" in diag["warnings"][0]
