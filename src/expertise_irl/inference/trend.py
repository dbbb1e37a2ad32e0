"""A parametric learning curve for the continuous methods: β that changes log-linearly.

The model (θ shared by all episodes; episodes e = 0 … E−1 in the order given,
``trajs.episode_ids``):

    log β_e = log β_0 + λ·g(e),   g(e) = e/(E−1)   (g = 0 when E = 1),

so β_0 is the first episode's expertise, β_0·e^λ the last one's, and λ = log(β_last/β_0)
(negative: the person improves, β falls). The log-likelihood is Σ_e ll_e(θ, β_e), ll_e the
differentiable log-likelihood of episode e alone
(:func:`~expertise_irl.planning.differentiable.make_log_likelihood` on that episode's counts),
one solve per episode per evaluation.

Prior (:data:`TREND_PRIOR_TEXT`), a density on (θ, log β_0, λ):

- θ uniform on the simplex;
- log β_0 uniform on [log 1e-3, log 1e2] (the β part of the ``log-uniform`` prior of
  :mod:`.priors`: p(β_0) ∝ 1/β_0 on [1e-3, 1e2]);
- λ ~ Normal(0, 2), independent of both.

:func:`log_prior_trend` is its log density up to a constant: −λ²/8 inside the support, −∞
outside. The MAP (:func:`map_trend`) maximises log-likelihood + that log prior over
(z, log β_0, λ), θ = softmax(z), the same way :func:`.gradient.map_estimate` does for one β.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from ..planning.differentiable import make_log_likelihood
from .priors import LOG_UNIFORM_RANGE
from .task_likelihood import pair_counts

__all__ = ["SLOPE_PRIOR_SD", "TREND_G", "TREND_PRIOR_TEXT", "TrendMAP", "episode_grid", "fit_trend",
           "log_prior_trend", "map_trend", "split_episodes", "trend_objective"]

#: The prior standard deviation of the slope λ = log(β_last/β_0).
SLOPE_PRIOR_SD = 2.0
#: The learning curve's shape in words.
TREND_G = "e/(E-1)"
TREND_PRIOR_TEXT = (
    f"θ uniform on the simplex, log β_0 uniform on [log {LOG_UNIFORM_RANGE[0]:g}, "
    f"log {LOG_UNIFORM_RANGE[1]:g}], λ ~ Normal(0, {SLOPE_PRIOR_SD:g}); "
    f"log β_e = log β_0 + λ·{TREND_G}")


@dataclass(frozen=True)
class TrendMAP:
    """The MAP learning curve and how it was found.

    Attributes:
        theta: ``[K]`` θ̂ on the simplex.
        beta0: β̂_0, the first episode's expertise.
        slope: λ̂ = log(β̂_last/β̂_0).
        betas: ``[E]`` β̂_e = β̂_0·exp(λ̂·g(e)).
        log_posterior: log-likelihood + :func:`log_prior_trend` at the optimum.
        optima: ``[n_starts]`` the log-posterior each start reached (the best is reported).
        evaluations: total objective-and-gradient evaluations.
        starts: ``[n_starts, K + 2]`` each start's (θ, β_0, λ).
    """

    theta: np.ndarray
    beta0: float
    slope: float
    betas: np.ndarray
    log_posterior: float
    optima: np.ndarray
    evaluations: int
    starts: np.ndarray


def episode_grid(n_episodes: int) -> np.ndarray:
    """``[E]`` g(e) = e/(E−1), 0 at the first episode and 1 at the last; ``[0.]`` when E = 1."""
    if n_episodes < 1:
        raise InputError("need at least one episode")
    if n_episodes == 1:
        return np.zeros(1)
    return np.arange(n_episodes) / (n_episodes - 1)


def split_episodes(trajs: Trajectories) -> list[Trajectories]:
    """One :class:`Trajectories` per episode, in the order of ``trajs.episode_ids``."""
    out = []
    for e in trajs.episode_ids:
        keep = trajs.episode == e
        out.append(Trajectories(trajs.episode[keep], trajs.step[keep], trajs.state[keep], trajs.action[keep]))
    return out


def log_prior_trend(log_beta0, slope):
    """log p(θ, log β_0, λ) up to a constant (JAX-traceable): −λ²/(2·2²) when log β_0 is in
    [log 1e-3, log 1e2], −∞ otherwise (θ's uniform density is a constant)."""
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)
    inside = (log_beta0 >= lo) & (log_beta0 <= hi)
    return jnp.where(inside, -0.5 * (slope / SLOPE_PRIOR_SD) ** 2, -jnp.inf)


def trend_objective(mdp: TabularMDP, trajs: Trajectories, *, tol: float = 1e-10,
                    model: str = DEFAULT_MODEL):
    """``(f, g)``: ``f(theta, log_beta0, slope) -> (log-likelihood, log prior)``, JAX-traceable,
    the log-likelihood Σ_e ll_e(θ, β_e); ``g`` the ``[E]`` grid g(e)."""
    if not isinstance(mdp, TabularMDP) or not isinstance(trajs, Trajectories):
        raise InputError("the learning curve takes one MDP and its trajectories")
    if len(trajs) == 0:
        raise InputError("need at least one demonstrated step")
    parts = [make_log_likelihood(mdp, pair_counts(mdp, t), tol=tol, model=model)
             for t in split_episodes(trajs)]
    g = episode_grid(len(parts))

    def f(theta, log_beta0, slope):
        ll = 0.0
        for part, ge in zip(parts, g, strict=True):
            ll = ll + part(theta, jnp.exp(log_beta0 + slope * ge))[0]
        return ll, log_prior_trend(log_beta0, slope)

    return f, g


def map_trend(mdp: TabularMDP, trajs: Trajectories, *, n_starts: int = 4, rng: np.random.Generator,
              model: str = DEFAULT_MODEL, tol: float = 1e-10) -> TrendMAP:
    """Maximise Σ_e ll_e(θ, β_e) + log p(θ, log β_0, λ) by L-BFGS-B from ``n_starts`` starts.

    Coordinates x = (z, log β_0, λ), θ = softmax(z); log β_0 is bounded to the prior's range,
    λ is free. Starts: θ uniform on the simplex, log β_0 uniform on the prior's range, λ = 0
    (no change; the slope's likelihood is smooth and its prior unimodal).
    """
    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    f, g = trend_objective(mdp, trajs, tol=tol, model=model)
    K = mdp.n_features
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)

    def objective(x):
        ll, lp = f(jax.nn.softmax(x[:K]), x[K], x[K + 1])
        return -(ll + lp)

    value_and_grad = jax.jit(jax.value_and_grad(objective))
    evaluations = 0

    def fun(x):
        nonlocal evaluations
        evaluations += 1
        v, gr = value_and_grad(jnp.asarray(x))
        v = float(v)
        if not math.isfinite(v):
            return 1e300, np.zeros_like(x)
        return v, np.asarray(gr, dtype=np.float64)

    bounds = [(None, None)] * K + [(lo, hi), (None, None)]
    starts, optima, best = [], [], None
    for _ in range(n_starts):
        theta0 = rng.dirichlet(np.ones(K))
        b0 = rng.uniform(lo, hi)
        x0 = np.concatenate([np.log(np.maximum(theta0, 1e-12)), [b0, 0.0]])
        res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"maxiter": 500, "ftol": 1e-12, "gtol": 1e-7})
        starts.append(np.concatenate([theta0, [math.exp(b0), 0.0]]))
        optima.append(-res.fun)
        if best is None or res.fun < best.fun:
            best = res
    x = np.asarray(best.x)
    theta = np.asarray(jax.nn.softmax(jnp.asarray(x[:K])))
    b0, slope = float(x[K]), float(x[K + 1])
    return TrendMAP(theta, math.exp(b0), slope, np.exp(b0 + slope * g), float(-best.fun),
                    np.array(optima), evaluations, np.array(starts))


def _label(v) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def fit_trend(mdp: TabularMDP, trajs: Trajectories, opts, seed) -> dict[str, Any]:
    """The MAP learning curve as a result dict, for ``opts`` a MAP options object
    (``get_method("map").options_from({...})``: its ``starts`` and ``model``; its prior must be
    ``log-uniform``, whose β part is the prior of β_0).

    Keys: ``theta_hat``; ``beta_hat``, the curve's geometric mean over the episodes,
    exp(mean_e log β̂_e) (= β̂_0·e^{λ̂/2}, the curve at g = 1/2, when E ≥ 2); ``expertise_by_episode``
    (one row per episode: ``episode`` label, ``mean`` = ``median`` = β̂_e, ``q05`` = ``q95`` = None:
    a point estimate has no band); ``trend`` (``beta0``, ``slope``, ``g``, ``prior``,
    ``log_ratio_mean`` = λ̂); ``diagnostics`` (``warnings``, ``optima``, ``starts``,
    ``evaluations``, ``log_posterior``).
    """
    from .diagnostics import map_warnings

    if getattr(opts, "prior", "log-uniform") != "log-uniform":
        raise InputError(f"the learning curve's prior is fixed ({TREND_PRIOR_TEXT}); "
                         f"got prior {opts.prior!r}, use 'log-uniform'")
    r = map_trend(mdp, trajs, n_starts=opts.starts, rng=np.random.default_rng(seed), model=opts.model)
    beta_hat = float(np.exp(np.mean(np.log(r.betas))))
    diag: dict[str, Any] = {"optima": r.optima.tolist(), "starts": r.starts.tolist(),
                            "evaluations": r.evaluations, "log_posterior": r.log_posterior}
    # Start agreement, and β̂_0 on the edge of its prior's range.
    warnings = [w.replace("β̂ =", "β̂_0 =") for w in map_warnings(diag, r.beta0, LOG_UNIFORM_RANGE)]
    if trajs.n_episodes == 1:
        warnings.append("one episode: the slope is not identified (λ̂ = 0 is the prior's mode)")
    diag["warnings"] = warnings
    rows = [{"episode": _label(lab), "mean": float(b), "median": float(b), "q05": None, "q95": None}
            for lab, b in zip(trajs.episode_ids, r.betas, strict=True)]
    return {
        "theta_hat": r.theta.tolist(),
        "beta_hat": beta_hat,
        "expertise_by_episode": rows,
        "trend": {"beta0": r.beta0, "slope": r.slope, "g": TREND_G, "prior": TREND_PRIOR_TEXT,
                  "log_ratio_mean": r.slope},
        "diagnostics": diag,
    }
