"""The Laplace approximation at a mode: a Gaussian in the optimiser's coordinates.

MAP (:func:`~.gradient.map_estimate`) finds the mode of the posterior density in x = (z, b),
θ = softmax(z), β = e^b (:mod:`.priors` says which density). Around it the posterior is
approximated by Normal(x̂, H⁻¹), H the Hessian of the negative log posterior there. ``jax.hessian``
cannot differentiate the likelihood twice (its gradient is an implicit-function ``custom_vjp``
whose adjoint is a ``while_loop``: no forward mode, no reverse over it), so H is central
differences of the exact gradient (:func:`hessian`), d + 1 gradients apart from the one at x̂.

From that Gaussian (:func:`laplace_summary`): the 90% interval of β is b̂ ± 1.645 sd mapped by
exp and cut at the prior's range; θ's are equal-tailed quantiles of softmax(z) over draws of
the Gaussian; the Laplace means are those draws' means. A **flat ridge** is a direction of H
whose curvature is so small that moving ±1.645 sd along it changes some θ_k by at least
:data:`RIDGE_THETA` or β by at least a factor :data:`RIDGE_BETA`: there the mode is one of many
nearly equally likely points.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["LAPLACE_DRAWS", "RIDGE_BETA", "RIDGE_THETA", "Z90", "hessian", "laplace_summary"]

#: The 95% quantile of the standard normal: ±Z90 sd holds 90%.
Z90 = 1.6448536269514722
#: Draws of the Gaussian for θ's intervals and the Laplace means.
LAPLACE_DRAWS = 4000
#: A flat ridge moves some θ_k by this much (a half of the simplex's side) within ±Z90 sd ...
RIDGE_THETA = 0.5
#: ... or β by this factor (an order of magnitude).
RIDGE_BETA = 10.0


def hessian(grad, x: np.ndarray, rel_step: float = 1e-4) -> np.ndarray:
    """``[d, d]`` symmetric Hessian at ``x`` by central differences of ``grad(x) -> [d]``, steps
    ``rel_step · max(1, |x_i|)``."""
    x = np.asarray(x, dtype=np.float64)
    h = rel_step * np.maximum(1.0, np.abs(x))
    rows = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h[i]
        rows.append((np.asarray(grad(x + e)) - np.asarray(grad(x - e))) / (2 * h[i]))
    H = np.stack(rows)
    return 0.5 * (H + H.T)


def _softmax(z: np.ndarray, n_tasks: int = 1) -> np.ndarray:
    """θ of z ``[..., T·K]``: ``[..., K]`` for one task, ``[..., T, K]`` for ``n_tasks`` > 1."""
    if n_tasks > 1:
        z = z.reshape(*z.shape[:-1], n_tasks, z.shape[-1] // n_tasks)
    e = np.exp(z - z.max(axis=-1, keepdims=True))
    return e / e.sum(axis=-1, keepdims=True)


def _ridge(x: np.ndarray, vals: np.ndarray, vecs: np.ndarray, K: int, n_tasks: int) -> dict[str, Any] | None:
    """The flattest direction that moves θ or β past the ridge thresholds, or None."""
    worst = None
    for lam, v in zip(vals, vecs.T, strict=True):
        step = Z90 / math.sqrt(lam) * v
        hi, lo = x + step, x - step
        d_theta = float(np.max(np.abs(_softmax(hi[:K], n_tasks) - _softmax(lo[:K], n_tasks))))
        factor = math.exp(min(abs(hi[K] - lo[K]), 700.0))  # a factor past e^700 is infinite enough
        if d_theta >= RIDGE_THETA or factor >= RIDGE_BETA:
            if worst is None or lam < worst["curvature"]:
                worst = {"curvature": float(lam), "theta_change": d_theta, "beta_factor": factor}
    return worst


def _edge(x: np.ndarray, grad: np.ndarray, bounds: tuple[float, float]) -> int:
    """-1 / +1 when b sits on its lower / upper bound with the posterior rising past it, else 0."""
    b, g = x[-1], grad[-1]
    if abs(b - bounds[0]) < 1e-9 and g > 0:
        return -1
    if abs(b - bounds[1]) < 1e-9 and g < 0:
        return 1
    return 0


def _one_sided(slope: float, curvature: float, span: float, prob: float) -> float:
    """The ``prob`` quantile of d ∈ [0, span] under the density ∝ exp(−slope·d − curvature·d²/2)."""
    d = np.linspace(0.0, span, 4001)
    logp = -slope * d - 0.5 * max(curvature, 0.0) * d**2
    w = np.exp(logp - logp.max())
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(d))])
    return float(np.interp(prob * cdf[-1], cdf, d))


def laplace_summary(x: np.ndarray, H: np.ndarray, grad: np.ndarray, beta_range: tuple[float, float],
                    rng: np.random.Generator, prob: float = 0.9, n_tasks: int = 1) -> dict[str, Any]:
    """The Gaussian Normal(x, H⁻¹) in x = (z [K], b) summarised on (θ, β); with ``n_tasks`` = T > 1,
    z holds T blocks (θ_1, …, θ_T, one β: :mod:`.shared_beta`) and θ's fields are ``[T][K]``.

    ``grad`` is the gradient of the negative log posterior at ``x``. Where b sits on an edge of
    ``log beta_range`` with the posterior rising past it (``edge``: −1 lower, +1 upper), the
    mode is not a stationary point: θ's Gaussian is the conditional one at that b (H's z block),
    and β's interval is one-sided, from the edge to the ``prob`` quantile of exp(−g·d − h·d²/2),
    d the distance from the edge in b, g the slope and h b's curvature given z.

    Returns ``positive_definite`` and ``edge``; when the (conditional) Hessian is positive
    definite, ``credible_intervals`` (``{"beta": [lo, hi], "theta": [[lo, hi], ...]}``, β's cut at
    ``beta_range``), ``theta_mean`` and ``beta_mean`` (the Laplace means), ``sd_log_beta`` and
    ``ridge`` (:func:`_ridge`: the flattest direction past the thresholds, or None).
    """
    x, H = np.asarray(x, dtype=np.float64), np.asarray(H, dtype=np.float64)
    K = x.size - 1
    lo, hi = (math.log(v) for v in beta_range)
    edge = _edge(x, np.asarray(grad, dtype=np.float64), (lo, hi))
    block = H[:K, :K] if edge else H
    vals, vecs = np.linalg.eigh(block)
    if not (np.all(np.isfinite(vals)) and vals.min() > 0):
        return {"positive_definite": False, "edge": edge, "min_curvature": float(np.nanmin(vals))}
    cov = (vecs / vals) @ vecs.T
    z = Z90 if prob == 0.9 else float(np.sqrt(2) * _erfinv(prob))
    q = [(1 - prob) / 2, (1 + prob) / 2]
    if edge:
        h = float(H[K, K] - H[K, :K] @ cov @ H[:K, K])
        d = _one_sided(abs(float(grad[-1])), h, hi - lo, prob)
        beta = sorted([math.exp(x[K]), math.exp(x[K] - edge * d)])
        draws = rng.multivariate_normal(x[:K], cov, size=LAPLACE_DRAWS, method="eigh")
        theta, b_draws, sd_b, ridge = _softmax(draws, n_tasks), None, None, None
    else:
        sd_b = math.sqrt(cov[K, K])
        beta = [math.exp(min(max(x[K] - z * sd_b, lo), hi)), math.exp(min(max(x[K] + z * sd_b, lo), hi))]
        draws = rng.multivariate_normal(x, cov, size=LAPLACE_DRAWS, method="eigh")
        theta, b_draws = _softmax(draws[:, :K], n_tasks), np.exp(np.clip(draws[:, K], lo, hi))
        ridge = _ridge(x, vals, vecs, K, n_tasks)
    return {"positive_definite": True, "edge": edge,
            "credible_intervals": {"beta": beta,
                                   "theta": np.moveaxis(np.quantile(theta, q, axis=0), 0, -1).tolist()},
            "theta_mean": theta.mean(axis=0).tolist(),
            "beta_mean": math.exp(x[K]) if b_draws is None else float(b_draws.mean()),
            "sd_log_beta": sd_b, "ridge": ridge}


def _erfinv(p: float) -> float:
    from scipy.special import erfinv

    return float(erfinv(p))
