"""A parametric learning curve for the continuous methods: β that changes log-linearly.

The model (θ shared by all episodes; episodes e = 0 … E−1 in the order given,
``trajs.episode_ids``, or, for several tasks, each task's episodes in turn, in the tasks' order):

    log β_e = log β_0 + λ·g(e),   g(e) = e/(E−1)   (g = 0 when E = 1),

so β_0 is the first episode's expertise, β_0·e^λ the last one's, and λ = log(β_last/β_0)
(negative: the person improves, β falls). The log-likelihood is Σ_e ll_e(θ, β_e), ll_e the
differentiable log-likelihood of episode e alone
(:func:`~expertise_irl.planning.differentiable.make_log_likelihood` on that episode's counts),
one solve per episode per evaluation.

Prior (:func:`trend_prior_text`), a density on (θ, log β_0, λ):

- θ ~ Dirichlet(α) on the simplex (α the MAP or NUTS options' ``concentration``, by default
  the ``log-uniform`` prior's, :func:`.priors.concentration_of`);
- log β_0 uniform on [log 1e-3, log 1e2] (the β part of the ``log-uniform`` prior of
  :mod:`.priors`: p(β_0) ∝ 1/β_0 on [1e-3, 1e2]);
- λ ~ Normal(0, 2), independent of both.

:func:`log_prior_trend` is the (log β_0, λ) part of its log density up to a constant: −λ²/8
inside the support, −∞ outside. The MAP (:func:`map_trend`) maximises log-likelihood + log prior
in (z, log β_0, λ), θ = softmax(z), the same way :func:`.gradient.map_estimate` does for one β:
θ's part written in z (:func:`.priors.log_prior_unconstrained`: Σ_i (α z_i − e^{z_i}), so the
mode maximises ∏θ_i^α), log β_0's flat there already.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from ..planning.differentiable import make_log_likelihood
from .gradient import multistart_lbfgsb
from .priors import LOG_UNIFORM_RANGE, concentration_of
from .task_likelihood import as_tasks, pair_counts

__all__ = ["SLOPE_PRIOR_SD", "TREND_G", "TREND_PRIOR_TEXT", "TrendMAP", "episode_grid", "episode_tasks",
           "fit_trend", "log_prior_trend", "map_trend", "split_episodes", "trend_objective",
           "trend_prior_text"]

#: The prior standard deviation of the slope λ = log(β_last/β_0).
SLOPE_PRIOR_SD = 2.0
#: The learning curve's shape in words.
TREND_G = "e/(E-1)"
_TREND_BETA_TEXT = (
    f"log β_0 uniform on [log {LOG_UNIFORM_RANGE[0]:g}, "
    f"log {LOG_UNIFORM_RANGE[1]:g}], λ ~ Normal(0, {SLOPE_PRIOR_SD:g}); "
    f"log β_e = log β_0 + λ·{TREND_G}")


def trend_prior_text(concentration: float | None = None) -> str:
    """The learning curve's prior in words, θ ~ Dirichlet(α) (default: the log-uniform prior's α)."""
    a = concentration_of("log-uniform", concentration)
    theta = "θ uniform on the simplex" if a == 1 else f"θ ~ Dirichlet({a:g}) on the simplex"
    return f"{theta}, {_TREND_BETA_TEXT}"


TREND_PRIOR_TEXT = trend_prior_text()


@dataclass(frozen=True)
class TrendMAP:
    """The MAP learning curve and how it was found.

    Attributes:
        theta: ``[K]`` θ̂ on the simplex.
        beta0: β̂_0, the first episode's expertise.
        slope: λ̂ = log(β̂_last/β̂_0).
        betas: ``[E]`` β̂_e = β̂_0·exp(λ̂·g(e)).
        log_posterior: log-likelihood + :func:`log_prior_trend` + θ's Dirichlet(α) in z at the optimum
            (at z's optimal scale α·Σ log θ_i + Kα·log(Kα) − Kα; :func:`.priors.log_prior_unconstrained`).
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


def episode_tasks(mdp, trajs) -> list[tuple[TabularMDP, Trajectories, dict[str, Any]]]:
    """``[(mdp, one episode's trajectories, label)]`` in learning-curve order: one MDP and its
    trajectories, or equal-length lists of both (:func:`~.task_likelihood.as_tasks`), each task's
    episodes in turn. ``label`` is ``{"episode": its label}`` for one task and ``{"episode": its
    position in the order, "task": its task's index in the lists, "task_episode": its label}`` for
    several."""
    tasks = as_tasks(mdp, trajs)
    several = not isinstance(mdp, TabularMDP)
    out = []
    for t, (m, tr) in enumerate(tasks):
        for lab, ep in zip(tr.episode_ids, split_episodes(tr), strict=True):
            label = ({"episode": len(out), "task": t, "task_episode": _label(lab)} if several
                     else {"episode": _label(lab)})
            out.append((m, ep, label))
    return out


def log_prior_trend(log_beta0, slope):
    """log p(θ, log β_0, λ) up to a constant (JAX-traceable): −λ²/(2·2²) when log β_0 is in
    [log 1e-3, log 1e2], −∞ otherwise (θ's uniform density is a constant)."""
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)
    inside = (log_beta0 >= lo) & (log_beta0 <= hi)
    return jnp.where(inside, -0.5 * (slope / SLOPE_PRIOR_SD) ** 2, -jnp.inf)


def trend_objective(mdp, trajs, *, tol: float = 1e-10, model: str = DEFAULT_MODEL):
    """``(f, g)``: ``f(theta, log_beta0, slope) -> (log-likelihood, log prior)``, JAX-traceable,
    the log-likelihood Σ_e ll_e(θ, β_e) over the episodes of :func:`episode_tasks` (one MDP and
    its trajectories, or lists of both); ``g`` the ``[E]`` grid g(e)."""
    episodes = episode_tasks(mdp, trajs)
    if not episodes or sum(len(t) for _, t, _ in episodes) == 0:
        raise InputError("need at least one demonstrated step")
    parts = [make_log_likelihood(m, pair_counts(m, t), tol=tol, model=model) for m, t, _ in episodes]
    g = episode_grid(len(parts))

    def f(theta, log_beta0, slope):
        ll = 0.0
        for part, ge in zip(parts, g, strict=True):
            ll = ll + part(theta, jnp.exp(log_beta0 + slope * ge))[0]
        return ll, log_prior_trend(log_beta0, slope)

    return f, g


def map_trend(mdp, trajs, *, n_starts: int = 4, rng: np.random.Generator,
              model: str = DEFAULT_MODEL, tol: float = 1e-10, concentration: float | None = None) -> TrendMAP:
    """Maximise Σ_e ll_e(θ, β_e) + log p(θ, log β_0, λ) by L-BFGS-B from ``n_starts`` starts.

    Coordinates x = (z, log β_0, λ), θ = softmax(z); log β_0 is bounded to the prior's range,
    λ is free. Starts: θ uniform on the simplex, log β_0 uniform on the prior's range, λ = 0
    (no change; the slope's likelihood is smooth and its prior unimodal). ``mdp`` and ``trajs``
    may be equal-length lists of tasks (:func:`episode_tasks`). θ's prior is Dirichlet(α),
    α = ``concentration`` (default: the log-uniform prior's), written in z.
    """
    from .priors import log_prior_unconstrained

    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    f, g = trend_objective(mdp, trajs, tol=tol, model=model)
    K = as_tasks(mdp, trajs)[0][0].n_features
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)
    theta_prior = log_prior_unconstrained("log-uniform", concentration)  # its b part is 0 here

    def objective(x):
        ll, lp = f(jax.nn.softmax(x[:K]), x[K], x[K + 1])
        return -(ll + lp + theta_prior(x[:K], 0.0))

    def draw_start():
        theta0 = rng.dirichlet(np.ones(K))
        b0 = rng.uniform(lo, hi)
        return (np.concatenate([np.log(np.maximum(theta0, 1e-12)), [b0, 0.0]]),
                np.concatenate([theta0, [math.exp(b0), 0.0]]))

    bounds = [(None, None)] * K + [(lo, hi), (None, None)]
    run = multistart_lbfgsb(objective, draw_start, n_starts, bounds)
    x = np.asarray(run.best.x)
    theta = np.asarray(jax.nn.softmax(jnp.asarray(x[:K])))
    b0, slope = float(x[K]), float(x[K + 1])
    return TrendMAP(theta, math.exp(b0), slope, np.exp(b0 + slope * g), float(-run.best.fun),
                    run.optima, run.evaluations, run.starts)


def _label(v) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def fit_trend(mdp, trajs, opts, seed) -> dict[str, Any]:
    """The MAP learning curve as a result dict, for ``opts`` a MAP options object
    (``get_method("map").options_from({...})``: its ``starts`` and ``model``; its prior must be
    ``log-uniform``, whose β part is the prior of β_0).

    ``mdp`` and ``trajs`` may be equal-length lists of tasks, their episodes one curve in the tasks'
    order (:func:`episode_tasks`). Keys: ``theta_hat``; ``beta_hat``, the curve's geometric mean
    over the episodes, exp(mean_e log β̂_e) (= β̂_0·e^{λ̂/2}, the curve at g = 1/2, when E ≥ 2);
    ``expertise_by_episode`` (one row per episode: its :func:`episode_tasks` label, ``mean`` =
    ``median`` = β̂_e, ``q05`` = ``q95`` = None: a point estimate has no band); ``trend``
    (``beta0``, ``slope``, ``g``, ``prior``, ``log_ratio_mean`` = λ̂); ``diagnostics``
    (``warnings``, ``optima``, ``starts``, ``evaluations``, ``log_posterior``).
    """
    from .diagnostics import map_warnings

    if getattr(opts, "prior", "log-uniform") != "log-uniform":
        raise InputError(f"the learning curve's prior is fixed ({TREND_PRIOR_TEXT}); "
                         f"got prior {opts.prior!r}, use 'log-uniform'")
    alpha = getattr(opts, "concentration", None)
    r = map_trend(mdp, trajs, n_starts=opts.starts, rng=np.random.default_rng(seed), model=opts.model,
                  concentration=alpha)
    beta_hat = float(np.exp(np.mean(np.log(r.betas))))
    diag: dict[str, Any] = {"optima": r.optima.tolist(), "starts": r.starts.tolist(),
                            "evaluations": r.evaluations, "log_posterior": r.log_posterior}
    # Start agreement, and β̂_0 on the edge of its prior's range.
    warnings = [w.replace("β̂ =", "β̂_0 =") for w in map_warnings(diag, r.beta0, LOG_UNIFORM_RANGE)]
    labels = [lab for _, _, lab in episode_tasks(mdp, trajs)]
    if len(labels) == 1:
        warnings.append("one episode: the slope is not identified (λ̂ = 0 is the prior's mode)")
    diag["warnings"] = warnings
    rows = [{**lab, "mean": float(b), "median": float(b), "q05": None, "q95": None}
            for lab, b in zip(labels, r.betas, strict=True)]
    return {
        "theta_hat": r.theta.tolist(),
        "beta_hat": beta_hat,
        "expertise_by_episode": rows,
        "trend": {"beta0": r.beta0, "slope": r.slope, "g": TREND_G, "prior": trend_prior_text(alpha),
                  "log_ratio_mean": r.slope},
        "diagnostics": diag,
    }


# ----------------------------------------------------------------------------- NUTS
# The same posterior as map_trend's objective, sampled with NUTS through the kernel and chain
# driver of .nuts_kernel (mirroring .shared_beta.nuts_shared_beta).
#
# Unconstrained coordinates x = (u [K−1], u_b, λ), dimension K + 1:
#   θ       = StickBreaking(u)                     (numpyro's biject_to(simplex)),
#   log β_0 = lo + (hi − lo)·σ(u_b)                 (biject_to(interval(lo, hi))),
#   λ       = x[K]                                  (identity).
# The density in (θ, log β_0, λ) is exp(ll + log_prior_trend) (θ's uniform density and log β_0's
# uniform density are constants), so the potential is
#   U(x) = −[ll(θ, log β_0, λ) + log_prior_trend(log β_0, λ)
#            + log|det ∂θ_{1:K−1}/∂u| + log(hi − lo) + log σ(u_b) + log(1 − σ(u_b))],
# λ's Jacobian being 1.
__all__ += ["TrendNUTS", "fit_trend_nuts", "nuts_trend", "trend_posterior"]


@dataclass(frozen=True)
class TrendNUTS:
    """Posterior draws of the learning curve (θ, log β_0, λ) from NUTS and their diagnostics.

    Attributes:
        theta: ``[C, D, K]`` draws of θ (on the simplex).
        log_beta0: ``[C, D]`` draws of log β_0.
        slope: ``[C, D]`` draws of λ = log(β_last/β_0).
        betas: ``[C, D, E]`` β_e = exp(log β_0 + λ·g(e)) of each draw.
        r_hat: ``{"slope", "log_beta0", "theta": [K]}`` split-R̂ (rank-normalised), or None when
            the run is too short (``unavailable`` says why).
        ess: ``{"slope", "log_beta0", "theta": [K]}`` bulk ESS, or None.
        divergences: divergent transitions after warm-up.
        unavailable: ``{statistic: reason}``, keys as ``"r_hat.slope"``, ``"ess_bulk.theta[k]"``.
        mean_tree_size: leapfrog steps per draw after warm-up, averaged.
        mean_accept_prob: mean acceptance statistic after warm-up.
        stuck: ``{"log_beta0" | "slope" | "theta[k]": {chain: value}}`` parameters a chain never moved.
        warnings: :func:`~.diagnostics.nuts_warnings` of the run, with β named log β_0 or λ.
        g: ``[E]`` the grid g(e).
    """

    theta: np.ndarray
    log_beta0: np.ndarray
    slope: np.ndarray
    betas: np.ndarray
    r_hat: dict | None
    ess: dict | None
    divergences: int
    unavailable: dict
    mean_tree_size: float = float("nan")
    mean_accept_prob: float = float("nan")
    stuck: dict = field(default_factory=dict)
    warnings: tuple = ()
    g: np.ndarray = field(default_factory=lambda: np.zeros(0))


class _Closed:
    """The ``f`` that :func:`~.nuts_kernel.compile_kernel` reads (``counts``, ``zero_start``):
    the trend's likelihood closes over its counts, so both are placeholders (no warm start)."""

    counts = np.zeros(())

    @staticmethod
    def zero_start():
        return jnp.zeros(())


def trend_posterior(mdp, trajs, *, tol: float = 1e-8, model: str = DEFAULT_MODEL,
                    concentration: float | None = None):
    """``(Posterior, g)``: the :class:`~.nuts_kernel.Posterior` of (θ, log β_0, λ) in the
    unconstrained coordinates x = (u, u_b, λ) above (``constrained(x) -> (θ, [log β_0, λ])``),
    the potential −(ll + :func:`log_prior_trend` + (α − 1)·Σ log θ_i + log Jacobian) of
    :func:`trend_objective`'s ``f``, α = ``concentration`` (default: the log-uniform prior's)."""
    import numpyro.distributions as dist
    from numpyro.distributions.transforms import biject_to

    from .nuts_kernel import Posterior

    f, g = trend_objective(mdp, trajs, tol=tol, model=model)
    K = as_tasks(mdp, trajs)[0][0].n_features
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)
    theta_map = biject_to(dist.constraints.simplex)
    b_map = biject_to(dist.constraints.interval(lo, hi))
    n_u = theta_map.inverse_shape((K,))[0]
    a = concentration_of("log-uniform", concentration)

    def log_theta_density(theta):
        return 0.0 if a == 1 else (a - 1) * jnp.sum(jnp.log(theta))

    def unpack(x):
        u, u_b, slope = x[:n_u], x[n_u], x[n_u + 1]
        return u, u_b, theta_map(u), b_map(u_b), slope

    def constrained(x):
        _, _, theta, b, slope = unpack(x)
        return theta, jnp.stack([b, slope])

    def potential(x, start, counts):
        u, u_b, theta, b, slope = unpack(x)
        ll, lp = f(theta, b, slope)
        log_jac = theta_map.log_abs_det_jacobian(u, theta) + b_map.log_abs_det_jacobian(u_b, b)
        return -(ll + lp + log_theta_density(theta) + log_jac)

    def log_density(theta, b_slope, counts):
        ll, lp = f(theta, b_slope[0], b_slope[1])
        return ll + lp + log_theta_density(theta)

    return Posterior(potential, constrained, log_density, n_u + 2), g


def _trend_statistics(theta: np.ndarray, log_beta0: np.ndarray, slope: np.ndarray,
                      feature_names, divergences: int) -> dict[str, Any]:
    """:func:`~.diagnostics.chain_statistics` and :func:`~.diagnostics.nuts_warnings` for
    (θ, log β_0) and for λ alone, their "β" renamed."""
    from .diagnostics import chain_statistics, nuts_warnings

    C = slope.shape[0]
    names = list(feature_names)
    a = chain_statistics(theta, log_beta0, feature_names=names)
    s = chain_statistics(theta[..., :0], slope, feature_names=[])
    out: dict[str, Any] = {}
    for stat in ("r_hat", "ess_bulk"):
        out[stat] = (None if a[stat] is None else
                     {"slope": s[stat]["beta"], "log_beta0": a[stat]["beta"], "theta": a[stat]["theta"]})
    unavailable: dict[str, str] = {}
    for src, name, label in ((a, "log_beta0", "log β_0"), (s, "slope", "λ")):
        for key, why in src["unavailable"].items():
            unavailable[key.replace(".beta", f".{name}")] = why.replace(" β ", f" {label} ")
    stuck = {("log_beta0" if i == 0 else f"theta[{i - 1}]"): v for i, v in a["stuck"].items()}
    if 0 in s["stuck"]:
        stuck["slope"] = s["stuck"][0]
    warnings: list[str] = []
    for src, label, div in ((a, "log β_0", divergences), (s, "λ", 0)):
        diag = {"r_hat": src["r_hat"], "ess_bulk": src["ess_bulk"], "divergences": div, "chains": C,
                "unavailable": src["unavailable"]}
        for w in nuts_warnings(diag, names if src is a else [], src["stuck"]):
            w = (w.replace("of β ", f"of {label} ").replace("in β ", f"in {label} ")
                 .replace("in β:", f"in {label}:").replace("β = ", f"{label} = ")
                 .replace(" β,", f" {label},").replace(" β ", f" {label} "))
            if w not in warnings:
                warnings.append(w)
    out.update(unavailable=unavailable, stuck=stuck, warnings=warnings)
    return out


def nuts_trend(
    mdp,
    trajs,
    *,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 4,
    seed: int = 0,
    model: str = DEFAULT_MODEL,
    tol: float = 1e-8,
    progress=None,
    dense_mass: bool = True,
    target_accept: float = 0.8,
    concentration: float | None = None,
) -> TrendNUTS:
    """Sample P(θ, log β_0, λ | Ξ) ∝ exp(Σ_e ll_e(θ, β_e) + :func:`log_prior_trend`) — the density
    :func:`map_trend` maximises — with NUTS, in the K + 1 unconstrained coordinates of
    :func:`trend_posterior`.

    The kernel, the chain driver, the Laplace starts and the chains' starts and keys are those of
    :func:`~.shared_beta.nuts_shared_beta` (and :func:`~.nuts.nuts_posterior`); no solver warm
    start (one solve per episode per evaluation, from zero). ``progress(done, total)`` counts
    iterations over the chains.
    """
    from .nuts_kernel import check_run, sample

    num_warmup, num_samples, num_chains = check_run(num_warmup, num_samples, num_chains, target_accept)
    post, g = trend_posterior(mdp, trajs, tol=tol, model=model, concentration=concentration)
    f = _Closed()
    draws = sample(post, f, num_warmup=num_warmup, num_samples=num_samples, num_chains=num_chains,
                   seed=seed, dense_mass=dense_mass, target_accept=target_accept, progress=progress)
    th, bs, div, steps, acc = draws
    th = np.asarray(th, np.float64)
    log_beta0, slope = np.asarray(bs[..., 0], np.float64), np.asarray(bs[..., 1], np.float64)
    betas = np.exp(log_beta0[..., None] + slope[..., None] * np.asarray(g)[None, None, :])
    names = as_tasks(mdp, trajs)[0][0].feature_names
    stats = _trend_statistics(th, log_beta0, slope, names, int(div.sum()))
    return TrendNUTS(
        theta=th, log_beta0=log_beta0, slope=slope, betas=betas, r_hat=stats["r_hat"],
        ess=stats["ess_bulk"], divergences=int(div.sum()), unavailable=stats["unavailable"],
        mean_tree_size=float(steps.mean()), mean_accept_prob=float(acc.mean()), stuck=stats["stuck"],
        warnings=tuple(stats["warnings"]), g=np.asarray(g, np.float64),
    )


def fit_trend_nuts(mdp, trajs, opts, seed, *, progress=None) -> dict[str, Any]:
    """The NUTS learning curve as a result dict, for ``opts`` a NUTS options object
    (``get_method("nuts").options_from({...})``: its ``chains``, ``warmup``, ``samples`` and
    ``model``; its prior must be ``log-uniform``), ``seed`` an int.

    Keys as :func:`fit_trend`'s, from the draws: ``theta_hat`` (posterior mean θ); ``beta_hat``,
    the posterior mean of the curve's geometric mean over the episodes, exp(mean_e log β_e);
    ``expertise_by_episode`` (per episode ``episode``, ``mean``, ``median``, ``q05``, ``q95`` of
    β_e); ``trend`` (``beta0`` = posterior mean of β_0, ``slope`` = mean λ, ``slope_q05``,
    ``slope_q95``, ``p_falls`` = the fraction of draws with λ < 0, ``p_rises`` with λ > 0, ``g``, ``prior``,
    ``log_ratio_mean`` = mean λ); ``diagnostics`` (``r_hat``, ``ess_bulk`` as
    ``{"slope", "log_beta0", "theta": [K]}``, ``divergences``, ``chains``, ``draws_per_chain``,
    ``mean_tree_size``, ``mean_accept_prob``, ``warnings``, ``unavailable``).
    """
    if getattr(opts, "prior", "log-uniform") != "log-uniform":
        raise InputError(f"the learning curve's prior is fixed ({TREND_PRIOR_TEXT}); "
                         f"got prior {opts.prior!r}, use 'log-uniform'")
    r = nuts_trend(mdp, trajs, num_warmup=opts.warmup, num_samples=opts.samples, num_chains=opts.chains,
                   seed=int(seed), model=opts.model, progress=progress,
                   concentration=getattr(opts, "concentration", None))
    C, D, K = r.theta.shape
    betas = r.betas.reshape(C * D, -1)
    slope, log_beta0 = r.slope.reshape(-1), r.log_beta0.reshape(-1)
    warnings = list(r.warnings)
    labels = [lab for _, _, lab in episode_tasks(mdp, trajs)]
    if len(labels) == 1:
        warnings.append("one episode: the slope is not identified (its posterior is its prior)")
    rows = [{**lab, "mean": float(b.mean()), "median": float(np.median(b)),
             "q05": float(np.quantile(b, 0.05)), "q95": float(np.quantile(b, 0.95))}
            for lab, b in zip(labels, betas.T, strict=True)]
    return {
        "theta_hat": r.theta.reshape(C * D, K).mean(axis=0).tolist(),
        "beta_hat": float(np.exp(np.log(betas).mean(axis=1)).mean()),
        "expertise_by_episode": rows,
        "trend": {"beta0": float(np.exp(log_beta0).mean()), "slope": float(slope.mean()),
                  "slope_q05": float(np.quantile(slope, 0.05)), "slope_q95": float(np.quantile(slope, 0.95)),
                  "p_falls": float(np.mean(slope < 0)), "p_rises": float(np.mean(slope > 0)),
                  "g": TREND_G, "prior": trend_prior_text(getattr(opts, "concentration", None)),
                  "log_ratio_mean": float(slope.mean())},
        "diagnostics": {"r_hat": r.r_hat, "ess_bulk": r.ess, "divergences": r.divergences,
                        "chains": C, "draws_per_chain": D, "mean_tree_size": r.mean_tree_size,
                        "mean_accept_prob": r.mean_accept_prob, "warnings": warnings,
                        "unavailable": r.unavailable},
    }
