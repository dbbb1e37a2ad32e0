"""Demonstrations: the Trajectories type, a simulated human, and CSV I/O (DESIGN §2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .mdp import TabularMDP


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Observed (state, action) pairs of one or more episodes, flat and in order.

    Attributes (all ``[N]`` int64, N = number of pairs):
        episode: episode label of each pair (pairs of one episode are contiguous).
        step: position of the pair within its episode, 0, 1, 2, ...
        state: state index s_t.
        action: action index a_t taken in s_t.

    An episode's last state (the one its last action leads to) is not stored: it is
    ``mdp.next_state[state[-1], action[-1]]``.
    """

    episode: np.ndarray
    step: np.ndarray
    state: np.ndarray
    action: np.ndarray

    def __post_init__(self) -> None:
        arrays = [np.asarray(getattr(self, k), dtype=np.int64) for k in ("episode", "step", "state", "action")]
        n = arrays[0].shape
        if any(a.ndim != 1 or a.shape != n for a in arrays):
            raise InputError("episode, step, state and action must be 1-D arrays of equal length")
        for k, a in zip(("episode", "step", "state", "action"), arrays, strict=True):
            a.setflags(write=False)
            object.__setattr__(self, k, a)

    def __len__(self) -> int:
        return int(self.state.shape[0])

    @property
    def episode_ids(self) -> np.ndarray:
        """Episode labels in order of first appearance."""
        _, first = np.unique(self.episode, return_index=True)
        return self.episode[np.sort(first)]

    @property
    def n_episodes(self) -> int:
        return int(self.episode_ids.size)

    def episodes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """``[(states, actions), ...]`` one pair of arrays per episode, in order."""
        return [(self.state[self.episode == e], self.action[self.episode == e]) for e in self.episode_ids]

    def first(self, n_episodes: int) -> Trajectories:
        """The first ``n_episodes`` episodes."""
        keep = np.isin(self.episode, self.episode_ids[:n_episodes])
        return Trajectories(self.episode[keep], self.step[keep], self.state[keep], self.action[keep])

    def paths(self, mdp: TabularMDP) -> list[np.ndarray]:
        """Visited states of each episode, including the state its last action leads to."""
        out = []
        for states, actions in self.episodes():
            last = mdp.next_state[states[-1], actions[-1]] if len(states) else None
            out.append(np.append(states, last) if last is not None else states)
        return out
