"""Warehouse world of paper Sec. VIII-A: cells with a heading, turn costs, several goals.

A floor plan is a text map (x = column, y = row, row 0 at the top) in this legend::

    .  free          #  obstacle       G  goal (terminal, several allowed)
    S  start (free)  x  restricted area
    > < ^ v  road with its travel direction

with a TOML file beside it (same name, ``.toml``)::

    world = "warehouse"   # required: this is what makes the map a floor plan
    cell_size = 0.5       # required: metres per cell
    goal_bonus = 10.0     # optional, added to the length feature on entering a goal
    goal_reward_mode = "scaled"  # optional: "fixed" pays goal_bonus outside θ·φ instead
    gamma = 0.95          # optional discount factor
    y_up = false          # optional: y of recordings measured up from the bottom edge

A state is a (cell, heading) pair, heading 0 = horizontal, 1 = vertical; state
``2 * c + h`` for the ``c``-th passable cell in row-major order. The four actions
``up, down, left, right`` move one cell; a move off the map or into an obstacle is
unavailable. A move along the current heading costs 1 length unit, a move on the other
axis costs 2, and every move leaves the heading on its own axis. Both states of a goal
cell are terminal; both states of each ``S`` cell are start states.

Features of a move ending in cell c' (each signed so that a larger θ_i means the person
cares more; paper Eq. 18):

1. ``length``     −1 along the heading, −2 across it (a turn), plus ``goal_bonus`` when c'
                  is a goal.
2. ``restricted`` −1 when c' is restricted (entering or moving inside a restricted area).
3. ``road``       c' is a road with direction r: +1 when the move goes along r, −1 against
                  it, 0 across it; −1 when c' is not a road cell (goals included).

Metric coordinates (recordings): x in metres to the right from the map's left edge, y in
metres down from its top edge, so cell (col, row) covers
``[col·c, (col+1)·c) × [row·c, (row+1)·c)`` for ``c = cell_size``; with ``y_up = true``,
y is measured up from the bottom edge, so row ``H − 1`` is at the bottom.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, read_text
from ..mdp import DEFAULT_GAMMA, TabularMDP
from .files import check_goal_settings, check_known, map_file, number_setting, read_toml
from .grid import (
    DEFAULT_GOAL_BONUS,
    DEFAULT_GOAL_REWARD_MODE,
    GOAL,
    START,
    GridMap,
    check_goal_reward_mode,
    legend,
    read_grid,
    road_feature,
)

WORLD = "warehouse"
HORIZONTAL, VERTICAL = 0, 1
#: Letter of each heading in demonstration files (``heading`` column).
HEADING_LETTERS = ("h", "v")
#: Axis of each action (up, down, left, right): the heading a move leaves behind.
ACTION_AXIS = np.array([VERTICAL, VERTICAL, HORIZONTAL, HORIZONTAL], dtype=np.int64)
FEATURE_NAMES = ("length", "restricted", "road")
RESTRICTED = "x"
LEGEND = legend(RESTRICTED)
DEFAULT_CELL_SIZE = 1.0
_NUMBER_SETTINGS = ("cell_size", "goal_bonus", "gamma")
_SETTINGS = ("world", *_NUMBER_SETTINGS, "y_up", "goal_reward_mode")


@dataclass(frozen=True, eq=False)
class WarehouseMap(GridMap):
    """A parsed floor plan. ``grid[row, col]`` holds one legend character.

    Attributes:
        grid: ``[height, width]`` array of single characters.
        cell_size: metres per cell (side of a square cell), > 0.
        goal_bonus: added to the length feature on entering a goal.
        gamma: discount factor of the compiled MDP.
        y_up: recordings measure y up from the bottom edge (default: down from the top).
        name: file name or label, used in messages and figures.
        goal_reward_mode: ``"scaled"`` (the bonus is part of ``length``) or ``"fixed"`` (a
            reward outside θ·φ); see :data:`~.grid.GOAL_REWARD_MODES`.
    """

    NOUN = "floor plan"
    grid: np.ndarray
    cell_size: float = DEFAULT_CELL_SIZE
    goal_bonus: float = DEFAULT_GOAL_BONUS
    gamma: float = DEFAULT_GAMMA
    y_up: bool = False
    name: str = "<floor plan>"
    goal_reward_mode: str = DEFAULT_GOAL_REWARD_MODE

    def __post_init__(self) -> None:
        raw = np.asarray(self.grid)
        if raw.dtype.kind != "U" or raw.ndim != 2 or raw.size == 0 or any(
                len(c) != 1 for c in raw.ravel().tolist()):
            raise InputError(f"{self.name}: a floor plan must be a non-empty rectangle of characters")
        g = raw.astype("<U1")
        self._check_cells(g, LEGEND)
        if not (math.isfinite(self.cell_size) and self.cell_size > 0):
            raise InputError(f"{self.name}: cell_size must be a number > 0 (metres), got {self.cell_size}")
        self._check_numbers()
        g.setflags(write=False)
        object.__setattr__(self, "grid", g)
        object.__setattr__(self, "cell_size", float(self.cell_size))
        object.__setattr__(self, "y_up", bool(self.y_up))

    # ------------------------------------------------------------------ cells
    @property
    def n_states(self) -> int:
        return 2 * int(self.passable.sum())

    def state_index(self) -> np.ndarray:
        """``[2, height, width]`` state of (heading, row, col), -1 for obstacles."""
        c = self.cell_index()
        return np.stack([np.where(c >= 0, 2 * c + h, -1) for h in (HORIZONTAL, VERTICAL)])

    def state_cells(self) -> np.ndarray:
        """``[S, 2]`` (col, row) of each state."""
        return np.repeat(self.cells, 2, axis=0)

    def state_headings(self) -> np.ndarray:
        """``[S]`` heading of each state (0 = horizontal, 1 = vertical)."""
        return np.tile(np.array([HORIZONTAL, VERTICAL], dtype=np.int64), int(self.passable.sum()))

    # ------------------------------------------------------------- coordinates
    def cell_of(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(col, row) int arrays of the cells holding points (x, y) in metres.

        Points outside the map give a col or row outside ``[0, width)`` / ``[0, height)``.
        """
        c = self.cell_size
        col = np.floor(np.asarray(x, dtype=np.float64) / c)
        up = np.floor(np.asarray(y, dtype=np.float64) / c)
        row = self.height - 1 - up if self.y_up else up
        big = float(2 * max(self.width, self.height) + 2)  # far outside, and safe as int64
        return (np.clip(col, -big, big).astype(np.int64), np.clip(row, -big, big).astype(np.int64))

    def centre_of(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) in metres of the centres of cells (col, row)."""
        c = self.cell_size
        x = (np.asarray(col, dtype=np.float64) + 0.5) * c
        r = np.asarray(row, dtype=np.float64)
        y = ((self.height - 1 - r) if self.y_up else r) * c + 0.5 * c
        return x, y

    def settings_text(self) -> str:
        """The TOML that goes beside the map's text to reproduce this floor plan."""
        return (f'world = "{WORLD}"\ncell_size = {self.cell_size!r}\ngoal_bonus = {self.goal_bonus!r}\n'
                f"gamma = {self.gamma!r}\ny_up = {'true' if self.y_up else 'false'}\n"
                + (f'goal_reward_mode = "{self.goal_reward_mode}"\n'
                   if self.goal_reward_mode != DEFAULT_GOAL_REWARD_MODE else ""))

    # --------------------------------------------------------------------- MDP
    def to_mdp(self) -> TabularMDP:
        """Compile to a :class:`TabularMDP` with heading states and the three features."""
        g = self.grid
        cells = self.cells
        C = len(cells)
        cols, rows = cells[:, 0], cells[:, 1]
        dest, dst = self.moves()  # [C, A] destination cell (-1 unavailable) and its character
        road = road_feature(dst, off_road=-1.0)
        restricted = -(dst == RESTRICTED).astype(float)
        bonus, offset = self.goal_rewards(dst)

        next_state = np.full((2 * C, 4), -1, dtype=np.int64)
        feats = np.zeros((2 * C, 4, 3))
        state_offset = None if offset is None else np.repeat(offset, 2, axis=0)  # both headings
        for h in (HORIZONTAL, VERTICAL):
            s = 2 * np.arange(C) + h
            next_state[s] = np.where(dest >= 0, 2 * dest + ACTION_AXIS[None, :], -1)
            feats[s, :, 0] = np.where(ACTION_AXIS[None, :] == h, -1.0, -2.0) + bonus
            feats[s, :, 1] = restricted
            feats[s, :, 2] = road
        goal_cell = g[rows, cols] == GOAL
        start_cell = np.flatnonzero(g[rows, cols] == START)
        starts = np.sort(np.concatenate([2 * start_cell, 2 * start_cell + 1]))
        return TabularMDP(
            next_state=next_state,
            features=feats,
            terminal=np.repeat(goal_cell, 2),
            gamma=self.gamma,
            feature_names=FEATURE_NAMES,
            start_states=starts if starts.size else None,
            state_xy=self.state_cells(),
            source=self.name,
            state_heading=self.state_headings(),
            reward_offset=state_offset,
        )

    def save_npz(self, path: str | Path) -> None:
        """Write the compiled MDP archive, with ``state_cell[S, 2]`` and ``state_heading[S]``."""
        self.to_mdp().save(path)


# ------------------------------------------------------------------- reading
def parse_floor_plan(text: str, *, name: str = "<floor plan>", cell_size: float = DEFAULT_CELL_SIZE,
                     goal_bonus: float = DEFAULT_GOAL_BONUS, gamma: float = DEFAULT_GAMMA,
                     y_up: bool = False, goal_reward_mode: str = DEFAULT_GOAL_REWARD_MODE) -> WarehouseMap:
    """Parse the text of a floor plan (legend in the module docstring)."""
    return WarehouseMap(read_grid(text, name, LEGEND), cell_size=cell_size, goal_bonus=goal_bonus,
                        gamma=gamma, y_up=y_up, name=name, goal_reward_mode=goal_reward_mode)


def read_floor_plan_settings(path: Path, text: str | None = None) -> dict:
    """The settings of a floor-plan TOML (``world``, ``cell_size`` required), as keyword arguments
    of :func:`parse_floor_plan`. ``text`` is the TOML's content when already read."""
    data = read_toml(path, text)
    for key in data:
        check_known(path, key, _SETTINGS)
    if data.get("world") != WORLD:
        raise InputError(f"{path}: a floor plan's TOML must say world = \"{WORLD}\"")
    if "cell_size" not in data:
        raise InputError(f"{path}: missing setting cell_size (metres per cell)")
    out: dict = {}
    for key in _NUMBER_SETTINGS:
        if key in data:
            out[key] = number_setting(path, key, data[key])
    if "y_up" in data:
        if not isinstance(data["y_up"], bool):
            raise InputError(f"{path}: setting 'y_up' must be true or false, got {data['y_up']!r}")
        out["y_up"] = data["y_up"]
    if "goal_reward_mode" in data:
        out["goal_reward_mode"] = check_goal_reward_mode(data["goal_reward_mode"], str(path))
    if not (math.isfinite(out["cell_size"]) and out["cell_size"] > 0):
        raise InputError(f"{path}: cell_size must be a number > 0 (metres), got {out['cell_size']:g}")
    check_goal_settings(path, out)
    return out


def load_floor_plan(path: str | Path) -> WarehouseMap:
    """Read a floor plan and the TOML beside it (``name.toml``, required)."""
    path = map_file(path, "floor-plan")
    toml = path.with_suffix(".toml")
    if not toml.is_file():
        raise InputError(f"{path}: a floor plan needs {toml.name} beside it, holding "
                         f"world = \"{WORLD}\" and cell_size")
    text = read_text(path, "not a text map (UTF-8)")
    return parse_floor_plan(text, name=str(path), **read_floor_plan_settings(toml))
