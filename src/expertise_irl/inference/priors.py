"""Priors of the continuous methods (Algorithm 1, MAP, NUTS), by name.

- ``log-uniform`` (the default): θ ~ Dirichlet(α, …, α) on the simplex (``concentration`` α,
  by default :data:`DEFAULT_CONCENTRATION`) and **log β uniform on [1e-3, 1e2]**, p(β) ∝ 1/β.
  Scale-free in β: it spreads its mass evenly over orders of magnitude of expertise, from a
  near-perfect expert to a near-random novice. Algorithm 1 keeps θ uniform (on its box or
  simplex lattice) and walks a lattice of β (by default 0.01, 0.11, …, 9.91); there the
  prior is ∝ 1/β on the lattice's range.
- ``paper`` (Sec. VII-A, for reproducing the paper): θ uniform (α = 1), β ~ Normal(5.005, 1.5)
  truncated to [0.01, 10]. It assumes a novice and pulls every β̂ towards 5 when the
  demonstrations say little.

Does the prior decide the answer? For NUTS and Algorithm 1, whose estimates are posterior
means, only as much as the data leave it to: with many actions the posterior forgets it. For
MAP it can decide more: the mode of a density depends on the coordinates the density is
written in, and where the likelihood is nearly flat (a θ–β ridge, an expert whose every
action is optimal for a θ on the simplex's edge) the prior's shape alone places the mode.
So MAP's prior is written, and documented, in the coordinates its optimiser moves in
(:func:`log_prior_unconstrained`):

- **β = e^b**: the density of b is p(β)·β. Under ``log-uniform`` it is flat, so the mode in b
  is where the likelihood alone puts it (the density of β, ∝ 1/β, has its mode at β's lower
  edge); under ``paper`` it is the truncated normal times β (mode 5.42 instead of 5.005).
- **θ = softmax(z)**, z ∈ R^K (one coordinate more than the simplex has): z_i = log g_i with
  g_i ~ Gamma(α, 1) independent, so that θ = g/Σg ~ Dirichlet(α) exactly; the density of z is
  Σ_i (α z_i − e^{z_i}). Its scale Σ e^{z_i} has nothing to do with θ, and maximising over it
  leaves Σ_i α log θ_i: **MAP in z maximises L(θ, β)·∏θ_i^α·p(b)**, the Dirichlet(α) density
  times the Jacobian ∏θ_i of the simplex's log-ratio coordinates. A uniform θ prior (α = 1)
  therefore keeps the mode off the simplex's edges as a Dirichlet(2) density would.

Each prior gives its log density up to a constant in NumPy (:func:`log_prior_numpy`, on (θ, β),
for Algorithm 1: θ uniform), in JAX (:func:`log_prior_jax` on (θ, β) and
:func:`log_prior_unconstrained` on (z, b), for MAP) and as NumPyro distributions
(:func:`numpyro_priors`, for NUTS, which adds the Jacobians of its own coordinates); for one
α they are the same prior.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..numerics import enable_float64

BETA_PRIOR_MEAN = 5.005
BETA_PRIOR_SD = 1.5
BETA_RANGE = (0.01, 10.0)  # the paper's β range
LOG_UNIFORM_RANGE = (1e-3, 1e2)
#: The default Dirichlet concentration of θ under ``log-uniform`` for MAP and NUTS
#: (``benchmarks/map_prior.py``; docs/model.md argues the choice).
DEFAULT_CONCENTRATION = 1.0


@dataclass(frozen=True)
class Prior:
    """A named prior: its β support, its β part in words, its default θ concentration and its
    description as Algorithm 1 uses it (θ uniform)."""

    name: str
    beta_range: tuple[float, float]
    beta_text: str
    concentration: float
    text: str


_BIRL_THETA = "θ uniform (on the simplex; Algorithm 1's box: on [0, 1]^K)"
_LOG_UNIFORM_BETA = (f"log β uniform on [{LOG_UNIFORM_RANGE[0]:g}, {LOG_UNIFORM_RANGE[1]:g}] "
                     f"(p(β) ∝ 1/β; Algorithm 1: on its lattice's range)")
_PAPER_BETA = (f"β ~ Normal({BETA_PRIOR_MEAN:g}, {BETA_PRIOR_SD:g}) truncated to "
               f"[{BETA_RANGE[0]:g}, {BETA_RANGE[1]:g}] (the paper's Sec. VII-A)")
PRIORS = {
    "log-uniform": Prior("log-uniform", LOG_UNIFORM_RANGE, _LOG_UNIFORM_BETA, DEFAULT_CONCENTRATION,
                         f"{_BIRL_THETA}, {_LOG_UNIFORM_BETA}"),
    "paper": Prior("paper", BETA_RANGE, _PAPER_BETA, 1.0, f"{_BIRL_THETA}, {_PAPER_BETA}"),
}
DEFAULT_PRIOR = "log-uniform"


def get_prior(name: str) -> Prior:
    """The prior called ``name``; an :class:`~expertise_irl.options.OptionError` naming the choices."""
    from ..options import one_of

    return PRIORS[one_of(name, PRIORS, "prior")]


def concentration_of(name: str, concentration: float | None = None) -> float:
    """θ's Dirichlet concentration α: ``concentration`` if given (finite and > 0, else
    :class:`~expertise_irl.errors.InputError`), otherwise the prior's default."""
    from ..errors import InputError

    prior = get_prior(name)
    if concentration is None:
        return prior.concentration
    a = float(concentration)
    if not (math.isfinite(a) and a > 0):
        raise InputError(f"concentration must be a finite number > 0, got {concentration!r}")
    return a


def prior_text(name: str, concentration: float | None = None) -> str:
    """The prior of MAP and NUTS in words: θ's Dirichlet(α) and β's part."""
    a = concentration_of(name, concentration)
    theta = "θ uniform on the simplex (Dirichlet(1))" if a == 1 else f"θ ~ Dirichlet({a:g}) on the simplex"
    return f"{theta}, {get_prior(name).beta_text}"


#: The default prior of MAP and NUTS in words, as the command line prints it and results record it.
PRIOR_TEXT = prior_text(DEFAULT_PRIOR)


def log_prior_numpy(name: str, theta, beta: float, beta_range: tuple[float, float] | None = None) -> float:
    """log p(θ, β) up to a constant (NumPy), θ uniform (Algorithm 1's prior); −∞ outside the
    support (θ < 0, β outside the range).

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


def _log_beta_density(name: str, beta):
    """log p(β) up to a constant inside the prior's range (JAX)."""
    import jax.numpy as jnp

    if name == "paper":
        return -0.5 * ((beta - BETA_PRIOR_MEAN) / BETA_PRIOR_SD) ** 2
    return -jnp.log(beta)


def log_prior_jax(name: str, concentration: float | None = None):
    """``f(theta, beta) -> log p`` up to a constant, JAX-traceable, the density on (θ, β):
    Σ(α − 1) log θ_i + log p(β) (θ is on the simplex; −∞ outside β's range)."""
    enable_float64()
    import jax.numpy as jnp

    lo, hi = get_prior(name).beta_range
    a = concentration_of(name, concentration)

    def f(theta, beta):
        inside = (beta >= lo) & (beta <= hi)
        lp = _log_beta_density(name, beta)
        if a != 1:
            lp = lp + (a - 1) * jnp.sum(jnp.log(theta))
        return jnp.where(inside, lp, -jnp.inf)

    return f


def log_prior_unconstrained(name: str, concentration: float | None = None):
    """``g(z, b) -> log p`` up to a constant, JAX-traceable: the prior's density in MAP's
    coordinates θ = softmax(z), β = e^b (the module docstring): Σ_i (α z_i − e^{z_i}) for θ,
    log p(e^b) + b for β, −∞ outside β's range."""
    enable_float64()
    import jax.numpy as jnp

    lo, hi = (math.log(v) for v in get_prior(name).beta_range)
    a = concentration_of(name, concentration)

    def g(z, b):
        inside = (b >= lo) & (b <= hi)
        lp = jnp.sum(a * z - jnp.exp(z)) + _log_beta_density(name, jnp.exp(b)) + b
        return jnp.where(inside, lp, -jnp.inf)

    return g


def unconstrained_from_density(log_prior):
    """``g(z, b)``: a density ``log_prior(theta, beta)`` on (θ, β) written in (z, b), with
    z's scale s = Σ e^{z_i} ~ Gamma(K, 1) apart from θ: log_prior(θ, β) + Σ log θ_i + b +
    K log s − s (for a Dirichlet(1) it is :func:`log_prior_unconstrained`'s at α = 1)."""
    enable_float64()
    import jax
    import jax.numpy as jnp

    def g(z, b):
        log_s = jax.scipy.special.logsumexp(z)
        log_theta = z - log_s
        return (log_prior(jnp.exp(log_theta), jnp.exp(b)) + jnp.sum(log_theta) + b
                + z.shape[-1] * log_s - jnp.exp(log_s))

    return g


def numpyro_priors(name: str, n_features: int, concentration: float | None = None):
    """``(theta_prior, beta_prior)`` NumPyro distributions of the prior called ``name``."""
    enable_float64()
    import jax.numpy as jnp
    import numpyro.distributions as dist

    prior = get_prior(name)
    lo, hi = prior.beta_range
    theta_prior = dist.Dirichlet(jnp.full(n_features, concentration_of(name, concentration)))
    if name == "paper":
        return theta_prior, dist.TruncatedNormal(BETA_PRIOR_MEAN, BETA_PRIOR_SD, low=lo, high=hi)
    return theta_prior, dist.LogUniform(lo, hi)
