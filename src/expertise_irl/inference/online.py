"""Online (per-action) estimation over a discrete hypothesis set (paper footnote 1).

:class:`OnlineEstimator` solves every hypothesis once, then keeps the running
log-likelihood of each. Observing an action is a gather of one row of the
log-policy table (stored ``[S, A, H]`` so the row is contiguous) and one
log-sum-exp over hypotheses; the estimate that comes back (β̂, θ̂, the β
marginal, the expertise-group probabilities, the entropy, the MAP hypothesis) is
the one :class:`~expertise_irl.inference.belief.DiscreteBelief` gives for the same
pairs, after every action.

The estimator also keeps the observed pairs, so it knows the episodes:
an episode ends on entering a terminal state or when :meth:`OnlineEstimator.end_episode`
is called, and within an episode each state must follow from the previous pair
(the rules of :func:`~expertise_irl.demos.trajectories.validate`). :meth:`~OnlineEstimator.undo`
takes back the last action; :meth:`~OnlineEstimator.snapshot` and
:meth:`~OnlineEstimator.restore` save and restore the whole state.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import ArgumentError, InputError
from ..hypotheses import HypothesisSet, expertise_group
from ..mdp import TabularMDP
from .belief import DiscreteBelief
from .posterior import summarise


class GroupProbabilities(dict):
    """``{"high": p, "medium": p, "low": p}``; also callable (returning itself), so code written for
    :meth:`DiscreteBelief.group_probabilities` works unchanged."""

    def __call__(self) -> GroupProbabilities:
        return self


class Estimate(NamedTuple):
    """The posterior summary after some number of observed actions.

    Attributes:
        n_observed: actions observed so far.
        beta_hat: E[β].
        theta_hat: ``[K]`` E[θ].
        beta_values: ``[n_beta]`` the temperatures of the set, as given.
        beta_probabilities: ``[n_beta]`` the β marginal P(β).
        group_probabilities: ``{"high": p, "medium": p, "low": p}``.
        entropy: posterior entropy over all hypotheses (nats).
        map_theta, map_beta, map_probability: the most probable hypothesis and its probability.
        map_index: its flat index in the hypothesis set.
    """

    n_observed: int
    beta_hat: float
    theta_hat: np.ndarray
    beta_values: np.ndarray
    beta_probabilities: np.ndarray
    group_probabilities: dict[str, float]
    entropy: float
    map_theta: np.ndarray
    map_beta: float
    map_probability: float
    map_index: int

    @property
    def mean_beta(self) -> float:
        """β̂ (the name :class:`DiscreteBelief` uses)."""
        return self.beta_hat

    @property
    def mean_theta(self) -> np.ndarray:
        """θ̂ (the name :class:`DiscreteBelief` uses)."""
        return self.theta_hat

    def map_hypothesis(self) -> tuple[np.ndarray, float, float]:
        """``(θ, β, probability)`` of the most probable hypothesis (as in :class:`DiscreteBelief`)."""
        return self.map_theta, self.map_beta, self.map_probability

    @property
    def expertise_group(self) -> str:
        """The group of β̂ (high / medium / low)."""
        return expertise_group(self.beta_hat)

    def to_dict(self, feature_names=None) -> dict[str, Any]:
        """JSON-ready form (plain floats and lists)."""
        names = list(feature_names) if feature_names is not None else None
        return {
            "n_observed": self.n_observed,
            "beta_hat": self.beta_hat,
            "expertise_group": self.expertise_group,
            "theta_hat": [float(x) for x in self.theta_hat],
            "feature_names": names,
            "beta_values": [float(x) for x in self.beta_values],
            "beta_probabilities": [float(x) for x in self.beta_probabilities],
            "group_probabilities": dict(self.group_probabilities),
            "entropy": self.entropy,
            "map": {"theta": [float(x) for x in self.map_theta], "beta": self.map_beta,
                    "probability": self.map_probability},
        }


@dataclass(frozen=True, eq=False)
class OnlineSnapshot:
    """Everything an :class:`OnlineEstimator` has observed (``[N]`` int64 arrays) and whether its
    last episode is still open. The log-likelihoods are recomputed from the pairs on restore,
    so a snapshot can never disagree with its estimator's tables."""

    episode: np.ndarray
    step: np.ndarray
    state: np.ndarray
    action: np.ndarray
    episode_open: bool
    n_hypotheses: int
    n_states: int
    n_actions: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form; :meth:`from_dict` reads it back."""
        return {"episode": self.episode.tolist(), "step": self.step.tolist(),
                "state": self.state.tolist(), "action": self.action.tolist(),
                "episode_open": bool(self.episode_open), "n_hypotheses": self.n_hypotheses,
                "n_states": self.n_states, "n_actions": self.n_actions}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> OnlineSnapshot:
        keys = ("episode", "step", "state", "action", "episode_open", "n_hypotheses", "n_states",
                "n_actions")
        if not isinstance(doc, dict) or any(k not in doc for k in keys):
            raise InputError(f"snapshot must be a mapping with keys {', '.join(keys)}")
        try:
            arrays = [np.asarray(doc[k], dtype=np.int64).reshape(-1) for k in keys[:4]]
            sizes = [int(doc[k]) for k in keys[5:]]
        except (TypeError, ValueError):
            raise InputError("snapshot: episode, step, state, action must be integer lists") from None
        return cls(*arrays, bool(doc["episode_open"]), *sizes)


def _solve(mdp: TabularMDP, hypotheses: HypothesisSet, progress, solve_kwargs) -> np.ndarray:
    from ..planning.soft_vi import solve

    if progress is True:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        cols = (TextColumn("solving soft value iteration"), BarColumn(), MofNCompleteColumn(),
                TextColumn("hypotheses"), TimeRemainingColumn())
        with Progress(*cols, console=Console(stderr=True)) as bar:
            task = bar.add_task("solve", total=len(hypotheses))
            return solve(mdp, hypotheses.theta, hypotheses.beta,
                         progress=lambda done, total: bar.update(task, completed=done, total=total),
                         **solve_kwargs).log_policy
    cb = progress if callable(progress) else None
    return solve(mdp, hypotheses.theta, hypotheses.beta, progress=cb, **solve_kwargs).log_policy


class OnlineEstimator:
    """A live estimate of (θ, β) that is updated after every observed action.

    Build it with :meth:`from_mdp` (solves every hypothesis; pass ``progress`` to see the
    solve) or :meth:`from_belief`. Then call :meth:`observe` for each action; it returns the
    new :class:`Estimate`. Per action the work is ``O(H)``: a contiguous gather of
    ``log π_h(a|s)`` for all H hypotheses and a log-sum-exp over them.

    Args:
        mdp: the task.
        hypotheses: the set Ψ = Θ × B, with the MDP's features.
        log_policy: ``[H, S, A]`` the hypotheses' log-policies; solved on ``mdp`` when None.
        prior: ``[H]`` prior probabilities (uniform by default).
        progress: as in :meth:`from_mdp`; only when ``log_policy`` is None.
        **solve_kwargs: options of :func:`~expertise_irl.planning.soft_vi.solve`; only when
            ``log_policy`` is None.

    Attributes:
        mdp: the task.
        hypotheses: the set Ψ = Θ × B.

    Raises:
        InputError: the hypotheses' features do not match the MDP's, solver options given with a
            ``log_policy``, or a bad table or prior.
        ArgumentError: ``log_policy`` of the wrong shape.
    """

    def __init__(self, mdp: TabularMDP, hypotheses: HypothesisSet, log_policy: np.ndarray | None = None, *,
                 prior: np.ndarray | None = None,
                 progress: Callable[[int, int], None] | bool | None = None, **solve_kwargs) -> None:
        H = len(hypotheses)
        if hypotheses.thetas.shape[1] != mdp.n_features:
            raise InputError(
                f"hypotheses have {hypotheses.thetas.shape[1]} features but the MDP has "
                f"{mdp.n_features} ({', '.join(mdp.feature_names)})"
            )
        if log_policy is None:
            log_policy = _solve(mdp, hypotheses, progress, solve_kwargs)
        elif solve_kwargs or progress:
            raise InputError("progress and solver options apply only when log_policy is not given")
        lp = np.asarray(log_policy, dtype=np.float64)
        if lp.shape != (H, mdp.n_states, mdp.n_actions):
            raise ArgumentError(
                f"log_policy must have shape [H, S, A] = [{H}, {mdp.n_states}, {mdp.n_actions}], "
                f"got {lp.shape}"
            )
        base = DiscreteBelief.from_log_policy(hypotheses, lp, prior=prior)  # validates table and prior
        self.mdp = mdp
        self.hypotheses = hypotheses
        # [S, A, H]: the H log-probabilities of one (s, a) lie next to each other.
        self._table = np.ascontiguousarray(np.transpose(lp, (1, 2, 0)))
        self._log_prior = base.log_prior
        self._ll = np.zeros(len(hypotheses))
        self._pairs: list[tuple[int, int, int, int]] = []  # (episode, step, state, action)
        self._open = False  # the last episode can take more actions
        self._estimate = self._summarise()

    # ------------------------------------------------------------ construction
    @classmethod
    def from_mdp(cls, mdp: TabularMDP, hypotheses: HypothesisSet, *, prior: np.ndarray | None = None,
                 progress: Callable[[int, int], None] | bool | None = None,
                 **solve_kwargs) -> OnlineEstimator:
        """Solve every hypothesis on ``mdp`` and start from ``prior`` (uniform by default).

        ``OnlineEstimator(mdp, hypotheses, progress=...)`` does the same.

        Args:
            mdp: the task.
            hypotheses: the set Ψ = Θ × B.
            prior: ``[H]`` prior probabilities.
            progress: ``progress(done, total)``, called as batches of hypotheses finish, or True for a
                progress bar on stderr.
            **solve_kwargs: options of :func:`~expertise_irl.planning.soft_vi.solve`.

        Returns:
            The estimator, with nothing observed.
        """
        return cls(mdp, hypotheses, None, prior=prior, progress=progress, **solve_kwargs)

    @classmethod
    def from_belief(cls, mdp: TabularMDP, belief: DiscreteBelief) -> OnlineEstimator:
        """An estimator on ``belief``'s tables and prior (what it has observed is not carried over).

        Args:
            mdp: the task ``belief`` was solved on.
            belief: the belief whose hypotheses, log-policies and prior are taken.

        Returns:
            The estimator, with nothing observed.
        """
        return cls(mdp, belief.hypotheses, belief.log_policy, prior=np.exp(belief.log_prior))

    # ---------------------------------------------------------------- observing
    @property
    def n_observed(self) -> int:
        return len(self._pairs)

    @property
    def episode_open(self) -> bool:
        """Whether the last episode can take more actions (it has not ended)."""
        return self._open

    @property
    def current_state(self) -> int | None:
        """The state the open episode is in (where its last action led), else None."""
        if not self._open:
            return None
        _, _, s, a = self._pairs[-1]
        return int(self.mdp.next_state[s, a])

    @property
    def n_episodes(self) -> int:
        return len({p[0] for p in self._pairs})

    def _next_label(self) -> tuple[int, int]:
        if self._open:
            e, t, _, _ = self._pairs[-1]
            return e, t + 1
        return (self._pairs[-1][0] + 1 if self._pairs else 0), 0

    def check(self, state: int, action: int) -> str | None:
        """Why ``(state, action)`` cannot be observed now, or None if it can.

        Args:
            state: the state index.
            action: the action index.

        Returns:
            A one-line reason (out of range, unavailable, from a goal, not where the open episode is),
            or None.
        """
        S, A = self.mdp.n_states, self.mdp.n_actions
        if not (0 <= state < S):
            return f"state {state} is out of range: the MDP has {S} states (0..{S - 1})"
        if not (0 <= action < A):
            return f"action {action} is out of range: the MDP has {A} actions (0..{A - 1})"
        if self.mdp.terminal[state]:
            return f"{self.mdp.describe_state(state)} is terminal (a goal): no action can follow"
        if self.mdp.next_state[state, action] < 0:
            return f"action {action} is not available in {self.mdp.describe_state(state)}"
        here = self.current_state
        if here is not None and state != here:
            return (f"{self.mdp.describe_state(state)} does not follow the last action, which led to "
                    f"{self.mdp.describe_state(here)}; call end_episode() to start a new episode")
        return None

    def observe(self, state: int, action: int) -> Estimate:
        """Condition on one action and return the new estimate.

        Args:
            state: the state the action was taken in.
            action: the action index.

        Returns:
            The estimate after it.

        Raises:
            InputError: (and nothing changes) the pair is out of range, unavailable, acts from a goal,
                does not follow the previous pair of the open episode, or is impossible under every
                hypothesis.
        """
        return self._observe(int(state), int(action), None)

    def _observe(self, state: int, action: int, label: tuple[int, int] | None) -> Estimate:
        why = self.check(state, action)
        if why is not None:
            raise InputError(why)
        ll = self._ll + self._table[state, action]
        if not np.isfinite(self._log_prior + ll).any():
            raise InputError(f"action {action} in {self.mdp.describe_state(state)} is impossible under "
                             "every hypothesis")
        e, t = self._next_label() if label is None else label
        self._ll = ll
        self._pairs.append((e, t, state, action))
        self._open = not bool(self.mdp.terminal[self.mdp.next_state[state, action]])
        self._estimate = self._summarise()
        return self._estimate

    def end_episode(self) -> None:
        """Close the open episode (the next action starts a new one, anywhere)."""
        self._open = False

    def start_episode(self) -> None:
        """Mark an episode boundary: the next action begins a new episode (same as :meth:`end_episode`)."""
        self._open = False

    def undo(self) -> Estimate:
        """Take back the last observed action.

        Its episode stays open at the state that action started from; if it was the episode's
        only action, the episode is gone and no episode is open.

        Returns:
            The estimate without it.

        Raises:
            InputError: no action has been observed.
        """
        if not self._pairs:
            raise InputError("nothing to undo: no action has been observed")
        e, _, _, _ = self._pairs.pop()
        self._ll = self._recompute()
        self._open = bool(self._pairs) and self._pairs[-1][0] == e
        self._estimate = self._summarise()
        return self._estimate

    def _recompute(self) -> np.ndarray:
        ll = np.zeros(len(self.hypotheses))
        for _, _, s, a in self._pairs:  # the same sequential sums as observe()
            ll = ll + self._table[s, a]
        return ll

    @property
    def estimate(self) -> Estimate:
        """The current estimate (the one the last call returned)."""
        return self._estimate

    # ---------------------------------------------------------------- summaries
    def _summarise(self) -> Estimate:
        s = summarise(self._log_prior + self._ll, self.hypotheses)
        h = int(np.argmax(s.log_probabilities))
        return Estimate(
            n_observed=len(self._pairs),
            beta_hat=float(s.mean_beta),
            theta_hat=s.mean_theta,
            beta_values=self.hypotheses.betas.copy(),
            beta_probabilities=s.beta_marginal,
            group_probabilities=GroupProbabilities(s.groups()),
            entropy=float(s.entropy),
            map_theta=self.hypotheses.theta[h],
            map_beta=float(self.hypotheses.beta[h]),
            map_probability=float(s.probabilities[h]),
            map_index=h,
        )

    @property
    def log_likelihood(self) -> np.ndarray:
        """``[H]`` accumulated log-likelihood of everything observed."""
        return self._ll.copy()

    def belief(self) -> DiscreteBelief:
        """The equivalent :class:`DiscreteBelief` (same tables, prior and log-likelihoods)."""
        lp = np.transpose(self._table, (2, 0, 1))  # a view, [H, S, A]
        return DiscreteBelief(self.hypotheses, lp, self._log_prior, self._ll.copy(), len(self._pairs))

    def trajectories(self) -> Trajectories:
        """Everything observed, as :class:`~expertise_irl.demos.trajectories.Trajectories`."""
        if not self._pairs:
            e = np.zeros(0, dtype=np.int64)
            return Trajectories(e, e, e, e)
        ep, st, s, a = (np.array(c, dtype=np.int64) for c in zip(*self._pairs, strict=True))
        return Trajectories(ep, st, s, a)

    # ------------------------------------------------------------ save / restore
    def snapshot(self) -> OnlineSnapshot:
        """Everything needed to :meth:`restore` this estimator's state later."""
        t = self.trajectories()
        return OnlineSnapshot(t.episode.copy(), t.step.copy(), t.state.copy(), t.action.copy(),
                              self._open, len(self.hypotheses), self.mdp.n_states, self.mdp.n_actions)

    def save(self, path) -> None:
        """Write :meth:`snapshot` as JSON to ``path`` (atomically); :meth:`restore` reads it back.

        Args:
            path: the file to write.
        """
        from ..results import write_json

        write_json(path, self.snapshot().to_dict())

    def restore(self, snap) -> Estimate:
        """Return to the state of ``snap`` (from an estimator on the same MDP and set).

        Args:
            snap: an :class:`OnlineSnapshot`, its :meth:`~OnlineSnapshot.to_dict` form, or the path
                of a file written by :meth:`save`.

        Returns:
            The estimate after everything the snapshot observed.

        Raises:
            InputError: no such file, not a snapshot, a snapshot of another set or MDP, or pairs that
                cannot be observed here.
        """
        if isinstance(snap, dict):
            snap = OnlineSnapshot.from_dict(snap)
        elif not isinstance(snap, OnlineSnapshot):
            import json
            from pathlib import Path

            path = Path(snap)
            if not path.is_file():
                raise InputError(f"{path}: no such snapshot file")
            try:
                snap = OnlineSnapshot.from_dict(json.loads(path.read_text(encoding="utf-8")))
            except ValueError as exc:
                raise InputError(f"{path}: not a snapshot ({exc})") from None
        sizes = (len(self.hypotheses), self.mdp.n_states, self.mdp.n_actions)
        if (snap.n_hypotheses, snap.n_states, snap.n_actions) != sizes:
            raise InputError(
                f"snapshot is of {snap.n_hypotheses} hypotheses on {snap.n_states} states × "
                f"{snap.n_actions} actions; this estimator has {sizes[0]} on {sizes[1]} × {sizes[2]}"
            )
        fresh = OnlineEstimator.__new__(OnlineEstimator)
        fresh.__dict__.update(self.__dict__)
        fresh._ll = np.zeros(len(self.hypotheses))
        fresh._pairs = []
        fresh._open = False
        fresh.feed(Trajectories(snap.episode, snap.step, snap.state, snap.action))
        if snap.episode_open and not fresh._open:
            raise InputError("snapshot says its last episode is open, but it ended in a goal")
        fresh._open = bool(snap.episode_open) and bool(fresh._pairs)
        self.__dict__.update(fresh.__dict__)
        self._estimate = self._summarise()
        return self._estimate

    def feed(self, trajs: Trajectories) -> Estimate:
        """Observe every pair of ``trajs`` in order, keeping their episode labels and steps.

        An episode that did not end in a goal is closed when the next one begins, and left open
        if it is the last (so a recording cut short mid-episode can be continued).

        Args:
            trajs: the demonstrations, episodes in increasing label order.

        Returns:
            The estimate after the last pair.

        Raises:
            InputError: episode labels that decrease, a pair after its episode ended, or a pair that
                cannot be observed (as :meth:`observe`); the message names its episode and step.
        """
        for e, t, s, a in zip(trajs.episode.tolist(), trajs.step.tolist(), trajs.state.tolist(),
                              trajs.action.tolist(), strict=True):
            if self._pairs and e != self._pairs[-1][0]:
                self.end_episode()
                if e < self._pairs[-1][0]:
                    raise InputError(f"episode {e}: episode labels must increase "
                                     f"(it follows episode {self._pairs[-1][0]})")
            elif self._pairs and not self._open:
                raise InputError(f"episode {e} step {t}: its episode has already ended")
            try:
                self._observe(s, a, (e, t))
            except InputError as exc:
                raise InputError(f"episode {e} step {t}: {exc}") from None
        return self._estimate
