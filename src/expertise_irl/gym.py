"""Gymnasium adapter: the zone world as a ``gymnasium.Env`` and a wrapper that records episodes.

:class:`ZoneEnv` is the grid of a :class:`~expertise_irl.worlds.zones.ZoneMap`:
observations are state indices (``Discrete(S)``), actions the four moves
(``Discrete(4)``: up, down, left, right), the reward of a move is ``θ · φ(s, a)``
with the map's five features (plus the goal reward on entering the goal under
``goal_reward_mode = "fixed"``: ``TabularMDP.reward``), and an episode terminates on entering the goal
(or is truncated after ``max_steps`` moves). A move into a wall or off the map
leaves the state unchanged, gives reward 0 and ``info["refused"] = True``; it is
not a transition of the MDP, so :class:`RecordTrajectories` does not record it.
``info["action_mask"]`` marks the available moves. ``render_mode="rgb_array"``
draws the map in the renderer's colours, the goal, the path of the current
episode and the agent.

:class:`RecordTrajectories` keeps every accepted ``(state, action)`` pair, one
episode per ``reset``, and returns them as :class:`~expertise_irl.demos.trajectories.Trajectories`
(or writes the demonstration CSV), so data collected with Gymnasium tools feeds
every inference of this library::

    env = RecordTrajectories(ZoneEnv("crossroads", render_mode="rgb_array"))
    obs, info = env.reset(seed=0)
    ...
    DiscreteBelief.from_mdp(env.mdp, hyp).update(env.trajectories())

The environment is registered as ``expertise_irl/ZoneWorld-v0``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces
from matplotlib.colors import to_rgb

from .demos.csv_io import write_demos_csv
from .demos.trajectories import Trajectories
from .errors import InputError
from .mdp import TabularMDP
from .plots.maps import ARROW_COLOR, GOAL_COLOR, GRID_COLOR, PATH_COLORS, ROAD_VECTORS, ZONE_COLORS
from .worlds.zones import ZoneMap, resolve_map

ENV_ID = "expertise_irl/ZoneWorld-v0"
DEFAULT_MAX_STEPS = 500


def _rgb(colour: str) -> np.ndarray:
    return (np.array(to_rgb(colour)) * 255).round().astype(np.uint8)


class ZoneEnv(gymnasium.Env):
    """A zone map as a Gymnasium environment (module docstring).

    Args:
        zone_map: a :class:`ZoneMap`, a map file or a bundled map name.
        theta: ``[K]`` reward weights (default: length only, ``(1, 0, 0, 0, 0)``).
        max_steps: truncate an episode after this many accepted moves.
        render_mode: None or ``"rgb_array"``.
        cell_px: pixels per cell of the rendering.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 8}

    def __init__(self, zone_map: ZoneMap | str | Path = "crossroads", theta=None, *,
                 max_steps: int = DEFAULT_MAX_STEPS, render_mode: str | None = None, cell_px: int = 16):
        if not isinstance(zone_map, ZoneMap):
            zone_map = resolve_map(zone_map)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise InputError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
            raise InputError(f"max_steps must be an integer >= 1, got {max_steps!r}")
        if isinstance(cell_px, bool) or not isinstance(cell_px, int) or not 4 <= cell_px <= 64:
            raise InputError(f"cell_px must be an integer in [4, 64], got {cell_px!r}")
        self.zone_map = zone_map
        self.mdp: TabularMDP = zone_map.to_mdp()
        K = self.mdp.n_features
        th = np.eye(K)[0] if theta is None else np.asarray(theta, dtype=np.float64)
        if th.shape != (K,) or not np.all(np.isfinite(th)):
            raise InputError(f"theta must be {K} finite numbers ({', '.join(self.mdp.feature_names)})")
        self.theta = th
        self.max_steps = max_steps
        self.render_mode = render_mode
        self.cell_px = cell_px
        self.observation_space = spaces.Discrete(self.mdp.n_states)
        self.action_space = spaces.Discrete(self.mdp.n_actions)
        self._state = int(self.mdp.initial_states()[0])
        self._steps = 0
        self._path: list[int] = [self._state]
        self._background: np.ndarray | None = None

    # ---------------------------------------------------------------- gym API
    def _info(self, **extra) -> dict[str, Any]:
        mask = (self.mdp.next_state[self._state] >= 0) & ~self.mdp.terminal[self._state]
        return {"xy": tuple(int(v) for v in self.mdp.state_xy[self._state]),
                "action_mask": mask.astype(np.int8), **extra}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode: at ``options["start"]`` (a state) or ``options["start_xy"]`` (a cell),
        else at a start drawn uniformly from the map's start cells (every non-goal cell if none)."""
        super().reset(seed=seed)
        options = options or {}
        unknown = set(options) - {"start", "start_xy"}
        if unknown:
            raise InputError(f"unknown reset option(s): {', '.join(sorted(map(str, unknown)))}")
        if "start_xy" in options:
            x, y = (int(v) for v in options["start_xy"])
            hit = np.flatnonzero((self.mdp.state_xy[:, 0] == x) & (self.mdp.state_xy[:, 1] == y))
            if hit.size == 0:
                raise InputError(f"start_xy ({x}, {y}) is not a free cell of {self.zone_map.name}")
            s = int(hit[0])
        elif "start" in options:
            s = int(options["start"])
            if not 0 <= s < self.mdp.n_states:
                raise InputError(f"start {s} is not a state index in [0, {self.mdp.n_states})")
        else:
            starts = self.mdp.initial_states()
            s = int(starts[self.np_random.integers(len(starts))])
        if self.mdp.terminal[s]:
            raise InputError(f"start {self.mdp.describe_state(s)} is a goal")
        self._state, self._steps, self._path = s, 0, [s]
        return s, self._info()

    def step(self, action):
        a = int(action)
        if not self.action_space.contains(a):
            raise InputError(f"action {action!r} is not in {self.action_space}")
        s = self._state
        nxt = int(self.mdp.next_state[s, a])
        if nxt < 0 or self.mdp.terminal[s]:
            return s, 0.0, bool(self.mdp.terminal[s]), self._steps >= self.max_steps, self._info(refused=True)
        reward = float(self.theta @ self.mdp.features[s, a]) + (
            float(self.mdp.reward_offset[s, a]) if self.mdp.has_offset else 0.0)
        phi = self.mdp.features[s, a].copy()
        self._state = nxt
        self._steps += 1
        self._path.append(nxt)
        terminated = bool(self.mdp.terminal[nxt])
        truncated = not terminated and self._steps >= self.max_steps
        return nxt, reward, terminated, truncated, self._info(refused=False, features=phi, state=s, action=a)

    # -------------------------------------------------------------- rendering
    def _draw_background(self) -> np.ndarray:
        g = self.zone_map.grid
        h, w = g.shape
        px = self.cell_px
        img = np.zeros((h, w, 3), dtype=np.uint8)
        for ch, col in ZONE_COLORS.items():
            img[g == ch] = _rgb(col)
        img = np.repeat(np.repeat(img, px, axis=0), px, axis=1)
        yy, xx = np.mgrid[0:px, 0:px] + 0.5
        u, v = (xx - px / 2) / px, (yy - px / 2) / px  # cell-centred coordinates in [-0.5, 0.5]
        for ch, (dx, dy) in ROAD_VECTORS.items():  # a triangle pointing along the road
            along, across = u * dx + v * dy, np.abs(u * dy - v * dx)
            tri = (along > -0.25) & (along < 0.3) & (across < (0.3 - along) * 0.55)
            for y, x in np.argwhere(g == ch):
                img[y * px:(y + 1) * px, x * px:(x + 1) * px][tri] = _rgb(ARROW_COLOR)
        disc = u**2 + v**2 < 0.32**2
        for y, x in np.argwhere(g == "G"):
            img[y * px:(y + 1) * px, x * px:(x + 1) * px][disc] = _rgb(GOAL_COLOR)
        img[::px, :] = _rgb(GRID_COLOR)
        img[:, ::px] = _rgb(GRID_COLOR)
        return img

    def render(self):
        """``[H·cell_px, W·cell_px, 3]`` uint8 image (``render_mode="rgb_array"``), else None."""
        if self.render_mode != "rgb_array":
            return None
        if self._background is None:
            self._background = self._draw_background()
        img = self._background.copy()
        px = self.cell_px
        yy, xx = np.mgrid[0:px, 0:px] + 0.5
        r2 = ((xx - px / 2) / px) ** 2 + ((yy - px / 2) / px) ** 2
        for s in self._path[:-1]:
            x, y = self.mdp.state_xy[s]
            img[y * px:(y + 1) * px, x * px:(x + 1) * px][r2 < 0.12**2] = _rgb(PATH_COLORS[0])
        x, y = self.mdp.state_xy[self._state]
        img[y * px:(y + 1) * px, x * px:(x + 1) * px][r2 < 0.34**2] = _rgb(PATH_COLORS[1])
        return img


class RecordTrajectories(gymnasium.Wrapper):
    """Record the accepted moves of a :class:`ZoneEnv` (however it is wrapped), one episode per reset.

    Episodes are labelled 0, 1, 2, ... in order; an episode with no accepted move is not kept.
    """

    def __init__(self, env: gymnasium.Env):
        super().__init__(env)
        if not isinstance(env.unwrapped, ZoneEnv):
            raise InputError("RecordTrajectories wraps a ZoneEnv (possibly inside other wrappers)")
        self._done: list[list[tuple[int, int]]] = []
        self._current: list[tuple[int, int]] = []

    @property
    def mdp(self) -> TabularMDP:
        return self.env.unwrapped.mdp

    def reset(self, **kwargs):
        if self._current:
            self._done.append(self._current)
        self._current = []
        return self.env.reset(**kwargs)

    def step(self, action):
        s = self.env.unwrapped._state
        out = self.env.step(action)
        if not out[4].get("refused", False):
            self._current.append((int(s), int(action)))
        return out

    def trajectories(self) -> Trajectories:
        """Every recorded episode (the current one included if it has a move)."""
        episodes = [*self._done, self._current] if self._current else list(self._done)
        rows = [(e, t, s, a) for e, ep in enumerate(episodes) for t, (s, a) in enumerate(ep)]
        if not rows:
            z = np.zeros(0, dtype=np.int64)
            return Trajectories(z, z, z, z)
        ep, st, s, a = (np.array(c, dtype=np.int64) for c in zip(*rows, strict=True))
        return Trajectories(ep, st, s, a)

    def write_csv(self, path: str | Path) -> None:
        """Write the recorded episodes as the demonstration CSV (``episode,step,x,y``)."""
        write_demos_csv(path, self.trajectories(), self.mdp)


if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="expertise_irl.gym:ZoneEnv")
