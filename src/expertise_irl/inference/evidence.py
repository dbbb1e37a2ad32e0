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
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..hypotheses import HypothesisSet, expertise_group
from ..mdp import TabularMDP
from ..models import check_model
from .belief import DiscreteBelief


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

    @property
    def strength(self) -> str:
        """Kass & Raftery's reading of the evidence against this model relative to the best."""
        return bayes_factor_reading(self.log_bayes_factor)


def check_model_list(models: Sequence[str]) -> tuple[str, ...]:
    """``models`` as a tuple, each a known observation model and none named twice (``--models``)."""
    models = tuple(models)
    if not models:
        raise InputError("--models: name at least one model")
    for m in models:
        check_model(m, "models")
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
) -> Comparison:
    """Fit every model in ``models`` to ``trajs`` over ``hypotheses`` (one solve per model).

    Args:
        mdp: the task.
        trajs: the demonstrations.
        hypotheses: the set Ψ = Θ × B every model is fitted over.
        models: names of observation models (:mod:`expertise_irl.models`).
        holdout: the share of episodes, in (0, 1), held out (the last ones in file order) for
            the held-out per-action log-likelihood.
        tol: soft value iteration's tolerance.
        progress: ``progress(model)`` may return a ``progress(done, total)`` callback for that
            model's solve.

    Returns:
        Every model's log evidence, its difference to the best, its held-out score and estimate.

    Raises:
        InputError: an unknown model, ``holdout`` outside (0, 1), or demonstrations impossible
            under every hypothesis of a model.
    """
    check_model_list(models)
    split = split_episodes(trajs, holdout)
    unavailable = {}
    if split is None:
        unavailable["heldout_per_action"] = ("the held-out check needs at least 2 episodes; "
                                             f"the demonstrations have {trajs.n_episodes}")
    rows = []
    for m in models:
        start = DiscreteBelief.from_mdp(mdp, hypotheses, tol=tol, model=m,
                                        progress=progress(m) if progress else None)
        post = start.update(trajs)
        heldout = None
        if split is not None:
            fit, test = split
            fitted = start.update(fit)
            ll_test = start.update(test).log_likelihood
            heldout = float(logsumexp(fitted.log_posterior + ll_test)) / len(test)
            if not math.isfinite(heldout):
                heldout = -math.inf
        rows.append((m, post, heldout))
    best = max(post.log_evidence for _, post, _ in rows)
    fits = [ModelFit(m, post.log_evidence, post.log_evidence - best, h, post.mean_beta, post.mean_theta,
                     expertise_group(post.mean_beta)) for m, post, h in rows]
    n_fit, n_test, n_act = 0, 0, 0
    if split is not None:
        n_fit, n_test, n_act = split[0].n_episodes, split[1].n_episodes, len(split[1])
    return Comparison(fits, n_fit, n_test, n_act, unavailable)
