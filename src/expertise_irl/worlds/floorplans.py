"""Large warehouse floor plans drawn at random, for measuring the solver on large worlds.

:func:`generate_floor_plan` lays out a ``size × size`` floor in the warehouse world's legend
(:mod:`expertise_irl.worlds.warehouse`): one-way roads every ``road_every_rows`` rows
(alternating ``>`` and ``<``) and every ``road_every_cols`` columns (alternating ``v`` and
``^``; a crossing keeps the row's direction), restricted blocks (``x``) of 3–6 cells a side
between the roads, scattered single obstacles (``#``) off the roads, one goal near the
bottom-right corner and one start near the top-left corner, so the goal is about a diameter
away from the start. Any pocket cut off from the goal is filled with obstacles, so the
compiled MDP always validates. The same arguments always draw the same plan.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .grid import FREE, GOAL, OBSTACLE, START
from .warehouse import RESTRICTED, WarehouseMap
from .zones import reachable_from_goals

#: The discount of the generated plans (a long horizon, as on a large floor).
LARGE_GAMMA = 0.99


def generate_floor_plan(size: int, *, seed: int = 0, road_every_rows: int = 10, road_every_cols: int = 15,
                        obstacle_fraction: float = 0.012, restricted_per_1000: float = 0.6,
                        gamma: float = LARGE_GAMMA, cell_size: float = 0.5,
                        name: str | None = None) -> WarehouseMap:
    """A random ``size × size`` floor plan (see the module docstring); ``size`` >= 8."""
    if isinstance(size, bool) or not isinstance(size, int | np.integer) or size < 8:
        raise InputError(f"size must be a whole number >= 8, got {size!r}")
    if road_every_rows < 2 or road_every_cols < 2:
        raise InputError("roads must be at least 2 rows and 2 columns apart")
    if not 0.0 <= obstacle_fraction < 0.5:
        raise InputError(f"obstacle_fraction must be in [0, 0.5), got {obstacle_fraction}")
    size = int(size)
    rng = np.random.default_rng(seed)
    g = np.full((size, size), FREE, dtype="<U1")
    road = np.zeros((size, size), dtype=bool)
    for k, c in enumerate(range(road_every_cols // 2, size, road_every_cols)):
        g[:, c] = "v" if k % 2 == 0 else "^"
        road[:, c] = True
    for k, r in enumerate(range(road_every_rows // 2, size, road_every_rows)):
        g[r, :] = ">" if k % 2 == 0 else "<"
        road[r, :] = True
    for _ in range(round(restricted_per_1000 * size * size / 1000)):
        rw, rh = (int(v) for v in rng.integers(3, 7, size=2))
        x0, y0 = int(rng.integers(0, size - rw + 1)), int(rng.integers(0, size - rh + 1))
        block = g[y0:y0 + rh, x0:x0 + rw]
        block[~road[y0:y0 + rh, x0:x0 + rw]] = RESTRICTED
    n_obstacles = round(obstacle_fraction * size * size)
    off_road = np.flatnonzero(~road.ravel())
    g.ravel()[rng.choice(off_road, size=min(n_obstacles, len(off_road)), replace=False)] = OBSTACLE
    goal = (size - 3, size - 3)
    start = (2, 2)
    g[goal] = GOAL
    g[start] = START
    reach = reachable_from_goals(g)
    g[(g != OBSTACLE) & ~reach] = OBSTACLE
    return WarehouseMap(g, cell_size=cell_size, gamma=gamma,
                        name=name if name is not None else f"<floor plan {size}x{size} seed {seed}>")


def floor_plan_text(plan: WarehouseMap) -> str:
    """The text of a floor plan (one line per row), to write beside its :meth:`settings_text`."""
    return "\n".join("".join(row) for row in plan.grid.tolist()) + "\n"
