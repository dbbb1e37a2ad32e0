"""Discrete-set Bayesian belief over Ψ = Θ × B (paper Eq. 13), in log space.

The belief keeps the accumulated log-likelihood of every hypothesis and its
log prior; the posterior is their normalised sum. Updating after each action
or after each whole trajectory gives the same posterior (the log-likelihood
is a sum over pairs, Eq. 11); the per-action form exists for live estimates.

A hypothesis that cannot produce an observed action gets log-likelihood −∞
and stays at probability 0 (``n_impossible`` counts them). If *every*
hypothesis becomes impossible the update raises :class:`InputError` naming
the offending step.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import ArgumentError, InputError
from ..hypotheses import GROUP_NAMES, HypothesisSet
from ..mdp import TabularMDP
from ..planning.soft_vi import solve
from ..planning.table_likelihood import check_pairs, pair_log_likelihoods
from ..planning.table_likelihood import log_likelihood as total_log_likelihood
from .posterior import Summary, beta_quantile, summarise


class Trace(NamedTuple):
    """Point estimates after each observed action (index 0 = prior, i = after i actions).

    Attributes:
        mean_beta: ``[N + 1]`` E[β].
        mean_theta: ``[N + 1, K]`` E[θ].
        entropy: ``[N + 1]`` posterior entropy (nats).
        truth_probability: ``[N + 1]`` probability of hypothesis ``truth`` (NaN if not given).
        group_probabilities: ``[N + 1, 3]`` posterior mass of the expertise groups, in the
            order of :data:`GROUP_NAMES` (high, medium, low).
        beta_low, beta_high: ``[N + 1]`` the 5% and 95% quantiles of the β marginal. β takes
            only the values of the grid, so these are grid values: the smallest β whose
            cumulative probability (β sorted ascending) reaches 0.05, resp. 0.95. The band
            ``[beta_low, beta_high]`` holds at least 90% of the mass.
    """

    mean_beta: np.ndarray
    mean_theta: np.ndarray
    entropy: np.ndarray
    truth_probability: np.ndarray
    group_probabilities: np.ndarray
    beta_low: np.ndarray
    beta_high: np.ndarray

    def groups_at(self, i: int) -> dict[str, float]:
        """``{"high": p, "medium": p, "low": p}`` after ``i`` actions."""
        return {g: float(v) for g, v in zip(GROUP_NAMES, self.group_probabilities[i], strict=True)}


#: Quantiles of the β marginal that bound the credible band of a trace (a 90% band).
TRACE_BAND = (0.05, 0.95)


def _traj_label(trajs: Trajectories):
    return lambda i: f"episode {trajs.episode[i]} step {trajs.step[i]}"


@dataclass(frozen=True, eq=False)
class DiscreteBelief:
    """Posterior over a finite hypothesis set; immutable (updates return a new belief).

    Attributes:
        hypotheses: the set Ψ = Θ × B, H = len(hypotheses).
        log_policy: ``[H, S, A]`` log π_h(a|s) from :func:`~expertise_irl.planning.soft_vi.solve`.
        log_prior: ``[H]`` normalised log prior.
        log_likelihood: ``[H]`` accumulated log P(Ξ | h) of everything observed.
        n_observed: number of (state, action) pairs observed so far.
    """

    hypotheses: HypothesisSet
    log_policy: np.ndarray
    log_prior: np.ndarray
    log_likelihood: np.ndarray
    n_observed: int = 0

    # ------------------------------------------------------------ construction
    @classmethod
    def from_mdp(
        cls,
        mdp: TabularMDP,
        hypotheses: HypothesisSet,
        *,
        prior: np.ndarray | None = None,
        **solve_kwargs,
    ) -> DiscreteBelief:
        """Solve every hypothesis on ``mdp`` and start from ``prior`` (uniform by default).

        Args:
            mdp: the task.
            hypotheses: the set Ψ = Θ × B, with the MDP's features.
            prior: ``[H]`` prior weights (normalised here).
            **solve_kwargs: go to :func:`~expertise_irl.planning.soft_vi.solve` (tol, chunk_size,
                progress, model...).

        Returns:
            The belief before any observation.

        Raises:
            InputError: the hypotheses' features do not match the MDP's, or a bad prior.
        """
        if hypotheses.thetas.shape[1] != mdp.n_features:
            raise InputError(
                f"hypotheses have {hypotheses.thetas.shape[1]} features but the MDP has "
                f"{mdp.n_features} ({', '.join(mdp.feature_names)})"
            )
        sol = solve(mdp, hypotheses.theta, hypotheses.beta, **solve_kwargs)
        return cls.from_log_policy(hypotheses, sol.log_policy, prior=prior)

    @classmethod
    def from_log_policy(
        cls, hypotheses: HypothesisSet, log_policy: np.ndarray, *, prior: np.ndarray | None = None
    ) -> DiscreteBelief:
        """A belief on log-policies already solved, e.g. a cached ``solve(...).log_policy``.

        Args:
            hypotheses: the set Ψ = Θ × B, H = len(hypotheses).
            log_policy: ``[H, S, A]`` log π_h(a|s).
            prior: ``[H]`` prior weights, finite and non-negative with a positive total (normalised
                here); uniform when None.

        Returns:
            The belief before any observation.

        Raises:
            ArgumentError: ``log_policy`` of the wrong shape.
            InputError: ``log_policy`` holds NaN or a value above 0, or a bad prior.
        """
        H = len(hypotheses)
        log_policy = np.asarray(log_policy, dtype=np.float64)
        if log_policy.ndim != 3 or log_policy.shape[0] != H:
            raise ArgumentError(f"log_policy must have shape [H={H}, S, A], got {log_policy.shape}")
        if np.isnan(log_policy).any() or (log_policy > 1e-9).any():
            raise InputError("log_policy must hold log-probabilities (no NaN, none above 0)")
        if prior is None:
            log_prior = np.full(H, -np.log(H))
        else:
            prior = np.asarray(prior, dtype=np.float64)
            if prior.shape != (H,) or np.any(prior < 0) or not np.all(np.isfinite(prior)):
                raise InputError(f"prior must be {H} finite non-negative weights")
            if prior.sum() <= 0:
                raise InputError("prior must have positive total weight")
            with np.errstate(divide="ignore"):
                log_prior = np.log(prior / prior.sum())
        return cls(hypotheses, log_policy, log_prior, np.zeros(H), 0)

    # ----------------------------------------------------------------- updates
    def update_pairs(self, states, actions, *, episode: int | None = None) -> DiscreteBelief:
        """Condition on (state, action) pairs (one trajectory or any batch of them).

        Args:
            states: ``[N]`` state indices.
            actions: ``[N]`` action indices.
            episode: the episode's label, named in messages.

        Returns:
            The new belief.

        Raises:
            InputError: pairs out of range or of unequal length, or a pair impossible under every
                hypothesis still possible (the message names it).
        """
        label = (lambda i: f"episode {episode} step {i}") if episode is not None else None
        states, actions = check_pairs(self.log_policy, states, actions, label=label)
        total = self.log_likelihood + total_log_likelihood(self.log_policy, states, actions)
        alive = np.isfinite(self.log_prior + total)
        if not alive.any():
            # The step at which the last surviving hypothesis became impossible.
            ll = pair_log_likelihoods(self.log_policy, states, actions)  # [H, N]
            prev_alive = np.isfinite(self.log_prior + self.log_likelihood)
            first_dead = np.argmax(~np.isfinite(ll), axis=1)  # first -inf pair per hypothesis
            t = int(first_dead[prev_alive].max()) if prev_alive.any() else 0
            at = (
                f"episode {episode} step {t}" if episode is not None
                else f"observed pair {self.n_observed + t}"
            )
            raise InputError(
                f"{at}: action {actions[t]} in state {states[t]} is impossible under every hypothesis"
            )
        return replace(self, log_likelihood=total, n_observed=self.n_observed + len(states))

    def update_action(self, state: int, action: int) -> DiscreteBelief:
        """Streaming update with a single observed action.

        Args:
            state: the state index.
            action: the action index.

        Returns:
            The new belief.

        Raises:
            InputError: as :meth:`update_pairs`.
        """
        return self.update_pairs([state], [action])

    def update_trajectory(self, states, actions, *, episode: int | None = None) -> DiscreteBelief:
        """Update with one whole trajectory (Eq. 13).

        Args:
            states: ``[T]`` the trajectory's states.
            actions: ``[T]`` its actions.
            episode: the episode's label, named in messages.

        Returns:
            The new belief.

        Raises:
            InputError: as :meth:`update_pairs`.
        """
        return self.update_pairs(states, actions, episode=episode)

    def update(self, trajs: Trajectories, *, per_action: bool = False) -> DiscreteBelief:
        """Condition on every episode of ``trajs``, one trajectory (or one action) at a time.

        The posterior is the same either way. Without ``per_action`` every pair is counted in
        one pass; only if that leaves no hypothesis possible are the episodes taken one at a
        time, to name the step where the last one became impossible.

        Args:
            trajs: the demonstrations.
            per_action: condition one action at a time.

        Returns:
            The new belief.

        Raises:
            InputError: a pair out of range, or the episode and step where the last possible
                hypothesis became impossible.
        """
        check_pairs(self.log_policy, trajs.state, trajs.action, label=_traj_label(trajs))
        if not per_action and len(trajs):
            total = self.log_likelihood + total_log_likelihood(self.log_policy, trajs.state, trajs.action)
            if np.isfinite(self.log_prior + total).any():
                return replace(self, log_likelihood=total, n_observed=self.n_observed + len(trajs))
        b = self
        for e, (states, actions) in zip(trajs.episode_ids, trajs.episodes(), strict=True):
            if per_action:
                for t, (s, a) in enumerate(zip(states.tolist(), actions.tolist(), strict=True)):
                    try:
                        b = b.update_action(s, a)
                    except InputError:
                        raise InputError(
                            f"episode {e} step {t}: action {a} in state {s} is impossible "
                            "under every hypothesis"
                        ) from None
            else:
                b = b.update_trajectory(states, actions, episode=int(e))
        return b

    # -------------------------------------------------------------- posterior
    @property
    def log_evidence(self) -> float:
        """log P(Ξ) = log Σ_h P(Ξ | h) P(h): the model evidence of everything observed (nats).

        Comparing it across observation models (or hypothesis sets) on the same
        demonstrations gives their Bayes factors; −∞ if no hypothesis can produce them.
        """
        from scipy.special import logsumexp

        return float(logsumexp(self.log_prior + self.log_likelihood))

    @cached_property
    def summary(self) -> Summary:
        """The posterior and its marginals, means, group masses and entropy (see :func:`summarise`)."""
        return summarise(self.log_prior + self.log_likelihood, self.hypotheses)

    @property
    def log_posterior(self) -> np.ndarray:
        """``[H]`` normalised log posterior."""
        return self.summary.log_probabilities.copy()

    @property
    def probabilities(self) -> np.ndarray:
        """``[H]`` posterior probabilities."""
        return self.summary.probabilities.copy()

    @property
    def n_impossible(self) -> int:
        """Hypotheses with log-likelihood −∞ (they cannot produce some observed action)."""
        return int(np.sum(np.isneginf(self.log_likelihood)))

    def marginal_beta(self) -> tuple[np.ndarray, np.ndarray]:
        """``(betas [n_beta], P(β) [n_beta])``."""
        return self.hypotheses.betas.copy(), self.summary.beta_marginal.copy()

    def marginal_theta(self) -> tuple[np.ndarray, np.ndarray]:
        """``(thetas [n_theta, K], P(θ) [n_theta])``."""
        return self.hypotheses.thetas.copy(), self.summary.theta_marginal.copy()

    @property
    def mean_beta(self) -> float:
        """β̂ = E[β] (the paper's point estimate)."""
        return float(self.summary.mean_beta)

    @property
    def mean_theta(self) -> np.ndarray:
        """θ̂ = E[θ], ``[K]`` (unit l1 norm, as every hypothesis θ is)."""
        return self.summary.mean_theta.copy()

    def map_hypothesis(self) -> tuple[np.ndarray, float, float]:
        """``(θ, β, probability)`` of the most probable hypothesis."""
        h = int(np.argmax(self.log_posterior))
        return self.hypotheses.theta[h], float(self.hypotheses.beta[h]), float(self.probabilities[h])

    @property
    def entropy(self) -> float:
        """Posterior entropy in nats."""
        return float(self.summary.entropy)

    def group_probabilities(self) -> dict[str, float]:
        """Posterior mass on each expertise group (high / medium / low)."""
        return self.summary.groups()

    def trace(self, trajs: Trajectories, *, truth: int | None = None, max_block: int = 2**24) -> Trace:
        """Live estimates after each action of ``trajs``, in order (see :class:`Trace`).

        E[β], E[θ], entropy, expertise-group probabilities and the 90% band of the β
        marginal. Equivalent to streaming :meth:`update_action` over every pair, but
        vectorised.

        Args:
            trajs: the demonstrations, after everything this belief has observed.
            truth: the index of the true hypothesis, whose probability is traced (NaN without it).
            max_block: bounds the ``H × pairs`` block held in memory at once.

        Returns:
            The estimates, index 0 before the first action of ``trajs``.

        Raises:
            InputError: a pair out of range, or one impossible under every hypothesis.
        """
        states, actions = check_pairs(self.log_policy, trajs.state, trajs.action, label=_traj_label(trajs))
        H, N = len(self.hypotheses), len(states)
        parts = [self._trace_part(np.asarray(self.log_prior + self.log_likelihood)[:, None], truth)]
        running = self.log_prior + self.log_likelihood
        block = max(1, max_block // max(H, 1))
        for start in range(0, N, block):
            stop = min(N, start + block)
            ll = pair_log_likelihoods(self.log_policy, states[start:stop], actions[start:stop])
            cum = running[:, None] + np.cumsum(ll, axis=1)
            if not np.isfinite(cum[:, -1]).any():
                t = start + int(np.argmax(~np.isfinite(cum).any(axis=0)))
                raise InputError(
                    f"episode {trajs.episode[t]} step {trajs.step[t]}: action {actions[t]} in "
                    f"state {states[t]} is impossible under every hypothesis"
                )
            parts.append(self._trace_part(cum, truth))
            running = cum[:, -1]
        return Trace(*(np.concatenate(column) for column in zip(*parts, strict=True)))

    def _trace_part(self, logw: np.ndarray, truth: int | None) -> Trace:
        """The :class:`Trace` rows of log-weights ``logw [H, n]`` (one column per point in time)."""
        s = summarise(logw, self.hypotheses)
        betas = self.hypotheses.betas
        tp = s.probabilities[truth] if truth is not None else np.full(logw.shape[1], np.nan)
        lo, hi = (beta_quantile(betas, s.beta_marginal, q) for q in TRACE_BAND)
        return Trace(s.mean_beta, s.mean_theta, s.entropy, tp, s.group_probabilities.T, lo, hi)
