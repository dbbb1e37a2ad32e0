"""How a demonstrator who teaches acts: the literal observer and the teacher's policy.

The model of ``--model pedagogical`` (after Ho, Littman, MacGlashan, Cushman and Austerweil,
"Showing versus doing: teaching by demonstration", NIPS 2016; ``docs/teaching.md``). A literal
observer believes the doer's model (``maxent``) over a fixed hypothesis set Ψ = Θ × B with prior
P(h); its predictive of an action is ``π̄(a|s) = Σ_h P(h) π_h(a|s)``, and given θ,
``π̄_θ(a|s) = Σ_b P(b|θ) π_{θ,b}(a|s)``. What an action tells it about θ is

    I_θ(s, a) = log P_lit(θ | s, a) − log P(θ) = log π̄_θ(a|s) − log π̄(a|s),

and a teacher with preferences θ, expertise β and teaching weight λ ≥ 0 acts by

    π_show(a | s) ∝ exp((Q_{θ,β}(s, a) + λ log P_lit(θ | s, a)) / β)
                  = π_{θ,β}(a|s) · exp(λ/β · I_θ(s, a)) / Z(s).

λ = 0 is ``maxent``. The posterior over (θ, β, λ) is :mod:`expertise_irl.inference.pedagogical`'s;
this module is what the simulator needs, below the inference layer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..hypotheses import HypothesisSet
from ..numerics import log_sum_exp

__all__ = ["MAX_LAMBDA", "Observer", "observer", "solved_observer", "teacher_log_policy",
           "teaching_log_policy", "theta_predictive"]


#: The largest teaching weight taken: λ = 1 already pays a step's reward per nat of the observer's
#: belief; far larger values mean nothing a person does and only overflow λ/β.
MAX_LAMBDA = 1000.0


@dataclass(frozen=True)
class Observer:
    """The literal observer's predictives over a hypothesis set, at some states.

    Attributes:
        hypotheses: the set Ψ it believes in.
        log_prior: ``[H]`` its normalised log prior.
        log_predictive: ``[S', A]`` log π̄(a|s) (−inf where an action is unavailable).
        log_theta_predictive: ``[n_theta, S', A]`` log π̄_θ(a|s).
    """

    hypotheses: HypothesisSet
    log_prior: np.ndarray
    log_predictive: np.ndarray
    log_theta_predictive: np.ndarray

    def informativeness(self, log_theta_predictive: np.ndarray | None = None) -> np.ndarray:
        """I_θ(s, a) = log π̄_θ(a|s) − log π̄(a|s), 0 where an action is unavailable.

        Args:
            log_theta_predictive: ``[..., S', A]`` log π̄_θ of θs off the set
                (:func:`theta_predictive`); None: the set's own θs.

        Returns:
            ``[n_theta, S', A]`` (or the shape given).
        """
        lt = self.log_theta_predictive if log_theta_predictive is None else log_theta_predictive
        ok = np.isfinite(self.log_predictive) & np.isfinite(lt)
        return np.where(ok, lt - np.where(ok, self.log_predictive, 0.0), 0.0)


def observer(hypotheses: HypothesisSet, log_policy: np.ndarray,
             log_prior: np.ndarray | None = None) -> Observer:
    """The literal observer of ``hypotheses`` from their log-policies ``[H, S', A]`` (any states).

    Args:
        hypotheses: the set Ψ = Θ × B.
        log_policy: ``[H, S', A]`` log π_h(a|s) under ``maxent`` at the states of interest.
        log_prior: ``[H]`` log prior (normalised here); uniform when None.

    Returns:
        The observer's predictives at those states.
    """
    H = len(hypotheses)
    if log_prior is None:
        log_prior = np.full(H, -math.log(H))
    log_prior = np.asarray(log_prior, dtype=np.float64) - log_sum_exp(log_prior)
    nt, nb = hypotheses.n_theta, hypotheses.n_beta
    lp = np.asarray(log_policy, dtype=np.float64).reshape(nt, nb, *log_policy.shape[1:])
    prior = log_prior.reshape(nt, nb)
    log_p_theta = log_sum_exp(prior, axis=1)  # [n_theta]
    with np.errstate(invalid="ignore"):
        cond = np.where(np.isfinite(log_p_theta)[:, None], prior - log_p_theta[:, None], -np.inf)
    theta_pred = log_sum_exp(lp + cond[:, :, None, None], axis=1)  # [n_theta, S', A]
    pred = log_sum_exp(theta_pred + log_p_theta[:, None, None], axis=0)
    return Observer(hypotheses, log_prior, pred, theta_pred)


def theta_predictive(log_policy_by_beta: np.ndarray, observer_: Observer) -> np.ndarray:
    """log π̄_θ(a|s) of a θ that need not be in the set: its log-policies at the set's βs, mixed
    by the set's β marginal.

    Args:
        log_policy_by_beta: ``[n_beta, S', A]`` log π_{θ,b}(a|s) at ``observer_.hypotheses.betas``.
        observer_: the observer (its prior gives the β marginal).

    Returns:
        ``[S', A]``.
    """
    hyp = observer_.hypotheses
    log_pb = log_sum_exp(observer_.log_prior.reshape(hyp.n_theta, hyp.n_beta), axis=0)
    return log_sum_exp(np.asarray(log_policy_by_beta) + log_pb[:, None, None], axis=0)


def teaching_log_policy(log_policy: np.ndarray, informativeness: np.ndarray, scale) -> np.ndarray:
    """log π_show: ``log_policy`` + ``scale`` · I renormalised over the actions.

    Args:
        log_policy: ``[..., S', A]`` the doer's log π_{θ,β}.
        informativeness: I_θ, broadcastable to ``log_policy``.
        scale: λ/β, broadcastable to ``log_policy``'s leading axes (``[...]`` or a number).

    Returns:
        ``[..., S', A]`` normalised log-probabilities (−inf where ``log_policy`` is −inf).
    """
    scale = np.asarray(scale, dtype=np.float64)
    logits = log_policy + scale.reshape((*scale.shape, 1, 1)) * informativeness
    m = np.max(logits, axis=-1, keepdims=True)
    dead = ~np.isfinite(m)  # a state with no action (a terminal state): its row stays −inf
    m = np.where(dead, 0.0, m)
    with np.errstate(divide="ignore"):
        log_z = np.log(np.sum(np.exp(logits - m), axis=-1, keepdims=True))
    return logits - m - np.where(dead, 0.0, log_z)



def solved_observer(mdp, hypotheses: HypothesisSet, *, tol: float = 1e-8, chunk_size: int | None = None,
                    progress=None) -> Observer:
    """The literal observer of ``hypotheses`` on every state of ``mdp`` (one ``maxent`` solve of the set,
    uniform prior), for simulating teachers."""
    from ..planning.soft_vi import solve

    sol = solve(mdp, hypotheses.theta, hypotheses.beta, tol=tol, chunk_size=chunk_size, progress=progress)
    return observer(hypotheses, np.asarray(sol.log_policy))


def teacher_log_policy(mdp, theta, beta: float, lam: float, observer_: Observer, *,
                       tol: float = 1e-8) -> np.ndarray:
    """``[S, A]`` log π_show of a teacher (θ, β, λ) before ``observer_`` (on every state of ``mdp``).

    θ need not be in the observer's set: its predictive mixes its own policies at the set's βs
    (:func:`theta_predictive`).

    Args:
        mdp: the task.
        theta: ``[K]`` the teacher's reward weights (used as given).
        beta: the teacher's expertise (temperature), > 0.
        lam: the teaching weight λ ≥ 0 (0: a doer, ``maxent``).
        observer_: the literal observer on every state of ``mdp`` (:func:`solved_observer`).
        tol: the solver's tolerance for the teacher's own solves.

    Returns:
        ``[S, A]`` the teacher's log-policy.

    Raises:
        InputError: λ not a finite number ≥ 0, or an observer of other states than ``mdp``'s.
    """
    from ..planning.soft_vi import solve

    if not (math.isfinite(lam) and 0 <= lam <= MAX_LAMBDA):
        raise InputError(f"lambda must be a number from 0 to {MAX_LAMBDA:g}, got {lam:g}")
    if observer_.log_predictive.shape != (mdp.n_states, mdp.n_actions):
        raise InputError(f"the observer covers {observer_.log_predictive.shape[0]} states, "
                         f"the task has {mdp.n_states}")
    betas = np.concatenate([[float(beta)], observer_.hypotheses.betas])
    th = np.repeat(np.asarray(theta, dtype=np.float64)[None, :], len(betas), axis=0)
    lp = np.asarray(solve(mdp, th, betas, tol=tol).log_policy)
    if lam == 0:
        return lp[0]
    info = observer_.informativeness(theta_predictive(lp[1:], observer_))
    return teaching_log_policy(lp[0], info, lam / float(beta))
