"""The grid both worlds stand on: shared legend characters, text maps, cells and moves.

Cells on a W×H grid (x = column, y = row, row 0 at the top); the four actions of
:data:`~expertise_irl.mdp.ACTION_DELTAS` move one cell, and a move off the grid or into an
obstacle is unavailable. :class:`GridMap` holds what a zone map and a floor plan share.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..mdp import ACTION_DELTAS

DEFAULT_GOAL_BONUS = 10.0
#: How the goal pays (the ``goal_reward_mode`` of a map's TOML): ``scaled`` adds ``goal_bonus``
#: to the ``length`` feature on entering a goal, so it is weighted by θ_length (and vanishes
#: with it); ``fixed`` pays ``goal_bonus`` on entering a goal as a reward outside θ·φ
#: (:attr:`~expertise_irl.mdp.TabularMDP.reward_offset`), the same for every θ.
GOAL_REWARD_MODES = ("scaled", "fixed")
DEFAULT_GOAL_REWARD_MODE = "scaled"
FREE, OBSTACLE, GOAL, START = ".", "#", "G", "S"
ROAD_DIRECTIONS = {"^": 0, "v": 1, "<": 2, ">": 3}  # road char -> action index of its direction
_OPPOSITE = np.array([1, 0, 3, 2])


def legend(*zones: str) -> tuple[str, ...]:
    """The characters of a world's text maps: the shared ones, its ``zones``, then the roads."""
    return (FREE, OBSTACLE, GOAL, START, *zones, *ROAD_DIRECTIONS)


class GridMap:
    """Cells of a parsed map, mixed into the frozen dataclasses of both worlds.

    A subclass holds ``grid`` (``[height, width]`` legend characters), ``goal_bonus``,
    ``gamma``, ``name`` and ``goal_reward_mode``, and names itself in messages with ``NOUN``.
    """

    NOUN = "map"
    grid: np.ndarray
    goal_bonus: float
    gamma: float
    name: str
    goal_reward_mode: str

    def _check_cells(self, g: np.ndarray, legend: tuple[str, ...]) -> None:
        """Refuse a character outside ``legend`` (naming its line and column) and a map without a goal."""
        bad = ~np.isin(g, legend)
        if bad.any():
            y, x = np.argwhere(bad)[0]
            raise InputError(f"{self.name}:{y + 1}:{x + 1}: unknown {self.NOUN.replace(' ', '-')} "
                             f"character {g[y, x]!r} (legend: {' '.join(legend)})")
        if not (g == GOAL).any():
            raise InputError(f"{self.name}: {self.NOUN} has no goal cell 'G'")

    def _check_numbers(self) -> None:
        """Refuse a goal bonus that is not finite and a discount outside (0, 1)."""
        if not math.isfinite(self.goal_bonus):
            raise InputError(f"{self.name}: goal_bonus must be a finite number")
        if not 0.0 < float(self.gamma) < 1.0:
            raise InputError(f"{self.name}: gamma must be in (0, 1), got {self.gamma}")
        check_goal_reward_mode(self.goal_reward_mode, self.name)

    def goal_rewards(self, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """For moves into cells ``dst`` ([C, A] characters): what entering a goal adds to the
        ``length`` feature, and the reward outside θ·φ (None under ``scaled``); see
        :data:`GOAL_REWARD_MODES`."""
        enters = np.where(dst == GOAL, self.goal_bonus, 0.0)
        if self.goal_reward_mode == "fixed":
            return np.zeros(dst.shape), enters
        return enters, None

    @property
    def height(self) -> int:
        return int(self.grid.shape[0])

    @property
    def width(self) -> int:
        return int(self.grid.shape[1])

    @property
    def passable(self) -> np.ndarray:
        """``[height, width]`` bool: the cell is not an obstacle."""
        return self.grid != OBSTACLE

    @property
    def cells(self) -> np.ndarray:
        """``[C, 2]`` (x, y) of each passable cell, row-major order."""
        ys, xs = np.nonzero(self.passable)
        return np.stack([xs, ys], axis=1).astype(np.int64)

    def cell_index(self) -> np.ndarray:
        """``[height, width]`` index of each passable cell (row-major), -1 for obstacles."""
        idx = np.full(self.grid.shape, -1, dtype=np.int64)
        idx[self.passable] = np.arange(int(self.passable.sum()))
        return idx

    def moves(self) -> tuple[np.ndarray, np.ndarray]:
        """``[C, A]`` cell index each action reaches from each passable cell (-1 off the grid or
        into an obstacle) and ``[C, A]`` the character there (the nearest cell on the grid for a
        move off it)."""
        cells = self.cells
        nx = cells[:, 0, None] + ACTION_DELTAS[None, :, 0]
        ny = cells[:, 1, None] + ACTION_DELTAS[None, :, 1]
        inside = (nx >= 0) & (nx < self.width) & (ny >= 0) & (ny < self.height)
        nxc, nyc = np.clip(nx, 0, self.width - 1), np.clip(ny, 0, self.height - 1)
        return np.where(inside, self.cell_index()[nyc, nxc], -1), self.grid[nyc, nxc]

    def to_text(self) -> str:
        return "\n".join("".join(row) for row in self.grid) + "\n"


def check_goal_reward_mode(mode, where: str) -> str:
    """``mode`` if it is one of :data:`GOAL_REWARD_MODES`, else a one-line :class:`InputError`."""
    if mode not in GOAL_REWARD_MODES:
        raise InputError(f"{where}: goal_reward_mode must be one of {', '.join(GOAL_REWARD_MODES)}, "
                         f"got {mode!r}")
    return mode


def road_feature(dst: np.ndarray, off_road: float) -> np.ndarray:
    """``[C, A]`` road feature of moves into cells ``dst``: +1 along the road's direction, −1
    against it, 0 across it, ``off_road`` into a cell that is not a road."""
    road_dir = np.full(dst.shape, -1)
    for ch, d in ROAD_DIRECTIONS.items():
        road_dir[dst == ch] = d
    act = np.arange(len(ACTION_DELTAS))[None, :]
    return np.where(road_dir < 0, off_road,
                    np.where(road_dir == act, 1.0, np.where(road_dir == _OPPOSITE[act], -1.0, 0.0)))


def read_grid(text: str, name: str, legend: tuple[str, ...]) -> np.ndarray:
    """``[height, width]`` characters of a text map whose cells are all in ``legend``.

    Blank lines at the start and end and trailing spaces are ignored; rows must be equally
    long. Problems raise :class:`InputError` naming ``name:line:column``.
    """
    lines = text.removeprefix("\ufeff").splitlines()
    first = 0
    while first < len(lines) and not lines[first].strip():
        first += 1
    rows = [ln.rstrip() for ln in lines[first:]]  # trailing spaces from editors are not cells
    while rows and not rows[-1].strip():
        rows.pop()
    if not rows:
        raise InputError(f"{name}: map is empty")
    width = len(rows[0])
    for i, row in enumerate(rows):
        lineno = first + i + 1
        if not row.strip():
            raise InputError(f"{name}:{lineno}: blank line inside the map")
        for j, ch in enumerate(row):
            if ch not in legend:
                raise InputError(
                    f"{name}:{lineno}:{j + 1}: unknown map character {ch!r} (legend: {' '.join(legend)})"
                )
        if len(row) != width:
            raise InputError(
                f"{name}:{lineno}: row has {len(row)} cells but the first row has {width}; "
                "every row must have the same length"
            )
    return np.array([list(r) for r in rows], dtype="<U1")
