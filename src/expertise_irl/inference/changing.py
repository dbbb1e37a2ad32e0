"""Expertise that changes over a person's episodes: an exact discrete model.

The paper takes one expertise β for all of a person's demonstrations and names expertise
that changes with practice as future work. This module is the exact discrete version of
that model over a hypothesis set Ψ = Θ × B (:class:`~expertise_irl.hypotheses.HypothesisSet`):

- θ is shared by all episodes, with a uniform prior over Θ (or ``log_prior_theta``).
- β_e, the expertise of episode e (episodes in the order given), is a sticky Markov chain on
  the β grid B (ascending, index j = 0 .. n_beta − 1):

  * β_1 is uniform on the grid;
  * ``trend=None`` (both ways): stay with probability 1 − ε, else move to a neighbouring grid
    value, ε/2 each side. At the ends of the grid the move that would leave it stays, so the
    end values stay with probability 1 − ε/2 (a grid of one value always stays);
  * ``trend="falling"`` (learning: β only falls): stay with probability 1 − ε, else one step
    down the grid; the smallest β always stays;
  * ``trend="rising"``: stay with probability 1 − ε, else one step up; the largest β always stays.

- ε is marginalised over a small grid (:data:`EPSILONS` by default) that must contain 0, the
  stationary model (β_1 = … = β_E, the paper's). Prior: P(ε = 0) = 1/2, and the other 1/2
  spread uniformly over the ε > 0 values (all mass on ε = 0 if there are none). Hence

      log BF (changing vs stationary) = log mean_{ε>0} Z(ε) − log Z(0),
      P(changing | Ξ) = sigmoid(log BF),

  with Z(ε) = P(Ξ | ε) = Σ_θ P(θ) Σ_{β_1..β_E} P(β_1..β_E | ε) Π_e P(ξ_e | θ, β_e).

Inputs are the per-episode log-likelihoods ``episode_ll [E, H]`` (log P(ξ_e | h) for every
hypothesis h of the set, which the set's one solve already gives: :func:`episode_log_likelihoods`
reads them from the solved log-policy table), so nothing is solved again. The posterior over
(θ, β_1..β_E) is a forward–backward pass over the β grid per θ, vectorised over θ and ε. Every
quantity is kept in log space, each state's predecessors combined by a log-sum-exp of their own
(no common scale), so probabilities are exact to rounding (≈1e-15 relative per episode) however
small, and impossible hypotheses (−inf log-likelihoods) propagate as exact zeros, never NaN.
The chain has three diagonals, so a pass costs O(|Θ|·|B|·E) per ε (within the O(|Θ|·|B|²·E)
of a dense chain); :func:`trend_summary`'s pairwise first/last marginal is |B| such passes.

Reported posteriors (``ChangingPosterior``):

- ``beta_smoothed``, ``beta_filtered`` and ``theta_probabilities`` are **model-averaged**: every ε
  of the grid (the stationary ε = 0 included) weighted by its posterior ``epsilon_posterior``,
  i.e. the changing and the stationary model mixed by their posterior probabilities.
- ``theta_probabilities_changing`` and ``beta_smoothed_changing`` are the changing model alone
  (ε > 0, mixed by its posterior within ε > 0).
- ``stationary`` is the usual posterior over Ψ (ε = 0: the sum of the episodes'
  log-likelihoods), as a :class:`~.posterior.Summary`; ``stationary.theta_marginal`` is the
  stationary θ posterior.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import expit, logsumexp

from ..errors import ArgumentError, InputError
from ..hypotheses import HypothesisSet
from .posterior import Summary, beta_quantile, log_sum_exp, summarise

#: The default grid of switching probabilities ε (0 = the stationary model).
EPSILONS: tuple[float, ...] = (0.0, 0.02, 0.05, 0.1, 0.2)
#: The chains: ``None`` (a step either way), ``"falling"`` (β only falls), ``"rising"``.
TRENDS: tuple[str | None, ...] = (None, "falling", "rising")
#: Quantiles of the per-episode β marginal reported by :func:`expertise_by_episode` (a 90% band).
BAND = (0.05, 0.95)


# ----------------------------------------------------------------------------- the chain
def transition_diagonals(n_beta: int, epsilon: float, trend: str | None = None) -> np.ndarray:
    """``[3, n_beta]`` log transition probabilities of the β chain: rows ``stay`` (log T[j, j]),
    ``up`` (log T[j, j+1]) and ``down`` (log T[j, j−1]); −inf where there is no such move."""
    eps = float(epsilon)
    stay, up, down = np.full(n_beta, 1.0 - eps), np.zeros(n_beta), np.zeros(n_beta)
    if trend is None:
        up[:-1] = down[1:] = eps / 2
        stay[0] += eps / 2  # the move off the grid's end stays
        stay[-1] += eps / 2  # (both at once when n_beta = 1: T = [[1]])
    elif trend == "falling":
        down[1:] = eps
        stay[0] = 1.0
    elif trend == "rising":
        up[:-1] = eps
        stay[-1] = 1.0
    else:
        raise InputError(f"trend must be one of none, falling, rising, got {trend!r}")
    with np.errstate(divide="ignore"):
        return np.log(np.stack([stay, up, down]))


def transition_matrix(n_beta: int, epsilon: float, trend: str | None = None) -> np.ndarray:
    """``[n_beta, n_beta]`` dense T[j, k] = P(β_{e+1} = B[k] | β_e = B[j]) (for checks and display)."""
    stay, up, down = np.exp(transition_diagonals(n_beta, epsilon, trend))
    return np.diag(stay) + np.diag(up[:-1], 1) + np.diag(down[1:], -1)


def _lse3(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Element-wise log(e^a + e^b + e^c), exact to rounding; −inf (no NaN) where all are −inf."""
    m = np.maximum(np.maximum(a, b), c)
    m0 = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        return m0 + np.log(np.exp(a - m0) + np.exp(b - m0) + np.exp(c - m0))


def _shift_right(x: np.ndarray) -> np.ndarray:
    """``out[..., k] = x[..., k − 1]`` (−inf at k = 0)."""
    out = np.full_like(x, -np.inf)
    out[..., 1:] = x[..., :-1]
    return out


def _shift_left(x: np.ndarray) -> np.ndarray:
    """``out[..., k] = x[..., k + 1]`` (−inf at the last k)."""
    out = np.full_like(x, -np.inf)
    out[..., :-1] = x[..., 1:]
    return out


def _push(x: np.ndarray, lt: np.ndarray) -> np.ndarray:
    """Forward step: ``out[..., k] = log Σ_j exp(x[..., j]) T[j, k]`` (β on the last axis;
    ``lt [..., 3, J]`` from :func:`transition_diagonals`, broadcast against ``x``)."""
    stay, up, down = lt[..., 0, :], lt[..., 1, :], lt[..., 2, :]
    return _lse3(x + stay, _shift_right(x + up), _shift_left(x + down))


def _pull(y: np.ndarray, lt: np.ndarray) -> np.ndarray:
    """Backward step: ``out[..., j] = log Σ_k T[j, k] exp(y[..., k])``."""
    stay, up, down = lt[..., 0, :], lt[..., 1, :], lt[..., 2, :]
    return _lse3(stay + y, up + _shift_left(y), down + _shift_right(y))


# ----------------------------------------------------------------------------- inputs
def _check_epsilons(epsilons) -> np.ndarray:
    try:
        eps = np.asarray(epsilons, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise InputError(f"epsilons must be numbers in [0, 1), got {epsilons!r}") from None
    if eps.size == 0:
        raise InputError("epsilons is empty; it needs 0 (the stationary model)")
    bad = ~np.isfinite(eps) | (eps < 0) | (eps >= 1)
    if bad.any():
        raise InputError(f"epsilon must be in [0, 1), got {eps[bad][0]:g}")
    if np.unique(eps).size != eps.size:
        raise InputError(f"epsilons must be distinct, got {eps.tolist()}")
    if not np.any(eps == 0):
        raise InputError(f"epsilons must include 0 (the stationary model, the Bayes factor's reference), "
                         f"got {eps.tolist()}")
    return np.sort(eps)


def _check_trend(trend) -> str | None:
    if trend is None or trend == "none":
        return None
    if trend not in TRENDS:
        raise InputError(f"trend must be one of none, falling, rising, got {trend!r}")
    return trend


def _check_episode_ll(episode_ll, hypotheses: HypothesisSet) -> np.ndarray:
    ll = np.asarray(episode_ll, dtype=np.float64)
    H = len(hypotheses)
    if ll.ndim != 2 or ll.shape[1] != H:
        raise ArgumentError(f"episode_ll must have shape [episodes, H={H}] "
                         f"({hypotheses.n_theta} θ × {hypotheses.n_beta} β), got {list(ll.shape)}")
    if ll.shape[0] == 0:
        raise InputError("episode_ll has no episodes")
    if np.isnan(ll).any() or (ll == np.inf).any():
        raise InputError("episode_ll must hold log-likelihoods (no NaN, no +inf)")
    return ll


def _check_log_prior_theta(log_prior_theta, n_theta: int) -> np.ndarray:
    if log_prior_theta is None:
        return np.full(n_theta, -np.log(n_theta))
    lp = np.asarray(log_prior_theta, dtype=np.float64)
    if lp.shape != (n_theta,):
        raise ArgumentError(f"log_prior_theta must have shape [n_theta={n_theta}], got {list(lp.shape)}")
    if np.isnan(lp).any() or (lp == np.inf).any() or not np.isfinite(lp).any():
        raise InputError("log_prior_theta must be log-weights (no NaN or +inf, at least one finite)")
    return lp - logsumexp(lp)


def log_epsilon_prior(epsilons) -> np.ndarray:
    """``[n_eps]`` log prior of the ε grid: 1/2 on ε = 0, 1/2 spread uniformly over ε > 0 (all on
    ε = 0 if the grid has no other value)."""
    eps = _check_epsilons(epsilons)
    n_pos = int(np.sum(eps > 0))
    if n_pos == 0:
        return np.zeros(1)
    return np.where(eps == 0, np.log(0.5), np.log(0.5 / n_pos))


def episode_log_likelihoods(log_policy: np.ndarray, trajs) -> np.ndarray:
    """``[E, H]`` log P(episode e | h) from a solved ``[H, S, A]`` log-policy table, episodes in
    the order of ``trajs.episode_ids`` (the input of :func:`changing_posterior`)."""
    from ..planning.table_likelihood import log_likelihood

    return np.stack([log_likelihood(log_policy, s, a) for s, a in trajs.episodes()])


# ----------------------------------------------------------------------------- the result
@dataclass(frozen=True, eq=False)
class ChangingPosterior:
    """The posterior of the changing-expertise model (see the module docstring for its meaning).

    Attributes:
        hypotheses: the set Ψ = Θ × B.
        epsilons: ``[n_eps]`` the ε grid, ascending (``epsilons[0] == 0``).
        trend: ``None``, ``"falling"`` or ``"rising"``.
        log_evidence_by_epsilon: ``[n_eps]`` log Z(ε) = log P(Ξ | ε) (nats).
        log_prior_epsilon, epsilon_posterior: ``[n_eps]`` log P(ε) and P(ε | Ξ).
        log_evidence: log P(Ξ) of the whole model (ε marginalised).
        log_bayes_factor: log mean_{ε>0} Z(ε) − log Z(0) (NaN without ε > 0; +inf if the
            episodes are impossible for every stationary hypothesis).
        p_changing: P(ε > 0 | Ξ) = sigmoid(log BF).
        epsilon_mean: E[ε | Ξ, ε > 0] (NaN without ε > 0).
        theta_probabilities: ``[n_theta]`` P(θ | Ξ), model-averaged over ε.
        theta_probabilities_changing: ``[n_theta]`` P(θ | Ξ, ε > 0) (the stationary one is
            ``stationary.theta_marginal``; NaN without ε > 0).
        theta_by_epsilon: ``[n_eps, n_theta]`` P(θ | Ξ, ε) (NaN rows where Z(ε) = 0).
        beta_smoothed: ``[E, n_beta]`` P(β_e | Ξ), model-averaged over ε.
        beta_smoothed_changing: ``[E, n_beta]`` P(β_e | Ξ, ε > 0).
        beta_smoothed_by_epsilon: ``[n_eps, E, n_beta]`` P(β_e | Ξ, ε).
        beta_filtered: ``[E, n_beta]`` P(β_e | ξ_1..ξ_e), model-averaged over ε with the ε
            posterior of those episodes (what a live display can show after episode e).
        stationary: the ε = 0 posterior over Ψ (:class:`~.posterior.Summary`), or ``None`` when no
            hypothesis of the set can produce all the episodes with one β.
    """

    hypotheses: HypothesisSet
    epsilons: np.ndarray
    trend: str | None
    log_evidence_by_epsilon: np.ndarray
    log_prior_epsilon: np.ndarray
    epsilon_posterior: np.ndarray
    log_evidence: float
    log_bayes_factor: float
    p_changing: float
    epsilon_mean: float
    theta_probabilities: np.ndarray
    theta_probabilities_changing: np.ndarray
    theta_by_epsilon: np.ndarray
    beta_smoothed: np.ndarray
    beta_smoothed_changing: np.ndarray
    beta_smoothed_by_epsilon: np.ndarray
    beta_filtered: np.ndarray
    stationary: Summary | None
    # The checked inputs, kept for trend_summary's pairwise pass (not part of the result).
    _episode_ll: np.ndarray = field(repr=False, default=None)
    _log_prior_theta: np.ndarray = field(repr=False, default=None)

    @property
    def n_episodes(self) -> int:
        return int(self.beta_smoothed.shape[0])

    @property
    def betas(self) -> np.ndarray:
        return self.hypotheses.betas

    @property
    def mean_beta(self) -> np.ndarray:
        """``[E]`` E[β_e | Ξ] (model-averaged)."""
        return self.beta_smoothed @ self.hypotheses.betas

    @property
    def mean_theta(self) -> np.ndarray:
        """``[K]`` E[θ | Ξ] (model-averaged)."""
        return self.theta_probabilities @ self.hypotheses.thetas

    def expertise_by_episode(self, episode_labels: Sequence | None = None) -> list[dict[str, Any]]:
        return expertise_by_episode(self, episode_labels)

    def changing_summary(self) -> dict[str, Any]:
        return changing_summary(self)

    def trend_summary(self) -> dict[str, float]:
        return trend_summary(self)

    def first_last_joint(self) -> np.ndarray:
        return first_last_joint(self)


# ----------------------------------------------------------------------------- inference
def _smoothed(la: np.ndarray, L: np.ndarray, lt: np.ndarray, lpt: np.ndarray,
              log_z: np.ndarray) -> np.ndarray:
    """``[n_eps, E, J]`` P(β_e = j | Ξ, ε): the backward pass, lb[ε, θ, j] = log P(ξ_{e+1}..ξ_E |
    β_e = j, θ, ε), met with the forward pass ``la`` (θ summed out under ``lpt``); NaN rows where
    Z(ε) = 0."""
    E, n_eps, n_t, J = la.shape
    smoothed = np.empty((E, n_eps, J))
    lb = np.zeros((n_eps, n_t, J))
    for e in range(E - 1, -1, -1):
        if e < E - 1:
            lb = _pull(L[e + 1][None] + lb, lt)
        smoothed[e] = log_sum_exp(la[e] + lb + lpt[None, :, None], axis=1)
    with np.errstate(invalid="ignore"):
        return np.exp(smoothed - log_z[None, :, None]).transpose(1, 0, 2)


def _changing_alone(eps: np.ndarray, log_z: np.ndarray, theta_by_eps: np.ndarray, by_eps: np.ndarray):
    """The changing model alone (ε > 0, a uniform prior within it) and its Bayes factor against
    ε = 0: ``(log BF, E[ε], P(changing), θ probabilities, smoothed β)``, NaN where no ε > 0."""
    pos = eps > 0
    if not pos.any():
        nan = float("nan")
        return nan, nan, 0.0, np.full(theta_by_eps.shape[1], nan), np.full(by_eps.shape[1:], nan)
    lzp = log_z[pos]
    log_mean_pos = float(logsumexp(lzp) - np.log(pos.sum()))
    log_bf = log_mean_pos - float(log_z[~pos][0])
    wp = np.exp(lzp - logsumexp(lzp))  # P(ε | Ξ, ε > 0)
    return (log_bf, float(wp @ eps[pos]), float(expit(log_bf)), wp @ theta_by_eps[pos],
            np.einsum("k,kej->ej", wp, by_eps[pos]))


def changing_posterior(
    episode_ll,
    hypotheses: HypothesisSet,
    *,
    epsilons: Sequence[float] = EPSILONS,
    trend: str | None = None,
    log_prior_theta=None,
) -> ChangingPosterior:
    """The posterior of the changing-expertise model from per-episode log-likelihoods.

    Args:
        episode_ll: ``[E, H]`` log P(ξ_e | h), episodes in the order the chain runs (−inf allowed).
        hypotheses: the set Ψ the columns of ``episode_ll`` index (θ-major, β fastest).
        epsilons: the ε grid (each in [0, 1), distinct, 0 included); sorted in the result.
        trend: ``None`` (a step either way), ``"falling"`` or ``"rising"`` (see the module).
        log_prior_theta: ``[n_theta]`` log-weights of θ (normalised here); uniform by default.

    Raises :class:`InputError` on a bad ε, trend or prior, no episodes, or episodes that no
    hypothesis and no β sequence can produce; :class:`~expertise_irl.errors.ArgumentError` on
    arrays of the wrong shape.
    """
    ll = _check_episode_ll(episode_ll, hypotheses)
    eps = _check_epsilons(epsilons)
    trend = _check_trend(trend)
    n_t, J = hypotheses.n_theta, hypotheses.n_beta
    lpt = _check_log_prior_theta(log_prior_theta, n_t)
    E = ll.shape[0]
    n_eps = eps.size
    L = ll.reshape(E, n_t, J)  # [E, θ, β]
    lt = np.stack([transition_diagonals(J, e, trend) for e in eps])[:, None]  # [n_eps, 1, 3, J]
    log_pi = -np.log(J)

    # Forward: la[e, ε, θ, j] = log P(ξ_1..ξ_e, β_e = j | θ, ε).
    la = np.empty((E, n_eps, n_t, J))
    la[0] = log_pi + L[0][None]
    for e in range(1, E):
        la[e] = _push(la[e - 1], lt) + L[e][None]
    # θ prior folded in: lf[e, ε, j] = log P(ξ_1..ξ_e, β_e = j | ε).
    lf = log_sum_exp(la + lpt[None, None, :, None], axis=2)  # [E, n_eps, J]
    log_zt = log_sum_exp(la[-1], axis=-1)  # [n_eps, θ]: log P(Ξ | θ, ε)
    log_z = log_sum_exp(lf[-1], axis=-1)  # [n_eps]
    if not np.isfinite(log_z).any():
        raise InputError("no hypothesis and no sequence of β can produce these episodes "
                         "(every one has an impossible action)")

    log_prior_eps = log_epsilon_prior(eps)
    lw = log_prior_eps + log_z
    log_evidence = float(logsumexp(lw))
    w = np.exp(lw - log_evidence)  # P(ε | Ξ)
    ok = np.isfinite(log_z)

    # θ posteriors.
    with np.errstate(invalid="ignore"):
        theta_by_eps = np.exp(lpt[None] + log_zt - log_z[:, None])  # NaN rows where Z(ε) = 0
    theta_avg = w[ok] @ theta_by_eps[ok]

    by_eps = _smoothed(la, L, lt, lpt, log_z)  # [n_eps, E, J]
    beta_avg = np.einsum("k,kej->ej", w[ok], by_eps[ok])

    # Filtered: P(β_e, ε | ξ_1..ξ_e) ∝ P(ε) P(ξ_1..ξ_e, β_e | ε), summed over ε.
    lj = log_prior_eps[None, :, None] + lf  # [E, n_eps, J]
    filtered = np.exp(lj - log_sum_exp(lj, axis=(1, 2))[:, None, None]).sum(axis=1)

    log_bf, eps_mean, p_changing, theta_changing, beta_changing = _changing_alone(
        eps, log_z, theta_by_eps, by_eps)

    logw_stat = (lpt[:, None] - np.log(J) + L.sum(axis=0)).ravel()
    stationary = summarise(logw_stat, hypotheses) if np.isfinite(logw_stat).any() else None

    return ChangingPosterior(
        hypotheses=hypotheses, epsilons=eps, trend=trend, log_evidence_by_epsilon=log_z,
        log_prior_epsilon=log_prior_eps, epsilon_posterior=w, log_evidence=log_evidence,
        log_bayes_factor=float(log_bf), p_changing=p_changing, epsilon_mean=eps_mean,
        theta_probabilities=theta_avg, theta_probabilities_changing=theta_changing,
        theta_by_epsilon=theta_by_eps, beta_smoothed=beta_avg, beta_smoothed_changing=beta_changing,
        beta_smoothed_by_epsilon=by_eps, beta_filtered=filtered, stationary=stationary,
        _episode_ll=ll, _log_prior_theta=lpt,
    )


def first_last_joint(posterior: ChangingPosterior) -> np.ndarray:
    """``[n_beta, n_beta]`` P(β_1 = B[a], β_E = B[b] | Ξ), model-averaged over ε.

    A forward pass conditioned on β_1 (one per grid value, vectorised): O(|B|²·E·|Θ|) per ε > 0
    with the banded chain; at ε = 0 the joint is the stationary β marginal on the diagonal.
    """
    p = posterior
    hyp = p.hypotheses
    n_t, J = hyp.n_theta, hyp.n_beta
    L = p._episode_ll.reshape(-1, n_t, J)
    E = L.shape[0]
    ok = np.isfinite(p.log_evidence_by_epsilon) & (p.epsilon_posterior > 0)
    out = np.zeros((J, J))
    if ok[0]:  # ε = 0: β never changes, the joint is the stationary marginal on the diagonal
        out += p.epsilon_posterior[0] * np.diag(p.stationary.beta_marginal)
    ok[0] = False
    if not ok.any():
        return out
    eps, w, log_z = p.epsilons[ok], p.epsilon_posterior[ok], p.log_evidence_by_epsilon[ok]
    lt = np.stack([transition_diagonals(J, e, p.trend) for e in eps])[:, None, None]  # [n, 1, 1, 3, J]
    # x[ε, θ, a, b] = log P(β_1 = a, ξ_1..ξ_e, β_e = b | θ, ε)
    x = np.full((eps.size, n_t, J, J), -np.inf)
    idx = np.arange(J)
    x[:, :, idx, idx] = (-np.log(J) + L[0])[None]
    for e in range(1, E):
        x = _push(x, lt) + L[e][None, :, None, :]
    joint = np.exp(log_sum_exp(x + p._log_prior_theta[None, :, None, None], axis=1) - log_z[:, None, None])
    return out + np.einsum("k,kab->ab", w, joint)


# ----------------------------------------------------------------------------- summaries
def expertise_by_episode(posterior: ChangingPosterior, episode_labels: Sequence | None = None
                         ) -> list[dict[str, Any]]:
    """One row per episode of the model-averaged smoothed β marginal: ``{"episode", "mean",
    "median", "q05", "q95"}``; quantiles on the grid (the smallest grid β whose cumulative
    probability reaches q), mean = Σ p β. Labels default to 0, 1, ….
    """
    E = posterior.n_episodes
    labels = list(range(E)) if episode_labels is None else list(episode_labels)
    if len(labels) != E:
        raise InputError(f"episode_labels has {len(labels)} labels for {E} episodes")
    b = posterior.hypotheses.betas
    pb = posterior.beta_smoothed.T  # [J, E]
    mean = b @ pb
    q = {k: beta_quantile(b, pb, v) for k, v in (("median", 0.5), ("q05", BAND[0]), ("q95", BAND[1]))}
    return [{"episode": lab, "mean": float(mean[e]), **{k: float(v[e]) for k, v in q.items()}}
            for e, lab in enumerate(labels)]


def changing_summary(posterior: ChangingPosterior) -> dict[str, Any]:
    """``{"log_bayes_factor", "p_changing", "epsilon_mean", "epsilons", "epsilon_posterior"}``."""
    p = posterior
    return {"log_bayes_factor": float(p.log_bayes_factor), "p_changing": float(p.p_changing),
            "epsilon_mean": float(p.epsilon_mean), "epsilons": [float(e) for e in p.epsilons],
            "epsilon_posterior": [float(v) for v in p.epsilon_posterior]}


def trend_summary(posterior: ChangingPosterior) -> dict[str, float]:
    """The sign and size of a learning trend: ``{"p_falls": P(β_E < β_1 | Ξ), "p_rises":
    P(β_E > β_1 | Ξ), "log_ratio_mean": E[log β_E − log β_1 | Ξ]}``, exact (the pairwise
    first/last marginal of :func:`first_last_joint`), model-averaged over ε."""
    joint = first_last_joint(posterior)
    lb = np.log(posterior.hypotheses.betas)
    return {"p_falls": float(np.tril(joint, -1).sum()), "p_rises": float(np.triu(joint, 1).sum()),
            "log_ratio_mean": float(np.sum(joint * (lb[None, :] - lb[:, None])))}


def filtered_by_action(step_ll, episode_index, hypotheses: HypothesisSet, *,
                       epsilons: Sequence[float] = EPSILONS, trend: str | None = None,
                       log_prior_theta=None) -> np.ndarray:
    """``[N, n_beta]`` P(β_e | everything up to action t): the current episode's expertise after each
    action, filtered (never using later actions), for a live display and ``--per-action`` traces.

    ``step_ll [N, H]`` is log π_h(a_t | s_t) of each action in order; ``episode_index [N]`` the
    0-based episode of each action (non-decreasing: episodes in order, each contiguous). After the
    last action of an episode the row equals :func:`changing_posterior`'s ``beta_filtered`` of that
    episode. Cost O(N · |ε| · |Θ| · |B|).
    """
    hyp = hypotheses
    step = np.asarray(step_ll, dtype=np.float64)
    ep = np.asarray(episode_index)
    if step.ndim != 2 or step.shape[1] != len(hyp) or ep.shape != (step.shape[0],):
        raise InputError(f"step_ll must be [N, {len(hyp)}] with one episode index per row, got "
                         f"{step.shape} and {ep.shape}")
    if step.shape[0] and (ep[0] != 0 or np.any(np.diff(ep) < 0) or np.any(np.diff(ep) > 1)):
        raise InputError("episode_index must start at 0 and step by 0 or 1 (episodes in order, contiguous)")
    eps = _check_epsilons(epsilons)
    trend = _check_trend(trend)
    n_t, J = hyp.n_theta, hyp.n_beta
    lpt = _check_log_prior_theta(log_prior_theta, n_t)
    lt = np.stack([transition_diagonals(J, e, trend) for e in eps])[:, None]  # [n_eps, 1, 3, J]
    log_prior_eps = log_epsilon_prior(eps)
    out = np.empty((step.shape[0], J))
    done = None  # forward message after the last finished episode: [n_eps, θ, J]
    partial = np.zeros((n_t, J))  # the current episode's log-likelihood so far
    current = 0
    for t in range(step.shape[0]):
        if ep[t] != current:  # the previous episode ended: fold it into the message
            start = np.full((eps.size, n_t, J), -np.log(J)) if done is None else _push(done, lt)
            done = start + partial[None]
            partial = np.zeros((n_t, J))
            current = int(ep[t])
        partial = partial + step[t].reshape(n_t, J)
        prior = np.full((eps.size, n_t, J), -np.log(J)) if done is None else _push(done, lt)
        # [ε, J]
        lj = log_prior_eps[:, None] + log_sum_exp(prior + partial[None] + lpt[None, :, None], axis=1)
        z = log_sum_exp(lj, axis=(0, 1))
        out[t] = np.exp(lj - z).sum(axis=0) if np.isfinite(z) else np.nan
    return out
