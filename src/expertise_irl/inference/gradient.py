"""Gradient-based estimators on the continuous space: MAP by quasi-Newton (and NUTS).

The parameters are θ on the unit simplex (‖θ‖₁ = 1 fixes the scale, DESIGN's scale
invariance) and β > 0. Both optimisers work on unconstrained coordinates,
θ = softmax(z) and β = exp(b), with the log-density and its exact gradient from
:func:`expertise_irl.likelihood.make_log_likelihood`.

Priors by name (:mod:`expertise_irl.inference.priors`): ``log-uniform`` (the default: θ
uniform on the simplex, log β uniform on [1e-3, 1e2]) or ``paper`` (Sec. VII-A: β ~
Normal(5.005, 1.5) truncated to [0.01, 10]). Any other prior can be passed as a
JAX-traceable ``log_prior(theta, beta)`` (MAP) or NumPyro distributions (NUTS).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from ..demos import Trajectories
from ..errors import InputError
from ..likelihood import make_log_likelihood, pair_counts
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from .diagnostics import chain_statistics
from .priors import BETA_PRIOR_MEAN, BETA_PRIOR_SD, DEFAULT_PRIOR, get_prior, log_prior_jax, numpyro_priors

__all__ = ["BETA_PRIOR_MEAN", "BETA_PRIOR_SD", "MAPResult", "NUTSResult", "map_estimate", "nuts_posterior",
           "paper_log_prior"]

#: Sec. VII-A prior: flat on the simplex for θ, Normal(5.005, 1.5) on [0.01, 10] for β.
paper_log_prior = log_prior_jax("paper")


@dataclass(frozen=True)
class MAPResult:
    """The MAP estimate and how it was found.

    Attributes:
        theta: ``[K]`` θ̂ on the simplex.
        beta: β̂.
        log_posterior: the unnormalised log-posterior at the optimum.
        starts: ``[n_starts, K + 1]`` the (θ, β) each run started from.
        optima: ``[n_starts]`` log-posterior each run reached (the best is reported).
        evaluations: total likelihood-and-gradient evaluations.
    """

    theta: np.ndarray
    beta: float
    log_posterior: float
    starts: np.ndarray
    optima: np.ndarray
    evaluations: int


def _unpack(x):
    z, b = x[:-1], x[-1]
    return jax.nn.softmax(z), jnp.exp(b)


def map_estimate(
    mdp: TabularMDP,
    trajs: Trajectories,
    *,
    n_starts: int = 4,
    rng: np.random.Generator,
    log_prior: Callable | None = None,
    beta_range: tuple[float, float] | None = None,
    tol: float = 1e-10,
    progress: Callable[[int, int], None] | None = None,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
) -> MAPResult:
    """Maximise log P(Ξ | θ, β) + log P(θ, β) by L-BFGS-B from ``n_starts`` random starts.

    Starts: θ uniform on the simplex, log β uniform on ``log beta_range``. The β search is
    bounded to ``beta_range`` (default: the support of ``prior``); θ moves freely on the
    simplex (components approach 0 as z → −∞). ``prior`` names the prior
    (``"log-uniform"`` or ``"paper"``) unless ``log_prior`` is given; ``model`` is the
    observation model.
    ``progress(done, n_starts)`` is called after each start.
    """
    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    beta_range = get_prior(prior).beta_range if beta_range is None else beta_range
    lo, hi = beta_range
    if not 0 < lo < hi:
        raise InputError(f"beta_range must satisfy 0 < low < high, got {beta_range}")
    log_prior = log_prior_jax(prior) if log_prior is None else log_prior
    f = make_log_likelihood(mdp, pair_counts(mdp, trajs), tol=tol, model=model)
    K = mdp.n_features

    @jax.jit
    def objective(x):
        theta, beta = _unpack(x)
        ll, _ = f(theta, beta)
        return -(ll + log_prior(theta, beta))

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

    bounds = [(None, None)] * K + [(math.log(lo), math.log(hi))]
    starts, optima, best = [], [], None
    for i in range(n_starts):
        theta0 = rng.dirichlet(np.ones(K))
        beta0 = math.exp(rng.uniform(math.log(lo), math.log(hi)))
        x0 = np.concatenate([np.log(np.maximum(theta0, 1e-12)), [math.log(beta0)]])
        res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"maxiter": 500, "ftol": 1e-12, "gtol": 1e-7})
        starts.append(np.concatenate([theta0, [beta0]]))
        optima.append(-res.fun)
        if best is None or res.fun < best.fun:
            best = res
        if progress is not None:
            progress(i + 1, n_starts)
    theta, beta = _unpack(jnp.asarray(best.x))
    return MAPResult(np.asarray(theta), float(beta), float(-best.fun), np.array(starts),
                     np.array(optima), evaluations)


def credible_intervals(theta: np.ndarray, beta: np.ndarray, prob: float = 0.9) -> dict:
    """Equal-tailed intervals of draws ``theta [n, K]``, ``beta [n]``:
    ``{"beta": [low, high], "theta": [[low, high], ...]}``."""
    q = [(1 - prob) / 2, (1 + prob) / 2]
    return {"beta": np.quantile(beta, q).tolist(), "theta": np.quantile(theta, q, axis=0).T.tolist()}


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
        unavailable: ``{statistic: reason}`` for each statistic that could not be computed.
        divergences: number of divergent transitions after warm-up.
        log_density: ``[chains, draws]`` unnormalised log-posterior of each draw (θ, β space).
    """

    theta: np.ndarray
    beta: np.ndarray
    idata: object
    r_hat: dict | None
    ess: dict | None
    divergences: int
    log_density: np.ndarray
    unavailable: dict

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
    mdp: TabularMDP,
    trajs: Trajectories,
    *,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 4,
    seed: int = 0,
    theta_prior=None,
    beta_prior=None,
    tol: float = 1e-8,
    progress_bar: bool = False,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
) -> NUTSResult:
    """Sample P(θ, β | Ξ) with NumPyro's NUTS on the same log-density as :func:`map_estimate`.

    ``prior`` names the prior (``"log-uniform"``, the default: a flat Dirichlet on the simplex
    for θ and log β uniform on [1e-3, 1e2]; ``"paper"``: β ~ Normal(5.005, 1.5) truncated to
    [0.01, 10]); ``theta_prior``/``beta_prior`` (NumPyro distributions) replace either part.
    ``model`` is the observation model. Chains are
    vectorised (run side by side in one program), which is fastest on a CPU; with
    ``progress_bar`` NumPyro shows one bar on stderr for all of them (they advance in lockstep),
    with the time left.
    """
    import arviz as az
    import numpyro
    from numpyro.infer import MCMC, NUTS

    for name, value, least in (("num_warmup", num_warmup, 1), ("num_samples", num_samples, 1),
                               ("num_chains", num_chains, 1)):
        if int(value) < least:
            raise InputError(f"{name} must be >= {least}, got {value}")
    f = make_log_likelihood(mdp, pair_counts(mdp, trajs), tol=tol, model=model)
    named_theta, named_beta = numpyro_priors(prior, mdp.n_features)
    theta_prior = named_theta if theta_prior is None else theta_prior
    beta_prior = named_beta if beta_prior is None else beta_prior

    def model():
        theta = numpyro.sample("theta", theta_prior)
        beta = numpyro.sample("beta", beta_prior)
        ll, _ = f(theta, beta)
        numpyro.factor("log_likelihood", ll)

    mcmc = MCMC(NUTS(model), num_warmup=int(num_warmup), num_samples=int(num_samples),
                num_chains=int(num_chains), chain_method="vectorized", progress_bar=progress_bar)
    mcmc.run(jax.random.PRNGKey(int(seed)), extra_fields=("diverging",))
    samples = mcmc.get_samples(group_by_chain=True)
    th, be = samples["theta"], samples["beta"]
    # One compiled, vectorised pass over every draw (each solve stops on its own tolerance).
    density = jax.jit(jax.vmap(lambda t, b: f(t, b)[0] + theta_prior.log_prob(t) + beta_prior.log_prob(b)))
    C_, D_ = be.shape
    log_density = np.asarray(density(th.reshape(C_ * D_, -1), be.reshape(-1))).reshape(C_, D_)
    idata = az.from_numpyro(mcmc)
    theta_draws, beta_draws = np.asarray(th), np.asarray(be)
    stats = chain_statistics(theta_draws, beta_draws)
    divergences = int(np.sum(np.asarray(mcmc.get_extra_fields()["diverging"])))
    return NUTSResult(
        theta=theta_draws, beta=beta_draws, idata=idata, r_hat=stats["r_hat"], ess=stats["ess_bulk"],
        divergences=divergences, log_density=log_density, unavailable=stats["unavailable"],
    )
