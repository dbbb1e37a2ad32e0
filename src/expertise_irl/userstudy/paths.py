"""Trajectory counts of the paper's Tables V–VI, and the optimal path of an estimate.

Counts every world has (:data:`WORLD_COUNTS`, :func:`task_counts`), of moves (s, a) in episodes:

- ``path_length``: number of moves;
- ``goal_reached``: episodes whose last move enters a goal (a terminal state);
- ``steps_to_goal``: the mean number of moves of those episodes (NaN when none did);
- ``cost_theta_hat``: the path's cost under the person's θ̂, −Σ θ̂·φ(s, a) over its moves
  (the features' part of the reward; a fixed goal reward outside θ·φ is not in it);
- ``feature_<name>``: each feature's sum Σ φ_i(s, a) over the moves.

Table V's counts of a path on a floor plan (each move ends in a cell c'; other worlds do not
define them, and get NaN, written empty):

- ``path_length``: number of moves;
- ``path_cost``: length units, 1 for a move along the heading and 2 for a turn;
- ``wrong_road_direction``: moves ending on a road cell against its direction;
- ``restricted_moves``: moves ending in a restricted cell;
- ``road_cells``: moves ending on a road cell (road usage = road_cells / path_length);
- ``direction_changes``: moves that flip the heading (the same moves that cost 2).

The optimal path (Table VI) follows the most probable action of the policy at β = 0.001
(ties to the lowest action index) from a start state until it enters a goal, or until it
would visit a state again (a deterministic policy that returns to a state loops forever).
"""

from __future__ import annotations

import numpy as np

from ..mdp import TabularMDP
from ..worlds.grid import ROAD_DIRECTIONS
from ..worlds.warehouse import ACTION_AXIS, RESTRICTED, WarehouseMap

COUNTS = (
    "path_length",
    "path_cost",
    "wrong_road_direction",
    "restricted_moves",
    "road_cells",
    "direction_changes",
)
#: Table V's counts that only a floor plan defines.
PLAN_COUNTS = COUNTS[1:]


def world_counts(feature_names) -> tuple[str, ...]:
    """The counts every world has, after ``path_length``."""
    return ("goal_reached", "steps_to_goal", "cost_theta_hat", *(f"feature_{f}" for f in feature_names))
#: β of the optimal trajectories (the paper's "high expertise coefficient").
OPTIMAL_BETA = 0.001
_OPPOSITE = np.array([1, 0, 3, 2])


def path_counts(plan: WarehouseMap, mdp: TabularMDP, states, actions) -> dict[str, int]:
    """The Table V counts of the moves ``(states[i], actions[i])`` (any number of episodes)."""
    states = np.asarray(states, dtype=np.int64)
    actions = np.asarray(actions, dtype=np.int64)
    if len(states) == 0:
        return dict.fromkeys(COUNTS, 0)
    nxt = mdp.next_state[states, actions]
    heading = np.asarray(mdp.state_heading)
    turn = ACTION_AXIS[actions] != heading[states]
    cells = plan.state_cells()[nxt]  # (col, row) of the cell each move ends in
    ch = plan.grid[cells[:, 1], cells[:, 0]]
    road_dir = np.full(len(ch), -1)
    for c, d in ROAD_DIRECTIONS.items():
        road_dir[ch == c] = d
    on_road = road_dir >= 0
    against = on_road & (actions == _OPPOSITE[np.maximum(road_dir, 0)])
    return {
        "path_length": len(states),
        "path_cost": int(len(states) + turn.sum()),
        "wrong_road_direction": int(against.sum()),
        "restricted_moves": int((ch == RESTRICTED).sum()),
        "road_cells": int(on_road.sum()),
        "direction_changes": int((heading[nxt] != heading[states]).sum()),
    }


def greedy_path(mdp: TabularMDP, log_policy: np.ndarray, start: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(states, actions, reached_goal)`` following the most probable action from ``start``.

    ``log_policy`` is ``[S, A]``. Stops on entering a terminal state, or before revisiting a
    state (``reached_goal`` False).
    """
    best = np.argmax(np.where(np.isfinite(log_policy), log_policy, -np.inf), axis=1)
    seen = np.zeros(mdp.n_states, dtype=bool)
    s = int(start)
    states, actions = [], []
    while not mdp.terminal[s] and not seen[s]:
        seen[s] = True
        a = int(best[s])
        states.append(s)
        actions.append(a)
        s = int(mdp.next_state[s, a])
    return np.asarray(states, dtype=np.int64), np.asarray(actions, dtype=np.int64), bool(mdp.terminal[s])


def task_counts(plan: WarehouseMap | None, mdp: TabularMDP, states, actions, episodes,
                theta) -> dict[str, float]:
    """Every world's counts of the moves ``(states[i], actions[i])`` of episodes ``episodes[i]`` under
    θ̂ ``theta``, then Table V's (NaN without a floor plan ``plan``); keys :data:`COUNTS` then
    :func:`world_counts`."""
    states = np.asarray(states, dtype=np.int64)
    actions = np.asarray(actions, dtype=np.int64)
    episodes = np.asarray(episodes)
    if plan is not None:
        out: dict[str, float] = dict(path_counts(plan, mdp, states, actions))
    else:
        out = {"path_length": len(states), **dict.fromkeys(PLAN_COUNTS, float("nan"))}
    phi = mdp.features[states, actions] if len(states) else np.zeros((0, mdp.n_features))
    steps, reached = [], 0
    for label in dict.fromkeys(episodes.tolist()):
        m = np.flatnonzero(episodes == label)
        if mdp.terminal[mdp.next_state[states[m[-1]], actions[m[-1]]]]:
            reached += 1
            steps.append(len(m))
    out["goal_reached"] = reached
    out["steps_to_goal"] = float(np.mean(steps)) if steps else float("nan")
    out["cost_theta_hat"] = float(-(phi @ np.asarray(theta, dtype=float)).sum()) + 0.0  # (no −0.0)
    for i, f in enumerate(mdp.feature_names):
        out[f"feature_{f}"] = float(phi[:, i].sum())
    return out
