"""Zone grid world of paper Sec. V: text maps, the five features, a random generator.

Cells on a W×H grid (x = column, y = row, row 0 at the top). Four actions,
``up, down, left, right``; a move off the grid or into an obstacle is
unavailable. Zone legend (as in the README)::

    .  free          #  obstacle       G  goal (terminal)   S  start (free)
    x  avoid (red)   s  slow (yellow)  t  high traffic (purple)
    > < ^ v  road (blue) with its travel direction

Features of a move from cell c to neighbour c' in direction d (each signed so
that a larger θ_i means the person cares more):

1. ``length``  −1 per move, plus ``goal_bonus`` on entering a goal (``goal_reward_mode =
               "scaled"``, the default); under ``"fixed"`` the goal pays ``goal_bonus`` outside
               θ·φ instead, the same for every θ (see :data:`~.grid.GOAL_REWARD_MODES`).
2. ``road``    if c' is a road cell with direction r: +1 when d = r, −1 when d = −r,
               0 across the road.
3. ``avoid``   −1 when the move enters or exits an avoid zone (exactly one of c, c' is in it).
4. ``slow``    −1 when the move is made from inside a slow-down zone (c is slow).
5. ``traffic`` −1 when the move enters or exits a high-traffic zone.

Optional settings live in a TOML file beside the map (same name, ``.toml``):
``goal_bonus`` (default 10), ``goal_reward_mode`` (``"scaled"`` or ``"fixed"``, default
``"scaled"``) and ``gamma`` (default 0.95); ``world = "zones"`` may be stated. A TOML
saying ``world = "warehouse"`` makes the map a warehouse floor plan
(:mod:`expertise_irl.worlds.warehouse`; :func:`expertise_irl.worlds.maps.resolve_world`
loads either kind).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import InputError, read_text
from ..mdp import ACTION_DELTAS, DEFAULT_GAMMA, TabularMDP
from .files import check_goal_settings, check_known, map_file, number_setting, read_toml
from .grid import (
    DEFAULT_GOAL_BONUS,
    DEFAULT_GOAL_REWARD_MODE,
    FREE,
    GOAL,
    OBSTACLE,
    START,
    GridMap,
    check_goal_reward_mode,
    legend,
    read_grid,
    road_feature,
)

FEATURE_NAMES = ("length", "road", "avoid", "slow", "traffic")

AVOID, SLOW, TRAFFIC = "x", "s", "t"
LEGEND = legend(AVOID, SLOW, TRAFFIC)
_SETTINGS = ("goal_bonus", "gamma", "goal_reward_mode")


@dataclass(frozen=True, eq=False)
class ZoneMap(GridMap):
    """A parsed zone map. ``grid[y, x]`` holds one legend character.

    Attributes:
        grid: ``[height, width]`` array of single characters.
        goal_bonus: what entering a goal pays (see ``goal_reward_mode``).
        gamma: discount factor of the compiled MDP.
        name: file name or label, used in messages and figures.
        goal_reward_mode: ``"scaled"`` (the bonus is part of ``length``, weighted by θ_length)
            or ``"fixed"`` (a reward outside θ·φ); see :data:`~.grid.GOAL_REWARD_MODES`.

    Raises:
        InputError: a cell is not one legend character, the grid is not a non-empty rectangle, or
            a setting is out of range.
    """

    grid: np.ndarray
    goal_bonus: float = DEFAULT_GOAL_BONUS
    gamma: float = DEFAULT_GAMMA
    name: str = "<map>"
    goal_reward_mode: str = DEFAULT_GOAL_REWARD_MODE

    def __post_init__(self) -> None:
        raw = np.asarray(self.grid)
        if raw.dtype.kind != "U" or any(len(c) != 1 for c in raw.ravel().tolist()):
            raise InputError(f"{self.name}: map cells must be single characters")
        g = raw.astype("<U1")
        if g.ndim != 2 or g.size == 0:
            raise InputError(f"{self.name}: map must be a non-empty rectangle of cells")
        self._check_cells(g, LEGEND)
        self._check_numbers()
        g.setflags(write=False)
        object.__setattr__(self, "grid", g)

    def state_index(self) -> np.ndarray:
        """``[height, width]`` state index of each cell, -1 for obstacles."""
        return self.cell_index()

    def to_mdp(self) -> TabularMDP:
        """Compile to a :class:`TabularMDP` with the five features of the module docstring.

        Returns:
            The MDP: one state per passable cell, goals terminal, the ``S`` cells its start states
            (every non-terminal state when there is none).
        """
        g = self.grid
        cells = self.cells
        xs, ys = cells[:, 0], cells[:, 1]
        next_state, dst = self.moves()  # [S, A]
        src = g[ys, xs][:, None]  # [S, 1]
        feats = np.zeros((len(cells), 4, 5))
        bonus, offset = self.goal_rewards(dst)
        feats[..., 0] = -1.0 + bonus
        feats[..., 1] = road_feature(dst, off_road=0.0)
        feats[..., 2] = -((src == AVOID) != (dst == AVOID)).astype(float)
        feats[..., 3] = -np.broadcast_to(src == SLOW, dst.shape).astype(float)
        feats[..., 4] = -((src == TRAFFIC) != (dst == TRAFFIC)).astype(float)
        terminal = g[ys, xs] == GOAL
        starts = np.flatnonzero(g[ys, xs] == START)
        return TabularMDP(
            next_state=next_state,
            features=feats,
            terminal=terminal,
            gamma=self.gamma,
            feature_names=FEATURE_NAMES,
            start_states=starts if starts.size else None,
            state_xy=cells,
            source=self.name,
            reward_offset=offset,
        )


def parse_map(text: str, *, name: str = "<map>", goal_bonus: float = DEFAULT_GOAL_BONUS,
              gamma: float = DEFAULT_GAMMA, goal_reward_mode: str = DEFAULT_GOAL_REWARD_MODE) -> ZoneMap:
    """Parse a text map. Blank lines at the start and end are ignored; rows must be equally long.

    Args:
        text: the map, one row of legend characters per line.
        name: a label for messages and figures (a file name, say).
        goal_bonus: what entering a goal pays.
        gamma: discount factor of the compiled MDP.
        goal_reward_mode: ``"scaled"`` or ``"fixed"`` (see :class:`ZoneMap`).

    Returns:
        The map.

    Raises:
        InputError: rows of unequal length, a character outside the legend, or a setting out of
            range; the message names ``name`` and the place.
    """
    return ZoneMap(read_grid(text, name, LEGEND), goal_bonus=goal_bonus, gamma=gamma, name=name,
                   goal_reward_mode=goal_reward_mode)


def read_settings(path: Path) -> dict:
    """Read the optional settings TOML; unknown keys or wrong types raise :class:`InputError`."""
    data = read_toml(path)
    out = {}
    for key, value in data.items():
        if key == "world":
            if value != "zones":
                raise InputError(f"{path}: world = {value!r}: not a zone map (this needs a map "
                                 "of the zone world, world = 'zones' or no world key)")
            continue
        check_known(path, key, _SETTINGS)
        if key == "goal_reward_mode":
            out[key] = check_goal_reward_mode(value, str(path))
            continue
        out[key] = number_setting(path, key, value)
    check_goal_settings(path, out)
    return out


def load_map(path: str | Path) -> ZoneMap:
    """Read a text map and, if present, the settings TOML beside it (``name.toml``).

    Args:
        path: the map's text file.

    Returns:
        The map, named by its path.

    Raises:
        InputError: the file is missing or not a UTF-8 text map, or its settings TOML has an
            unknown key or a value of the wrong type.
    """
    path = map_file(path, "map")
    hint = "; pass an MDP archive with --mdp" if path.suffix == ".npz" else ""
    text = read_text(path, f"not a text map (UTF-8){hint}")
    settings_path = path.with_suffix(".toml")
    settings = read_settings(settings_path) if settings_path.is_file() else {}
    return parse_map(text, name=str(path), **settings)


def bundled_maps() -> list[str]:
    """Names of the example maps shipped with the package."""
    files = resources.files("expertise_irl") / "maps"
    return sorted(p.name[:-4] for p in files.iterdir() if p.name.endswith(".txt"))


def load_bundled(name: str) -> ZoneMap:
    """Load a bundled example map by name (see :func:`bundled_maps`).

    Args:
        name: the map's name, e.g. ``"crossroads"``.

    Returns:
        The map, named ``bundled:<name>``, with its bundled settings.

    Raises:
        InputError: no bundled map has that name (the message lists those that do).
    """
    if name not in bundled_maps():
        raise InputError(f"no bundled map {name!r} (available: {', '.join(bundled_maps())})")
    base = resources.files("expertise_irl") / "maps"
    text = (base / f"{name}.txt").read_text(encoding="utf-8")
    toml = base / f"{name}.toml"
    settings = {}
    if toml.is_file():
        with resources.as_file(toml) as p:
            settings = read_settings(Path(p))
    return parse_map(text, name=f"bundled:{name}", **settings)


def resolve_map(spec: str | Path) -> ZoneMap:
    """A map from a file path, or a bundled map by name if no such file exists."""
    p = Path(spec)
    if p.is_file():
        return load_map(p)
    if str(spec) in bundled_maps():
        return load_bundled(str(spec))
    raise InputError(
        f"{spec}: no such map file, and no bundled map of that name "
        f"(bundled: {', '.join(bundled_maps())})"
    )


def reachable_from_goals(grid: np.ndarray) -> np.ndarray:
    """``[height, width]`` bool: passable cells connected to a goal (4-neighbourhood)."""
    h, w = grid.shape
    passable = grid != OBSTACLE
    seen = grid == GOAL
    frontier = list(zip(*np.nonzero(seen), strict=True))
    while frontier:
        nxt = []
        for y, x in frontier:
            for dx, dy in ACTION_DELTAS:
                yy, xx = y + dy, x + dx
                if 0 <= yy < h and 0 <= xx < w and passable[yy, xx] and not seen[yy, xx]:
                    seen[yy, xx] = True
                    nxt.append((yy, xx))
        frontier = nxt
    return seen


def _zones(rng: np.random.Generator, w: int, h: int, max_zones: int) -> np.ndarray:
    """A ``[h, w]`` free grid with up to ``max_zones`` roads, then as many rectangles of each of
    slow, traffic, avoid and obstacle, painted in that order (:func:`generate_map`'s draws)."""
    g = np.full((h, w), FREE, dtype="<U1")

    def rect(max_frac: float) -> tuple[int, int, int, int]:
        rw = int(rng.integers(1, max(2, int(w * max_frac)) + 1))
        rh = int(rng.integers(1, max(2, int(h * max_frac)) + 1))
        x0 = int(rng.integers(0, w - min(rw, w) + 1))
        y0 = int(rng.integers(0, h - min(rh, h) + 1))
        return x0, y0, min(rw, w), min(rh, h)

    for _z in range(int(rng.integers(0, max_zones + 1))):  # roads
        thick = int(rng.integers(1, 3))
        if rng.random() < 0.5:  # horizontal
            length = int(rng.integers(max(2, w // 3), w + 1))
            x0, y0 = int(rng.integers(0, w - length + 1)), int(rng.integers(0, h - thick + 1))
            g[y0:y0 + thick, x0:x0 + length] = ">" if rng.random() < 0.5 else "<"
        else:
            length = int(rng.integers(max(2, h // 3), h + 1))
            x0, y0 = int(rng.integers(0, w - thick + 1)), int(rng.integers(0, h - length + 1))
            g[y0:y0 + length, x0:x0 + thick] = "v" if rng.random() < 0.5 else "^"
    for ch, frac in ((SLOW, 0.3), (TRAFFIC, 0.3), (AVOID, 0.25), (OBSTACLE, 0.2)):
        for _z in range(int(rng.integers(0, max_zones + 1))):
            x0, y0, rw, rh = rect(frac)
            g[y0:y0 + rh, x0:x0 + rw] = ch
    return g


def generate_map(
    rng: np.random.Generator,
    *,
    min_size: int = 10,
    max_size: int = 30,
    width: int | None = None,
    height: int | None = None,
    max_zones: int = 4,
    goal_bonus: float = DEFAULT_GOAL_BONUS,
    gamma: float = DEFAULT_GAMMA,
    name: str = "<generated>",
    goal_reward_mode: str = DEFAULT_GOAL_REWARD_MODE,
) -> ZoneMap:
    """A random zone map following Sec. V-A, with the goal reachable from every free cell.

    Size is drawn uniformly in ``[min_size, max_size]`` per side unless given. For each
    zone type (road, slow, traffic, avoid, obstacle, painted in that order) 0..``max_zones``
    rectangles are placed at random positions with random sizes; roads are strips one or
    two cells wide along a random axis and direction. One goal is placed on a random
    non-obstacle cell; any pocket cut off from it by obstacles is filled with obstacles,
    so the compiled MDP always passes validation. Draws are retried (at most 100 times)
    until at least half of the grid stays passable.

    Args:
        rng: the random generator every draw comes from.
        min_size: the smallest side drawn.
        max_size: the largest side drawn.
        width: the width, instead of a draw.
        height: the height, instead of a draw.
        max_zones: the most rectangles (or roads) of each zone type.
        goal_bonus: what entering the goal pays.
        gamma: discount factor of the compiled MDP.
        name: a label for messages and figures.
        goal_reward_mode: ``"scaled"`` or ``"fixed"`` (see :class:`ZoneMap`).

    Returns:
        The map.

    Raises:
        InputError: ``min_size`` below 3 or above ``max_size``, or ``width``/``height`` below 3.
        RuntimeError: 100 draws left less than half of the grid passable.
    """
    if min_size < 3 or max_size < min_size:
        raise InputError(f"need 3 <= min_size <= max_size, got {min_size}, {max_size}")
    for side, value in (("width", width), ("height", height)):
        if value is not None and value < 3:
            raise InputError(f"{side} must be at least 3, got {value}")
    for _ in range(100):
        w = width if width is not None else int(rng.integers(min_size, max_size + 1))
        h = height if height is not None else int(rng.integers(min_size, max_size + 1))
        g = _zones(rng, w, h, max_zones)
        free = np.argwhere(g != OBSTACLE)
        if len(free) < 2:
            continue
        gy, gx = free[int(rng.integers(len(free)))]
        g[gy, gx] = GOAL
        reach = reachable_from_goals(g)
        g[(g != OBSTACLE) & ~reach] = OBSTACLE
        if reach.sum() >= 0.5 * w * h and reach.sum() >= 2:
            return ZoneMap(g, goal_bonus=goal_bonus, gamma=gamma, name=name,
                           goal_reward_mode=goal_reward_mode)
    raise RuntimeError("could not generate a map with at least half the grid passable")
