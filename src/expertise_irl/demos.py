"""Demonstrations: the Trajectories type, a simulated human, and CSV I/O (formats in the README)."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .csv_rows import read_rows
from .errors import InputError, where
from .mdp import TabularMDP
from .models import DEFAULT_MODEL, check_model
from .planning import solve
from .worlds.zones import ACTION_DELTAS, ACTION_NAMES


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


# ---------------------------------------------------------------------------- simulation
DEFAULT_MAX_STEPS = 500


def _check_hypothesis(mdp: TabularMDP, theta, beta) -> tuple[np.ndarray, float]:
    th = np.asarray(theta, dtype=np.float64)
    if th.shape != (mdp.n_features,):
        raise InputError(
            f"theta must have shape [K] with K = {mdp.n_features} features "
            f"({', '.join(mdp.feature_names)}), got shape {th.shape}"
        )
    if not np.all(np.isfinite(th)) or np.any(th < 0):
        raise InputError(f"theta must be finite and non-negative, got {th.tolist()}")
    b = np.asarray(beta, dtype=np.float64)
    if b.shape != () or not np.isfinite(b) or b <= 0:
        raise InputError(f"beta must be a single finite number > 0, got {beta!r}")
    return th, float(b)


def _check_log_policy(mdp: TabularMDP, log_policy) -> np.ndarray:
    lp = np.asarray(log_policy, dtype=np.float64)
    S, A = mdp.n_states, mdp.n_actions
    if lp.shape != (S, A):
        raise InputError(f"log_policy must have shape [S, A] = [{S}, {A}], got {lp.shape}")
    pi = np.exp(lp)
    if np.isnan(pi).any() or np.any(pi[~mdp.available] > 0):
        raise InputError("log_policy must be -inf on unavailable actions and contain no NaN")
    row = pi.sum(axis=1)
    bad = ~mdp.terminal & ~(np.abs(row - 1.0) <= 1e-6)
    if bad.any():
        s = int(np.flatnonzero(bad)[0])
        raise InputError(f"log_policy of {mdp.describe_state(s)} sums to {row[s]:.6g}, not 1")
    return lp


def check_start_states(mdp: TabularMDP, starts, what: str = "starts") -> np.ndarray:
    """``starts`` as an int array of non-terminal states (default: ``mdp.initial_states()``).

    :class:`InputError` named after ``what`` for an empty list, a non-integer, an index out of
    range or a terminal state.
    """
    if starts is None:
        return np.asarray(mdp.initial_states(), dtype=np.int64)
    st = np.atleast_1d(np.asarray(starts))
    if st.ndim != 1 or st.size == 0 or not np.issubdtype(st.dtype, np.integer):
        raise InputError(f"{what} must be a non-empty 1-D array of state indices")
    st = st.astype(np.int64)
    out = (st < 0) | (st >= mdp.n_states)
    if out.any():
        raise InputError(f"{what}: {int(st[out][0])} is not a state index in [0, {mdp.n_states})")
    term = mdp.terminal[st]
    if term.any():
        raise InputError(f"{what}: {mdp.describe_state(int(st[term][0]))} is terminal (a goal)")
    return st


def simulate(
    mdp: TabularMDP,
    theta,
    beta,
    n_episodes: int,
    rng: np.random.Generator | int,
    *,
    starts=None,
    max_steps: int = DEFAULT_MAX_STEPS,
    log_policy: np.ndarray | None = None,
    model: str = DEFAULT_MODEL,
) -> Trajectories:
    """Episodes of a simulated person acting with the policy π(θ, β) of ``model``.

    All episodes are advanced together, one step at a time; each step draws one
    uniform number per active episode and picks the action by inverse-CDF sampling
    from the cumulative policy. The same ``rng`` state gives identical output.

    Parameters
    ----------
    mdp : TabularMDP
        The task.
    theta : array ``[K]``
        Reward weights, finite and ``>= 0``; used as given (not normalised).
    beta : float
        Expertise (temperature), ``> 0``.
    n_episodes : int
        Number of episodes N (``>= 0``).
    rng : numpy.random.Generator or int
        Source of all randomness (start states and actions); an int is used as a seed.
    starts : array ``[M]`` of int, optional
        Non-terminal states to start from, drawn uniformly per episode. Default:
        ``mdp.initial_states()`` (the map's start cells, else every non-terminal state).
    max_steps : int
        An episode ends on entering a terminal state or after ``max_steps`` actions.
        Truncating at a fixed step count does not bias the likelihood of the recorded
        pairs: the stopping rule does not depend on the actions' probabilities under
        any hypothesis, so it contributes the same factor to every hypothesis.
    log_policy : array ``[S, A]``, optional
        Use this log-policy instead of solving for ``(theta, beta)`` (e.g. one row of
        ``planning.solve(...).log_policy``); ``theta`` and ``beta`` may then be None.
    model : str
        The observation model of :mod:`expertise_irl.models` (default ``"maxent"``, the
        paper's); ignored when ``log_policy`` is given.

    Returns
    -------
    Trajectories
        ``[n]`` pairs; episodes labelled ``0..N-1``, steps ``0..T-1`` within each.

    Raises
    ------
    InputError
        Bad θ, β, ``starts``, ``max_steps``, ``n_episodes`` or ``log_policy``.
    """
    if log_policy is None:
        if theta is None or beta is None:
            raise InputError("simulate needs theta and beta (or a log_policy)")
        th, b = _check_hypothesis(mdp, theta, beta)
        log_policy = solve(mdp, th, b, model=check_model(model)).log_policy[0]
    else:
        if theta is not None or beta is not None:
            _check_hypothesis(mdp, theta, beta)
    lp = _check_log_policy(mdp, log_policy)
    st = check_start_states(mdp, starts)
    if isinstance(n_episodes, bool) or not isinstance(n_episodes, int | np.integer) or n_episodes < 0:
        raise InputError(f"n_episodes must be an integer >= 0, got {n_episodes!r}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise InputError(f"max_steps must be an integer >= 1, got {max_steps!r}")

    if not isinstance(rng, np.random.Generator):
        if isinstance(rng, bool) or not isinstance(rng, int | np.integer) or rng < 0:
            raise InputError(f"rng must be a numpy Generator or a seed >= 0, got {rng!r}")
        rng = np.random.default_rng(int(rng))
    cdf = np.cumsum(np.exp(lp), axis=1)
    total = cdf[:, -1:]
    # Dividing by the row total makes the last entry exactly 1.0, so u in [0, 1) never
    # runs past the last action with positive probability. Terminal rows are never used.
    cdf = np.where(total > 0, cdf / np.where(total > 0, total, 1.0), 1.0)
    current = st[rng.integers(0, st.size, size=int(n_episodes))]
    active = np.arange(int(n_episodes), dtype=np.int64)
    chunks: list[tuple[np.ndarray, ...]] = []
    for t in range(int(max_steps)):
        if active.size == 0:
            break
        s = current[active]
        u = rng.random(active.size)
        a = np.sum(cdf[s] <= u[:, None], axis=1)
        chunks.append((active, np.full(active.size, t, dtype=np.int64), s, a))
        nxt = mdp.next_state[s, a]
        current[active] = nxt
        active = active[~mdp.terminal[nxt]]
    if not chunks:
        empty = np.zeros(0, dtype=np.int64)
        return Trajectories(empty, empty, empty, empty)
    ep, step, state, action = (np.concatenate(c) for c in zip(*chunks, strict=True))
    order = np.lexsort((step, ep))
    return Trajectories(ep[order], step[order], state[order], action[order])


def capped_flags(trajs: Trajectories, mdp: TabularMDP, max_steps: int) -> np.ndarray:
    """``[n_episodes]`` whether each episode ran to ``max_steps`` actions without entering a
    terminal state (in episode order)."""
    if len(trajs) == 0:
        return np.zeros(0, dtype=bool)
    last = np.flatnonzero(np.append(trajs.episode[1:] != trajs.episode[:-1], True))
    ended = mdp.terminal[mdp.next_state[trajs.state[last], trajs.action[last]]]
    return ~ended & (trajs.step[last] + 1 >= max_steps)


def capped_episodes(trajs: Trajectories, mdp: TabularMDP, max_steps: int) -> int:
    """Episodes that ran to ``max_steps`` actions without entering a terminal state."""
    return int(np.sum(capped_flags(trajs, mdp, max_steps)))


# ---------------------------------------------------------------------------- validation
def _action_label(mdp: TabularMDP, a: int) -> str:
    if mdp.n_actions == len(ACTION_NAMES) and mdp.state_xy is not None and 0 <= a < mdp.n_actions:
        return f"action {a} ({ACTION_NAMES[a]})"
    return f"action {a}"


def _structure_error(episode: np.ndarray, step: np.ndarray) -> tuple[int, str] | None:
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


def _validate(
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
    for err in (_structure_error(tr.episode, tr.step), _pair_error(mdp, tr)):
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
    _validate(trajs, mdp, source)


# ---------------------------------------------------------------------------- CSV I/O
#: Header of the generic format: one row per (state, action) pair.
STATE_COLUMNS = ("episode", "step", "state", "action")
#: Header of the grid format: one row per visited cell, the final cell included.
GRID_COLUMNS = ("episode", "step", "x", "y")
#: Optional column of the grid format in heading worlds: ``h`` or ``v``, the state's heading.
HEADING_COLUMN = "heading"
_HEADING_LETTERS = ("h", "v")
_HEADERS = {"state": STATE_COLUMNS, "grid": GRID_COLUMNS}
_HEADER_HELP = "'episode,step,state,action' (generic MDP) or 'episode,step,x,y' (grid map)"
# _MOVE[dx + 1, dy + 1] = the action with that (dx, dy), -1 for anything else.
_MOVE = np.full((3, 3), -1, dtype=np.int64)
_MOVE[ACTION_DELTAS[:, 0] + 1, ACTION_DELTAS[:, 1] + 1] = np.arange(len(ACTION_DELTAS))


def _cell_index(mdp: TabularMDP) -> np.ndarray | None:
    """``[L, H, W]`` state of each (heading, cell) (-1: not a state), ``L`` = 2 in a heading
    world (``mdp.state_heading``), else 1; None if ``mdp`` is not a grid of that kind."""
    xy = mdp.state_xy
    if xy is None or mdp.n_actions != len(ACTION_DELTAS) or (xy < 0).any():
        return None
    heading = mdp.state_heading if mdp.state_heading is not None else np.zeros(mdp.n_states, np.int64)
    layers = 2 if mdp.state_heading is not None else 1
    idx = np.full((layers, int(xy[:, 1].max()) + 1, int(xy[:, 0].max()) + 1), -1, dtype=np.int64)
    idx[heading, xy[:, 1], xy[:, 0]] = np.arange(mdp.n_states)
    return idx if int((idx >= 0).sum()) == mdp.n_states else None  # one state per (heading, cell)


def _require_grid(mdp: TabularMDP, source) -> np.ndarray:
    idx = _cell_index(mdp)
    if idx is None:
        raise InputError(
            f"{where(source)}the grid format (episode,step,x,y) needs a grid map: 4 actions and "
            "one state per cell (per cell and heading in a heading world); use the generic "
            "format episode,step,state,action"
        )
    return idx


def write_demos_csv(path: str | Path, trajs: Trajectories, mdp: TabularMDP, *, fmt: str = "auto") -> None:
    """Write demonstrations as CSV (formats in the README); :func:`read_demos_csv` reads them back.

    Parameters
    ----------
    path : str or Path
        File to write (overwritten).
    trajs : Trajectories
        ``[N]`` pairs, checked with :func:`validate` first.
    mdp : TabularMDP
        The task they belong to.
    fmt : {"auto", "state", "grid"}
        ``"state"``: header ``episode,step,state,action``, one row per pair.
        ``"grid"``: header ``episode,step,x,y``, one row per visited cell including the
        cell the last action leads to (needs ``mdp.state_xy``, 4 actions, one state per
        cell); in a heading world (``mdp.state_heading``) one state per cell and heading,
        and a ``heading`` column (``h``/``v``) is added. ``"auto"``: grid when the MDP is
        such a grid, else state.
    """
    if fmt not in ("auto", "state", "grid"):
        raise InputError(f"fmt must be 'auto', 'state' or 'grid', got {fmt!r}")
    validate(trajs, mdp)
    if len(trajs) == 0:
        raise InputError(f"{where(path)}no demonstrations to write")
    if fmt == "auto":
        fmt = "grid" if _cell_index(mdp) is not None else "state"
    if fmt == "grid":
        _require_grid(mdp, path)
    ep, step, s, a = trajs.episode, trajs.step, trajs.state, trajs.action
    heading = mdp.state_heading if fmt == "grid" else None
    with open(path, "w", encoding="utf-8", newline="") as fh:
        out = csv.writer(fh, lineterminator="\n")
        out.writerow(_HEADERS[fmt] + ((HEADING_COLUMN,) if heading is not None else ()))
        if fmt == "state":
            out.writerows(np.stack([ep, step, s, a], axis=1).tolist())
            return
        xy = mdp.state_xy

        def cell(state: int) -> list:
            extra = [_HEADING_LETTERS[int(heading[state])]] if heading is not None else []
            return [*xy[state].tolist(), *extra]

        last = np.append(ep[1:] != ep[:-1], True)
        for i in range(len(trajs)):
            out.writerow([int(ep[i]), int(step[i]), *cell(s[i])])
            if last[i]:
                out.writerow([int(ep[i]), int(step[i]) + 1, *cell(mdp.next_state[s[i], a[i]])])


_INT_LIMIT = 2**62  # far beyond any state, cell, step or episode label; keeps int64 safe


def _parse_int(text: str, column: str, prefix: str) -> int:
    try:
        value = int(text)
    except ValueError:
        pass
    else:
        if abs(value) >= _INT_LIMIT:
            raise InputError(f"{prefix}column '{column}': {text!r} is out of range")
        return value
    if not text:
        raise InputError(f"{prefix}column '{column}' is empty")
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{prefix}column '{column}': {text!r} is not a number") from None
    if not math.isfinite(value) or value != int(value):
        raise InputError(f"{prefix}column '{column}': {text!r} is not an integer")
    if abs(value) >= _INT_LIMIT:
        raise InputError(f"{prefix}column '{column}': {text!r} is out of range")
    return int(value)


def _read_rows(path: str | Path, heading: bool = False) -> tuple[str, np.ndarray, np.ndarray,
                                                                  np.ndarray | None]:
    """Format name, ``[n, 4]`` int values, ``[n]`` line numbers of the data rows, and with
    ``heading`` the ``[n]`` headings (0 = h, 1 = v) of a grid file's ``heading`` column
    (None when the file has none)."""
    records = read_rows(path, kind="a demonstrations CSV file", nothing="no demonstrations")
    line, header = records[0]
    names = [h.lower() for h in header]
    # Columns are found by name, in any order; other columns (a timestamp, say) are ignored.
    fmt = next((k for k, cols in _HEADERS.items() if set(cols) <= set(names)), None)
    if fmt is None:
        got = ",".join(header)
        if all(h.lstrip("-").isdigit() for h in header):
            raise InputError(f"{where(path, line)}missing header row: expected {_HEADER_HELP}, got {got!r}")
        cols = min(_HEADERS.values(), key=lambda c: len(set(c) - set(names)))
        missing = [c for c in cols if c not in names]
        raise InputError(
            f"{where(path, line)}expected header {_HEADER_HELP}, got {got!r} "
            f"(missing column(s) {', '.join(missing)})"
        )
    cols = _HEADERS[fmt]
    dup = [c for c in cols if names.count(c) > 1]
    if dup:
        raise InputError(f"{where(path, line)}column {dup[0]!r} appears more than once in the header")
    pos = [names.index(c) for c in cols]
    if len(records) == 1:
        raise InputError(f"{where(path, line)}no demonstrations: the file has a header but no rows")
    values = np.empty((len(records) - 1, 4), dtype=np.int64)
    lines = np.empty(len(records) - 1, dtype=np.int64)
    hpos = names.index(HEADING_COLUMN) if heading and fmt == "grid" and HEADING_COLUMN in names else None
    if hpos is not None and names.count(HEADING_COLUMN) > 1:
        raise InputError(f"{where(path, line)}column {HEADING_COLUMN!r} appears more than once in the header")
    headings = np.empty(len(records) - 1, dtype=np.int64) if hpos is not None else None
    for r, (line, fields) in enumerate(records[1:]):
        prefix = where(path, line)
        if len(fields) != len(header):
            raise InputError(
                f"{prefix}row has {len(fields)} fields, expected {len(header)} ({','.join(header)})"
            )
        values[r] = [_parse_int(fields[i], c, prefix) for i, c in zip(pos, cols, strict=True)]
        lines[r] = line
        if headings is not None:
            letter = fields[hpos].lower()
            if letter not in _HEADING_LETTERS:
                raise InputError(f"{prefix}episode {values[r, 0]} step {values[r, 1]}: column "
                                 f"'{HEADING_COLUMN}': {fields[hpos]!r} is not h (horizontal) or "
                                 "v (vertical)")
            headings[r] = _HEADING_LETTERS.index(letter)
    err = _structure_error(values[:, 0], values[:, 1])
    if err is not None:
        i, msg = err
        raise InputError(f"{where(path, lines[i])}episode {values[i, 0]} step {values[i, 1]}: {msg}")
    return fmt, values, lines, headings


def read_demos_csv(path: str | Path, mdp: TabularMDP) -> Trajectories:
    """Read demonstrations from CSV, detecting the format from the header (formats in the README).

    ``episode,step,state,action`` gives one (state, action) pair per row;
    ``episode,step,x,y`` gives one visited cell per row (the final cell included,
    at least 2 cells per episode) and each action is the move between consecutive
    cells. In a heading world (``mdp.state_heading``, e.g. a warehouse floor plan) an
    optional ``heading`` column (``h``/``v``) gives each state's heading; without it, a
    state's heading is the axis of the move that entered it and an episode's first state
    takes the axis of its first move. Rows of one episode must be contiguous, steps 0, 1,
    2, ...; episodes keep their labels and file order. Blank lines, whitespace around fields, a UTF-8 BOM
    and CRLF line ends are accepted.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    mdp : TabularMDP
        The task; every pair is checked with the rules of :func:`validate`.

    Returns
    -------
    Trajectories
        ``[N]`` pairs.

    Raises
    ------
    InputError
        One line ``"<path>:<line>: [episode E step T: ]<reason>"`` (line 1 = header).
    """
    fmt, v, lines, given_heading = _read_rows(path, heading=mdp.state_heading is not None)
    ep, step = v[:, 0], v[:, 1]
    if fmt == "state":
        trajs = Trajectories(ep, step, v[:, 2], v[:, 3])
        _validate(trajs, mdp, path, lines)
        return trajs
    idx = _require_grid(mdp, path)
    _, H, W = idx.shape
    x, y = v[:, 2], v[:, 3]
    inside = (x >= 0) & (x < W) & (y >= 0) & (y < H)
    same = np.zeros(ep.size, dtype=bool)
    same[1:] = ep[1:] == ep[:-1]
    last = ~np.append(same[1:], False)
    dx = np.diff(x, prepend=0)
    dy = np.diff(y, prepend=0)
    dist = np.abs(dx) + np.abs(dy)
    xc, yc = np.clip(x, 0, W - 1), np.clip(y, 0, H - 1)
    wrong_heading = np.zeros(ep.size, dtype=bool)
    if mdp.state_heading is None:
        heading = np.zeros(ep.size, dtype=np.int64)
    else:  # heading of the move into each row; an episode's first row takes its first move's
        moved = np.where(dx != 0, 0, 1)
        heading = np.where(same, moved, np.append(moved[1:], 0))
        if given_heading is not None:
            wrong_heading = same & (dist == 1) & (given_heading != heading)
            heading = given_heading
    state = np.where(inside, idx[heading, yc, xc], -1)
    is_cell = inside & (idx.max(axis=0)[yc, xc] >= 0)
    checks = (
        (~inside, lambda i: f"cell (x={x[i]}, y={y[i]}) is outside the map (x 0..{W - 1}, y 0..{H - 1})"),
        (~is_cell, lambda i: f"cell (x={x[i]}, y={y[i]}) is an obstacle (not a state of the map)"),
        (is_cell & (state < 0), lambda i: (
            f"cell (x={x[i]}, y={y[i]}) with heading {_HEADING_LETTERS[heading[i]]} is not a state "
            "of the map")),
        (same & (dist == 0), lambda i: f"cell (x={x[i]}, y={y[i]}) repeats the previous cell (a zero move)"),
        (same & (dist > 1), lambda i: (
            f"jumps from ({x[i - 1]},{y[i - 1]}) to ({x[i]},{y[i]}); consecutive cells must be "
            "adjacent (one move up, down, left or right)")),
        (~same & last, lambda i: "episode has a single cell; the grid format needs at least 2 cells"),
        (wrong_heading, lambda i: (
            f"heading {_HEADING_LETTERS[given_heading[i]]} at cell (x={x[i]}, y={y[i]}) does not "
            f"match the {('horizontal', 'vertical')[1 - given_heading[i]]} move into it: a move "
            f"leaves the heading on its own axis ({_HEADING_LETTERS[1 - given_heading[i]]})")),
    )
    bad = np.logical_or.reduce([m for m, _ in checks])
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        msg = next(describe(i) for m, describe in checks if m[i])
        raise InputError(f"{where(path, lines[i])}episode {ep[i]} step {step[i]}: {msg}")
    j = np.flatnonzero(~last)  # rows that have a next cell: one pair each
    action = _MOVE[dx[j + 1] + 1, dy[j + 1] + 1]
    trajs = Trajectories(ep[j], step[j], state[j], action)
    # A pair is reported at the row of the cell its action moves to.
    _validate(trajs, mdp, path, lines[j + 1], step[j + 1], source_lines=lines[j])
    return trajs
