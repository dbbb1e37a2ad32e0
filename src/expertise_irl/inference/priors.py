"""Priors of the continuous methods (Algorithm 1, MAP, NUTS), by name.

- ``log-uniform`` (the default): θ uniform on the simplex (Algorithm 1's box: on
  [0, 1]^K) and **log β uniform on [1e-3, 1e2]**, p(β) ∝ 1/β. Scale-free: it spreads its
  mass evenly over orders of magnitude of expertise, from a near-perfect expert to a
  near-random novice, so it does not decide the answer. Algorithm 1 walks a lattice of β
  (by default 0.01, 0.11, …, 9.91); there the prior is ∝ 1/β on the lattice's range.
- ``paper`` (Sec. VII-A, for reproducing the paper): θ uniform, β ~ Normal(5.005, 1.5)
  truncated to [0.01, 10]. It assumes a novice and pulls every β̂ towards 5 when the
  demonstrations say little.

Each prior gives its log density up to a constant in NumPy (:func:`log_prior_numpy`, for
Algorithm 1), in JAX (:func:`log_prior_jax`, for MAP) and as NumPyro distributions
(:func:`numpyro_priors`, for NUTS); all three are the same density.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

BETA_PRIOR_MEAN = 5.005
BETA_PRIOR_SD = 1.5
BETA_RANGE = (0.01, 10.0)  # the paper's β range
LOG_UNIFORM_RANGE = (1e-3, 1e2)


@dataclass(frozen=True)
class Prior:
    """A named prior: its β support and its description in words."""

    name: str
    beta_range: tuple[float, float]
    text: str


PRIORS = {
    "log-uniform": Prior(
        "log-uniform", LOG_UNIFORM_RANGE,
        f"θ uniform (on the simplex; Algorithm 1's box: on [0, 1]^K), log β uniform on "
        f"[{LOG_UNIFORM_RANGE[0]:g}, {LOG_UNIFORM_RANGE[1]:g}] (p(β) ∝ 1/β; Algorithm 1: on its "
        f"lattice's range)"),
    "paper": Prior(
        "paper", BETA_RANGE,
        f"θ uniform (on the simplex; Algorithm 1's box: on [0, 1]^K), "
        f"β ~ Normal({BETA_PRIOR_MEAN:g}, {BETA_PRIOR_SD:g}) truncated to "
        f"[{BETA_RANGE[0]:g}, {BETA_RANGE[1]:g}] (the paper's Sec. VII-A)"),
}
DEFAULT_PRIOR = "log-uniform"
#: The default prior in words, as the command line prints it and results record it.
PRIOR_TEXT = PRIORS[DEFAULT_PRIOR].text


def get_prior(name: str) -> Prior:
    """The prior called ``name``; :class:`~expertise_irl.errors.InputError` naming the choices."""
    from ..errors import InputError

    if name not in PRIORS:
        raise InputError(f"prior must be one of {', '.join(PRIORS)}, got {name!r}")
    return PRIORS[name]


def log_prior_numpy(name: str, theta, beta: float, beta_range: tuple[float, float] | None = None) -> float:
    """log p(θ, β) up to a constant (NumPy); −∞ outside the support (θ < 0, β outside the range).

    ``beta_range`` narrows the support (Algorithm 1's lattice); the density is unchanged.
    """
    import numpy as np

    prior = get_prior(name)
    lo, hi = beta_range if beta_range is not None else prior.beta_range
    if not lo <= beta <= hi * (1 + 1e-9) or np.any(np.asarray(theta) < 0):
        return -math.inf
    if name == "paper":
        return -0.5 * ((beta - BETA_PRIOR_MEAN) / BETA_PRIOR_SD) ** 2
    return -math.log(beta)


def log_prior_jax(name: str):
    """``f(theta, beta) -> log p`` up to a constant, JAX-traceable (θ is on the simplex)."""
    import jax.numpy as jnp

    prior = get_prior(name)
    lo, hi = prior.beta_range

    def f(theta, beta):
        inside = (beta >= lo) & (beta <= hi)
        if name == "paper":
            lp = -0.5 * ((beta - BETA_PRIOR_MEAN) / BETA_PRIOR_SD) ** 2
        else:
            lp = -jnp.log(beta)
        return jnp.where(inside, lp, -jnp.inf)

    return f


def numpyro_priors(name: str, n_features: int):
    """``(theta_prior, beta_prior)`` NumPyro distributions of the prior called ``name``."""
    import jax.numpy as jnp
    import numpyro.distributions as dist

    prior = get_prior(name)
    lo, hi = prior.beta_range
    theta_prior = dist.Dirichlet(jnp.ones(n_features))
    if name == "paper":
        return theta_prior, dist.TruncatedNormal(BETA_PRIOR_MEAN, BETA_PRIOR_SD, low=lo, high=hi)
    return theta_prior, dist.LogUniform(lo, hi)
