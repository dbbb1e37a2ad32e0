"""Summaries of a posterior over a hypothesis set Ψ = Θ × B, from unnormalised log-weights.

One set of formulas serves :class:`~expertise_irl.inference.belief.DiscreteBelief`, the
per-action :class:`~expertise_irl.inference.belief.Trace`, the
:class:`~expertise_irl.inference.online.OnlineEstimator` and the active start choice: the
normalised posterior, the β and θ marginals, E[β], E[θ], the expertise-group masses, the
entropy and grid quantiles of the β marginal. Every function takes one posterior (``[H]``)
or a batch of them as columns (``[H, n]``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.special import logsumexp

from ..hypotheses import GROUP_NAMES, HypothesisSet, expertise_group
from ..numerics import log_sum_exp  # noqa: F401  (re-exported)


def normalize_log(logw: np.ndarray, axis: int = 0) -> np.ndarray:
    """Log-probabilities from unnormalised log-weights (−inf allowed, not all)."""
    return logw - logsumexp(logw, axis=axis, keepdims=True)


def entropy(p: np.ndarray, lp: np.ndarray, axis: int = 0) -> np.ndarray:
    """−Σ p log p, with 0 log 0 = 0 (no 0·(−∞) is ever evaluated)."""
    terms = np.multiply(p, lp, out=np.zeros_like(p), where=p > 0)
    return -np.sum(terms, axis=axis)


def group_masses(betas: np.ndarray, beta_marginal: np.ndarray) -> np.ndarray:
    """``[3, ...]`` mass of the expertise groups (order of :data:`GROUP_NAMES`), normalised.

    ``beta_marginal`` is ``[n_beta, ...]``; the masses are summed in the order of ``betas``.
    """
    index = [GROUP_NAMES.index(expertise_group(float(b))) for b in betas]
    g = np.zeros((len(GROUP_NAMES), *beta_marginal.shape[1:]))
    for j, i in enumerate(index):
        g[i] += beta_marginal[j]
    return g / g.sum(axis=0)


def beta_quantile(betas: np.ndarray, beta_marginal: np.ndarray, q: float) -> np.ndarray:
    """The smallest β of the (ascending) grid whose cumulative probability reaches ``q``."""
    cdf = np.cumsum(beta_marginal, axis=0) / beta_marginal.sum(axis=0)
    return betas[np.argmax(cdf >= q - 1e-12, axis=0)]


class Summary(NamedTuple):
    """A posterior over Ψ and its summaries (``...`` = the batch shape of the log-weights).

    Attributes:
        log_probabilities, probabilities: ``[H, ...]`` the normalised posterior.
        beta_marginal: ``[n_beta, ...]`` P(β); theta_marginal: ``[n_theta, ...]`` P(θ).
        mean_beta: ``[...]`` E[β]; mean_theta: ``[..., K]`` E[θ].
        group_probabilities: ``[3, ...]`` mass of each expertise group (:data:`GROUP_NAMES`).
        entropy: ``[...]`` posterior entropy over all hypotheses (nats).
    """

    log_probabilities: np.ndarray
    probabilities: np.ndarray
    beta_marginal: np.ndarray
    theta_marginal: np.ndarray
    mean_beta: np.ndarray
    mean_theta: np.ndarray
    group_probabilities: np.ndarray
    entropy: np.ndarray

    def groups(self) -> dict[str, float]:
        """``{"high": p, "medium": p, "low": p}`` of a single posterior."""
        return {g: float(v) for g, v in zip(GROUP_NAMES, self.group_probabilities, strict=True)}


def summarise(logw: np.ndarray, hypotheses: HypothesisSet) -> Summary:
    """The :class:`Summary` of unnormalised log-weights ``logw`` ``[H]`` or ``[H, n]``."""
    lp = normalize_log(logw, axis=0)
    p = np.exp(lp)
    grid = p.reshape(hypotheses.n_theta, hypotheses.n_beta, *p.shape[1:])
    pb, pt = grid.sum(axis=0), grid.sum(axis=1)
    return Summary(lp, p, pb, pt, hypotheses.betas @ pb, pt.T @ hypotheses.thetas,
                   group_masses(hypotheses.betas, pb), entropy(p, lp, axis=0))
