"""Which model of noise fits a person: log evidence, Bayes factors and a held-out check.

For each observation model m (:mod:`expertise_irl.models`) over one hypothesis set Ψ
with a uniform prior:

- **log evidence** ``log P(Ξ | m) = log Σ_h P(Ξ | h, m) P(h)`` of all the demonstrations;
- **Bayes factor** against the best model, ``log BF = log P(Ξ | m) − max_m' log P(Ξ | m')``
  (≤ 0), with the usual reading of ``2 |log BF|`` (Kass & Raftery, 1995): < 2 barely worth
  mentioning, 2–6 positive, 6–10 strong, > 10 very strong;
- **held-out log-likelihood per action**: the posterior from the first episodes (in file
  order) predicts the remaining ones, ``log Σ_h P(h | Ξ_fit, m) P(Ξ_test | h, m) / n_test``.
  It needs at least two episodes; the split is ``holdout`` (a fraction of the episodes,
  at least one held out and one kept).

``pedagogical`` (:mod:`.pedagogical`, a demonstrator who may be teaching) is a model with a
teaching weight λ on a grid Λ whose 0 is ``maxent``. Its row is the **teacher**'s:

- log evidence ``log P(Ξ | teacher) = log mean_{λ ∈ Λ, λ > 0} P(Ξ | λ)`` (the positive grid
  evenly, as the model's prior spreads its teaching half), so that its difference to the
  ``maxent`` row, which is ``log P(Ξ | λ = 0)`` over the same set and prior, is the model's Bayes
  factor of teaching against doing (:attr:`.pedagogical.TeachingPosterior.log_bayes_factor`);
- held out: the posterior over Ψ × Λ (λ's prior half on 0) of the first episodes predicting the
  rest, ``log Σ_{h,λ} P(h, λ | Ξ_fit) P(Ξ_test | h, λ) / n_test``; the literal observer is fixed
  by the set, so the test pairs' teaching likelihoods need no other solve;
- β̂, θ̂, λ̂: the posterior's over Ψ × Λ (λ marginalised, 0 included), as ``infer --model
  pedagogical`` reports them; ``teaching`` holds λ̂, its interval, the verdict and the evidence.

It needs the set solved once under ``maxent``, shared with the ``maxent`` row when both are asked.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import logsumexp

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..hypotheses import HypothesisSet, expertise_group
from ..mdp import TabularMDP
from ..models import PEDAGOGICAL, check_model
from . import pedagogical
from .belief import DiscreteBelief
from .posterior import log_sum_exp


@dataclass(frozen=True)
class ModelFit:
    """One observation model's fit to the demonstrations."""

    model: str
    log_evidence: float
    log_bayes_factor: float  # against the best model (0 for the best)
    heldout_per_action: float | None  # None when there are fewer than 2 episodes
    beta_hat: float
    theta_hat: np.ndarray
    expertise_group: str
    teaching: dict | None = None  # pedagogical: λ̂, its interval, the verdict (:func:`teaching_entry`)

    @property
    def strength(self) -> str:
        """Kass & Raftery's reading of the evidence against this model relative to the best."""
        return bayes_factor_reading(self.log_bayes_factor)


def check_model_list(models: Sequence[str]) -> tuple[str, ...]:
    """``models`` as a tuple, each a known observation model and none named twice (``--models``).

    Args:
        models: the names.

    Returns:
        The names, in order.

    Raises:
        InputError: none, an unknown one or one named twice.
    """
    models = tuple(models)
    if not models:
        raise InputError("--models: name at least one model")
    for m in models:
        check_model(m, "models", solvable=False)
    if len(set(models)) != len(models):
        raise InputError(f"--models names a model twice: {','.join(models)}")
    return models


def bayes_factor_reading(log_bayes_factor: float) -> str:
    """Kass & Raftery's reading of a log Bayes factor against the best model (≤ 0)."""
    x = 2 * abs(log_bayes_factor)
    if log_bayes_factor == 0:
        return "best"
    if x < 2:
        return "barely worse"
    if x < 6:
        return "positively worse"
    if x < 10:
        return "strongly worse"
    return "very strongly worse"


@dataclass(frozen=True)
class Comparison:
    """Every model's fit, the held-out split, and why a statistic is missing (if it is)."""

    fits: list[ModelFit]
    n_fit_episodes: int
    n_test_episodes: int
    n_test_actions: int
    unavailable: dict[str, str]

    @property
    def best(self) -> ModelFit:
        return max(self.fits, key=lambda f: f.log_evidence)


def split_episodes(trajs: Trajectories, holdout: float) -> tuple[Trajectories, Trajectories] | None:
    """``(fit, test)``: the first episodes in file order and the rest; None with < 2 episodes."""
    if not 0 < holdout < 1:
        raise InputError(f"--holdout must be a fraction in (0, 1), got {holdout:g}")
    ids = trajs.episode_ids
    if len(ids) < 2:
        return None
    n_test = min(len(ids) - 1, max(1, round(holdout * len(ids))))
    test_ids = ids[len(ids) - n_test:]
    in_test = np.isin(trajs.episode, test_ids)

    def pick(mask):
        return Trajectories(trajs.episode[mask], trajs.step[mask], trajs.state[mask], trajs.action[mask])

    return pick(~in_test), pick(in_test)


def compare_models(
    mdp: TabularMDP,
    trajs: Trajectories,
    hypotheses: HypothesisSet,
    models: Sequence[str],
    *,
    holdout: float = 0.5,
    tol: float = 1e-8,
    progress: Callable[[str], Callable[[int, int], None] | None] | None = None,
    lambdas=pedagogical.LAMBDAS,
) -> Comparison:
    """Fit every model in ``models`` to ``trajs`` over ``hypotheses`` (one solve per model).

    Args:
        mdp: the task.
        trajs: the demonstrations.
        hypotheses: the set Ψ = Θ × B every model is fitted over.
        models: names of observation models (:mod:`expertise_irl.models`); ``pedagogical``
            shares ``maxent``'s solve (module docstring).
        holdout: the share of episodes, in (0, 1), held out (the last ones in file order) for
            the held-out per-action log-likelihood.
        tol: soft value iteration's tolerance.
        progress: ``progress(model)`` may return a ``progress(done, total)`` callback for that
            model's solve.
        lambdas: ``pedagogical``'s λ grid (:func:`.pedagogical.parse_lambdas`; 0 and a λ > 0).

    Returns:
        Every model's log evidence, its difference to the best, its held-out score and estimate.

    Raises:
        InputError: an unknown model, ``holdout`` outside (0, 1), a bad λ grid, or
            demonstrations impossible under every hypothesis of a model.
    """
    check_model_list(models)
    lam = pedagogical.parse_lambdas(lambdas) if PEDAGOGICAL in models else None
    split = split_episodes(trajs, holdout)
    unavailable = {}
    if split is None:
        unavailable["heldout_per_action"] = ("the held-out check needs at least 2 episodes; "
                                             f"the demonstrations have {trajs.n_episodes}")
    starts: dict[str, DiscreteBelief] = {}

    def start_of(solved: str, asked: str) -> DiscreteBelief:
        if solved not in starts:  # one solve per model with a backup: pedagogical's is maxent's
            starts[solved] = DiscreteBelief.from_mdp(mdp, hypotheses, tol=tol, model=solved,
                                                     progress=progress(asked) if progress else None)
        return starts[solved]

    rows = [_teaching_fit(start_of("maxent", m), trajs, split, lam) if m == PEDAGOGICAL
            else _doer_fit(m, start_of(m, m), trajs, split) for m in models]
    best = max(f.log_evidence for f in rows)
    fits = [replace(f, log_bayes_factor=f.log_evidence - best) for f in rows]
    n_fit, n_test, n_act = 0, 0, 0
    if split is not None:
        n_fit, n_test, n_act = split[0].n_episodes, split[1].n_episodes, len(split[1])
    return Comparison(fits, n_fit, n_test, n_act, unavailable)


def _finite_or_minus_inf(x: float) -> float:
    return x if math.isfinite(x) else -math.inf


def _doer_fit(model: str, start: DiscreteBelief, trajs: Trajectories, split) -> ModelFit:
    """A model with a Bellman backup: its posterior over Ψ and held-out score (the Bayes factor
    against the best is filled in by :func:`compare_models`)."""
    post = start.update(trajs)
    heldout = None
    if split is not None:
        fit, test = split
        fitted = start.update(fit)
        ll_test = start.update(test).log_likelihood
        heldout = _finite_or_minus_inf(float(logsumexp(fitted.log_posterior + ll_test)) / len(test))
    return ModelFit(model, post.log_evidence, 0.0, heldout, post.mean_beta, post.mean_theta,
                    expertise_group(post.mean_beta))


def teaching_pair_log_likelihoods(log_policy: np.ndarray, hypotheses: HypothesisSet, trajs: Trajectories,
                                  lambdas, log_prior: np.ndarray | None = None) -> np.ndarray:
    """``[L, H]`` log P(Ξ | h, λ) of ``trajs``' pairs under the teaching model, the literal observer
    believing ``hypotheses`` with ``log_prior`` (uniform when None).

    The observer's predictives are per state, so any subset of the demonstrations (an episode, a
    held-out part) gets the values the whole would give its pairs: the sums over parts add up.

    Args:
        log_policy: ``[H, S, A]`` the set's log-policies under ``maxent`` (one solve).
        hypotheses: the set Ψ.
        trajs: the pairs.
        lambdas: the λ grid (:func:`.pedagogical.parse_lambdas`).
        log_prior: ``[H]`` the observer's log prior over Ψ.

    Returns:
        ``[L, H]`` (zeros with no pair).
    """
    lam = pedagogical.parse_lambdas(lambdas)
    states, counts = pedagogical.observed_counts(trajs, log_policy.shape[2])
    lp = np.asarray(log_policy[:, states, :], dtype=np.float64)
    obs = pedagogical.observer(hypotheses, lp, log_prior)
    return pedagogical.teaching_log_likelihoods(obs, lp, counts, lam)


def teacher_log_evidence(posterior: pedagogical.TeachingPosterior) -> float:
    """log P(Ξ | teacher): log of the mean of P(Ξ | λ) over the grid's positive λ.

    Args:
        posterior: the posterior over Ψ × Λ.

    Returns:
        The log evidence; minus ``log P(Ξ | λ = 0)`` it is the Bayes factor of teaching.
    """
    z = posterior.log_evidence_by_lambda
    return float(log_sum_exp(z[1:]) - math.log(len(z) - 1))


def teaching_entry(posterior: pedagogical.TeachingPosterior, log_policy: np.ndarray) -> dict:
    """The ``teaching`` entry of a pedagogical fit: the result's record
    (:meth:`.pedagogical.TeachingPosterior.record`) with ``two_log_bayes_factor`` (the evidence
    against ``maxent``, teaching against doing), ``log_evidence_by_lambda`` and ``warnings``
    (:meth:`.pedagogical.TeachingPosterior.warnings`).

    Args:
        posterior: the posterior over Ψ × Λ.
        log_policy: ``[H, S, A]`` (or ``[H, 0, A]``) the log-policies its beliefs carry.

    Returns:
        A JSON-ready dict.
    """
    rec = posterior.record(log_policy)
    rec["two_log_bayes_factor"] = 2 * rec["log_bayes_factor"]
    rec["log_evidence_by_lambda"] = posterior.log_evidence_by_lambda.tolist()
    rec["warnings"] = posterior.warnings()
    return rec


def _teaching_fit(start: DiscreteBelief, trajs: Trajectories, split, lambdas: np.ndarray) -> ModelFit:
    """``pedagogical``'s row (module docstring) from the set's ``maxent`` start."""
    lp, hyp = start.log_policy, start.hypotheses
    tp = pedagogical.teaching_posterior(lp, hyp, trajs, lambdas=lambdas, prior=np.exp(start.log_prior))
    taught = tp.belief(lp)
    heldout = None
    if split is not None:
        fit, test = split
        tp_fit = pedagogical.teaching_posterior(lp, hyp, fit, lambdas=lambdas, prior=np.exp(start.log_prior))
        joint = tp_fit.log_likelihood + tp_fit.log_prior[None, :] + tp_fit.log_prior_lambda[:, None]
        ll_test = teaching_pair_log_likelihoods(lp, hyp, test, lambdas, tp_fit.log_prior)
        heldout = _finite_or_minus_inf(float(log_sum_exp((joint - log_sum_exp(joint)) + ll_test)) / len(test))
    return ModelFit(PEDAGOGICAL, teacher_log_evidence(tp), 0.0, heldout, taught.mean_beta, taught.mean_theta,
                    expertise_group(taught.mean_beta), teaching_entry(tp, lp))
