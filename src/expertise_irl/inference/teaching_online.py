"""Online (per-action) estimation under the teaching model (``--model pedagogical``).

:class:`TeachingOnlineEstimator` is an :class:`~expertise_irl.inference.online.OnlineEstimator` whose
likelihood is the teacher's (:mod:`~expertise_irl.inference.pedagogical`): it keeps the ``[L, H]``
log-likelihood sums log P(pairs | h, λ) for every λ of the grid and hypothesis h of a fixed set, and
its belief over Ψ is the teaching model's exact posterior with λ marginalised under its prior
(:meth:`~expertise_irl.inference.pedagogical.TeachingPosterior.belief`).

A new pair adds one ``[L, H]`` row. The literal observer's informativeness I_θ(s, a) depends only
on the state, the set and its prior, so the row is the teacher's log-policy at the pair's state
alone (:func:`~expertise_irl.inference.pedagogical.teaching_log_likelihoods` on that one state): an
action costs a few milliseconds however many were observed before, where recomputing
:func:`~expertise_irl.inference.pedagogical.teaching_posterior` from every pair grows with the number
of distinct states visited. The sums agree with that batch posterior to round-off (the same terms,
added in another order).

Everything else (the episodes, :meth:`~OnlineEstimator.undo`, the estimate after every action, the
active start choice that reads :meth:`~OnlineEstimator.belief`) is the parent's, over the λ-marginal
belief.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InputError
from ..hypotheses import HypothesisSet
from ..mdp import TabularMDP
from .online import Estimate, OnlineEstimator
from .pedagogical import LAMBDAS, TeachingPosterior, observer, parse_lambdas, teaching_log_likelihoods


class TeachingOnlineEstimator(OnlineEstimator):
    """The teaching model's posterior over a fixed set Ψ × Λ, updated after every action.

    Args:
        mdp: the task.
        hypotheses: the fixed set Ψ = Θ × B (the literal observer's and the inference's).
        log_policy: ``[H, S, A]`` the hypotheses' ``maxent`` log-policies; solved on ``mdp`` when None.
        lambdas: the λ grid (:func:`~expertise_irl.inference.pedagogical.parse_lambdas`).
        prior: ``[H]`` prior probabilities over Ψ (uniform by default); the observer's too.
        progress: as in :meth:`OnlineEstimator.from_mdp`; only when ``log_policy`` is None.
        **solve_kwargs: options of :func:`~expertise_irl.planning.soft_vi.solve`; only when
            ``log_policy`` is None (``model`` is not one of them: the teacher reweights ``maxent``).

    Attributes:
        mdp: the task.
        hypotheses: the set Ψ.
        lambdas: ``[L]`` the λ grid (``lambdas[0] == 0``).

    Raises:
        InputError: a bad λ grid, a ``model`` among the solver options, or as
            :class:`~expertise_irl.inference.online.OnlineEstimator`.
    """

    def __init__(self, mdp: TabularMDP, hypotheses: HypothesisSet, log_policy: np.ndarray | None = None, *,
                 lambdas=LAMBDAS, prior: np.ndarray | None = None,
                 progress: Callable[[int, int], None] | bool | None = None, **solve_kwargs) -> None:
        lam = parse_lambdas(lambdas)
        if solve_kwargs.get("model", "maxent") != "maxent":
            raise InputError(f"the teaching model reweights maxent's policies, not {solve_kwargs['model']}'s")
        self.lambdas = lam
        self._ll_lambda = np.zeros((len(lam), len(hypotheses)))
        super().__init__(mdp, hypotheses, log_policy, prior=prior, progress=progress, **solve_kwargs)

    @classmethod
    def from_mdp(cls, mdp: TabularMDP, hypotheses: HypothesisSet, *, lambdas=LAMBDAS,
                 prior: np.ndarray | None = None, progress: Callable[[int, int], None] | bool | None = None,
                 **solve_kwargs) -> TeachingOnlineEstimator:
        """Solve every hypothesis on ``mdp`` (``maxent``, once for every λ) and start from ``prior``.

        Args:
            mdp: the task.
            hypotheses: the fixed set Ψ = Θ × B.
            lambdas: the λ grid.
            prior: ``[H]`` prior probabilities over Ψ.
            progress: ``progress(done, total)`` as batches of hypotheses finish, or True for a bar.
            **solve_kwargs: options of :func:`~expertise_irl.planning.soft_vi.solve`.

        Returns:
            The estimator, with nothing observed.
        """
        return cls(mdp, hypotheses, None, lambdas=lambdas, prior=prior, progress=progress, **solve_kwargs)

    # ---------------------------------------------------------------- the likelihood
    def pair_log_likelihood(self, state: int, action: int) -> np.ndarray:
        """``[L, H]`` log π_show(action | state) of every teacher (λ, h), before the literal observer.

        Args:
            state: the state index.
            action: the action index.

        Returns:
            The row that observing the pair adds to the sums.
        """
        lp = np.ascontiguousarray(np.transpose(self._table[state], (1, 0)))[:, None, :]  # [H, 1, A]
        obs = observer(self.hypotheses, lp, self._log_prior)
        counts = np.zeros((1, lp.shape[2]))
        counts[0, action] = 1.0
        return teaching_log_likelihoods(obs, lp, counts, self.lambdas)

    def _marginal(self, ll_lambda: np.ndarray) -> np.ndarray:
        return self._posterior(ll_lambda, len(self._pairs)).marginal_log_likelihood

    def _posterior(self, ll_lambda: np.ndarray, n: int) -> TeachingPosterior:
        return TeachingPosterior(self.hypotheses, self.lambdas, self._log_prior, ll_lambda, n)

    def _observe(self, state: int, action: int, label: tuple[int, int] | None) -> Estimate:
        why = self.check(state, action)
        if why is not None:
            raise InputError(why)
        ll_lambda = self._ll_lambda + self.pair_log_likelihood(state, action)
        if not np.isfinite(self._log_prior + ll_lambda[0]).any():  # λ > 0 keeps λ = 0's support
            raise InputError(f"action {action} in {self.mdp.describe_state(state)} is impossible under "
                             "every hypothesis")
        e, t = self._next_label() if label is None else label
        self._ll_lambda = ll_lambda
        self._ll = self._marginal(ll_lambda)
        self._pairs.append((e, t, state, action))
        self._open = not bool(self.mdp.terminal[self.mdp.next_state[state, action]])
        self._estimate = self._summarise()
        return self._estimate

    def _recompute(self) -> np.ndarray:
        ll_lambda = np.zeros_like(self._ll_lambda)
        for _, _, s, a in self._pairs:  # the same sequential sums as _observe()
            ll_lambda = ll_lambda + self.pair_log_likelihood(s, a)
        self._ll_lambda = ll_lambda
        return self._marginal(ll_lambda)

    def restore(self, snap) -> Estimate:
        """Return to the state of ``snap`` (from an estimator on the same MDP, set and grid).

        Args:
            snap: as :meth:`OnlineEstimator.restore`.

        Returns:
            The estimate after everything the snapshot observed.

        Raises:
            InputError: as :meth:`OnlineEstimator.restore` (and nothing changes).
        """
        super().restore(snap)  # checks and replays the pairs (maxent's sums; nothing changes if it raises)
        self._ll = self._recompute()  # the teaching model's sums of the same pairs
        self._estimate = self._summarise()
        return self._estimate

    # ---------------------------------------------------------------- summaries
    def posterior(self) -> TeachingPosterior:
        """The teaching model's posterior over Ψ × Λ of everything observed (its ``record`` is the
        result's ``teaching`` entry)."""
        return self._posterior(self._ll_lambda.copy(), len(self._pairs))

    def record(self) -> dict:
        """The result's ``teaching`` entry (:meth:`~.pedagogical.TeachingPosterior.record`).

        Returns:
            The verdict, λ̂ and its interval, the λ posterior, β̂ and θ̂ under ``maxent`` (λ = 0).
        """
        return self.posterior().record(np.transpose(self._table, (2, 0, 1)))
