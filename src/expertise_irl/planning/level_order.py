"""Gauss–Seidel sweeps in order of the distance to a goal (the ``levels`` solver method).

A red-black sweep moves values two states per sweep, so a person who follows long paths or
circles loops for ever (small β) needs ~1,200 sweeps at γ = 0.99 whatever the start. Here the
states are updated level by level, a level being the states at one distance from a terminal
state: first from the goal outwards, then back inwards (a symmetric sweep). A move towards the
goal (distance − 1) then reads a value updated earlier in the outward pass, and a move away
from it (distance ≥ + 1) one updated earlier in the inward pass, so one symmetric sweep carries
values along a whole run of moves towards the goal followed by a run away from it: down a path
to the goal in one pass, round a loop (one run out, one back) in one sweep. In a grid world no
move stays within a level (each move changes the parity of the distance); elsewhere moves
within a level read the values of the pass before, which is still a valid block Gauss–Seidel
sweep.

Levels are cut into blocks of :data:`BLOCK` states (the last block of a level padded with
repeats of its first state, which recompute and write the same value), so every pass is one
``fori_loop`` over blocks of one shape. A pass costs about what a red-black sweep costs per
state. Over-relaxation is not used: along a chain updated in order it would compound as
(γω)^length.

Without a caller's start, the sweeps start from :func:`approach_start`: the values of the soft
walk that may only move towards the goal, found exactly in one outward pass (each level reads
the level below it, already final). Dropping moves only lowers a backup, so these values are a
lower bound that the sweeps rise from monotonically; for a person heading for the goal they are
nearly the solution, where a zero start lies hundreds of nats above the values of states far
from the goal and the sweeps bring it down only as γ per move.

:func:`level_start` runs these sweeps as a pool of lanes, as :func:`.kernels.jump_start` does;
each hypothesis stops when its change meets the tolerance, when its sweeps stop contracting
faster than four red-black sweeps would (a wandering person, whom the red-black pool's
over-relaxation serves better), or after a cap. Nothing here certifies anything: the values
only start :func:`.kernels.solve_pool`, whose plain red-black sweeps certify the tolerance.
"""

from __future__ import annotations

import weakref
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..mdp import TabularMDP
from ..models import backup
from .kernels import Prepared, _from_lanes, _to_lanes, drain, goal_distance, hand_out, repack
from .screening import gate_check

#: States per block of a level (padded); 64–128 were fastest at 200 × 200 on 2 cores.
BLOCK = 64
#: Symmetric sweeps every hypothesis makes before it must show progress.
LEVEL_GRACE = 8
#: A hypothesis keeps sweeping in level order while its change shrinks at least as much per
#: symmetric sweep (two passes) as four plain red-black sweeps would shrink it, γ^LEVEL_RATE_POWER
#: (0.923 at γ = 0.99), over the last :data:`LEVEL_WINDOW`.
LEVEL_RATE_POWER = 8
#: Symmetric sweeps over which the rate is measured (it is uneven from one to the next).
LEVEL_WINDOW = 4
#: Most symmetric sweeps one hypothesis makes.
LEVEL_MAX = 1000


class Levels(NamedTuple):
    """The solver rows in level order, in blocks of :data:`BLOCK`."""

    rows: jnp.ndarray  # [n_blocks, BLOCK] solver rows (padding repeats the block's first row)
    features: jnp.ndarray  # [n_blocks, A, BLOCK, K]
    next_row: jnp.ndarray  # [n_blocks, A, BLOCK]
    avail: jnp.ndarray  # [n_blocks, A, BLOCK]
    log_n_actions: jnp.ndarray  # [n_blocks, BLOCK]
    toward: jnp.ndarray  # [n_blocks, A, BLOCK] available moves to the level below (towards the goal)


def level_blocks(mdp: TabularMDP, prep: Prepared, block: int = BLOCK) -> Levels:
    """The blocks of :class:`Levels` for ``mdp`` in ``prep``'s layout (every state of a
    :class:`~expertise_irl.mdp.TabularMDP` reaches a terminal state)."""
    dist = goal_distance(mdp)
    live = ~mdp.terminal
    blocks = []
    for k in range(1, int(dist.max()) + 1):
        r = prep.rows[np.flatnonzero(live & (dist == k))]
        for i in range(0, len(r), block):
            c = r[i:i + block]
            blocks.append(np.concatenate([c, np.repeat(c[:1], block - len(c))]))
    rows = np.array(blocks)
    nb, A = prep.n_block, prep.features.shape[1]
    flat = lambda x: np.moveaxis(np.asarray(x), 0, 1).reshape(A, 2 * nb, *np.shape(x)[3:])  # noqa: E731
    feats, nxt, ok = flat(prep.features), flat(prep.next_row), flat(prep.avail)
    log_n = np.asarray(prep.log_n_actions).reshape(2 * nb)
    row_dist = np.full(prep.n_rows, -1, dtype=np.int64)  # padding and the dummy row: -1
    row_dist[prep.rows] = dist
    nxt_b, ok_b = np.moveaxis(nxt[:, rows], 0, 1), np.moveaxis(ok[:, rows], 0, 1)
    toward = ok_b & (row_dist[nxt_b] == row_dist[rows][:, None, :] - 1)
    return Levels(jnp.asarray(rows, jnp.int32), jnp.asarray(np.moveaxis(feats[:, rows], 0, 1)),
                  jnp.asarray(nxt_b, jnp.int32), jnp.asarray(ok_b), jnp.asarray(log_n[rows]),
                  jnp.asarray(toward))


_LEVELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def levels_of(mdp: TabularMDP, prep: Prepared, dtype: str) -> Levels:
    """:func:`level_blocks`, kept while the (immutable) MDP lives."""
    per_mdp = _LEVELS.setdefault(mdp, {})
    if dtype not in per_mdp:
        per_mdp[dtype] = level_blocks(mdp, prep)
    return per_mdp[dtype]


def _update_block(lv: Levels, i, moves, w, v, gamma, model: str):
    """``v`` with block ``i`` backed up over the actions ``moves [A, BLOCK]`` only."""
    r = jnp.where(moves[..., None], jnp.einsum("abk,kl->abl", lv.features[i], w), -jnp.inf)
    q = r + gamma * v.at[lv.next_row[i]].get(mode="promise_in_bounds")  # [A, BLOCK, L]
    new, _ = backup(model, q, lv.log_n_actions[i][:, None], axis=0)
    return v.at[lv.rows[i]].set(new, mode="promise_in_bounds")


def symmetric_sweep(lv: Levels, w, v, gamma, model: str):
    """One symmetric sweep of one lane group: outwards over the blocks, then inwards.
    Returns ``(v, change [L])`` with the change ``max |v' − v|`` over the whole sweep."""
    n = lv.rows.shape[0]

    def body(j, v):
        i = jnp.where(j < n, j, 2 * n - 1 - j)
        return _update_block(lv, i, lv.avail[i], w, v, gamma, model)

    out = jax.lax.fori_loop(0, 2 * n, body, v)
    return out, jnp.max(jnp.abs(out - v), axis=0)


_sym_groups = jax.vmap(symmetric_sweep, in_axes=(None, 0, 0, None, None))


def approach_pass(lv: Levels, w, v, gamma, model: str):
    """One outward pass of one lane group that backs up only the moves towards the goal (to the
    level below), so each level reads the values just written for the level below it."""

    return jax.lax.fori_loop(0, lv.rows.shape[0],
                             lambda i, v: _update_block(lv, i, lv.toward[i], w, v, gamma, model), v)


@partial(jax.jit, static_argnames=("lanes", "model"))
def _approach_impl(lv: Levels, weights, v0, gamma, *, lanes: int, model: str):
    dtype = lv.features.dtype
    groups = weights.shape[0] // lanes
    w, v = _to_lanes(weights.astype(dtype), groups), _to_lanes(v0.astype(dtype), groups)
    out = jax.lax.map(lambda x: approach_pass(lv, x[0], x[1], gamma.astype(dtype), model), (w, v))
    return _from_lanes(out)


def approach_start(lv: Levels, weights, v0, gamma, *, lanes: int, model: str = "maxent"):
    """The scaled values of the soft walk that may only move towards the goal, one lane group at
    a time: ``[n, rows]`` for ``weights [n, K']``, with ``v0 [n, rows]``'s terminal (zero) values.

    Every state has a move to the level below it, so each value is finite; dropping moves can
    only lower a backup, so these values ``v`` satisfy ``v ≤ T v`` (T the Bellman backup of any
    of the three observation models) and the sweeps rise from them monotonically to the
    solution. On a large plan a person who heads for the goal starts within a few nats of their
    values everywhere, where a zero start is hundreds of nats above them far from the goal and
    sweeps down only as γ per move (docs/performance.md, "Large worlds").
    """
    n = weights.shape[0]
    pad = -n % lanes
    if pad:
        weights = jnp.concatenate([weights, jnp.repeat(weights[-1:], pad, 0)])
        v0 = jnp.concatenate([v0, jnp.repeat(v0[-1:], pad, 0)])
    return _approach_impl(lv, weights, v0, gamma, lanes=lanes, model=model)[:n]


@partial(jax.jit, static_argnames=("groups", "lanes"))
def _level_init(weights, v0, best, *, groups: int, lanes: int):
    H = weights.shape[0]
    slots = groups * lanes
    lane_h = jnp.arange(slots)
    active = lane_h < H
    lane_h = jnp.where(active, lane_h, 0)
    return (_to_lanes(weights[lane_h], groups), _to_lanes(v0[lane_h], groups), lane_h, active,
            jnp.zeros(slots, jnp.int64), jnp.minimum(slots, H),  # sweeps, next hypothesis
            jnp.full((LEVEL_WINDOW, slots), jnp.inf, v0.dtype),  # the last changes, oldest first
            jnp.zeros_like(v0), jnp.zeros(H, jnp.int64),  # outputs: values, sweeps
            jnp.zeros(H, v0.dtype), jnp.asarray(best, v0.dtype))  # the gate's: tol_h, best log mass


@partial(jax.jit, static_argnames=("groups", "lanes", "model"))
def _level_run(lv: Levels, weights, v0, carry, gamma, thresh, floor, gate, rising, *, groups: int,
               lanes: int, model: str):
    """Run the level pool from ``carry`` until every lane is idle, or until nothing is left to hand
    out and at most ``floor`` lanes are busy."""
    dtype = lv.features.dtype
    gamma, thresh = gamma.astype(dtype), thresh.astype(dtype)
    H = weights.shape[0]

    def cond(c):
        return jnp.any(c[3]) & ((c[5] < H) | (jnp.sum(c[3]) > floor))

    def body(c):
        w, v, lane_h, active, k, next_h, past, out_v, out_k, out_t, best = c
        v_before = v
        v, d = _sym_groups(lv, w, v, gamma, model)
        d = _from_lanes(d)
        k = k + active.astype(k.dtype)
        ok = jnp.isfinite(d)
        fast = d <= gamma ** (LEVEL_RATE_POWER * LEVEL_WINDOW) * past[0]
        go = ok & (d > thresh) & (k < LEVEL_MAX) & ((k < LEVEL_GRACE) | fast)
        if gate is not None:  # certified elimination (screening.py): a symmetric sweep is a γ²-contraction
            vmax = _from_lanes(jnp.max(jnp.abs(v), axis=1))
            # from the approach start the sweeps rise to the solution (screening.py); a fall flags rounding
            below = rising & (_from_lanes(jnp.min(v - v_before, axis=1)) >= 0)
            stop, best, tol_h = gate_check(gate, _from_lanes(v[:, gate.rows, :]), d, vmax, lane_h, active,
                                           best, gamma * gamma / (1.0 - gamma * gamma), below)
            out_t = out_t.at[jnp.where(stop, lane_h, H)].set(tol_h, mode="drop")
            go = go & ~stop
        fin = active & ~go
        past = jnp.concatenate([past[1:], d[None]])
        take, (w, v, lane_h, active, k, next_h, out_v, out_k) = hand_out(
            fin, v, (w, v, lane_h, active, k, next_h, out_v, out_k), weights, v0, groups)
        past = jnp.where(take, jnp.inf, past)
        return w, v, lane_h, active, k, next_h, past, out_v, out_k, out_t, best

    return jax.lax.while_loop(cond, body, carry)


@partial(jax.jit, static_argnames=("groups",))
def _level_repack(carry, *, groups: int):
    w, v, lane_h, active, k, next_h, past, *rest = carry
    (w, v), (lane_h, active, k, past) = repack(active, (w, v), (lane_h, active, k, past), groups)
    return (w, v, lane_h, active, k, next_h, past, *rest)


def _level_impl(lv: Levels, weights, v0, gamma, thresh, *, groups: int, lanes: int,
                model: str, gate, best, rising: bool):
    dtype = lv.features.dtype
    weights, v0 = jnp.asarray(weights).astype(dtype), jnp.asarray(v0).astype(dtype)
    gamma, thresh = jnp.asarray(gamma), jnp.asarray(thresh)
    def run(c, floor, g):
        return _level_run(lv, weights, v0, c, gamma, thresh, floor, gate, jnp.asarray(rising), groups=g,
                          lanes=lanes, model=model)

    carry = drain(run, lambda c, g: _level_repack(c, groups=g),
                  _level_init(weights, v0, best, groups=groups, lanes=lanes), v0.shape[1], groups, lanes,
                  to_one=gate is not None)
    return carry[7], carry[8], carry[9], float(carry[10])


def level_start(lv: Levels, weights, v0, gamma, thresh, *, groups: int, lanes: int, model: str = "maxent",
                gate=None, best: float = -np.inf, rising: bool = False):
    """Starting values for :func:`.kernels.solve_pool` from symmetric level-order sweeps, with a
    pool of ``groups × lanes`` lanes that take the next hypothesis as each one stops.

    A hypothesis stops when its change over a symmetric sweep is at most ``thresh``, when it has
    not shrunk by γ^:data:`LEVEL_RATE_POWER` per sweep over the last :data:`LEVEL_WINDOW` (after
    :data:`LEVEL_GRACE`), after :data:`LEVEL_MAX`, or when it is not finite (its values are then
    replaced by its start ``v0``, for the pool to solve from there). Each hypothesis' result
    depends on its own weights and start only, not on its lane or the others in the pool. On a
    large MDP the pool moves to fewer lane groups once its busy lanes fit and nothing is left to
    hand out (:func:`.kernels.shrink_floor`).

    With ``gate`` (:class:`.screening.GateArrays` for these hypotheses), a hypothesis also stops
    when it is certainly eliminated (:mod:`.screening`), starting from the certain log mass
    ``best``; its values are then final. ``rising``: ``v0`` is below the solution
    (:func:`approach_start`'s values), so the sweeps' values are too (a tighter bound, :mod:`.screening`).

    Returns ``(v [n, rows], symmetric sweeps [n], tol_h [n], best)``: ``tol_h`` is the tolerance
    the values of each hypothesis the gate stopped certify (0 for the others, whose values only
    start the pool), ``best`` the best certain log mass seen (as given without a gate).
    """
    v, k, tol_h, best = _level_impl(lv, weights, v0, gamma, thresh, groups=groups, lanes=lanes, model=model,
                                    gate=gate, best=best, rising=rising)
    v = jnp.where(jnp.isfinite(v).all(axis=1, keepdims=True), v, v0)
    return v, k, np.asarray(tol_h), best
