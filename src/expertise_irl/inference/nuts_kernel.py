"""NUTS's pieces: the potential, Laplace starts, the compiled step kernel, the chain driver.

The layering is NumPyro's and BlackJAX's: a potential (:func:`unconstrained_posterior`, the
negative log posterior in unconstrained coordinates), a step kernel (:func:`compile_kernel`:
NumPyro's NUTS transition on a :class:`ChainState`, compiled to run :data:`CHUNK` iterations
per call), and a driver (:func:`run_chains`: one program per chain, the chains in threads).
:func:`expertise_irl.inference.nuts.nuts_posterior` assembles them and summarises the draws;
its module docstring says why each choice is made.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

#: Iterations per compiled call of the sampler (between progress reports).
CHUNK = 25


# ----------------------------------------------------------------------------- potential
class Posterior(NamedTuple):
    """The posterior in unconstrained coordinates ``x = (u_θ, u_β)`` (``dim`` of them).

    ``potential(x, start, counts)`` is −log p(x) (prior, Jacobians and log-likelihood; ``start``
    is the solver's warm start), ``constrained(x)`` maps x to ``(θ, β)``, and
    ``log_density(θ, β, counts)`` is the unnormalised log posterior in (θ, β) space.
    """

    potential: Callable
    constrained: Callable
    log_density: Callable
    dim: int


def unconstrained_posterior(f, n_features: int, theta_prior, beta_prior, *, warm_start: bool) -> Posterior:
    """The :class:`Posterior` of log-likelihood ``f`` (:mod:`~expertise_irl.planning.differentiable`).

    Written out rather than traced from a NumPyro model (numpyro.infer.util.initialize_model
    keeps ~400 memory maps of compiled code per call, so a process running NUTS ~150 times ran
    out of them). A log-uniform β is sampled as log β, uniform: mapping β's interval to the real
    line by a sigmoid in β would squeeze experts' many orders of magnitude near the lower edge.
    """
    import numpyro.distributions as dist
    from numpyro.distributions.transforms import biject_to

    log_scale = isinstance(beta_prior, dist.LogUniform)
    beta_dist = (dist.Uniform(jnp.log(beta_prior.low), jnp.log(beta_prior.high)) if log_scale
                 else beta_prior)
    theta_map, beta_map = biject_to(theta_prior.support), biject_to(beta_dist.support)
    n_u_theta = theta_map.inverse_shape((n_features,))[0]

    def constrained(x):
        theta, b = theta_map(x[:n_u_theta]), beta_map(x[n_u_theta])
        return theta, (jnp.exp(b) if log_scale else b)

    def potential(x, start, counts):
        u_theta, u_beta = x[:n_u_theta], x[n_u_theta]
        theta, b = theta_map(u_theta), beta_map(u_beta)
        beta = jnp.exp(b) if log_scale else b
        log_p = (theta_prior.log_prob(theta) + theta_map.log_abs_det_jacobian(u_theta, theta)
                 + beta_dist.log_prob(b) + beta_map.log_abs_det_jacobian(u_beta, b)
                 + f(theta, beta, start=start if warm_start else None, counts=counts)[0])
        return -log_p

    def log_density(t, b, n):
        return f(t, b, counts=n)[0] + theta_prior.log_prob(t) + beta_prior.log_prob(b)

    return Posterior(potential, constrained, log_density, n_u_theta + 1)


def _laplace_start(value_and_grad, x: np.ndarray, rng: np.random.Generator, dense_mass: bool):
    """A dispersed start near a mode and the Laplace approximation's mass matrix there.

    ``x`` is the chain's random start (flat unconstrained coordinates) and ``value_and_grad``
    the compiled potential and its gradient there. From ``x``, L-BFGS on the exact gradient
    finds a mode; the Hessian there (central differences of the gradient) gives the Gaussian
    whose covariance is the chain's initial inverse mass matrix, and the chain starts at a
    draw from it, so chains from different starts stay dispersed and R-hat keeps its power.
    Where the optimiser fails or the Hessian is not positive definite, the chain keeps its
    start and NumPyro's identity. Returns ``(start, inverse_mass)``.
    """
    from scipy.optimize import minimize

    def fun(y):
        v, g = value_and_grad(jnp.asarray(y))
        v = float(v)
        return (v, np.asarray(g, dtype=np.float64)) if np.isfinite(v) else (1e300, np.zeros_like(y))

    d = x.size
    cov = np.eye(d)
    try:
        res = minimize(fun, x, jac=True, method="L-BFGS-B", options={"maxiter": 200})
        h = 1e-4 * np.maximum(1.0, np.abs(res.x))
        step = np.eye(d) * h
        hess = np.stack([(fun(res.x + step[i])[1] - fun(res.x - step[i])[1]) / (2 * h[i]) for i in range(d)])
        hess = 0.5 * (hess + hess.T)
        if res.fun < 1e300 and np.all(np.isfinite(hess)) and np.linalg.eigvalsh(hess).min() > 0:
            cov = np.linalg.inv(hess)
            draw = rng.multivariate_normal(res.x, cov)
            x = draw if fun(draw)[0] < 1e300 else res.x
    except (ValueError, np.linalg.LinAlgError):
        pass  # keep the random start and the identity
    return x, (cov if dense_mass else np.diag(cov))


# ----------------------------------------------------------------------------- kernel
class ChainState(NamedTuple):
    """One chain between iterations: NumPyro's ``HMCState`` and the solver's warm start."""

    hmc: Any
    start: Any


class Kernel(NamedTuple):
    """Compiled programs shared by every chain (their arguments include the counts).

    ``init(x, inverse_mass, key, counts) -> ChainState``; ``chunk(state, counts) -> (state,
    (θ, β, diverging, num_steps, accept_prob))`` runs ``chunk_size`` iterations;
    ``value_and_grad(x, counts)`` is the potential (at a zero warm start) and its gradient.
    """

    init: Callable
    chunk: Callable
    value_and_grad: Callable
    chunk_size: int


def compile_kernel(post: Posterior, f, x0: np.ndarray, key0, *, num_warmup: int, total: int,
                   dense_mass: bool, target_accept: float, warm_start: bool) -> Kernel:
    """Compile NumPyro's NUTS on ``post`` once, at the first chain's start ``x0`` and key ``key0``."""
    from numpyro.infer.hmc import hmc

    zero, counts = f.zero_start(), f.counts
    init_kernel, sample_kernel = hmc(potential_fn_gen=lambda start, n: lambda x: post.potential(x, start, n),
                                     algo="NUTS")
    chunk = min(CHUNK, total)  # the last chunk may run past ``total``; those draws are dropped

    def init_chain(x, inverse_mass, key, counts):
        state = init_kernel(x, num_warmup, inverse_mass_matrix=inverse_mass, dense_mass=dense_mass,
                            target_accept_prob=target_accept, model_args=(zero, counts), rng_key=key)
        start = f.start_at(*post.constrained(state.z), counts=counts) if warm_start else zero
        return ChainState(state, start)

    def run_chunk(carry, counts):
        def body(c, _):
            state = sample_kernel(c.hmc, model_args=(c.start, counts))
            theta, beta = post.constrained(state.z)
            start = f.start_at(theta, beta, c.start, counts=counts) if warm_start else c.start
            draw = (theta, beta, state.diverging, state.num_steps, state.accept_prob)
            return ChainState(state, start), draw
        return jax.lax.scan(body, carry, None, length=chunk)

    value_and_grad = jax.jit(jax.value_and_grad(lambda x, counts: post.potential(x, zero, counts)))
    eye = np.eye(x0.size) if dense_mass else np.ones(x0.size)
    value_and_grad(jnp.asarray(x0), counts)
    init_compiled = jax.jit(init_chain).lower(x0, eye, key0, counts).compile()
    carry0 = init_compiled(x0, eye, key0, counts)
    chunk_compiled = jax.jit(run_chunk).lower(carry0, counts).compile()
    return Kernel(init_compiled, chunk_compiled, value_and_grad, chunk)


# ----------------------------------------------------------------------------- driver
def run_chains(kernel: Kernel, counts, x_init: np.ndarray, keys, total: int, *, seed: int,
               laplace_init: bool, dense_mass: bool,
               progress: Callable[[int, int], None] | None = None) -> list[tuple[np.ndarray, ...]]:
    """Run every chain for ``total`` iterations; per chain ``(θ, β, diverging, steps, accept)``.

    One program per chain, the chains in threads, as many at once as there are CPU cores: XLA
    runs them on separate cores, and no chain waits for another's longer trajectory or slower
    solve (as vectorised chains do). The draws do not depend on how many run at once.
    ``progress(done, total · chains)`` follows the iterations summed over the chains.
    """
    num_chains = len(x_init)
    eye = np.eye(x_init.shape[1]) if dense_mass else np.ones(x_init.shape[1])
    done = np.zeros(num_chains, dtype=int)
    lock, stop = threading.Lock(), threading.Event()

    def run_chain(c: int) -> tuple[np.ndarray, ...]:
        x, inverse_mass = x_init[c], eye
        if laplace_init:
            rng = np.random.default_rng([int(seed), c])
            x, inverse_mass = _laplace_start(lambda y: kernel.value_and_grad(y, counts), x, rng, dense_mass)
        carry = kernel.init(x, inverse_mass, keys[c], counts)
        parts = []
        while len(parts) * kernel.chunk_size < total and not stop.is_set():
            carry, out = kernel.chunk(carry, counts)
            parts.append(jax.device_get(out))
            with lock:
                done[c] = min(len(parts) * kernel.chunk_size, total)
                if progress is not None:
                    progress(int(done.sum()), total * num_chains)
        return tuple(np.concatenate([part[k] for part in parts])[:total] for k in range(5))

    with ThreadPoolExecutor(max_workers=min(num_chains, os.cpu_count() or 1)) as pool:
        futures = [pool.submit(run_chain, c) for c in range(num_chains)]
        try:
            return [fut.result() for fut in futures]
        except BaseException:
            stop.set()  # let the other chains finish their chunk and return
            raise


def check_run(num_warmup, num_samples, num_chains, target_accept) -> tuple[int, int, int]:
    """The run's lengths as ints; :class:`~expertise_irl.errors.InputError` for a length below 1 or a
    ``target_accept`` outside (0, 1)."""
    from ..errors import InputError

    for name, value in (("num_warmup", num_warmup), ("num_samples", num_samples), ("num_chains", num_chains)):
        if int(value) < 1:
            raise InputError(f"{name} must be >= 1, got {value}")
    if not 0 < target_accept < 1:
        raise InputError(f"target_accept must be in (0, 1), got {target_accept}")
    return int(num_warmup), int(num_samples), int(num_chains)


def sample(post: Posterior, f, *, num_warmup: int, num_samples: int, num_chains: int, seed: int,
           dense_mass: bool, target_accept: float, warm_start: bool = False, laplace_init: bool = True,
           progress: Callable[[int, int], None] | None = None) -> list[np.ndarray]:
    """Run ``num_chains`` chains on ``post`` (each its own compiled program, :func:`run_chains`)
    from NumPyro's default start (``init_to_uniform``: uniform on (−2, 2) in unconstrained
    coordinates), keys split from ``seed``; returns the five per-draw arrays after warm-up, each
    ``[chains, draws, ...]``: θ, β (or the model's second block), divergences, tree sizes, accept
    probabilities. ``f.counts`` is the data argument of the compiled programs."""
    key_init, key_run = jax.random.split(jax.random.PRNGKey(int(seed)))
    x_init = np.asarray(jax.random.uniform(key_init, (num_chains, post.dim), minval=-2.0, maxval=2.0),
                        np.float64)
    keys = jax.random.split(key_run, num_chains)
    total = num_warmup + num_samples
    kernel = compile_kernel(post, f, x_init[0], keys[0], num_warmup=num_warmup, total=total,
                            dense_mass=dense_mass, target_accept=target_accept, warm_start=warm_start)
    per_chain = run_chains(kernel, f.counts, x_init, keys, total, seed=int(seed), laplace_init=laplace_init,
                           dense_mass=dense_mass, progress=progress)
    return [np.stack([chain[k][num_warmup:] for chain in per_chain]) for k in range(5)]
