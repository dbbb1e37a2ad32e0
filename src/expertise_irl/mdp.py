"""Deterministic tabular MDP with transition features and its ``.npz`` archive.

Shapes: ``S`` states, ``A`` actions, ``K`` features.

- ``next_state[S, A]`` (int): successor state, ``-1`` where the action is unavailable.
- ``features[S, A, K]`` (float): φ(s, a, next(s, a)); ignored where unavailable.
- ``terminal[S]`` (bool): absorbing goal states, value 0; an episode ends on entering one.
- optional ``state_xy[S, 2]`` (int): grid cell (x = column, y = row) of each state, and for
  worlds whose state also holds a heading, ``state_heading[S]`` (0 = horizontal, 1 = vertical);
  such an MDP has two states per cell and its archive names the cells ``state_cell``.
- optional ``reward_offset[S, A]`` (float): a reward every hypothesis gets alike, not weighted
  by θ (a fixed goal reward, ``goal_reward_mode = "fixed"`` of the grid worlds).

The reward of a hypothesis θ is exactly ``R[s, a] = θ · φ(s, a) + reward_offset[s, a]``
(:meth:`TabularMDP.reward`; the offset is 0 where none is given). Every solver, likelihood
and simulator uses this one reward: the planning kernels see the offset as one more feature
whose weight is fixed at 1 (:meth:`TabularMDP.reward_basis`, :meth:`TabularMDP.reward_weights`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

DEFAULT_GAMMA = 0.95
#: The four moves of the grid worlds (zones and floor plans), in action-index order.
ACTION_NAMES = ("up", "down", "left", "right")
#: (dx, dy) of each move; y grows downwards.
ACTION_DELTAS = np.array([(0, -1), (0, 1), (-1, 0), (1, 0)], dtype=np.int64)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a


def _checked_tables(src: str, next_state, features, terminal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``next_state``, ``features`` (float64, zero where unavailable) and ``terminal`` (bool) checked
    for shape, dtype, indices and finiteness, with at least one terminal and one other state."""
    ns = np.asarray(next_state)
    if ns.ndim != 2:
        raise InputError(f"{src}: next_state must have shape [S, A], got {ns.shape}")
    if not np.issubdtype(ns.dtype, np.integer):
        raise InputError(f"{src}: next_state must be integer, got dtype {ns.dtype}")
    S, A = ns.shape
    if S == 0 or A == 0:
        raise InputError(f"{src}: next_state must be non-empty, got shape {ns.shape}")
    feats = np.asarray(features)
    if feats.ndim != 3 or feats.shape[:2] != (S, A):
        raise InputError(
            f"{src}: features must have shape [S, A, K] = [{S}, {A}, K], got {feats.shape}"
        )
    if feats.shape[2] == 0:
        raise InputError(f"{src}: features must have at least one feature (K >= 1)")
    if not np.issubdtype(feats.dtype, np.number) or np.iscomplexobj(feats):
        raise InputError(f"{src}: features must be real numbers, got dtype {feats.dtype}")
    term = np.asarray(terminal)
    if term.shape != (S,):
        raise InputError(f"{src}: terminal must have shape [S] = [{S}], got {term.shape}")
    if term.dtype != bool:
        if not np.all(np.isin(term, (0, 1))):
            raise InputError(f"{src}: terminal must be boolean (0/1)")
        term = term.astype(bool)
    bad = (ns < -1) | (ns >= S)
    if bad.any():
        s, a = np.argwhere(bad)[0]
        raise InputError(
            f"{src}: next_state[{s}, {a}] = {ns[s, a]} is not a state index in [0, {S}) or -1"
        )
    avail = ns >= 0
    feats = feats.astype(np.float64)
    nonfinite = ~np.isfinite(feats) & avail[:, :, None]
    if nonfinite.any():
        s, a, k = np.argwhere(nonfinite)[0]
        raise InputError(f"{src}: features[{s}, {a}, {k}] is {feats[s, a, k]} (must be finite)")
    # Unavailable entries never matter; zero them so they cannot leak NaN into sums.
    feats = np.where(avail[:, :, None], feats, 0.0)
    if not term.any():
        raise InputError(f"{src}: the MDP has no terminal (goal) state")
    if term.all():
        raise InputError(f"{src}: every state is terminal; there is no state to act in")
    return ns, feats, term


def _checked_offset(src: str, offset, avail: np.ndarray) -> np.ndarray | None:
    """``reward_offset`` as frozen float64 ``[S, A]`` (zero where unavailable), or None."""
    if offset is None:
        return None
    off = np.asarray(offset)
    if off.shape != avail.shape:
        raise InputError(f"{src}: reward_offset must have shape [S, A] = [{avail.shape[0]}, "
                         f"{avail.shape[1]}], got {off.shape}")
    if not np.issubdtype(off.dtype, np.number) or np.iscomplexobj(off):
        raise InputError(f"{src}: reward_offset must be real numbers, got dtype {off.dtype}")
    off = off.astype(np.float64)
    bad = ~np.isfinite(off) & avail
    if bad.any():
        s, a = np.argwhere(bad)[0]
        raise InputError(f"{src}: reward_offset[{s}, {a}] is {off[s, a]} (must be finite)")
    return _frozen(np.where(avail, off, 0.0))


def _checked_starts(src: str, starts, term: np.ndarray) -> np.ndarray | None:
    """``start_states`` as frozen int64 (None for none), each a non-terminal state."""
    if starts is None:
        return None
    S = term.shape[0]
    starts = np.asarray(starts)
    if starts.ndim != 1 or not np.issubdtype(starts.dtype, np.integer):
        raise InputError(f"{src}: start_states must be a 1-D integer array")
    if ((starts < 0) | (starts >= S)).any():
        raise InputError(f"{src}: start_states contains an index outside [0, {S})")
    if term[starts].any():
        raise InputError(f"{src}: start_states contains a terminal state")
    return _frozen(starts.astype(np.int64)) if starts.size else None


def _checked_layout(src: str, xy, heading, S: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``state_xy`` and ``state_heading`` as frozen int64 arrays (None where not given)."""
    if xy is not None:
        xy = np.asarray(xy)
        if xy.shape != (S, 2) or not np.issubdtype(xy.dtype, np.integer):
            raise InputError(f"{src}: state_xy must be an integer array of shape [{S}, 2]")
        xy = _frozen(xy.astype(np.int64))
    if heading is not None:
        heading = np.asarray(heading)
        if xy is None:
            raise InputError(f"{src}: state_heading needs the cell of each state (state_xy)")
        if heading.shape != (S,) or not np.issubdtype(heading.dtype, np.integer) or not np.isin(
                heading, (0, 1)).all():
            raise InputError(f"{src}: state_heading must be an integer array of shape [{S}] "
                             "holding 0 (horizontal) or 1 (vertical)")
        heading = _frozen(heading.astype(np.int64))
    return xy, heading


@dataclass(frozen=True, eq=False)
class TabularMDP:
    """A validated deterministic tabular MDP.

    Construction checks shapes, dtypes and two structural rules:
    every non-terminal state has an available action, and every non-terminal
    state can reach a terminal state. Violations raise :class:`InputError`.

    Attributes:
        next_state: ``[S, A]`` int64, successor or -1 (unavailable).
        features: ``[S, A, K]`` float64 transition features.
        terminal: ``[S]`` bool.
        gamma: discount factor in (0, 1).
        feature_names: ``K`` names (default ``f0 .. f{K-1}``).
        start_states: optional ``[M]`` int64 states episodes may start from.
        state_xy: optional ``[S, 2]`` int64 grid cell (x, y) of each state.
        state_heading: optional ``[S]`` int64 heading of each state, 0 = horizontal,
            1 = vertical (needs ``state_xy``); see :mod:`expertise_irl.worlds.warehouse`.
        source: where the MDP came from, used in error messages.
        reward_offset: optional ``[S, A]`` float64 reward added to θ·φ for every hypothesis
            alike (see the module docstring); None for none.
    """

    next_state: np.ndarray
    features: np.ndarray
    terminal: np.ndarray
    gamma: float = DEFAULT_GAMMA
    feature_names: tuple[str, ...] = ()
    start_states: np.ndarray | None = None
    state_xy: np.ndarray | None = None
    source: str = field(default="<mdp>", compare=False)
    state_heading: np.ndarray | None = None
    reward_offset: np.ndarray | None = None

    def __post_init__(self) -> None:
        src = self.source
        ns, feats, term = _checked_tables(src, self.next_state, self.features, self.terminal)
        S = ns.shape[0]
        stuck = ~term & ~(ns >= 0).any(axis=1)
        if stuck.any():
            s = int(np.flatnonzero(stuck)[0])
            raise InputError(f"{src}: state {s}{self._cell(s)} has no available action")
        gamma = float(self.gamma)
        if not (0.0 < gamma < 1.0):
            raise InputError(f"{src}: gamma must be in (0, 1), got {self.gamma}")
        K = feats.shape[2]
        names = tuple(str(n) for n in self.feature_names) or tuple(f"f{k}" for k in range(K))
        if len(names) != K:
            raise InputError(f"{src}: {len(names)} feature names for {K} features")
        starts = _checked_starts(src, self.start_states, term)
        xy, heading = _checked_layout(src, self.state_xy, self.state_heading, S)
        set_ = object.__setattr__
        set_(self, "next_state", _frozen(ns.astype(np.int64)))
        set_(self, "features", _frozen(feats))
        set_(self, "terminal", _frozen(term))
        set_(self, "gamma", gamma)
        set_(self, "feature_names", names)
        set_(self, "start_states", starts)
        set_(self, "state_xy", xy)
        set_(self, "state_heading", heading)
        set_(self, "reward_offset", _checked_offset(src, self.reward_offset, ns >= 0))
        unreachable = ~term & ~self._reaches_terminal()
        if unreachable.any():
            s = int(np.flatnonzero(unreachable)[0])
            n = int(unreachable.sum())
            raise InputError(
                f"{src}: state {s}{self._cell(s)} cannot reach a terminal (goal) state"
                f" ({n} such state{'s' if n > 1 else ''})"
            )

    # ------------------------------------------------------------------ shape
    @property
    def n_states(self) -> int:
        return int(self.next_state.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.next_state.shape[1])

    @property
    def n_features(self) -> int:
        return int(self.features.shape[2])

    @property
    def has_offset(self) -> bool:
        """Whether a reward not weighted by θ is part of every hypothesis' reward."""
        return self.reward_offset is not None

    def reward(self, theta) -> np.ndarray:
        """``[..., S, A]`` reward ``θ·φ(s, a) + reward_offset[s, a]`` of ``theta [..., K]``.

        Args:
            theta: reward weights ``[..., K]`` (any leading batch axes).

        Returns:
            The reward of every move, ``[..., S, A]``.
        """
        r = np.einsum("sak,...k->...sa", self.features, np.asarray(theta, dtype=np.float64))
        return r + self.reward_offset if self.has_offset else r

    def reward_basis(self) -> np.ndarray:
        """``[S, A, K']``: the features, with the offset as one more column when there is one.

        With :meth:`reward_weights` the reward is ``basis · weights``: the solvers' one reward.
        """
        if not self.has_offset:
            return self.features
        return np.concatenate([self.features, self.reward_offset[..., None]], axis=-1)

    def reward_weights(self, theta) -> np.ndarray:
        """``theta [..., K]`` with the offset's weight 1 appended when there is an offset.

        Args:
            theta: reward weights ``[..., K]``.

        Returns:
            ``[..., K']``, the weights of :meth:`reward_basis`.
        """
        theta = np.asarray(theta, dtype=np.float64)
        if not self.has_offset:
            return theta
        return np.concatenate([theta, np.ones((*theta.shape[:-1], 1))], axis=-1)

    @property
    def available(self) -> np.ndarray:
        """``[S, A]`` bool: action available (terminal states count as having none)."""
        return (self.next_state >= 0) & ~self.terminal[:, None]

    def initial_states(self) -> np.ndarray:
        """States episodes start from: ``start_states`` if given, else every non-terminal state."""
        if self.start_states is not None:
            return self.start_states
        return np.flatnonzero(~self.terminal)

    def _cell(self, s: int) -> str:
        if self.state_xy is None:
            return ""
        x, y = self.state_xy[s]
        if self.state_heading is not None:
            return f" (cell x={x}, y={y}, heading {'hv'[int(self.state_heading[s])]})"
        return f" (cell x={x}, y={y})"

    def describe_state(self, s: int) -> str:
        """Human-readable name of a state for messages, e.g. ``state 12 (cell x=3, y=1)``.

        Args:
            s: the state index.

        Returns:
            The name.
        """
        return f"state {s}{self._cell(s)}"

    def _reaches_terminal(self) -> np.ndarray:
        """``[S]`` bool: a terminal state is reachable (backward BFS from terminals)."""
        S = self.n_states
        preds: list[list[int]] = [[] for _ in range(S)]
        ok = np.zeros(S, dtype=bool)
        avail = (self.next_state >= 0) & ~self.terminal[:, None]
        s_idx, a_idx = np.nonzero(avail)
        for s, a in zip(s_idx.tolist(), a_idx.tolist(), strict=True):
            preds[int(self.next_state[s, a])].append(s)
        queue = deque(np.flatnonzero(self.terminal).tolist())
        ok[self.terminal] = True
        while queue:
            t = queue.popleft()
            for s in preds[t]:
                if not ok[s]:
                    ok[s] = True
                    queue.append(s)
        return ok

    # ---------------------------------------------------------------- archive
    def save(self, path: str | Path) -> None:
        """Write the MDP archive (``.npz``, format in the README).

        Args:
            path: the file to write.
        """
        arrays: dict[str, np.ndarray] = {
            "next_state": self.next_state,
            "features": self.features,
            "terminal": self.terminal,
            "feature_names": np.array(self.feature_names, dtype=str),
            "gamma": np.array(self.gamma),
        }
        if self.start_states is not None:
            arrays["start_states"] = self.start_states
        if self.state_heading is not None:
            arrays["state_cell"] = self.state_xy
            arrays["state_heading"] = self.state_heading
        elif self.state_xy is not None:
            arrays["state_xy"] = self.state_xy
        if self.reward_offset is not None:
            arrays["reward_offset"] = self.reward_offset
        from .atomic import atomic_open

        with atomic_open(path, "wb") as fh:
            np.savez_compressed(fh, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> TabularMDP:
        """Read an MDP archive (``.npz``, format in the README).

        Args:
            path: the archive.

        Returns:
            The MDP, named by its path.

        Raises:
            InputError: no such file, or missing or malformed entries.
        """
        path = Path(path)
        if not path.is_file():
            raise InputError(f"{path}: no such file")
        return cls.from_bytes(path.read_bytes(), source=str(path))

    @classmethod
    def from_bytes(cls, data: bytes, *, source: str = "<mdp>") -> TabularMDP:
        """An MDP archive's content (the bytes of a ``.npz`` file).

        Args:
            data: the bytes.
            source: names the archive in messages.

        Returns:
            The MDP.

        Raises:
            InputError: not a readable archive of plain arrays, or missing or malformed entries.
        """
        import io

        path = source
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except ValueError as exc:
            if "pickle" in str(exc):
                raise InputError(
                    f"{path}: not a readable .npz archive of plain arrays "
                    "(expected next_state, features, terminal; see the README)"
                ) from None
            raise InputError(f"{path}: not a readable .npz archive ({exc})") from None
        except Exception as exc:  # zipfile / format errors
            raise InputError(f"{path}: not a readable .npz archive ({exc})") from None
        missing = [k for k in ("next_state", "features", "terminal") if k not in data]
        if missing:
            raise InputError(f"{path}: archive lacks required array(s) {', '.join(missing)}")
        unknown = set(data) - {
            "next_state", "features", "terminal", "feature_names", "gamma",
            "start_states", "state_xy", "state_cell", "state_heading", "reward_offset",
        }
        if unknown:
            raise InputError(f"{path}: unknown array(s) in archive: {', '.join(sorted(unknown))}")
        try:
            gamma = float(data["gamma"]) if "gamma" in data else DEFAULT_GAMMA
        except (TypeError, ValueError):
            raise InputError(f"{path}: gamma must be a single number") from None
        if "state_cell" in data and "state_xy" in data:
            raise InputError(f"{path}: archive holds both state_xy and state_cell; give one")
        if "state_heading" in data and "state_cell" not in data:
            raise InputError(f"{path}: archive has state_heading but no state_cell")
        names = tuple(np.atleast_1d(data["feature_names"]).tolist()) if "feature_names" in data else ()
        return cls(
            next_state=data["next_state"],
            features=data["features"],
            terminal=data["terminal"],
            gamma=gamma,
            feature_names=names,
            start_states=data.get("start_states"),
            state_xy=data.get("state_cell", data.get("state_xy")),
            source=str(path),
            state_heading=data.get("state_heading"),
            reward_offset=data.get("reward_offset"),
        )
