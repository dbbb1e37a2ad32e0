"""One expertise, a reward per task: MAP and NUTS with β shared and θ_t per task ("share beta").

:func:`~.gradient.map_estimate` and :func:`~.nuts.nuts_posterior` take a person's tasks and sum
their log-likelihoods at one (θ, β): the person wants the same thing everywhere. In a study
whose tasks ask for different things (a different reward per task), the person's expertise is
still one β, and each task has its own θ_t on the simplex. The log-posterior is

    Σ_t log P(Ξ_t | θ_t, β) + Σ_t log p(θ_t) + log p(β),

with the named prior's parts (:mod:`.priors`): each θ_t has the prior's θ part (Dirichlet(α),
α the ``concentration``) and β the prior's β part.

- :func:`map_shared_beta` maximises it as :func:`~.gradient.map_estimate` does, as a density in
  its coordinates θ_t = softmax(z_t), β = exp(b) (:func:`~.priors.log_prior_unconstrained`, each
  z_t's part Σ_i (α z_ti − e^{z_ti})), L-BFGS-B on the exact gradient with b bounded to the prior's range,
  from ``n_starts`` random starts (each θ_t uniform on the simplex, log β uniform). With one
  task the starts, the objective and so the optimum are ``map_estimate``'s.
- :func:`nuts_shared_beta` samples it with NumPyro's NUTS through the same kernel and chain
  driver as :func:`~.nuts.nuts_posterior` (:mod:`.nuts_kernel`: one program per chain, chains
  in threads, Laplace starts, dense mass matrix): the potential is written out here for
  T·(K−1)+1 unconstrained coordinates (each θ_t by the stick-breaking map of its Dirichlet
  prior's support, β as in ``nuts_kernel.unconstrained_posterior``: log β for a log-uniform
  prior). With one task it is ``nuts_posterior``'s potential, term for term.
- :func:`fit_shared_beta` runs either and returns the result fields the study writes, shaped
  like ``get_method(name).run(...).fields`` with ``theta_hat`` per task and ``"share": "beta"``.

Flat parameter indices (``stuck``; ``starts``): 0 is β, ``1 + t·K + k`` is θ_t's component k
(MAP's ``starts`` rows are ``(θ_1, …, θ_T, β)``, as ``map_estimate``'s are ``(θ, β)``).
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from .gradient import multistart_lbfgsb
from .laplace import hessian, laplace_summary
from .priors import (
    DEFAULT_PRIOR,
    concentration_of,
    get_prior,
    log_prior_jax,
    log_prior_unconstrained,
    numpyro_priors,
)
from .task_likelihood import as_tasks, pair_counts

__all__ = ["PerTaskSum", "SharedBetaMAP", "SharedBetaNUTS", "fit_shared_beta", "map_shared_beta",
           "nuts_shared_beta", "shared_beta_log_likelihood", "shared_beta_log_posterior"]

Progress = Callable[[int, int], None] | None


# ----------------------------------------------------------------------------- likelihood
class PerTaskSum:
    """Σ_t log P(Ξ_t | θ_t, β): each task's log-likelihood at its own θ_t and the shared β.

    Same interface as :class:`~expertise_irl.planning.differentiable.TaskSum` (so the NUTS kernel
    takes it), except that ``thetas`` is ``[T, K]``: ``f(thetas, beta, *, start=None,
    counts=None) -> (L, None)``; a start and the counts are tuples with one entry per task.
    """

    def __init__(self, parts: list):
        self._parts = list(parts)
        self.counts = tuple(p.counts for p in self._parts)

    @property
    def n_tasks(self) -> int:
        return len(self._parts)

    def zero_start(self) -> tuple:
        return tuple(p.zero_start() for p in self._parts)

    def _each(self, start, counts):
        n = len(self._parts)
        return zip(self._parts, (None,) * n if start is None else start,
                   (None,) * n if counts is None else counts, strict=True)

    def per_task(self, thetas, beta, *, start: tuple | None = None, counts: tuple | None = None) -> list:
        """``[log P(Ξ_t | θ_t, β) for t]`` (JAX scalars)."""
        return [p(thetas[t], beta, start=s, counts=c)[0]
                for t, (p, s, c) in enumerate(self._each(start, counts))]

    def __call__(self, thetas, beta, v0=None, *, start: tuple | None = None, counts: tuple | None = None):
        if v0 is not None:
            raise InputError("v0 warm starts a single task; pass start= for several")
        return sum(self.per_task(thetas, beta, start=start, counts=counts)), None

    def start_at(self, thetas, beta, start: tuple | None = None, counts: tuple | None = None) -> tuple:
        return tuple(p.start_at(thetas[t], beta, s, c)
                     for t, (p, s, c) in enumerate(self._each(start, counts)))


def _tasks(mdps, trajs) -> list[tuple[TabularMDP, Trajectories]]:
    """``as_tasks`` (one MDP or equal-length lists; the features shared), at least one task."""
    return as_tasks(mdps, trajs)


def shared_beta_log_likelihood(mdps, trajs, *, tol: float = 1e-10, max_iter: int = 200_000,
                               model: str = DEFAULT_MODEL) -> PerTaskSum:
    """``f(thetas [T, K], beta) -> (Σ_t log P(Ξ_t | θ_t, β), None)`` of one person's tasks."""
    from ..planning.differentiable import make_log_likelihood

    return PerTaskSum([make_log_likelihood(m, pair_counts(m, t), tol=tol, max_iter=max_iter, model=model)
                       for m, t in _tasks(mdps, trajs)])


def _separable_prior(prior: str, concentration: float | None = None) -> Callable:
    """``log p(thetas [T, K], beta)`` up to a constant: the named prior's β part (as
    :func:`~.priors.log_prior_jax` gives it, −∞ outside its range) and its θ part,
    (α − 1)·Σ log θ_tk, per task."""
    a = concentration_of(prior, concentration)
    beta_part = log_prior_jax(prior, 1.0)  # a function of β alone: it is log p(β)

    def log_prior(thetas, beta):
        lp = beta_part(thetas[0], beta)
        return lp if a == 1 else lp + (a - 1) * jnp.sum(jnp.log(thetas))

    return log_prior


def shared_beta_log_posterior(mdps, trajs, *, prior: str = DEFAULT_PRIOR, model: str = DEFAULT_MODEL,
                              tol: float = 1e-10, concentration: float | None = None) -> Callable:
    """``g(thetas [T, K], beta)``: Σ_t log P(Ξ_t | θ_t, β) + Σ_t log p(θ_t) + log p(β), up to a
    constant: the posterior density on (θ_1, …, θ_T, β) (:func:`map_shared_beta` maximises it
    written in its own coordinates)."""
    f = shared_beta_log_likelihood(mdps, trajs, tol=tol, model=model)
    log_prior = _separable_prior(prior, concentration)

    def g(thetas, beta):
        return f(thetas, beta)[0] + log_prior(thetas, beta)

    return g


# ----------------------------------------------------------------------------- MAP
@dataclass(frozen=True)
class SharedBetaMAP:
    """The MAP estimate of (θ_1, …, θ_T, β) and how it was found.

    Attributes:
        thetas: ``[T, K]`` θ̂_t on the simplex, one row per task.
        beta: β̂, shared by the tasks.
        log_posterior: the unnormalised log-posterior at the optimum.
        starts: ``[n_starts, T·K + 1]`` the (θ_1, …, θ_T, β) each run started from.
        optima: ``[n_starts]`` log-posterior each run reached (the best is reported).
        evaluations: total likelihood-and-gradient evaluations (the Hessian's included).
        laplace: :func:`~.laplace.laplace_summary` at the optimum (θ's fields ``[T][K]``).
    """

    thetas: np.ndarray
    beta: float
    log_posterior: float
    starts: np.ndarray
    optima: np.ndarray
    evaluations: int
    laplace: dict | None = None


def map_shared_beta(
    mdps: TabularMDP | Sequence[TabularMDP],
    trajs: Trajectories | Sequence[Trajectories],
    *,
    n_starts: int = 4,
    rng: np.random.Generator,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
    tol: float = 1e-10,
    progress: Progress = None,
    concentration: float | None = None,
) -> SharedBetaMAP:
    """Maximise Σ_t log P(Ξ_t | θ_t, β) + Σ_t log p(θ_t) + log p(β) by L-BFGS-B.

    As :func:`~.gradient.map_estimate`, in x = (z_1, …, z_T, b) with θ_t = softmax(z_t) and
    β = exp(b), b bounded to the log of ``prior``'s β range. Each start draws θ_1, …, θ_T
    uniform on the simplex (in task order) and then log β uniform on the range, from ``rng``:
    with one task the draws, the objective and so the optimum are ``map_estimate``'s.
    ``progress(done, n_starts)`` is called after each start.
    """

    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    tasks = _tasks(mdps, trajs)
    T, K = len(tasks), tasks[0][0].n_features
    lo, hi = get_prior(prior).beta_range
    f = shared_beta_log_likelihood(mdps, trajs, tol=tol, model=model)
    prior_x = log_prior_unconstrained(prior, concentration)  # θ's part sums over every z_tk

    def unpack(x):
        return jax.nn.softmax(x[:-1].reshape(T, K), axis=-1), jnp.exp(x[-1])

    def objective(x):
        thetas, beta = unpack(x)
        return -(f(thetas, beta)[0] + prior_x(x[:-1], x[-1]))

    def draw_start():
        thetas0 = np.stack([rng.dirichlet(np.ones(K)) for _ in range(T)])
        beta0 = math.exp(rng.uniform(math.log(lo), math.log(hi)))
        x0 = np.concatenate([np.log(np.maximum(thetas0, 1e-12)).ravel(), [math.log(beta0)]])
        return x0, np.concatenate([thetas0.ravel(), [beta0]])

    bounds = [(None, None)] * (T * K) + [(math.log(lo), math.log(hi))]
    run = multistart_lbfgsb(objective, draw_start, n_starts, bounds, maxiter=500 * T, progress=progress)
    x = np.asarray(run.best.x, dtype=np.float64)
    grad = lambda y: np.asarray(run.value_and_grad(jnp.asarray(y))[1])  # noqa: E731
    H = hessian(grad, x)
    lap = laplace_summary(x, H, grad(x), (lo, hi), rng, n_tasks=T)
    thetas, beta = unpack(jnp.asarray(x))
    return SharedBetaMAP(np.asarray(thetas), float(beta), float(-run.best.fun), run.starts, run.optima,
                         run.evaluations + 2 * x.size + 1, lap)


# ----------------------------------------------------------------------------- NUTS
@dataclass(frozen=True)
class SharedBetaNUTS:
    """Posterior draws of (θ_1, …, θ_T, β) from NUTS and their diagnostics.

    Attributes:
        theta: ``[chains, draws, T, K]`` draws of each task's θ (on the simplex).
        beta: ``[chains, draws]`` draws of the shared β.
        r_hat: ``{"beta": float, "theta": [T][K]}`` split-R̂ (rank-normalised), or None when the
            run is too short (see ``unavailable``); a stuck parameter's is None.
        ess: ``{"beta": float, "theta": [T][K]}`` bulk ESS (0 where a chain did not move), or None.
        divergences: divergent transitions after warm-up.
        log_density: ``[chains, draws]`` unnormalised log-posterior of each draw.
        unavailable: ``{statistic: reason}``, keys as ``"r_hat.beta"``, ``"ess_bulk.theta[t][k]"``.
        mean_tree_size: leapfrog steps per draw after warm-up, averaged.
        mean_accept_prob: mean acceptance statistic after warm-up.
        stuck: ``{i: {chain: value}}`` (:func:`~.diagnostics.stuck_parameters`) with the flat index
            ``i``: 0 = β, ``1 + t·K + k`` = θ_t's component k.
        feature_names: the tasks' features.
    """

    theta: np.ndarray
    beta: np.ndarray
    r_hat: dict | None
    ess: dict | None
    divergences: int
    log_density: np.ndarray
    unavailable: dict
    mean_tree_size: float = float("nan")
    mean_accept_prob: float = float("nan")
    stuck: dict = field(default_factory=dict)
    feature_names: tuple = ()

    @property
    def n_tasks(self) -> int:
        return int(self.theta.shape[2])

    @property
    def mean_theta(self) -> np.ndarray:
        """``[T, K]`` posterior mean of each task's θ."""
        C, D, T, K = self.theta.shape
        return self.theta.reshape(C * D, T, K).mean(axis=0)

    @property
    def mean_beta(self) -> float:
        return float(self.beta.mean())

    def credible_intervals(self, prob: float = 0.9) -> dict:
        """Equal-tailed intervals: ``{"beta": [low, high], "theta": [T][K][low, high]}``."""
        C, D, T, K = self.theta.shape
        q = [(1 - prob) / 2, (1 + prob) / 2]
        th = np.quantile(self.theta.reshape(C * D, T, K), q, axis=0)  # [2, T, K]
        return {"beta": np.quantile(self.beta.ravel(), q).tolist(),
                "theta": np.moveaxis(th, 0, -1).tolist()}


def _shared_posterior(f: PerTaskSum, n_features: int, theta_prior, beta_prior):
    """The :class:`~.nuts_kernel.Posterior` of (θ_1, …, θ_T, β) in unconstrained coordinates
    ``x = (u_1, …, u_T, u_β)``: each θ_t by its prior support's bijection (stick-breaking for a
    Dirichlet, K − 1 coordinates), β as in :func:`~.nuts_kernel.unconstrained_posterior`."""
    import numpyro.distributions as dist
    from numpyro.distributions.transforms import biject_to

    from .nuts_kernel import Posterior

    T = f.n_tasks
    log_scale = isinstance(beta_prior, dist.LogUniform)
    beta_dist = (dist.Uniform(jnp.log(beta_prior.low), jnp.log(beta_prior.high)) if log_scale
                 else beta_prior)
    theta_map, beta_map = biject_to(theta_prior.support), biject_to(beta_dist.support)
    n_u = theta_map.inverse_shape((n_features,))[0]

    def split(x):
        return [x[t * n_u:(t + 1) * n_u] for t in range(T)], x[T * n_u]

    def constrained(x):
        us, u_beta = split(x)
        b = beta_map(u_beta)
        return jnp.stack([theta_map(u) for u in us]), (jnp.exp(b) if log_scale else b)

    def potential(x, start, counts):
        us, u_beta = split(x)
        thetas = [theta_map(u) for u in us]
        b = beta_map(u_beta)
        beta = jnp.exp(b) if log_scale else b
        # Term for term (and in the same order) nuts_kernel.unconstrained_posterior's with T = 1.
        log_p = (sum(theta_prior.log_prob(th) + theta_map.log_abs_det_jacobian(u, th)
                     for u, th in zip(us, thetas, strict=True))
                 + beta_dist.log_prob(b) + beta_map.log_abs_det_jacobian(u_beta, b)
                 + f(jnp.stack(thetas), beta, counts=counts)[0])
        return -log_p

    def log_density(thetas, b, n):
        return (f(thetas, b, counts=n)[0] + sum(theta_prior.log_prob(thetas[t]) for t in range(T))
                + beta_prior.log_prob(b))

    return Posterior(potential, constrained, log_density, T * n_u + 1)


_THETA_KEY = re.compile(r"\.theta\[(\d+)\]")


def _task_names(feature_names, t: int, T: int) -> list[str]:
    return list(feature_names) if T == 1 else [f"{n}, task {t + 1}" for n in feature_names]


def _statistics(th: np.ndarray, be: np.ndarray, feature_names) -> dict[str, Any]:
    """:func:`~.diagnostics.chain_statistics` task by task (β's are the same in each), joined:
    ``r_hat``/``ess_bulk`` ``{"beta", "theta": [T][K]}``, ``unavailable`` keyed ``theta[t][k]``,
    ``stuck`` by flat index."""
    from .diagnostics import chain_statistics

    _, _, T, K = th.shape
    per = [chain_statistics(th[:, :, t, :], be, feature_names=_task_names(feature_names, t, T))
           for t in range(T)]
    out: dict[str, Any] = {"unavailable": {}, "stuck": {}}
    for stat in ("r_hat", "ess_bulk"):
        out[stat] = (None if per[0][stat] is None else
                     {"beta": per[0][stat]["beta"], "theta": [p[stat]["theta"] for p in per]})
    for t, p in enumerate(per):
        for key, why in p["unavailable"].items():
            if ".theta[" in key:
                out["unavailable"][_THETA_KEY.sub(lambda m, t=t: f".theta[{t}][{m.group(1)}]", key)] = why
            elif t == 0:  # β's and the run's own reasons, the same for every task
                out["unavailable"][key] = why
        for i, per_chain in p["stuck"].items():
            out["stuck"][0 if i == 0 else 1 + t * K + (i - 1)] = per_chain
    return out


def nuts_shared_beta(
    mdps: TabularMDP | Sequence[TabularMDP],
    trajs: Trajectories | Sequence[Trajectories],
    *,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 4,
    seed: int = 0,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
    tol: float = 1e-8,
    progress: Progress = None,
    dense_mass: bool = True,
    target_accept: float = 0.8,
    concentration: float | None = None,
) -> SharedBetaNUTS:
    """Sample P(θ_1, …, θ_T, β | Ξ_1, …, Ξ_T) with NUTS (the density :func:`map_shared_beta`
    maximises, in T·(K−1)+1 unconstrained coordinates).

    The kernel, the chain driver, the Laplace starts and the chains' starts and keys are
    :func:`~.nuts.nuts_posterior`'s (see its docstring for the options); with one task the
    potential is its potential. ``progress(done, total)`` counts iterations over the chains.
    """
    from .nuts_kernel import check_run, sample

    num_warmup, num_samples, num_chains = check_run(num_warmup, num_samples, num_chains, target_accept)
    first = _tasks(mdps, trajs)[0][0]
    f = shared_beta_log_likelihood(mdps, trajs, tol=tol, model=model)
    theta_prior, beta_prior = numpyro_priors(prior, first.n_features, concentration)
    post = _shared_posterior(f, first.n_features, theta_prior, beta_prior)
    draws = sample(post, f, num_warmup=num_warmup, num_samples=num_samples, num_chains=num_chains,
                   seed=seed, dense_mass=dense_mass, target_accept=target_accept, progress=progress)
    th, be, div, steps, acc = draws
    C, D = be.shape
    density = jax.jit(jax.vmap(post.log_density, in_axes=(0, 0, None)))
    log_density = np.asarray(density(th.reshape(C * D, *th.shape[2:]), be.reshape(-1), f.counts))
    log_density = log_density.reshape(C, D)
    stats = _statistics(th, be, first.feature_names)
    return SharedBetaNUTS(
        theta=th, beta=be, r_hat=stats["r_hat"], ess=stats["ess_bulk"], divergences=int(div.sum()),
        log_density=log_density, unavailable=stats["unavailable"], mean_tree_size=float(steps.mean()),
        mean_accept_prob=float(acc.mean()), stuck=stats["stuck"], feature_names=tuple(first.feature_names),
    )


# ----------------------------------------------------------------------------- result fields
def _nest_keys(d: dict[str, str], K: int) -> dict[str, str]:
    """Keys ``"….theta[j]"`` of flat index j → ``"….theta[t][k]"`` (j = t·K + k)."""
    return {_THETA_KEY.sub(lambda m: f".theta[{int(m.group(1)) // K}][{int(m.group(1)) % K}]", k): v
            for k, v in d.items()}


def _flatten_keys(d: dict[str, str], K: int) -> dict[str, str]:
    pattern = re.compile(r"\.theta\[(\d+)\]\[(\d+)\]")
    return {pattern.sub(lambda m: f".theta[{int(m.group(1)) * K + int(m.group(2))}]", k): v
            for k, v in d.items()}


def _flat_stat(stat: dict | None) -> dict | None:
    if stat is None:
        return None
    return {"beta": stat["beta"], "theta": [x for row in stat["theta"] for x in row]}


def _nest(values: list, T: int, K: int) -> list:
    return [list(values[t * K:(t + 1) * K]) for t in range(T)]


def _describe_map(r: SharedBetaMAP, opts) -> dict[str, Any]:
    from .diagnostics import map_description

    return {
        "theta_hat": r.thetas.tolist(), "beta_hat": r.beta,
        "map": {"theta": r.thetas.tolist(), "beta": r.beta, "log_posterior": r.log_posterior},
        **map_description(r, opts.starts, get_prior(opts.prior).beta_range),
    }


def _describe_nuts(r: SharedBetaNUTS, feature_names) -> dict[str, Any]:
    from .diagnostics import nuts_warnings, withhold_intervals
    from .methods import CREDIBLE

    C, D, T, K = r.theta.shape
    theta, beta = r.theta.reshape(C * D, T, K), r.beta.reshape(-1)
    best = int(np.argmax(r.log_density.reshape(-1)))
    # The diagnostics' helpers read one θ of K components: here one of T·K, named "feature, task t".
    names = [n for t in range(T) for n in _task_names(feature_names, t, T)]
    unavailable = _flatten_keys(r.unavailable, K)
    ci = r.credible_intervals(CREDIBLE)
    flat_ci = {"beta": ci["beta"], "theta": [x for row in ci["theta"] for x in row]}
    flat_ci = withhold_intervals(flat_ci, r.stuck, C, names, unavailable)
    flat_diag = {"r_hat": _flat_stat(r.r_hat), "ess_bulk": _flat_stat(r.ess), "divergences": r.divergences,
                 "chains": C, "unavailable": unavailable}
    warnings = nuts_warnings(flat_diag, names, r.stuck)
    diag = {"r_hat": r.r_hat, "ess_bulk": r.ess, "divergences": r.divergences,
            "chains": C, "draws_per_chain": D, "mean_tree_size": r.mean_tree_size,
            "mean_accept_prob": r.mean_accept_prob, "unavailable": _nest_keys(unavailable, K),
            "warnings": warnings}
    return {
        "theta_hat": r.mean_theta.tolist(), "beta_hat": r.mean_beta,
        "map": {"theta": theta[best].tolist(), "beta": float(beta[best]),
                "log_posterior": float(r.log_density.reshape(-1)[best])},
        "credible_intervals": {"beta": flat_ci["beta"], "theta": _nest(flat_ci["theta"], T, K)},
        "diagnostics": diag,
        "draws": (np.repeat(np.arange(C), D), theta, beta),
    }


def fit_shared_beta(method: str, mdps, trajs, opts, seed, *, progress: Progress = None) -> dict[str, Any]:
    """The result fields of ``method`` (``"map"`` or ``"nuts"``) with β shared and θ per task.

    Shaped as ``get_method(method).run(mdps, trajs, opts, seed).fields`` (``opts`` is that
    method's options, e.g. ``get_method("nuts").options_from({...})``; ``seed`` as there:
    ``np.random.default_rng(seed)`` for map, an int for nuts), except ``theta_hat``,
    ``map["theta"]`` and the θ intervals are ``[T][K]`` (per task), ``draws`` is ``(chain [n],
    theta [n, T, K], beta [n])``, and ``"share": "beta"`` says so. R-hat and ESS are
    ``{"beta", "theta": [T][K]}``; warnings name θ's components ``θ[feature, task t]``.
    """
    from .methods import MAPOptions, NUTSOptions

    expected = {"map": MAPOptions, "nuts": NUTSOptions}
    if method not in expected:
        raise InputError(f"sharing β takes method map or nuts, got {method!r}")
    if not isinstance(opts, expected[method]):
        raise InputError(f"method {method} takes {expected[method].__name__}, got {type(opts).__name__}")
    t0 = time.perf_counter()
    tasks = _tasks(mdps, trajs)
    if method == "map":
        r = map_shared_beta(mdps, trajs, n_starts=opts.starts, rng=np.random.default_rng(seed),
                            prior=opts.prior, model=opts.model, progress=progress,
                            concentration=opts.concentration)
        out = _describe_map(r, opts)
    else:
        r = nuts_shared_beta(mdps, trajs, num_warmup=opts.warmup, num_samples=opts.samples,
                             num_chains=opts.chains, seed=seed, prior=opts.prior, model=opts.model,
                             progress=progress, concentration=opts.concentration)
        out = _describe_nuts(r, tasks[0][0].feature_names)
    out["share"] = "beta"
    out["run_time_s"] = time.perf_counter() - t0
    return out
