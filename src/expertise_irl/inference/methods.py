"""The inference methods behind one interface: an options dataclass and a run function each.

:data:`METHODS` maps a name to its :class:`Method`: ``discrete`` (the paper's hypothesis set,
Eq. 13), ``birl`` (Algorithm 1, box or simplex), ``map`` (L-BFGS on the exact gradient) and
``nuts`` (the full posterior). Every method is called the same way::

    method = get_method("nuts")
    run = method.run(mdp, trajs, method.options_from({"chains": 2}), seed)

``options_from`` takes the options a method reads, by the names of its options dataclass's
fields, which are the command line's option names; the options validate themselves when they
are made (an :class:`~expertise_irl.options.OptionError` naming the field; the command line writes
it as the flag). Each :class:`Method` meets the :class:`InferenceMethod` protocol; its choices
(``expertise``, ``variant``, ``prior``, ``model``) are the enums of :mod:`expertise_irl.options`.
``run`` returns a :class:`MethodRun`: the method's own result and the fields of the result document,
``theta_hat``, ``beta_hat``, the ``map`` point, ``samples`` (as ``draws``) and 90%
``credible_intervals`` for the samplers, ``diagnostics`` and ``run_time_s``; :func:`document`
writes them with :mod:`expertise_irl.results`. ``fit`` alone runs the method without
describing it; ``setup`` settles what comes before the long part (the discrete set, the
notes a user should see before a progress bar). Nothing here imports JAX until a method runs.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any, NamedTuple, Protocol, TypeVar

import numpy as np

from ..errors import InputError
from ..models import DEFAULT_MODEL, MODELS, PEDAGOGICAL
from ..options import (
    ADAPTIVE,
    DEFAULT_BETAS,
    DEFAULT_EXPERTISE,
    DEFAULT_THETAS,
    Expertise,
    OptionError,
    choose,
    one_of,
)
from ..options import Method as MethodName
from .priors import BETA_RANGE, DEFAULT_PRIOR, PRIORS

CREDIBLE = 0.9
#: Loosest solver tolerance of the discrete set (nats); looser makes the log-likelihoods meaningless.
MAX_TOL = 0.1

#: ``np.random.default_rng(seed)`` for birl and map (an int, a list of ints or a Generator); nuts: an int.
Seed = int | Sequence[int] | np.random.Generator
Progress = Callable[[int, int], None] | None
Note = Callable[[str], None] | None


#: ``expertise``: one β for every episode (the paper's), or a β per episode that may change.
EXPERTISE = tuple(e.value for e in Expertise)


# ----------------------------------------------------------------------------- options
def _one_of(field: str, value: str, choices) -> None:
    one_of(value, choices, field)


def _check_prior_and_model(prior: str, model: str) -> None:
    _one_of("prior", prior, PRIORS)
    if model == PEDAGOGICAL:
        raise OptionError("{model} pedagogical needs a discrete observer set (the literal observer's "
                          "hypothesis set is fixed before the data, and the teaching weight's posterior is "
                          "exact over it): use {method} discrete", "model", "method")
    _one_of("model", model, MODELS)


def _check_concentration(prior: str, concentration: float | None) -> None:
    from .priors import concentration_of

    try:
        concentration_of(prior, concentration)
    except InputError as e:
        raise OptionError("{concentration}" + str(e).removeprefix("concentration"), "concentration") from None


def _check_expertise(value: str) -> None:
    choose(Expertise, value, "expertise")


def _check_teaching(opts: DiscreteOptions) -> None:
    """The discrete method's model, and what the pedagogical model takes and refuses."""
    from .pedagogical import parse_lambdas

    _one_of("model", opts.model, MODELS)
    if opts.model != PEDAGOGICAL:
        if opts.lambdas is not None:
            raise OptionError("{lambdas} is the teaching weight's grid of {model} pedagogical, not of "
                              f"{{model}} {opts.model}", "lambdas", "model")
        return
    if opts.lambdas is not None:
        try:
            parse_lambdas(opts.lambdas)
        except InputError as e:
            raise OptionError("{lambdas}" + str(e).removeprefix("--lambdas"), "lambdas") from None
    if opts.refine:
        raise OptionError("{refine} cannot be used with {model} pedagogical: the literal observer's "
                          "hypothesis set is fixed before the data, and refining it where the posterior has "
                          "its mass would change the observer with the data", "refine", "model")
    if opts.per_action:
        raise OptionError("{per_action} is not built for {model} pedagogical: its posterior over the "
                          "teaching weight is computed from the demonstrations' pair counts as a whole, "
                          "not traced action by action", "per_action", "model")
    if opts.expertise == Expertise.CHANGING:
        raise OptionError("{expertise} changing is not built for {model} pedagogical: the teaching "
                          "model has one β and one teaching weight λ for every episode", "expertise", "model")


@dataclass(frozen=True)
class DiscreteOptions:
    """The paper's hypothesis set Ψ = Θ × B under a uniform prior (Eq. 13)."""

    thetas: str | None = None  # a preset or comma-separated component values (None: adaptive or paper-real)
    betas: str | None = None  # a preset or comma-separated temperatures (None: adaptive or paper-sim)
    sample_thetas: int | None = None  # use k directions of Θ drawn with the seed
    per_action: bool = False  # record the estimate after every action (a trace)
    tol: float | None = None  # solver tolerance (nats); None: the one the demonstrations need (certified)
    chunk_size: int | None = None  # hypotheses in flight in the solver
    model: str = DEFAULT_MODEL
    expertise: str = DEFAULT_EXPERTISE  # or "changing": β_e per episode (inference.changing)
    refine: bool | None = None  # refine the set (inference.adaptive); None: when no set is named
    max_hypotheses: int = 20_000  # refinement's cap on hypotheses solved
    max_seconds: float | None = None  # refinement's time cap: no round starts after it
    lambdas: str | None = None  # model pedagogical: the teaching weight's grid (None: pedagogical.LAMBDAS)

    def __post_init__(self) -> None:
        if self.tol is not None and not (0 < self.tol <= MAX_TOL):
            raise OptionError(f"{{tol}} must be > 0 and at most {MAX_TOL:g} nats, got {self.tol:g}", "tol")
        _check_expertise(self.expertise)
        if self.max_hypotheses < 1:
            raise OptionError(f"{{max_hypotheses}} must be >= 1, got {self.max_hypotheses}", "max_hypotheses")
        if self.max_seconds is not None and not (math.isfinite(self.max_seconds) and self.max_seconds > 0):
            raise OptionError(f"{{max_seconds}} must be a finite number > 0, got {self.max_seconds:g}",
                              "max_seconds")
        if self.refine and self.expertise == Expertise.CHANGING:
            raise OptionError("{refine} follows the one-β posterior and cannot be used with {expertise} "
                              "changing, whose β grid must span every episode's β (name it with {betas})",
                              "refine", "expertise", "betas")
        _check_teaching(self)

    max_draws = 0

    @property
    def named(self) -> bool:
        """Whether a set was named (``thetas``, ``betas`` or ``sample_thetas``)."""
        return self.thetas is not None or self.betas is not None or self.sample_thetas is not None

    @property
    def refines(self) -> bool:
        """Whether the set is refined: as asked, else exactly when no set is named and β is one for
        every episode (the refinement follows the one-β posterior, while a changing β's grid must
        span every episode's β). Never for the ``pedagogical`` model, whose observer's set is fixed
        before the data."""
        if self.model == PEDAGOGICAL:
            return False
        if self.refine is None:
            return not self.named and self.expertise == Expertise.STATIONARY
        return self.refine

    def hypotheses(self, n_features: int, seed: int = 0, note: Note = None):
        """The set Ψ over ``n_features`` (the start of the refinement when it :attr:`refines`);
        ``note`` hears when ``sample_thetas`` asks for too many."""
        from ..hypotheses import HypothesisSet, resolve_betas, resolve_thetas, sample_thetas

        if not self.named:
            if self.refines:
                from .adaptive import start_set

                return start_set(n_features)
            return HypothesisSet(resolve_thetas(DEFAULT_THETAS, n_features), resolve_betas(DEFAULT_BETAS))
        th = resolve_thetas(self.thetas or DEFAULT_THETAS, n_features)
        k = self.sample_thetas
        if k is not None:
            if k > len(th) and note is not None:
                name = self.thetas or DEFAULT_THETAS
                note(f"--sample-thetas {k} exceeds the {len(th)} directions of --thetas {name}; "
                     "using all of them")
            th = sample_thetas(th, min(k, len(th)), np.random.default_rng(seed))
        return HypothesisSet(th, resolve_betas(self.betas or DEFAULT_BETAS))


@dataclass(frozen=True)
class BIRLOptions:
    """Algorithm 1 (defaults follow the paper where it gives them)."""

    iterations: int = 1000  # Algorithm 1's K
    delta: float = 0.05  # θ grid step
    beta_step: float = 0.1  # β grid step
    variant: str = "box"  # "box" (as printed) or "simplex"
    prior: str = DEFAULT_PRIOR
    model: str = DEFAULT_MODEL

    def __post_init__(self) -> None:
        from .birl import VARIANTS

        for name, x in (("delta", self.delta), ("beta_step", self.beta_step)):
            if not (math.isfinite(x) and x > 0):
                raise OptionError(f"{{{name}}} must be a finite number > 0, got {x:g}", name)
        n = 1.0 / self.delta
        if abs(n - round(n)) > 1e-9 * max(1.0, n):
            raise OptionError(f"{{delta}} must divide 1 (1/{{delta}} an integer), got {self.delta:g}",
                              "delta")
        lo, hi = BETA_RANGE
        if lo + self.beta_step > hi:
            raise OptionError(f"{{beta_step}} {self.beta_step:g} leaves a single β in the prior's range "
                              f"[{lo:g}, {hi:g}]", "beta_step")
        _one_of("variant", self.variant, VARIANTS)
        _check_prior_and_model(self.prior, self.model)

    @property
    def max_draws(self) -> int:
        return self.iterations


@dataclass(frozen=True)
class MAPOptions:
    """MAP by L-BFGS on the simplex and β > 0, from random starts."""

    starts: int = 4
    prior: str = DEFAULT_PRIOR
    model: str = DEFAULT_MODEL
    expertise: str = DEFAULT_EXPERTISE  # or "changing": also the learning curve (inference.trend)
    concentration: float | None = None  # θ ~ Dirichlet(α); None: the prior's (priors.concentration_of)

    def __post_init__(self) -> None:
        _check_prior_and_model(self.prior, self.model)
        _check_concentration(self.prior, self.concentration)
        _check_expertise(self.expertise)

    max_draws = 0


@dataclass(frozen=True)
class NUTSOptions:
    """NUTS on the continuous space."""

    chains: int = 4
    warmup: int = 500  # warm-up iterations per chain
    samples: int = 500  # draws per chain
    prior: str = DEFAULT_PRIOR
    model: str = DEFAULT_MODEL
    expertise: str = DEFAULT_EXPERTISE  # or "changing": also the learning curve's posterior (inference.trend)
    concentration: float | None = None  # θ ~ Dirichlet(α); None: the prior's (priors.concentration_of)

    def __post_init__(self) -> None:
        _check_prior_and_model(self.prior, self.model)
        _check_concentration(self.prior, self.concentration)
        _check_expertise(self.expertise)

    @property
    def max_draws(self) -> int:
        return self.chains * self.samples


# ----------------------------------------------------------------------------- fits
class DiscreteFit(NamedTuple):
    """The discrete method's result: the posterior and, with ``per_action``, its trace."""

    posterior: Any  # DiscreteBelief
    trace: Any  # Trace | None
    trace_index: tuple[np.ndarray, np.ndarray]  # episode and step of each traced action
    changing: Any = None  # --expertise changing: (ChangingPosterior, episode labels)
    refined: Any = None  # the refined set's record and warnings (inference.adaptive.Refined)
    certified: Any = None  # a fixed set's certified solve (inference.certified.Certified.record())
    teaching: Any = None  # model pedagogical: the posterior over Ψ × Λ (pedagogical.TeachingPosterior)

    @property
    def result(self) -> DiscreteFit:
        """The fit itself (what :attr:`MethodRun.result` holds)."""
        return self


class ContinuousFit(NamedTuple):
    """A continuous method's result (``BIRLResult``, ``MAPResult`` or ``NUTSResult``) and, with
    ``expertise="changing"`` (map, nuts), the learning curve of :mod:`.trend` beside it."""

    result: Any
    curve: dict[str, Any] | None = None


def _setup_discrete(mdp, opts: DiscreteOptions, seed: Seed, note: Note = None):
    return opts.hypotheses(mdp.n_features, seed, note)


def _fit_discrete(mdp, trajs, opts: DiscreteOptions, seed: Seed, progress: Progress = None,
                  setup=None) -> DiscreteFit:
    from .belief import DiscreteBelief

    hyp = _setup_discrete(mdp, opts, seed) if setup is None else setup
    if opts.model == PEDAGOGICAL:
        return _fit_teaching(mdp, trajs, hyp, opts, progress)
    refined = certified = solved_ll = None
    if opts.refines:
        refined = refined_set(mdp, trajs, hyp, opts, progress)
        hyp, solved_ll = refined.hypotheses, refined.log_likelihood
        start = DiscreteBelief.from_log_policy(hyp, refined.log_policy, prior=refined.prior)
    elif opts.per_action or opts.expertise == Expertise.CHANGING:
        # every hypothesis matters somewhere (early in the trace, in some episode): all to one tolerance
        from ..planning.soft_vi import DEFAULT_TOL

        start = DiscreteBelief.from_mdp(mdp, hyp, tol=opts.tol or DEFAULT_TOL, chunk_size=opts.chunk_size,
                                        model=opts.model, progress=progress)
    else:
        from .certified import certified_log_likelihoods

        cert = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta, tol=opts.tol,
                                         chunk_size=opts.chunk_size, model=opts.model, progress=progress)
        start, certified = DiscreteBelief.from_log_policy(hyp, cert.log_policy[0]), cert.record()
        solved_ll = cert.log_likelihood
    post = start.update(trajs, per_action=opts.per_action)
    if solved_ll is not None and not opts.per_action:  # the certified sums, not the table's (certified.py)
        post = dataclasses.replace(post, log_likelihood=np.where(np.isfinite(post.log_likelihood), solved_ll,
                                                                 -np.inf))
    trace = start.trace(trajs) if opts.per_action else None
    changing = None
    if opts.expertise == Expertise.CHANGING:
        from .changing import changing_posterior, episode_log_likelihoods

        cp = changing_posterior(episode_log_likelihoods(start.log_policy, trajs), hyp)
        live = None
        if opts.per_action:  # the current episode's β after each action, filtered
            from .changing import filtered_by_action

            order = {e: i for i, e in enumerate(trajs.episode_ids)}
            index = np.array([order[e] for e in trajs.episode.tolist()])
            step_ll = np.asarray(start.log_policy)[:, trajs.state, trajs.action].T
            live = filtered_by_action(step_ll, index, hyp)
        changing = (cp, list(trajs.episode_ids), live)
    return DiscreteFit(post, trace, (trajs.episode, trajs.step), changing, refined, certified)


def _fit_teaching(mdp, trajs, hyp, opts: DiscreteOptions, progress: Progress = None) -> DiscreteFit:
    """The pedagogical model: one ``maxent`` solve of the fixed set to one tolerance (every hypothesis
    is part of the observer, so none is screened out), then the exact posterior over Ψ × Λ. The fit's
    posterior is λ's marginal; its ``teaching`` holds the whole."""
    from ..planning.soft_vi import DEFAULT_TOL
    from .belief import DiscreteBelief
    from .pedagogical import LAMBDAS, teaching_posterior

    start = DiscreteBelief.from_mdp(mdp, hyp, tol=opts.tol or DEFAULT_TOL, chunk_size=opts.chunk_size,
                                    model="maxent", progress=progress)
    tp = teaching_posterior(start.log_policy, hyp, trajs, lambdas=opts.lambdas or LAMBDAS)
    return DiscreteFit(tp.belief(start.log_policy), None, (trajs.episode, trajs.step), teaching=tp)


def teaching_draws(fit: DiscreteFit, n: int, rng: np.random.Generator) -> dict[str, Any]:
    """``n`` independent draws of (θ, β, λ) from a pedagogical fit's joint posterior, each with its
    teacher's policy on every state, as the misspecification checks take a posterior
    (:func:`~.misspecification.misspecification`'s ``theta``, ``beta``, ``weights``, ``tables``).

    The teacher's policy is the literal observer's (the set with its prior, on every state) reweighting
    of the draw's ``maxent`` policy, so the posterior predictive checks judge the teaching model itself.

    Args:
        fit: the discrete method's fit with ``teaching``.
        n: the number of draws.
        rng: draws them.

    Returns:
        ``theta [n, K]``, ``beta [n]``, ``weights`` None (equally weighted draws), ``tables``
        (``[[n, S, A]]``) and ``draws_note``.
    """
    from .pedagogical import observer, teaching_log_policy
    from .posterior import log_sum_exp

    tp, lp = fit.teaching, np.asarray(fit.posterior.log_policy)
    hyp = tp.hypotheses
    joint = tp.log_likelihood + tp.log_prior[None, :] + tp.log_prior_lambda[:, None]  # [L, H]
    p = np.exp(joint - log_sum_exp(joint)).ravel()
    li, hi = np.divmod(rng.choice(p.size, size=n, p=p / p.sum()), len(hyp))
    info = observer(hyp, lp, tp.log_prior).informativeness()  # [n_theta, S, A]
    tables = teaching_log_policy(lp[hi], info[hi // hyp.n_beta], tp.lambdas[li] / hyp.beta[hi])
    return {"theta": hyp.theta[hi], "beta": hyp.beta[hi], "weights": None, "tables": [tables],
            "draws_note": f"{n} draws of (θ, β, λ) from the teaching model's posterior, each replicate "
                          "simulated with its draw's teacher policy"}


def refined_set(mdp, trajs, start, opts: DiscreteOptions, progress: Progress = None):
    """``start`` refined where the posterior of ``trajs`` has its mass (:func:`.adaptive.refine`)."""
    from .adaptive import Refinement, refine, start_resolution

    step = None if opts.named else 1 / start_resolution(mdp.n_features)
    caps = Refinement(max_hypotheses=opts.max_hypotheses, max_seconds=opts.max_seconds)
    return refine(mdp, trajs, start, settings=caps, theta_step=step,
                  solve_kwargs={"tol": opts.tol, "chunk_size": opts.chunk_size, "model": opts.model},
                  progress=progress)


def _announce(mdp, opts, seed: Seed, note: Note = None) -> str:
    """The continuous methods' setup: the prior in words, told to ``note``."""
    text = _prior_text(opts)
    if note is not None:
        note(f"prior ({opts.prior}): {text}; model {opts.model}")
    return text


def _fit_birl(mdp, trajs, opts: BIRLOptions, seed: Seed, progress: Progress = None, setup=None):
    from ..mdp import TabularMDP
    from .birl import extended_birl
    from .task_likelihood import as_tasks

    as_tasks(mdp, trajs)
    if not isinstance(mdp, TabularMDP):
        raise InputError("--method birl (Algorithm 1) takes one task; use map or nuts for several")
    r = extended_birl(mdp, trajs, n_iter=opts.iterations, delta=opts.delta, beta_step=opts.beta_step,
                      variant=opts.variant, rng=np.random.default_rng(seed), progress=progress,
                      prior=opts.prior, model=opts.model)
    if mdp.has_offset:  # (θ/‖θ‖₁, β/‖θ‖₁) is another policy once a fixed reward is part of R
        r = dataclasses.replace(r, mean_theta_normalized=None, mean_beta_normalized=None)
    return ContinuousFit(r)


def _fit_map(mdp, trajs, opts: MAPOptions, seed: Seed, progress: Progress = None, setup=None):
    from .gradient import map_estimate
    from .task_likelihood import as_tasks

    as_tasks(mdp, trajs)
    r = map_estimate(mdp, trajs, n_starts=opts.starts, rng=np.random.default_rng(seed), progress=progress,
                     prior=opts.prior, model=opts.model, concentration=opts.concentration)
    if opts.expertise == Expertise.CHANGING:  # the one-β estimate stays the result's; the curve beside it
        from .trend import fit_trend

        # several tasks: their episodes in turn
        return ContinuousFit(r, fit_trend(mdp, trajs, opts, seed))
    return ContinuousFit(r)


def _fit_nuts(mdp, trajs, opts: NUTSOptions, seed: Seed, progress: Progress = None, setup=None):
    from .nuts import nuts_posterior
    from .task_likelihood import as_tasks

    as_tasks(mdp, trajs)
    r = nuts_posterior(mdp, trajs, num_warmup=opts.warmup, num_samples=opts.samples,
                       num_chains=opts.chains, seed=seed, progress=progress, prior=opts.prior,
                       model=opts.model, concentration=opts.concentration)
    if opts.expertise == Expertise.CHANGING:  # the one-β posterior stays the result's; the curve beside it
        from .trend import fit_trend_nuts

        # several tasks: their episodes in turn
        return ContinuousFit(r, fit_trend_nuts(mdp, trajs, opts, seed))
    return ContinuousFit(r)


# ----------------------------------------------------------------------------- descriptions
def _describe_discrete(fit: DiscreteFit, opts: DiscreteOptions, names) -> dict[str, Any]:
    from .diagnostics import discrete_warnings

    out: dict[str, Any] = {"diagnostics": {"warnings": discrete_warnings(fit.posterior, names)}}
    if fit.teaching is not None:  # beside beta_hat, which is the teaching model's (λ marginalised)
        out["teaching"] = fit.teaching.record(fit.posterior.log_policy)
        out["diagnostics"]["warnings"] += fit.teaching.warnings()
    if fit.refined is not None:
        out["refinement"] = fit.refined.record
        out["diagnostics"]["warnings"] = fit.refined.warnings + out["diagnostics"]["warnings"]
    if fit.changing is not None:  # beside beta_hat, which stays the stationary estimate
        from .changing import changing_summary, expertise_by_episode, trend_summary

        cp, labels, live = fit.changing
        out["expertise_by_episode"] = expertise_by_episode(cp, [int(x) for x in labels])
        if live is not None:  # --per-action: one entry per action, in order
            from .posterior import beta_quantile

            b = cp.hypotheses.betas
            episodes, steps = fit.trace_index
            lo, hi = (beta_quantile(b, live.T, q) for q in (0.05, 0.95))
            out["expertise_trace"] = [
                {"episode": int(e), "step": int(s), "beta_mean": float(p @ b), "q05": float(a),
                 "q95": float(c)} for e, s, p, a, c in zip(episodes, steps, live, lo, hi, strict=True)]
        out["changing"] = changing_summary(cp)
        out["trend"] = trend_summary(cp)
        out["theta_hat_changing"] = (cp.theta_probabilities @ cp.hypotheses.thetas).tolist()
    return out


def _with_curve(out: dict[str, Any], curve: dict[str, Any], no_evidence: str) -> dict[str, Any]:
    """A continuous method's fields with the learning curve of :mod:`.trend` beside them."""
    out["expertise_by_episode"] = curve["expertise_by_episode"]
    out["trend"] = {**curve["trend"], "theta_hat": curve["theta_hat"]}
    out["changing"] = {"log_bayes_factor": None, "p_changing": None, "epsilon_mean": None,
                       "unavailable": no_evidence}
    out["diagnostics"]["warnings"] += [f"learning curve: {w}" for w in curve["diagnostics"]["warnings"]]
    return out


def _describe_birl(fit: ContinuousFit, opts: BIRLOptions, names) -> dict[str, Any]:
    from .diagnostics import birl_warnings, chain_statistics, withhold_intervals
    from .gradient import credible_intervals

    r = fit.result
    theta, beta = r.kept_theta, r.kept_beta
    # one chain: R-hat compares its halves
    stats = chain_statistics(theta, beta, halves=True, feature_names=names)
    intervals = withhold_intervals(credible_intervals(theta, beta, CREDIBLE), stats["stuck"], 1, names,
                                   stats["unavailable"])
    diag = {"acceptance_rate": r.acceptance_rate, "out_of_bounds": r.n_out_of_bounds,
            "burn_in": r.n_burn, "solves": r.n_solves, "sweeps": r.n_sweeps,
            "variant": r.variant, "moves": r.moves, "r_hat": stats["r_hat"],
            "r_hat_method": "split halves of the kept chain", "ess_bulk": stats["ess_bulk"],
            "unavailable": stats["unavailable"]}
    diag["warnings"] = birl_warnings(diag, names, stats["stuck"])
    return {
        "theta_hat": r.mean_theta.tolist(), "beta_hat": float(r.mean_beta),
        # None on an MDP with a fixed reward, where the rescaled point is another policy
        "theta_hat_normalized": None if r.mean_beta_normalized is None else r.mean_theta_normalized.tolist(),
        "beta_hat_normalized": None if r.mean_beta_normalized is None else float(r.mean_beta_normalized),
        "map": {"theta": r.best_theta.tolist(), "beta": float(r.best_beta),
                "log_posterior": float(r.best_log_posterior)},
        "credible_intervals": intervals,
        "diagnostics": diag,
        "draws": (np.zeros(len(beta), dtype=int), theta, beta),
    }


def _describe_map(fit: ContinuousFit, opts: MAPOptions, names) -> dict[str, Any]:
    from .diagnostics import map_description

    r, curve = fit
    out = {  # the mode, its Laplace intervals (docs/model.md: why the mode)
        "theta_hat": r.theta.tolist(), "beta_hat": r.beta,
        "map": {"theta": r.theta.tolist(), "beta": r.beta, "log_posterior": r.log_posterior},
        **map_description(r, opts.starts, PRIORS[opts.prior].beta_range),
    }
    if curve is not None:  # --expertise changing: the one-β MAP and the learning curve
        out = _with_curve(out, curve, "MAP gives no evidence: see trend.slope, or use --method discrete "
                                      "for the Bayes factor")
        out["trend"]["log_posterior"] = curve["diagnostics"]["log_posterior"]
    return out


def _describe_nuts(fit: ContinuousFit, opts: NUTSOptions, names) -> dict[str, Any]:
    r, curve = fit
    out = _describe_nuts_posterior(r, names)
    if curve is not None:  # --expertise changing: the one-β posterior and the learning curve
        out = _with_curve(out, curve, "NUTS samples no evidence for the model choice: see trend.p_falls "
                                      "(the share of draws with λ < 0), or use --method discrete")
    return out


def _describe_nuts_posterior(r, names) -> dict[str, Any]:
    from .diagnostics import nuts_warnings, withhold_intervals

    C, D, K = r.theta.shape
    theta, beta = r.theta.reshape(-1, K), r.beta.reshape(-1)
    best = int(np.argmax(r.log_density.reshape(-1)))
    unavailable = dict(r.unavailable)
    intervals = withhold_intervals(r.credible_intervals(CREDIBLE), r.stuck, C, names, unavailable)
    diag = {"r_hat": r.r_hat, "ess_bulk": r.ess, "divergences": r.divergences,
            "chains": C, "draws_per_chain": D, "mean_tree_size": r.mean_tree_size,
            "mean_accept_prob": r.mean_accept_prob, "unavailable": unavailable}
    diag["warnings"] = nuts_warnings(diag, names, r.stuck)
    return {
        "theta_hat": r.mean_theta.tolist(), "beta_hat": r.mean_beta,
        "map": {"theta": theta[best].tolist(), "beta": float(beta[best]),
                "log_posterior": float(r.log_density.reshape(-1)[best])},
        "credible_intervals": intervals,
        "diagnostics": diag,
        "draws": (np.repeat(np.arange(C), D), theta, beta),
    }


# ----------------------------------------------------------------------------- settings
def _discrete_settings(fit: DiscreteFit, opts: DiscreteOptions) -> dict[str, Any]:
    hyp = fit.posterior.hypotheses
    refined = fit.refined is not None
    return {"thetas": opts.thetas or (ADAPTIVE if refined else DEFAULT_THETAS.value),
            "betas": opts.betas or (ADAPTIVE if refined else DEFAULT_BETAS.value),
            "sample_thetas": opts.sample_thetas,
            "hypotheses": "adaptive" if refined else "fixed", "max_hypotheses": opts.max_hypotheses,
            "max_seconds": opts.max_seconds,
            "n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "n_hypotheses": len(hyp),
            "prior": fit.refined.record["prior"] if refined else "uniform",
            "model": opts.model, **_teaching_settings(fit), "per_action": opts.per_action,
            "tol": _tol_used(fit, opts),
            **_certified_settings(fit), "expertise": opts.expertise,
            **({"epsilons": list(fit.changing[0].epsilons.tolist()),
                "epsilon_prior": "P(ε = 0) = 1/2, the rest uniform over ε > 0",
                "chain": "β_1 uniform; stay 1 − ε, else a neighbouring grid value (ε/2 each side)"}
               if fit.changing is not None else {})}


def _teaching_settings(fit: DiscreteFit) -> dict[str, Any]:
    """The pedagogical model's λ grid, its prior and the observer (nothing for another model)."""
    if fit.teaching is None:
        return {}
    return {"lambdas": fit.teaching.lambdas.tolist(),
            "lambda_prior": "P(λ = 0) = 1/2, the rest uniform over the grid's λ > 0",
            "observer": "literal: maxent over this hypothesis set with its prior"}


def _tol_used(fit: DiscreteFit, opts: DiscreteOptions) -> float | None:
    """The tolerance asked for: ``opts.tol``, else 1e-8 where every hypothesis is solved to one
    tolerance (a trace, changing expertise), else None (certified: ``solver_tol`` and
    ``probability_error`` say what was reached)."""
    from ..planning.soft_vi import DEFAULT_TOL

    if opts.tol is not None:
        return opts.tol
    return None if fit.refined is not None or fit.certified is not None else DEFAULT_TOL


def _certified_settings(fit: DiscreteFit) -> dict[str, Any]:
    """What the certified solve guarantees (:mod:`.certified`): the bound on every probability
    and how many hypotheses stopped at the screening tolerance (nothing for a solve to one tolerance)."""
    if fit.refined is not None:
        rec = fit.refined.record
        return {"probability_error": rec.get("probability_error"), "eliminated": rec.get("eliminated")}
    if fit.certified is not None:
        c = fit.certified
        return {"probability_error": c["probability_error"], "eliminated": c["eliminated"],
                "solver_tol": c["tol"], "screen_tol": c["screen_tol"]}
    return {}


def _continuous_settings(fit, opts) -> dict[str, Any]:
    """Every continuous method's options (this one's as given, the others' defaults) and the prior."""
    out: dict[str, Any] = {}
    for cls in (BIRLOptions, MAPOptions, NUTSOptions):
        out.update(asdict(cls()))
    mine = asdict(opts)
    if "concentration" in mine:  # map, nuts: the α used (birl's θ is uniform: None)
        from .priors import concentration_of

        mine["concentration"] = concentration_of(opts.prior, opts.concentration)
    return {**out, **mine, "prior_text": _prior_text(opts)}


def _prior_text(opts) -> str:
    """The prior in words: Algorithm 1's (θ uniform) for birl, θ's Dirichlet(α) for map and nuts."""
    from .priors import prior_text

    return prior_text(opts.prior, opts.concentration) if hasattr(opts, "concentration") else \
        PRIORS[opts.prior].text


# ----------------------------------------------------------------------------- registry
class MethodRun(NamedTuple):
    """What :meth:`Method.run` returns.

    Attributes:
        method: the method's name.
        result: its own result (:class:`DiscreteFit`, ``BIRLResult``, ``MAPResult``, ``NUTSResult``).
        fields: the result document's fields (see the module docstring), ``run_time_s`` included.
        settings: the options as the result records them (the method's ``record``).
    """

    method: str
    result: Any
    fields: dict[str, Any]
    settings: dict[str, Any]


Opts = TypeVar("Opts")


class InferenceMethod(Protocol[Opts]):
    """What every inference method offers (:class:`Method` is the package's one implementation).

    Attributes:
        name: the method's name (a :class:`~expertise_irl.options.Method`).
        options: its options dataclass (fields named as the command line's options).
        unit: what its progress counts; ``label``: the bar's name.
        measure_lanes: whether it solves many hypotheses at once (the lane width is worth measuring).
    """

    name: str
    options: type[Opts]
    unit: str
    measure_lanes: bool

    def options_from(self, values: Mapping[str, Any]) -> Opts:
        """The options from ``values`` (keys that are not its fields are ignored)."""
        ...

    def progress_label(self, opts: Opts) -> str:
        """The progress bar's name for ``opts``."""
        ...

    def run(self, mdp, trajs, opts: Opts, seed: Seed, *, progress: Progress = None, note: Note = None,
            setup: Any = None) -> MethodRun:
        """Set up, fit and describe (see :meth:`Method.run`)."""
        ...


@dataclass(frozen=True)
class Method:
    """One inference method: its options dataclass, what it runs and how it is described.

    ``setup(mdp, opts, seed, note=None)`` settles what comes before the long part (the discrete
    set; ``note(line)`` hears what the user should know: the prior, a capped --sample-thetas), and
    ``fit(mdp, trajs, opts, seed, progress=None, setup=None)`` runs the method (``mdp`` and
    ``trajs`` may be equal-length lists of tasks for map and nuts); ``progress(done, total)``
    counts ``unit`` (``label`` names the bar, formatted with the options' fields).
    ``measure_lanes``: it solves many hypotheses at once, so the solver's lane width is worth
    measuring first.
    """

    name: str
    options: type
    setup: Callable[..., Any]
    fit: Callable[..., Any]
    describe: Callable[[Any, Any, Sequence[str]], dict[str, Any]]
    record: Callable[[Any, Any], dict[str, Any]]
    unit: str
    label: str
    measure_lanes: bool = False

    def options_from(self, values: Mapping[str, Any]):
        """This method's options from ``values``, keeping only the names its options dataclass has."""
        names = {f.name for f in fields(self.options)}
        return self.options(**{k: v for k, v in values.items() if k in names})

    def progress_label(self, opts) -> str:
        return self.label.format(**asdict(opts))

    def run(self, mdp, trajs, opts, seed: Seed, *, progress: Progress = None, note: Note = None,
            setup: Any = None) -> MethodRun:
        """Set up (unless ``setup`` is given), run the method and describe its result."""
        if not isinstance(opts, self.options):
            raise InputError(f"method {self.name} takes {self.options.__name__}, got {type(opts).__name__}")
        t0 = time.perf_counter()
        if setup is None:
            setup = self.setup(mdp, opts, seed, note)
        fit = self.fit(mdp, trajs, opts, seed, progress, setup)
        first = mdp if hasattr(mdp, "feature_names") else mdp[0]
        out = self.describe(fit, opts, first.feature_names)
        out["run_time_s"] = time.perf_counter() - t0
        return MethodRun(self.name, fit.result, out, self.record(fit, opts))


_M = MethodName
METHODS: dict[str, Method] = {
    _M.DISCRETE: Method(_M.DISCRETE, DiscreteOptions, _setup_discrete, _fit_discrete, _describe_discrete,
                        _discrete_settings, "hypotheses", "solving soft value iteration", measure_lanes=True),
    _M.BIRL: Method(_M.BIRL, BIRLOptions, _announce, _fit_birl, _describe_birl, _continuous_settings,
                    "iterations", "Algorithm 1"),
    _M.MAP: Method(_M.MAP, MAPOptions, _announce, _fit_map, _describe_map, _continuous_settings,
                   "starts", "MAP (L-BFGS-B)"),
    _M.NUTS: Method(_M.NUTS, NUTSOptions, _announce, _fit_nuts, _describe_nuts, _continuous_settings,
                    "iterations", "NUTS ({chains} chains, warm-up included)"),
}


def get_method(name: str) -> Method:
    """The method called ``name``; an :class:`~expertise_irl.options.OptionError` (``method``) naming
    the choices."""
    return METHODS[choose(MethodName, name, "method")]


def option_owners() -> dict[str, tuple[str, ...]]:
    """Each option that only some methods read -> those methods (in :data:`METHODS` order)."""
    owners: dict[str, list[str]] = {}
    for m in METHODS.values():
        for f in fields(m.options):
            owners.setdefault(f.name, []).append(m.name)
    return {k: tuple(v) for k, v in owners.items() if len(v) < len(METHODS)}


def document(run: MethodRun, *, feature_names: Sequence[str], settings: dict[str, Any],
             data: dict[str, Any], samples_path=None) -> dict[str, Any]:
    """The result document of ``run``; ``settings`` (command, inputs, seed...) precede the method's.

    Draws beyond :data:`~expertise_irl.results.INLINE_DRAWS` go to ``samples_path``.
    """
    from ..results import continuous_result, discrete_result

    settings = {**settings, **run.settings}
    if run.method == MethodName.DISCRETE:
        fit = run.result
        doc = discrete_result(fit.posterior, feature_names=feature_names, settings=settings, data=data,
                              trace=fit.trace, trace_index=fit.trace_index)
        return {**doc, **run.fields}
    return continuous_result(run.fields, method=run.method, feature_names=feature_names, settings=settings,
                             data=data, samples_path=samples_path)
