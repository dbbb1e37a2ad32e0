"""NUTS on the continuous space: chains as separate programs in threads, Laplace starts.

The sampler is NumPyro's NUTS (its tree building, step-size and mass-matrix adaptation),
driven one iteration at a time through its functional interface
(:func:`numpyro.infer.hmc.hmc` with a ``potential_fn_gen``). What this module adds, each
measured in ``benchmarks/nuts_speed.py``:

- **One program per chain, chains in threads.** XLA runs them on separate cores, and no
  chain waits for another's deeper tree or slower solve, as vectorised chains do.
- **Laplace starts.** Each chain starts near a mode with the Laplace approximation there as
  its initial mass matrix, so the first adaptation window does not run with the identity
  (whose trees were five times deeper).
- **Dense mass matrix** by default: θ's simplex coordinates and log β are correlated in
  the posterior, and with a diagonal one the trees were twice as deep.
- **The data as an input.** The counts are an argument of the compiled programs, so one
  compile serves every data set on a map, and with JAX's persistent cache (the command line
  turns it on) later runs do not compile again.
- **Warm starts** (opt-in, ``warm_start=True``): each iteration's potential carries a
  :class:`~expertise_irl.planning.differentiable.WarmStart`, the converged values and gradient adjoint at
  the chain's last draw, and every leapfrog step of the next trajectory starts its forward
  and adjoint fixed points there. NumPyro's potential is a pure function of the position,
  so the start is the trajectory's origin, not the previous leapfrog step. A solve's result
  does not depend on its start beyond the tolerance, so the target is the same.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from .diagnostics import chain_statistics
from .gradient import credible_intervals
from .priors import DEFAULT_PRIOR, numpyro_priors
from .task_likelihood import as_tasks, tasks_log_likelihood

__all__ = ["NUTSResult", "nuts_posterior"]

#: Iterations per compiled call of the sampler (between progress reports).
CHUNK = 25


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


@dataclass(frozen=True)
class NUTSResult:
    """Posterior samples from NUTS and their diagnostics.

    Attributes:
        theta: ``[chains, draws, K]`` samples of θ (on the simplex).
        beta: ``[chains, draws]`` samples of β.
        idata: the ArviZ ``InferenceData`` (posterior, sample_stats).
        r_hat: ``{"beta": float, "theta": [K]}`` split-R̂ (rank-normalised), or None when the
            run is too short to compute it (fewer than 2 chains or 4 draws; see ``unavailable``).
        ess: ``{"beta": float, "theta": [K]}`` bulk effective sample size, or None (fewer than
            4 draws per chain).
        divergences: number of divergent transitions after warm-up.
        log_density: ``[chains, draws]`` unnormalised log-posterior of each draw (θ, β space).
        unavailable: ``{statistic: reason}`` for each statistic that could not be computed.
        mean_tree_size: leapfrog steps per draw after warm-up, averaged over chains and draws.
        mean_accept_prob: mean acceptance statistic after warm-up.
    """

    theta: np.ndarray
    beta: np.ndarray
    idata: object
    r_hat: dict | None
    ess: dict | None
    divergences: int
    log_density: np.ndarray
    unavailable: dict
    mean_tree_size: float = float("nan")
    mean_accept_prob: float = float("nan")

    @property
    def mean_theta(self) -> np.ndarray:
        return self.theta.reshape(-1, self.theta.shape[-1]).mean(axis=0)

    @property
    def mean_beta(self) -> float:
        return float(self.beta.mean())

    def credible_intervals(self, prob: float = 0.9) -> dict:
        """Equal-tailed intervals: ``{"beta": [low, high], "theta": [[low, high], ...]}``."""
        return credible_intervals(self.theta.reshape(-1, self.theta.shape[-1]), self.beta.ravel(), prob)


def nuts_posterior(
    mdp: TabularMDP | Sequence[TabularMDP],
    trajs: Trajectories | Sequence[Trajectories],
    *,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 4,
    seed: int = 0,
    theta_prior=None,
    beta_prior=None,
    tol: float = 1e-8,
    progress: Callable[[int, int], None] | None = None,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
    dense_mass: bool = True,
    warm_start: bool = False,
    laplace_init: bool = True,
    target_accept: float = 0.8,
) -> NUTSResult:
    """Sample P(θ, β | Ξ) with NUTS on the same log-density as :func:`map_estimate`.

    ``prior`` names the prior (``"log-uniform"``, the default: a flat Dirichlet on the simplex
    for θ and log β uniform on [1e-3, 1e2]; ``"paper"``: β ~ Normal(5.005, 1.5) truncated to
    [0.01, 10]); ``theta_prior``/``beta_prior`` (NumPyro distributions) replace either part.
    ``model`` is the observation model. ``mdp`` and ``trajs`` may be equal-length lists, one
    per task of the same person: the log-likelihoods are summed.

    Each chain is its own compiled program; the chains run in threads, as many at once as
    there are CPU cores, and the draws do not depend on how many run at once.
    ``progress(done, total)`` counts iterations summed over the chains (warm-up included),
    every :data:`CHUNK` iterations of a chain. ``laplace_init`` starts each chain near a mode
    with the Laplace approximation as its mass matrix (see :func:`_laplace_start`);
    ``dense_mass`` adapts a dense mass matrix (the default) instead of a diagonal one;
    ``warm_start`` starts every solve at the chain's last draw instead of at zero (same target;
    it was slower in ``benchmarks/nuts_speed.py``, so it is off by default). ``target_accept``
    is the step-size adaptation's target acceptance (NumPyro's default, 0.8; raising it to
    0.95 halved the divergences of experts' posteriors on ``corridor`` at 2-4× the time and,
    for one person, a fraction of the effective samples: docs/calibration.md).
    """
    import arviz as az
    import numpyro.distributions as dist
    from numpyro.distributions.transforms import biject_to
    from numpyro.infer.hmc import hmc

    for name, value, least in (("num_warmup", num_warmup, 1), ("num_samples", num_samples, 1),
                               ("num_chains", num_chains, 1)):
        if int(value) < least:
            raise InputError(f"{name} must be >= {least}, got {value}")
    if not 0 < target_accept < 1:
        raise InputError(f"target_accept must be in (0, 1), got {target_accept}")
    num_warmup, num_samples, num_chains = int(num_warmup), int(num_samples), int(num_chains)
    f = tasks_log_likelihood(mdp, trajs, tol=tol, model=model)
    first = as_tasks(mdp, trajs)[0][0]
    named_theta, named_beta = numpyro_priors(prior, first.n_features)
    theta_prior = named_theta if theta_prior is None else theta_prior
    beta_prior = named_beta if beta_prior is None else beta_prior

    # The posterior in unconstrained coordinates x = (u_θ, u_β), written out rather than traced
    # from a NumPyro model (numpyro.infer.util.initialize_model keeps ~400 memory maps of
    # compiled code per call, so a process running NUTS ~150 times ran out of them).
    # The counts are an argument of every compiled program, not a constant in it: programs for
    # one map are then the same for every data set, and JAX's persistent cache (where enabled,
    # as the command line does) serves them to later runs without compiling again.
    # A log-uniform β is sampled as log β, uniform: mapping β's interval to the real line by a
    # sigmoid in β would squeeze experts' many orders of magnitude near the lower edge.
    log_scale = isinstance(beta_prior, dist.LogUniform)
    beta_dist = (dist.Uniform(jnp.log(beta_prior.low), jnp.log(beta_prior.high)) if log_scale
                 else beta_prior)
    theta_map, beta_map = biject_to(theta_prior.support), biject_to(beta_dist.support)
    n_u_theta = theta_map.inverse_shape((first.n_features,))[0]

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

    def potential_gen(start, counts):
        return lambda x: potential(x, start, counts)

    key_init, key_run = jax.random.split(jax.random.PRNGKey(int(seed)))
    zero, counts = f.zero_start(), f.counts
    init_kernel, sample_kernel = hmc(potential_fn_gen=potential_gen, algo="NUTS")
    # NumPyro's default start (init_to_uniform): uniform on (-2, 2) in unconstrained coordinates.
    x_init = np.asarray(jax.random.uniform(key_init, (num_chains, n_u_theta + 1), minval=-2.0, maxval=2.0),
                        np.float64)
    keys = jax.random.split(key_run, num_chains)
    total = num_warmup + num_samples
    chunk = min(CHUNK, total)  # the last chunk may run past ``total``; those draws are dropped

    def init_chain(x, inverse_mass, key, counts):
        state = init_kernel(x, num_warmup, inverse_mass_matrix=inverse_mass, dense_mass=dense_mass,
                            target_accept_prob=target_accept, model_args=(zero, counts), rng_key=key)
        start = f.start_at(*constrained(state.z), counts=counts) if warm_start else zero
        return state, start

    def run_chunk(carry, counts):
        def body(c, _):
            state, start = c
            state = sample_kernel(state, model_args=(start, counts))
            theta, beta = constrained(state.z)
            if warm_start:
                start = f.start_at(theta, beta, start, counts=counts)
            return (state, start), (theta, beta, state.diverging, state.num_steps, state.accept_prob)
        return jax.lax.scan(body, carry, None, length=chunk)

    value_and_grad = jax.jit(jax.value_and_grad(lambda x, counts: potential(x, zero, counts)))
    eye = np.eye(x_init.shape[1]) if dense_mass else np.ones(x_init.shape[1])
    # Compiled once, here, and shared: the chain threads only run compiled code.
    value_and_grad(jnp.asarray(x_init[0]), counts)
    init_compiled = jax.jit(init_chain).lower(x_init[0], eye, keys[0], counts).compile()
    carry0 = init_compiled(x_init[0], eye, keys[0], counts)
    chunk_compiled = jax.jit(run_chunk).lower(carry0, counts).compile()

    def potential_and_grad(x):
        return value_and_grad(x, counts)

    done = np.zeros(num_chains, dtype=int)
    lock, stop = threading.Lock(), threading.Event()

    def run_chain(c: int) -> list:
        x, inverse_mass = x_init[c], eye
        if laplace_init:
            rng = np.random.default_rng([int(seed), c])
            x, inverse_mass = _laplace_start(potential_and_grad, x, rng, dense_mass)
        carry = init_compiled(x, inverse_mass, keys[c], counts)
        parts = []
        while len(parts) * chunk < total and not stop.is_set():
            carry, out = chunk_compiled(carry, counts)
            parts.append(jax.device_get(out))
            with lock:
                done[c] = min(len(parts) * chunk, total)
                if progress is not None:
                    progress(int(done.sum()), total * num_chains)
        return parts

    # One program per chain, the chains in threads: XLA runs them on separate cores, and no
    # chain waits for another's longer trajectory or slower solve (as vectorised chains do).
    with ThreadPoolExecutor(max_workers=min(num_chains, os.cpu_count() or 1)) as pool:
        futures = [pool.submit(run_chain, c) for c in range(num_chains)]
        try:
            per_chain = [fut.result() for fut in futures]
        except BaseException:
            stop.set()  # let the other chains finish their chunk and return
            raise
    # [chains, draws, ...] after warm-up.
    th, be, div, steps, acc = (
        np.stack([np.concatenate([part[k] for part in parts])[num_warmup:total] for parts in per_chain])
        for k in range(5))

    def log_posterior(t, b, n):
        return f(t, b, counts=n)[0] + theta_prior.log_prob(t) + beta_prior.log_prob(b)

    density = jax.jit(jax.vmap(log_posterior, in_axes=(0, 0, None)))
    C_, D_ = be.shape
    log_density = np.asarray(density(th.reshape(C_ * D_, -1), be.reshape(-1), counts)).reshape(C_, D_)
    idata = az.from_dict(
        posterior={"theta": th, "beta": be},
        sample_stats={"diverging": div, "n_steps": steps, "acceptance_rate": acc, "lp": log_density},
        coords={"feature": list(first.feature_names)}, dims={"theta": ["feature"]},
    )
    stats = chain_statistics(th, be)
    return NUTSResult(
        theta=th, beta=be, idata=idata, r_hat=stats["r_hat"], ess=stats["ess_bulk"],
        divergences=int(div.sum()), log_density=log_density, unavailable=stats["unavailable"],
        mean_tree_size=float(steps.mean()), mean_accept_prob=float(acc.mean()),
    )
