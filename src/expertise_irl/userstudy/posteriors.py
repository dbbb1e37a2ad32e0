"""A participant's discrete posterior over their tasks, both ways of sharing, and the held-out check.

The engine gives, for every episode e of every task t of a participant, the log-likelihood
``ll[t][e, h]`` of each hypothesis h = (θ_i, β_j) of the set (θ-major, β fastest). With the
prior P(h) (uniform over the allowed θ's times uniform over the β grid):

- ``share = "both"``: one (θ, β) for all their tasks,
  ``P(h | Ξ) ∝ P(h) Π_t Π_e P(ξ_te | h)``;
- ``share = "beta"``: one β, a θ_t per task (each with the same prior over the θ set),
  ``P(β_j, θ_1 … θ_T | Ξ) ∝ P(β_j) Π_t P(θ_t) P(Ξ_t | θ_t, β_j)``, so the β marginal is
  ``P(β_j | Ξ) ∝ P(β_j) Π_t M_t(j)`` with ``M_t(j) = Σ_i P(θ_i) P(Ξ_t | θ_i, β_j)`` (each task's
  θ-marginal at that β), and ``P(θ_t = θ_i | Ξ) = Σ_j P(β_j | Ξ) P(θ_i) P(Ξ_t | θ_i, β_j) / M_t(j)``.

**Held-out check** (:func:`heldout_check`), the log-likelihood per action of data the fit did
not see, from the posterior of everything else:

- ``episode``: when some task has ≥ 2 episodes, each episode of such a task is held out in turn
  (leave-one-episode-out), predicted from every other episode of the participant:
  ``log P(ξ_u | Ξ∖ξ_u) = log Σ_h P(h | Ξ∖ξ_u) P(ξ_u | h)``;
- ``task``: otherwise, with ``share = "both"`` and ≥ 2 tasks, each task is held out in turn
  (leave-one-task-out), predicted from the other tasks;
- ``none``: a single episode in all, or single-episode tasks with ``share = "beta"`` (a held-out
  task's θ would be the prior's: nothing the participant showed predicts it); the reason is given.

The result is ``Σ_u log P(ξ_u | Ξ∖ξ_u) / Σ_u |ξ_u|`` in nats per action (0 is perfect; the uniform
policy over four moves scores −log 4 ≈ −1.39).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import logsumexp

from ..hypotheses import GROUP_NAMES, HypothesisSet, expertise_group

SPLITS = ("episode", "task", "none")
HELDOUT_RULE = ("leave-one-episode-out within tasks of at least 2 episodes; otherwise, with --share both, "
                "leave-one-task-out across the participant's tasks")


def _lse(x, axis=None):
    with np.errstate(divide="ignore", invalid="ignore"):
        return logsumexp(x, axis=axis)


def allows_zero(hyp: HypothesisSet, zero_features: Sequence[int]) -> bool:
    """Whether some θ of the set has every component of ``zero_features`` 0."""
    return bool(np.isfinite(log_prior_theta(hyp, zero_features)).any())


def log_prior_theta(hyp: HypothesisSet, zero_features: Sequence[int] = ()) -> np.ndarray:
    """``[n_theta]`` log prior over the θ set: uniform over the θ's whose ``zero_features``
    components are 0 (−inf elsewhere)."""
    allowed = np.ones(hyp.n_theta, dtype=bool)
    for i in zero_features:
        allowed &= np.isclose(hyp.thetas[:, i], 0.0, atol=1e-12)
    with np.errstate(divide="ignore"):
        return np.where(allowed, -math.log(int(allowed.sum())), -np.inf)


def log_prior_joint(hyp: HypothesisSet, zero_features: Sequence[int] = ()) -> np.ndarray:
    """``[H]`` the joint prior: :func:`log_prior_theta` times uniform over the β grid."""
    return np.repeat(log_prior_theta(hyp, zero_features), hyp.n_beta) - math.log(hyp.n_beta)


def _grid(ll: np.ndarray, hyp: HypothesisSet) -> np.ndarray:
    """``[..., H]`` as ``[..., n_theta, n_beta]``."""
    return ll.reshape(*ll.shape[:-1], hyp.n_theta, hyp.n_beta)


def share_beta_terms(task_ll: Sequence[np.ndarray], hyp: HypothesisSet, lp_theta: np.ndarray) -> np.ndarray:
    """``[T, n_beta]`` log M_t(j) = log Σ_i P(θ_i) P(Ξ_t | θ_i, β_j) of each task's ``[H]`` log-likelihood."""
    return np.stack([_lse(_grid(ll, hyp) + lp_theta[:, None], axis=0) for ll in task_ll])


@dataclass(frozen=True)
class SharedBeta:
    """The ``share = "beta"`` posterior of one participant.

    Attributes:
        beta_probabilities: ``[n_beta]`` P(β_j | Ξ).
        theta_probabilities: ``[T, n_theta]`` P(θ_t = θ_i | Ξ).
        log_evidence: log P(Ξ).
    """

    hypotheses: HypothesisSet
    beta_probabilities: np.ndarray
    theta_probabilities: np.ndarray
    log_evidence: float

    @property
    def mean_beta(self) -> float:
        return float(self.beta_probabilities @ self.hypotheses.betas)

    @property
    def mean_thetas(self) -> np.ndarray:
        """``[T, K]`` θ̂_t."""
        return self.theta_probabilities @ self.hypotheses.thetas

    def group_probabilities(self) -> dict[str, float]:
        out = dict.fromkeys(GROUP_NAMES, 0.0)
        for b, p in zip(self.hypotheses.betas, self.beta_probabilities, strict=True):
            out[expertise_group(float(b))] += float(p)
        return out


def shared_beta_posterior(task_ll: Sequence[np.ndarray], hyp: HypothesisSet,
                          zero_features: Sequence[int] = ()) -> SharedBeta:
    """The ``share = "beta"`` posterior from each task's ``[H]`` log-likelihood (module docstring)."""
    lp_theta = log_prior_theta(hyp, zero_features)
    terms = share_beta_terms(task_ll, hyp, lp_theta)  # [T, nβ]
    joint = terms.sum(axis=0) - math.log(hyp.n_beta)  # [nβ]
    z = float(_lse(joint))
    T = len(task_ll)
    if not math.isfinite(z):
        nan_b = np.full(hyp.n_beta, np.nan)
        return SharedBeta(hyp, nan_b, np.full((T, hyp.n_theta), np.nan), z)
    pb = np.exp(joint - z)
    thetas = np.empty((T, hyp.n_theta))
    for t, ll in enumerate(task_ll):
        with np.errstate(invalid="ignore"):
            cond = np.exp(_grid(ll, hyp) + lp_theta[:, None] - terms[t][None, :])  # P(θ_i | β_j, Ξ_t)
        cond = np.nan_to_num(cond)
        thetas[t] = cond @ pb
    return SharedBeta(hyp, pb, thetas, z)


def log_evidence(task_ll: Sequence[np.ndarray], hyp: HypothesisSet, share: str,
                 zero_features: Sequence[int] = (), log_prior: np.ndarray | None = None) -> float:
    """log P(Ξ) of a participant's tasks (``[H]`` log-likelihood each) under ``share``; with
    ``log_prior`` (``share = "both"``), over the hypotheses it weighs (e.g. the teaching model's
    Ψ × Λ, flattened like the log-likelihoods) instead of :func:`log_prior_joint`."""
    if share == "beta":
        terms = share_beta_terms(task_ll, hyp, log_prior_theta(hyp, zero_features))
        return float(_lse(terms.sum(axis=0) - math.log(hyp.n_beta)))
    prior = log_prior_joint(hyp, zero_features) if log_prior is None else log_prior
    return float(_lse(np.sum(task_ll, axis=0) + prior))


def heldout_units(episodes: Sequence[int], share: str) -> tuple[str, list[tuple[int, int | None]]]:
    """The held-out split of a participant whose task t has ``episodes[t]`` episodes (rules in the
    module docstring): ``(split, units)``, each unit ``(task, episode)``, episode None for a whole
    task."""
    T = len(episodes)
    units: list[tuple[int, int | None]] = [(t, e) for t in range(T) if episodes[t] >= 2
                                           for e in range(episodes[t])]
    if units:
        return "episode", units
    if T >= 2 and share == "both":
        return "task", [(t, None) for t in range(T)]
    return "none", []


def heldout_check(episode_ll: Sequence[np.ndarray], episode_actions: Sequence[Sequence[int]],
                  hyp: HypothesisSet, share: str, zero_features: Sequence[int] = (),
                  log_prior: np.ndarray | None = None) -> dict[str, Any]:
    """The held-out check of one participant (rules in the module docstring).

    ``episode_ll[t]`` is task t's ``[E_t, H]`` per-episode log-likelihood; ``episode_actions[t][e]``
    the number of actions of its episode e; ``log_prior`` as :func:`log_evidence` takes it. Returns
    ``{"split", "units", "actions", "log_likelihood", "per_action", "unavailable"}`` (``per_action``
    None and ``unavailable`` the reason when there is no split or the fit explains nothing).
    """
    task_ll = [np.sum(e, axis=0) for e in episode_ll]
    T = len(task_ll)
    episodes = sum(len(e) for e in episode_ll)
    split, units = heldout_units([len(e) for e in episode_ll], share)
    out: dict[str, Any] = {"split": split, "units": 0, "actions": 0, "log_likelihood": None,
                           "per_action": None, "unavailable": None}
    if split == "none":
        out["unavailable"] = (
            f"{episodes} episode(s) in {T} task(s): the held-out check needs a task with 2 episodes"
            + (" (with --share beta a held-out task's θ is unknown, so tasks are not held out)"
               if share == "beta" and T >= 2 else " or, with --share both, 2 tasks")
        )
        return out
    total = log_evidence(task_ll, hyp, share, zero_features, log_prior)
    if not math.isfinite(total):
        out["unavailable"] = "every hypothesis of the set gives the participant's data probability 0"
        return out
    score, actions = 0.0, 0
    for t, e in units:
        rest = list(task_ll)
        if e is None:
            del rest[t]
            n = int(sum(episode_actions[t]))
        else:
            rest[t] = np.sum(np.delete(episode_ll[t], e, axis=0), axis=0)
            n = int(episode_actions[t][e])
        score += total - log_evidence(rest, hyp, share, zero_features, log_prior)
        actions += n
    out.update(units=len(units), actions=actions, log_likelihood=score, per_action=score / actions)
    return out
