"""Demonstrations as arrays: the :class:`Trajectories` type and its checks against an MDP."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, where
from ..mdp import ACTION_NAMES, TabularMDP


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Observed (state, action) pairs of one or more episodes, flat and in order.

    The four arrays are ``[N]`` int64, N = number of pairs. An episode's last state (the one its
    last action leads to) is not stored: it is ``mdp.next_state[state[-1], action[-1]]``.

    Attributes:
        episode: episode label of each pair (pairs of one episode are contiguous).
        step: position of the pair within its episode, 0, 1, 2, ...
        state: state index s_t.
        action: action index a_t taken in s_t.

    Raises:
        InputError: the four are not 1-D arrays of equal length.
    """

    episode: np.ndarray
    step: np.ndarray
    state: np.ndarray
    action: np.ndarray

    def __post_init__(self) -> None:
        names = ("episode", "step", "state", "action")
        arrays = [np.asarray(getattr(self, k), dtype=np.int64) for k in names]
        n = arrays[0].shape
        if any(a.ndim != 1 or a.shape != n for a in arrays):
            raise InputError("episode, step, state and action must be 1-D arrays of equal length")
        for k, a in zip(names, arrays, strict=True):
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
        """The first ``n_episodes`` episodes.

        Args:
            n_episodes: how many, in the order the episodes appear.

        Returns:
            Their pairs (all of them when there are fewer episodes).
        """
        keep = np.isin(self.episode, self.episode_ids[:n_episodes])
        return Trajectories(self.episode[keep], self.step[keep], self.state[keep], self.action[keep])

    def paths(self, mdp: TabularMDP) -> list[np.ndarray]:
        """Visited states of each episode, including the state its last action leads to.

        Args:
            mdp: the task the pairs belong to.

        Returns:
            One array of state indices per episode, in episode order.
        """
        out = []
        for states, actions in self.episodes():
            last = mdp.next_state[states[-1], actions[-1]] if len(states) else None
            out.append(np.append(states, last) if last is not None else states)
        return out


# ---------------------------------------------------------------------------- validation
def _action_label(mdp: TabularMDP, a: int) -> str:
    if mdp.n_actions == len(ACTION_NAMES) and mdp.state_xy is not None and 0 <= a < mdp.n_actions:
        return f"action {a} ({ACTION_NAMES[a]})"
    return f"action {a}"


def structure_error(episode: np.ndarray, step: np.ndarray) -> tuple[int, str] | None:
    """First row whose episode is not contiguous or whose step is not the next one."""
    n = episode.size
    if n == 0:
        return None
    new = np.ones(n, dtype=bool)
    new[1:] = episode[1:] != episode[:-1]
    run_start = np.flatnonzero(new)
    run_of = np.cumsum(new) - 1
    _, first_run = np.unique(episode[run_start], return_index=True)
    repeated = np.ones(run_start.size, dtype=bool)
    repeated[first_run] = False
    bad_dup = new & repeated[run_of]
    expected = np.arange(n) - run_start[run_of]
    bad = bad_dup | (step != expected)
    if not bad.any():
        return None
    i = int(np.flatnonzero(bad)[0])
    if bad_dup[i]:
        msg = ("episode appears again after other episodes; the rows of one episode must be "
               "contiguous (sort the file by episode, then step)")
    elif expected[i] == 0:
        msg = f"episode starts at step {step[i]}, expected step 0 (sort the file by episode, then step)"
    else:
        msg = f"step {step[i]} follows step {step[i - 1]}; steps must be consecutive 0, 1, 2, ..."
    return i, msg


def _pair_error(mdp: TabularMDP, tr: Trajectories) -> tuple[int, str] | None:
    """First pair that is out of range or impossible in the MDP, with the reason."""
    S, A = mdp.n_states, mdp.n_actions
    s, a = tr.state, tr.action
    bad_s = (s < 0) | (s >= S)
    bad_a = (a < 0) | (a >= A)
    sc, ac = np.clip(s, 0, S - 1), np.clip(a, 0, A - 1)
    nxt = mdp.next_state[sc, ac]
    follows = np.zeros(s.size, dtype=bool)
    follows[1:] = (tr.episode[1:] == tr.episode[:-1]) & (nxt[:-1] != s[1:])
    term = mdp.terminal[sc]
    unavail = nxt < 0
    bad = bad_s | bad_a | follows | term | unavail
    if not bad.any():
        return None
    i = int(np.flatnonzero(bad)[0])
    si, ai = int(s[i]), int(a[i])
    if bad_s[i]:
        return i, f"state {si} is out of range: the MDP has {S} states (0..{S - 1})"
    if bad_a[i]:
        return i, f"action {ai} is out of range: the MDP has {A} actions (0..{A - 1})"
    if follows[i]:
        p, pa = int(s[i - 1]), int(a[i - 1])
        return i, (
            f"{mdp.describe_state(si)} does not follow from {mdp.describe_state(p)} by "
            f"{_action_label(mdp, pa)}: expected {mdp.describe_state(int(nxt[i - 1]))}"
        )
    if term[i] and (i == 0 or tr.episode[i] != tr.episode[i - 1]):
        return i, (
            f"starts in {mdp.describe_state(si)}, which is terminal (a goal): "
            "an episode must start outside every goal"
        )
    if term[i]:
        return i, (
            f"acts from {mdp.describe_state(si)}, which is terminal (a goal): "
            "the demonstration continues after the episode ended"
        )
    return i, f"{_action_label(mdp, ai)} is not available in {mdp.describe_state(si)}"


def validate_rows(
    tr: Trajectories,
    mdp: TabularMDP,
    source,
    lines: np.ndarray | None = None,
    shown_step: np.ndarray | None = None,
    source_lines: np.ndarray | None = None,
) -> None:
    """Raise on the first bad pair; ``lines``/``shown_step`` locate a pair (by default its own
    row), ``source_lines`` the row of the state it starts from (they differ for the grid format)."""
    source_lines = lines if source_lines is None else source_lines
    steps = tr.step if shown_step is None else shown_step
    for err in (structure_error(tr.episode, tr.step), _pair_error(mdp, tr)):
        if err is not None:
            i, msg = err
            if msg.startswith("starts in "):  # the first cell is at fault, not the move out of it
                line = None if source_lines is None else int(source_lines[i])
                step = tr.step[i]
            else:
                line = None if lines is None else int(lines[i])
                step = steps[i]
            raise InputError(f"{where(source, line)}episode {tr.episode[i]} step {step}: {msg}")


def validate(trajs: Trajectories, mdp: TabularMDP, source: str | Path | None = None) -> None:
    """Check that demonstrations are well formed and possible in ``mdp``.

    Checks, in order of the pairs: the rows of each episode are contiguous and their
    steps run 0, 1, 2, ...; states and actions are in range; each action is available
    in its state; each state follows from the previous pair by ``mdp.next_state``; no
    pair acts from a terminal state. The last pair of an episode may lead anywhere
    (episodes may be truncated before the goal).

    Parameters
    ----------
    trajs : Trajectories
        ``[N]`` pairs to check.
    mdp : TabularMDP
        The task they were recorded in.
    source : str or Path, optional
        Prefix for messages (e.g. a file name).

    Raises
    ------
    InputError
        One line naming the episode and step, e.g.
        ``"episode 3 step 5: action 2 (left) is not available in state 12 (cell x=0, y=3)"``.
    """
    validate_rows(trajs, mdp, source)
