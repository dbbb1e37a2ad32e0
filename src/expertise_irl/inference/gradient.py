"""Gradient-based estimators on the continuous space: MAP by quasi-Newton (NUTS: :mod:`.nuts`).

The parameters are θ on the unit simplex (‖θ‖₁ = 1 fixes the scale: (θ, β) and (cθ, cβ)
behave alike) and β > 0. The optimiser works on unconstrained coordinates x = (z, b),
θ = softmax(z) and β = exp(b), with the log-density and its exact gradient from
:func:`expertise_irl.planning.differentiable.make_log_likelihood`.

**MAP is the mode of the posterior density in x**, not in (θ, β): a mode moves when the
coordinates change, and where the likelihood is nearly flat the prior's shape in the chosen
coordinates decides it. The prior is therefore written in x (:func:`.priors.log_prior_unconstrained`):
b's density is p(β)·β (flat for the default ``log-uniform`` prior, whose density in β would put
the mode at β's lower edge) and z's is Σ_i (α z_i − e^{z_i}), whose push-forward is θ ~
Dirichlet(α); maximised over z's free scale it leaves ∏θ_i^α. So MAP maximises
L(θ, β)·∏θ_i^α·p(β)·β, α the ``concentration``.

Priors by name (:mod:`expertise_irl.inference.priors`): ``log-uniform`` (the default: θ ~
Dirichlet(α) on the simplex, log β uniform on [1e-3, 1e2]) or ``paper`` (Sec. VII-A: θ uniform,
β ~ Normal(5.005, 1.5) truncated to [0.01, 10]). Any other prior can be passed as a
JAX-traceable density on (θ, β), ``log_prior(theta, beta)``, which is written in x as
:func:`.priors.unconstrained_from_density` says.

At the optimum, the Laplace approximation (:mod:`.laplace`) gives the curvature, 90% intervals
and a check for a flat ridge.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from ..numerics import enable_float64
from .laplace import hessian, laplace_summary
from .priors import (
    BETA_PRIOR_MEAN,
    BETA_PRIOR_SD,
    DEFAULT_PRIOR,
    concentration_of,
    get_prior,
    log_prior_jax,
    log_prior_unconstrained,
    unconstrained_from_density,
)
from .task_likelihood import as_tasks, tasks_log_likelihood

__all__ = ["BETA_PRIOR_MEAN", "BETA_PRIOR_SD", "MAPResult", "credible_intervals", "map_estimate",
           "paper_log_prior"]

def paper_log_prior(theta, beta):
    """Sec. VII-A prior, JAX-traceable: flat on the simplex for θ, Normal(5.005, 1.5) on [0.01, 10]
    for β (:func:`.priors.log_prior_jax` ``("paper")``, built when called, so importing this module
    does not switch JAX to float64)."""
    return log_prior_jax("paper")(theta, beta)


@dataclass(frozen=True)
class MAPResult:
    """The MAP estimate and how it was found.

    Attributes:
        theta: ``[K]`` θ̂ on the simplex.
        beta: β̂.
        log_posterior: the unnormalised log-posterior density at the optimum, in the optimiser's
            coordinates x = (z, b) (the module docstring).
        starts: ``[n_starts, K + 1]`` the (θ, β) each run started from.
        optima: ``[n_starts]`` log-posterior each run reached (the best is reported).
        evaluations: total likelihood-and-gradient evaluations (the Hessian's included).
        x: ``[K + 1]`` the optimum in x = (z, b).
        hessian: ``[K + 1, K + 1]`` the Hessian of the negative log posterior in x there.
        laplace: :func:`.laplace.laplace_summary` of the Gaussian Normal(x, hessian⁻¹).
        concentration: θ's Dirichlet concentration α (None for a ``log_prior`` given by the caller).
    """

    theta: np.ndarray
    beta: float
    log_posterior: float
    starts: np.ndarray
    optima: np.ndarray
    evaluations: int
    x: np.ndarray | None = None
    hessian: np.ndarray | None = None
    laplace: dict | None = None
    concentration: float | None = None


class MultiStart(NamedTuple):
    """What :func:`multistart_lbfgsb` found: the best run, each start's recorded point and optimum
    (the negated minimum), the objective's evaluations in all, and the compiled
    ``value_and_grad(x)``."""

    best: Any  # scipy.optimize.OptimizeResult
    starts: np.ndarray
    optima: np.ndarray
    evaluations: int
    value_and_grad: Callable | None = None


def multistart_lbfgsb(objective, draw_start, n_starts: int, bounds, *, maxiter: int = 500,
                      progress: Callable[[int, int], None] | None = None) -> MultiStart:
    """Minimise the JAX-traceable ``objective(x)`` by L-BFGS-B with its exact gradient from
    ``n_starts`` starts; ``draw_start()`` returns ``(x0, recorded)``, the start and what to report of
    it. A non-finite value counts as 1e300 with a zero gradient (the search steps back)."""
    value_and_grad = jax.jit(jax.value_and_grad(objective))
    evaluations = 0

    def fun(x):
        nonlocal evaluations
        evaluations += 1
        v, g = value_and_grad(jnp.asarray(x))
        v = float(v)
        if not math.isfinite(v):
            return 1e300, np.zeros_like(x)
        return v, np.asarray(g, dtype=np.float64)

    starts, optima, best = [], [], None
    for i in range(n_starts):
        x0, recorded = draw_start()
        res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"maxiter": maxiter, "ftol": 1e-12, "gtol": 1e-7})
        starts.append(recorded)
        optima.append(-res.fun)
        if best is None or res.fun < best.fun:
            best = res
        if progress is not None:
            progress(i + 1, n_starts)
    return MultiStart(best, np.array(starts), np.array(optima), evaluations, value_and_grad)


def _unpack(x):
    z, b = x[:-1], x[-1]
    return jax.nn.softmax(z), jnp.exp(b)


def map_estimate(
    mdp: TabularMDP | Sequence[TabularMDP],
    trajs: Trajectories | Sequence[Trajectories],
    *,
    n_starts: int = 4,
    rng: np.random.Generator,
    log_prior: Callable | None = None,
    beta_range: tuple[float, float] | None = None,
    tol: float = 1e-10,
    progress: Callable[[int, int], None] | None = None,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
    concentration: float | None = None,
) -> MAPResult:
    """The MAP estimate of (θ, β) by L-BFGS-B from random starts, and the Laplace approximation there.

    It maximises log P(Ξ | θ, β) + log p(z, b), the log posterior density in x = (z, b), that is
    L·∏θ_i^α·p(β)·β (α = 1 for a given ``log_prior``, whose own θ density is part of it).

    Args:
        mdp: the task, or a list of tasks of the same person (their log-likelihoods are summed).
        trajs: the demonstrations, or a list of them as long as ``mdp``'s, one per task.
        n_starts: runs of L-BFGS-B, from θ uniform on the simplex and log β uniform on
            ``log beta_range``.
        rng: draws the starts, then the Laplace Gaussian's samples (θ's intervals).
        log_prior: a density ``log_prior(theta, beta)`` on (θ, β) to use instead of ``prior``
            (written in x by :func:`.priors.unconstrained_from_density`).
        beta_range: bounds of the β search (default: the support of ``prior``); θ moves freely.
        tol: soft value iteration's tolerance in the likelihood.
        progress: ``progress(done, n_starts)``, called after each start.
        prior: ``"log-uniform"`` or ``"paper"`` (written in x by
            :func:`.priors.log_prior_unconstrained`).
        model: the observation model of :mod:`expertise_irl.models`.
        concentration: θ's Dirichlet concentration (default: the prior's,
            :func:`.priors.concentration_of`).

    Returns:
        The estimate, the runs and the Laplace approximation.

    Raises:
        InputError: ``n_starts`` below 1, ``beta_range`` not 0 < low < high, an unknown ``prior``
            or ``model``, or tasks and demonstrations that do not pair up.
    """
    enable_float64()
    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    beta_range = get_prior(prior).beta_range if beta_range is None else beta_range
    lo, hi = beta_range
    if not 0 < lo < hi:
        raise InputError(f"beta_range must satisfy 0 < low < high, got {beta_range}")
    if log_prior is None:
        alpha = concentration_of(prior, concentration)
        prior_x = log_prior_unconstrained(prior, alpha)
    else:
        alpha, prior_x = None, unconstrained_from_density(log_prior)
    f = tasks_log_likelihood(mdp, trajs, tol=tol, model=model)
    K = as_tasks(mdp, trajs)[0][0].n_features

    @jax.jit
    def objective(x):
        theta, beta = _unpack(x)
        ll, _ = f(theta, beta)
        return -(ll + prior_x(x[:-1], x[-1]))

    def draw_start():
        theta0 = rng.dirichlet(np.ones(K))
        beta0 = math.exp(rng.uniform(math.log(lo), math.log(hi)))
        x0 = np.concatenate([np.log(np.maximum(theta0, 1e-12)), [math.log(beta0)]])
        return x0, np.concatenate([theta0, [beta0]])

    bounds = [(None, None)] * K + [(math.log(lo), math.log(hi))]
    run = multistart_lbfgsb(objective, draw_start, n_starts, bounds, progress=progress)
    x = np.asarray(run.best.x, dtype=np.float64)
    grad = lambda y: np.asarray(run.value_and_grad(jnp.asarray(y))[1])  # noqa: E731
    H = hessian(grad, x)
    laplace = laplace_summary(x, H, grad(x), (lo, hi), rng)
    theta, beta = _unpack(jnp.asarray(x))
    return MAPResult(np.asarray(theta), float(beta), float(-run.best.fun), run.starts, run.optima,
                     run.evaluations + 2 * x.size + 1, x, H, laplace, alpha)


def credible_intervals(theta: np.ndarray, beta: np.ndarray, prob: float = 0.9) -> dict:
    """Equal-tailed intervals of draws ``theta [n, K]``, ``beta [n]``:
    ``{"beta": [low, high], "theta": [[low, high], ...]}``."""
    q = [(1 - prob) / 2, (1 + prob) / 2]
    return {"beta": np.quantile(beta, q).tolist(), "theta": np.quantile(theta, q, axis=0).T.tolist()}
