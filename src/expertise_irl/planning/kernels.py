"""JAX kernels of batched soft value iteration (used by :mod:`expertise_irl.planning.soft_vi`).

Layout. States are split into two blocks by the parity of their distance to a goal
(:func:`sweep_blocks`); a sweep updates block 0, then block 1 with the fresh block-0
values (red-black Gauss–Seidel). Hypotheses are the minor axis, in *lanes* (8 float64 on
an AVX-512 machine; the width is chosen per machine by :mod:`expertise_irl.planning.tuning`), and
several lane groups are vmapped side by side, which lets XLA spread them over the cores.
Everything is in scaled units: with weights ``w = θ'/β`` the reward is ``r = w·φ'`` and
``V = β v``, where φ' and θ' are the MDP's :meth:`~expertise_irl.mdp.TabularMDP.reward_basis`
and :meth:`~expertise_irl.mdp.TabularMDP.reward_weights` (the features and θ, plus a fixed
reward not weighted by θ as one more feature of weight 1 where the MDP has one). The backup
itself is the observation model's (:func:`expertise_irl.models.backup`, a static argument of
every kernel), and :func:`sweep` is also the fixed-point map of the differentiable likelihood.

Work pool. :func:`solve_pool` keeps every lane busy: when a hypothesis converges its
values are written out and the lane takes the next unsolved hypothesis, so a batch
costs the sum of its members' sweeps, not its slowest member's times the batch size. Once
none is left to hand out, on a large MDP the busy lanes move into half the lane groups
whenever they fit (:func:`shrink_floor`), so the last few hypotheses do not sweep idle lanes
with them.

Over-relaxation. A lane whose Gauss–Seidel sweeps contract at the slowest possible rate
(about γ² per sweep: a person who wanders, large β) switches to successive over-relaxation,
which on ``zones30`` needs a quarter of the sweeps; a lane on which it does not beat plain
sweeps stays plain from the better of its values before and after the trial. Every check's
last sweep is plain, and only its change certifies the tolerance, so the guarantee is the
plain sweeps' whatever happened before.
"""

from __future__ import annotations

import os
import weakref
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..mdp import TabularMDP
from ..models import backup
from ..numerics import enable_float64
from .screening import gate_check

#: Hypotheses along the minor (vector) axis of one group where none is chosen for the machine
#: (:mod:`expertise_irl.planning.tuning` picks it at first use). XLA's CPU code ran about twice as fast
#: per backup with 8 float64 lanes (one AVX-512 vector) as with 16 or more on an AVX-512 machine.
LANES = 8
#: Sweeps between convergence checks (a converged lane may do up to CHECK_EVERY - 1 more,
#: which only tightens it; they are counted in the reported sweeps). The last sweep of each
#: check is a plain Gauss–Seidel sweep, whose change certifies the tolerance.
CHECK_EVERY = 8
#: Lane modes of the over-relaxation (see :func:`solve_pool`).
_MEASURE, _RELAX, _PLAIN = 0, 1, 2


def relaxation_factor(gamma):
    """The over-relaxation factor ω of the pool's SOR sweeps for discount ``gamma``.

    Young's optimum ``2 / (1 + sqrt(1 - ρ²))`` for the largest possible Jacobi spectral radius
    ρ = γ, plus 0.05: the rate of SOR rises steeply below the optimum and only as ω − 1 above
    it, and a plain certifying sweep in every :data:`CHECK_EVERY` pulls the optimum up a little.
    On ``zones30`` (γ = 0.95) the paper's β ≥ 0.5 then converge in 56 sweeps instead of 224.
    """
    return jnp.minimum(1.95, 2.0 / (1.0 + jnp.sqrt(1.0 - gamma * gamma)) + 0.05)


class Prepared(NamedTuple):
    """The MDP in the solver's layout: two blocks of states, each padded to ``n_block`` rows.

    Solver rows: block 0 (rows ``0 .. n_block-1``), block 1 (``n_block .. 2 n_block-1``),
    then one row that is always 0 (terminal states and padding point there).
    """

    features: jnp.ndarray  # [2, A, n_block, K]
    next_row: jnp.ndarray  # [2, A, n_block] solver row of the successor (unavailable: zero row)
    avail: jnp.ndarray  # [2, A, n_block] (padding rows: one zero-reward move to the zero row)
    log_n_actions: jnp.ndarray  # [2, n_block] log of the number of available actions
    rows: np.ndarray  # [S] solver row of each state (terminal: the zero row)
    n_block: int

    @property
    def n_rows(self) -> int:
        return 2 * self.n_block + 1


def goal_distance(mdp: TabularMDP) -> np.ndarray:
    """``[S]`` fewest moves from each state to a terminal state: 0 at terminal states, -1 where
    none can be reached."""
    S = mdp.n_states
    src, act = np.nonzero(mdp.available)
    dst = mdp.next_state[src, act]
    keep = dst >= 0
    src, dst = src[keep], dst[keep]
    by_dst = np.argsort(dst, kind="stable")
    src, dst = src[by_dst], dst[by_dst]
    starts = np.searchsorted(dst, np.arange(S + 1))
    dist = np.full(S, -1, dtype=np.int64)
    frontier = np.flatnonzero(mdp.terminal)
    dist[frontier] = 0
    d = 0
    while len(frontier):
        d += 1
        preds = np.concatenate([src[starts[t]:starts[t + 1]] for t in frontier])
        preds = np.unique(preds)
        frontier = preds[dist[preds] < 0]
        dist[frontier] = d
    return dist


def sweep_blocks(mdp: TabularMDP) -> np.ndarray:
    """``[S]`` block (0 or 1) of each state for the Gauss–Seidel sweep; -1 for terminal states.

    The block is the parity of the shortest distance to a terminal state (:func:`goal_distance`).
    In a grid world, where every move changes the parity of x + y, no move stays inside a block,
    so a sweep is an exact red-black Gauss–Seidel sweep. In any other MDP the split is still a
    valid block Gauss–Seidel sweep (each sweep is a γ-contraction with the same fixed point);
    moves within a block use the previous sweep's values, as in plain value iteration.
    """
    return np.where(mdp.terminal, -1, goal_distance(mdp) % 2)


def prepare(mdp: TabularMDP, dtype) -> Prepared:
    """Move the MDP to the device in the solver's layout (JAX in float64 first: every solve and
    likelihood starts here)."""
    enable_float64()
    block = sweep_blocks(mdp)
    members = [np.flatnonzero(block == b) for b in (0, 1)]
    n_block = max(1, max(len(m) for m in members))
    zero_row = 2 * n_block
    rows = np.full(mdp.n_states, zero_row, dtype=np.int64)
    for b, m in enumerate(members):
        rows[m] = b * n_block + np.arange(len(m))
    basis = mdp.reward_basis()
    A, K = mdp.n_actions, basis.shape[2]
    avail = mdp.available
    feats = np.zeros((2, A, n_block, K))
    next_row = np.full((2, A, n_block), zero_row, dtype=np.int64)
    ok = np.zeros((2, A, n_block), dtype=bool)
    ok[:, 0, :] = True  # padding rows: a single zero-reward move to the zero row (value stays 0)
    for b, m in enumerate(members):
        n = len(m)
        feats[b, :, :n] = np.transpose(basis[m], (1, 0, 2))
        next_row[b, :, :n] = np.where(avail[m], rows[np.maximum(mdp.next_state[m], 0)], zero_row).T
        ok[b, :, :n] = avail[m].T
    log_n = np.log(ok.sum(axis=1))  # [2, n_block]
    return Prepared(jnp.asarray(feats, dtype=dtype), jnp.asarray(next_row, dtype=jnp.int32),
                    jnp.asarray(ok), jnp.asarray(log_n, dtype=dtype), rows, n_block)


#: Memory budget for one chunk of hypotheses (bytes of [H, S, A] work arrays).
DEFAULT_CHUNK_BYTES = 1 * 2**20

_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def prepared(mdp: TabularMDP, dtype: str) -> Prepared:
    """The MDP in the solver's layout, kept while the (immutable) MDP lives: samplers that
    solve one hypothesis at a time on the same task pay the set-up once."""
    per_mdp = _PREPARED.setdefault(mdp, {})
    if dtype not in per_mdp:
        per_mdp[dtype] = prepare(mdp, jnp.float64 if dtype == "float64" else jnp.float32)
    return per_mdp[dtype]


#: Share of the memory available when a solve starts that its pool of lanes may take.
MEMORY_SHARE = 0.25
#: Copies of one lane's values the pool holds at once (values, the over-relaxation's saved values,
#: the jump's values and successors, the backups' temporaries), for sizing the pool from memory.
LANE_COPIES = 8
#: Pools over MDPs of at least this many solver rows shrink once no hypothesis is left to hand out
#: and the busy lanes fit in fewer groups (each size compiles once). On smaller MDPs a sweep of the
#: idle lanes costs less than the compilation. By halving (95 hypotheses to 1e-8 at 100 × 100 with
#: sweeps alone, 8 groups of 4 lanes: 18.7 s against 26.2 s straight to one group), but straight to
#: one group where a gate eliminates in the sweeps (:mod:`.screening`), whose tail is short: the
#: 200 × 200 ``infer`` took 17.3–18.7 s against 20.0 s by halving and 23.2 s without shrinking.
SHRINK_MIN_ROWS = 10_000


def available_memory() -> int:
    """Bytes of memory available now: ``MemAvailable`` of /proc/meminfo where there is one, else
    the free physical pages, else 8 GiB."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


def default_chunk_size(mdp: TabularMDP, dtype=np.float64, budget_bytes: int = DEFAULT_CHUNK_BYTES,
                       lanes: int = LANES, memory: int | None = None) -> int:
    """Hypotheses in flight at once (a multiple of the lane width ``lanes``).

    Sized so the lanes' values (``[S, chunk]``) stay near ``budget_bytes``: 144 on a 30×30
    map, fewer on large maps, never fewer than 32 hypotheses or more than 256 (rounded down
    to whole lane groups). Measured on 2 cores with 8 lanes: 128-144 lanes are fastest on
    883 states, 32 on 4,546 states. On a map so large that 32 lanes' :data:`LANE_COPIES` copies
    of their values would take more than :data:`MEMORY_SHARE` of ``memory`` (default: what
    :func:`available_memory` finds now), the pool shrinks to fit, down to one lane group.
    """
    per_hypothesis = mdp.n_states * np.dtype(dtype).itemsize  # rewards are recomputed per sweep
    n = min(256, max(32, budget_bytes // per_hypothesis))
    if memory is None:
        memory = available_memory()
    n = min(n, int(MEMORY_SHARE * memory) // (LANE_COPIES * per_hypothesis))
    return int(lanes * max(1, n // lanes))


def block_backup(prep: Prepared, b: int, w, v, gamma, model: str):
    """Backup of block ``b`` for one lane group: (values [n_block, L], log π [A, n_block, L]).

    ``w [K, L]`` scaled weights, ``v [rows, L]`` scaled values; ``model`` (static) picks the
    observation model (:func:`expertise_irl.models.backup`).
    """
    r = jnp.where(prep.avail[b][..., None], jnp.einsum("ask,kl->asl", prep.features[b], w), -jnp.inf)
    q = r + gamma * v.at[prep.next_row[b]].get(mode="promise_in_bounds")  # [A, n_block, L]
    return backup(model, q, prep.log_n_actions[b][:, None], axis=0)


def sweep(prep: Prepared, w, v, gamma, model: str, omega=None):
    """One red-black sweep of one lane group: (v [rows, L], largest change per lane [L]).

    With ``omega [L]`` it is an SOR sweep: each block moves ``omega`` times its Gauss–Seidel
    step (the change reported is still the Gauss–Seidel step's).
    """
    nb = prep.features.shape[2]  # static (n_block itself is traced inside jit)
    delta = jnp.zeros(v.shape[1], v.dtype)
    for b in (0, 1):
        new, _ = block_backup(prep, b, w, v, gamma, model)
        old = v[b * nb:(b + 1) * nb]
        delta = jnp.maximum(delta, jnp.max(jnp.abs(new - old), axis=0))
        if omega is not None:
            new = new + (omega - 1.0) * (new - old)
        v = jax.lax.dynamic_update_slice_in_dim(v, new, b * nb, axis=0)
    return v, delta


_sweep_groups = jax.vmap(sweep, in_axes=(None, 0, 0, None, None))
_relaxed_groups = jax.vmap(sweep, in_axes=(None, 0, 0, None, None, 0))


def _to_lanes(x, groups: int):
    """``[groups * lanes, ...]`` -> ``[groups, ..., lanes]``."""
    x = x.reshape(groups, x.shape[0] // groups, *x.shape[1:])
    return jnp.moveaxis(x, 1, -1)


def _from_lanes(x):
    """``[groups, ..., lanes]`` -> ``[groups * lanes, ...]``."""
    x = jnp.moveaxis(x, -1, 1)
    return x.reshape(-1, *x.shape[2:])


def solve_pool(prep: Prepared, weights, v0, gamma, tol, max_iter, *, groups: int, lanes: int = LANES,
               model: str = "maxent", relax: bool = True, gate=None, best=-np.inf, n_live: int | None = None):
    """Solve every hypothesis with a pool of ``groups × lanes`` lanes that refill as they finish.

    A lane starts with plain Gauss–Seidel sweeps. With ``relax``, from its second check on, a
    lane whose change over the last check shrank by a factor no smaller than 0.99 γ² per sweep
    (the slowest rate red-black sweeps show, where a wandering person's walk rarely ends)
    switches, once, to SOR with
    :func:`relaxation_factor` from its current values; if a later check shows it contracting
    slower than γ² per sweep, or further from convergence than at the start, it stays plain
    from then on, going back to those values unless its own certified change is smaller by
    then, so a failed trial never leaves a lane further from convergence than it began. Only
    the plain last sweep of a check can certify convergence.

    Args:
        weights: ``[H, K']`` scaled reward weights θ'/β (θ' = :meth:`TabularMDP.reward_weights`).
        v0: ``[H, rows]`` initial scaled values in solver rows.
        gamma, tol, max_iter: scalars (see :func:`expertise_irl.planning.soft_vi.solve`).

    With ``gate`` (:class:`.screening.GateArrays` for these hypotheses), a lane also stops when
    its hypothesis is certainly eliminated (:mod:`.screening`), starting from the certain log mass
    ``best``. Only the first ``n_live`` hypotheses (default all) are handed out; the others' rows of
    the outputs are zeros.

    Returns ``(v [H, rows], sweeps [H], last change [H], best)``; the last change is 0 for every
    hypothesis that met its tolerance, ``−tol_h`` for one the gate stopped (its values are within
    ``tol_h`` of the solution), and positive (or NaN) for one that did not converge; ``best`` is
    the best certain log mass the gate saw (``best`` as given without a gate).
    """
    H = weights.shape[0]
    n_live = H if n_live is None else int(n_live)
    return _pool_impl(prep, weights, v0, gamma, tol, max_iter, groups=groups, lanes=lanes, model=model,
                      relax=relax, gate=gate, best=best, n_live=n_live)


@partial(jax.jit, static_argnames=("model",))
def _final_backup(prep: Prepared, w, v, gamma, model: str):
    """Values ``[n, S]`` and log-policies ``[n, S, A]`` in state order from converged values
    ``[G, rows, L]`` in lanes (terminal states: value 0, log-policy -inf)."""
    def one(w, v):
        v0, lp0 = block_backup(prep, 0, w, v, gamma, model)
        v1, lp1 = block_backup(prep, 1, w, v, gamma, model)
        return jnp.concatenate([v0, v1, v[2 * prep.features.shape[2]:]], axis=0), jnp.stack([lp0, lp1])

    vf, lp = jax.vmap(one)(w, v)
    vf, lp = _from_lanes(vf), _from_lanes(lp)  # [n, rows], [n, 2, A, n_block]
    n, _, A, nb = lp.shape
    lp = jnp.moveaxis(lp, 1, 2).reshape(n, A, 2 * nb)
    lp = jnp.concatenate([lp, jnp.full((n, A, 1), -jnp.inf, lp.dtype)], axis=2)  # the zero row
    return vf[:, prep.rows], jnp.transpose(lp[:, :, prep.rows], (0, 2, 1))


def _switch_relaxation(sor, v, d, fin, gamma, *, omega_ok: bool, groups: int):
    """Over-relaxation per lane, after a plain check with certified change ``d``.

    From the second plain check on, a lane contracting at about γ² per sweep starts it from its
    current values; one that then contracts slower than γ² per sweep, or whose change is larger
    than at the start (after a check's grace), stays plain from then on, from the start's values
    unless its own certified change is already smaller. Returns ``(v, d, sor)``.
    """
    mode, checks, d_prev, v_save, d_save = sor
    checks = checks + 1
    rate = (d / d_prev) ** (1.0 / CHECK_EVERY)
    start = omega_ok & (mode == _MEASURE) & (checks >= 2) & (rate >= 0.99 * gamma * gamma) & ~fin
    back = (mode == _RELAX) & (checks >= 2) & ~((rate <= gamma * gamma) & (d <= d_save)) & ~fin
    undo = back & ~(d < d_save)  # keep SOR's values where they are closer than the start's
    v = jnp.where(_to_lanes(undo, groups)[:, None, :], v_save, v)
    d = jnp.where(undo, d_save, d)
    v_save = jnp.where(_to_lanes(start, groups)[:, None, :], v, v_save)
    d_save = jnp.where(start, d, d_save)
    mode = jnp.where(start, _RELAX, jnp.where(back, _PLAIN, mode))
    checks = jnp.where(start, 0, checks)
    return v, d, (mode, checks, d, v_save, d_save)


def _retire(c, fin, conv, d, weights, v0, groups: int, n_live):
    """Write finished lanes' values, sweeps and last change out, and hand them the next of the
    first ``n_live`` hypotheses."""
    H = weights.shape[0]
    w, v, lane_h, active, it, next_h, out_v, out_it, out_d, sor, best = c
    where = jnp.where(fin, lane_h, H)  # index H is out of range: dropped
    out_v = out_v.at[where].set(_from_lanes(v), mode="drop")
    out_it = out_it.at[where].set(it, mode="drop")
    out_d = out_d.at[where].set(jnp.where(conv, 0.0, d), mode="drop")
    new_h = next_h + jnp.cumsum(fin) - 1
    take = fin & (new_h < n_live)
    src = jnp.clip(new_h, 0, H - 1)
    lane_h = jnp.where(take, new_h, lane_h)
    w = jnp.where(_to_lanes(take, groups)[:, None, :], _to_lanes(weights[src], groups), w)
    v = jnp.where(_to_lanes(take, groups)[:, None, :], _to_lanes(v0[src], groups), v)
    it = jnp.where(take, 0, it)
    active = jnp.where(fin, take, active)
    next_h = jnp.minimum(next_h + jnp.sum(fin), n_live)
    mode, checks, d_prev, v_save, d_save = sor
    sor = (jnp.where(take, _MEASURE, mode), jnp.where(take, 0, checks),
           jnp.where(take, jnp.inf, d_prev), v_save, d_save)
    return w, v, lane_h, active, it, next_h, out_v, out_it, out_d, sor, best


def _pool_init(weights, v0, n_live, best, *, groups: int, lanes: int):
    """The pool's first state: the first ``groups × lanes`` of the first ``n_live`` hypotheses in
    the lanes, and the certain log mass ``best``."""
    dtype = v0.dtype
    H = weights.shape[0]
    slots = groups * lanes
    lane_h = jnp.arange(slots)
    active = lane_h < n_live
    lane_h = jnp.where(active, lane_h, 0)
    return (
        _to_lanes(weights[lane_h], groups),  # w [G, K, L]
        _to_lanes(v0[lane_h], groups),  # v [G, rows, L]
        lane_h, active, jnp.zeros(slots, jnp.int64),  # lane -> hypothesis, busy, sweeps
        jnp.minimum(slots, n_live),  # next hypothesis to hand out
        jnp.zeros_like(v0), jnp.zeros(H, jnp.int64), jnp.zeros(H, dtype),  # outputs
        # over-relaxation per lane: mode, checks in this mode, last change, values and change
        # where it started
        (jnp.full(slots, _MEASURE, jnp.int32), jnp.zeros(slots, jnp.int32), jnp.full(slots, jnp.inf, dtype),
         jnp.zeros((groups, v0.shape[1], lanes), dtype), jnp.zeros(slots, dtype)),
        jnp.asarray(best, dtype),  # the best certain log mass (screening.Gate)
    )


def _pool_run(prep: Prepared, weights, v0, carry, gamma, tol, max_iter, min_active, n_live, gate, *,
              groups: int, lanes: int, model: str, relax: bool):
    """Run the pool from ``carry`` until every lane is idle, or until no hypothesis is left to hand
    out and at most ``min_active`` lanes are busy (then the caller repacks them into fewer groups)."""
    dtype = prep.features.dtype
    eps = jnp.finfo(dtype).eps
    gamma = gamma.astype(dtype)
    # Each sweep is a γ-contraction, so ||v_n+1 - v_n|| <= tol (1-γ)/γ bounds ||v_n+1 - v*|| by
    # tol; the threshold is floored at the floating-point resolution of the values themselves.
    base_thresh = tol * (1.0 - gamma) / gamma
    omega = relaxation_factor(gamma)

    def cond(c):
        active, next_h = c[3], c[5]
        return jnp.any(active) & ((next_h < n_live) | (jnp.sum(active) > min_active))

    def body(c):
        w, v, lane_h, active, it, next_h, out_v, out_it, out_d, sor, best = c
        mode = sor[0]
        # CHECK_EVERY - 1 sweeps (over-relaxed in lanes that chose it), then a plain one.
        omega_l = _to_lanes(jnp.where(mode == _RELAX, omega, 1.0).astype(dtype), groups)
        v = jax.lax.fori_loop(0, CHECK_EVERY - 1,
                              lambda _, v: _relaxed_groups(prep, w, v, gamma, model, omega_l)[0], v)
        v_before = v
        v, d = _sweep_groups(prep, w, v, gamma, model)
        d = _from_lanes(d)
        it = it + CHECK_EVERY * active.astype(it.dtype)
        vmax = _from_lanes(jnp.max(jnp.abs(v), axis=1))
        conv = active & (d <= jnp.maximum(base_thresh, 8.0 * eps * vmax))
        stop = jnp.zeros_like(conv)
        if gate is not None:  # certified elimination (screening.py); converged lanes raise best too
            below = _from_lanes(jnp.min(v - v_before, axis=1)) >= 0  # screening.py: then v <= T v <= v*
            stop, best, tol_h = gate_check(gate, _from_lanes(v[:, gate.rows, :]), d, vmax, lane_h, active,
                                           best, gamma / (1.0 - gamma), below)
            stop = stop & ~conv
        fin = conv | stop | (active & (it >= max_iter))
        v, d, sor = _switch_relaxation(sor, v, d, fin, gamma, omega_ok=relax, groups=groups)
        d = d if gate is None else jnp.where(stop, -tol_h, d)
        return _retire((w, v, lane_h, active, it, next_h, out_v, out_it, out_d, sor, best), fin, conv, d,
                       weights, v0, groups, n_live)

    return jax.lax.while_loop(cond, body, carry)


_jit_pool_init = jax.jit(_pool_init, static_argnames=("groups", "lanes"))
_jit_pool_run = jax.jit(_pool_run, static_argnames=("groups", "lanes", "model", "relax"))


def repack(active, grouped: tuple, slotted: tuple, groups: int):
    """Move the busy lanes (``active [slots]``) into the first slots of a pool of ``groups`` lane
    groups, in their order (every busy lane must fit). ``grouped`` arrays are laid out
    ``[G, ..., L]``, ``slotted`` ones have the slots along their last axis. Each lane keeps its
    hypothesis and state; only its place changes."""
    lanes = grouped[0].shape[-1]
    keep = jnp.argsort(~active, stable=True)[:groups * lanes]
    return (tuple(_to_lanes(_from_lanes(x)[keep], groups) for x in grouped),
            tuple(x[..., keep] for x in slotted))


@partial(jax.jit, static_argnames=("groups",))
def _repack_pool(carry, *, groups: int):
    w, v, lane_h, active, it, next_h, out_v, out_it, out_d, sor, best = carry
    mode, checks, d_prev, v_save, d_save = sor
    (w, v, v_save), (lane_h, active, it, mode, checks, d_prev, d_save) = repack(
        active, (w, v, v_save), (lane_h, active, it, mode, checks, d_prev, d_save), groups)
    return (w, v, lane_h, active, it, next_h, out_v, out_it, out_d, (mode, checks, d_prev, v_save, d_save),
            best)


def shrink_floor(n_rows: int, groups: int, lanes: int, to_one: bool = False) -> int:
    """Busy lanes at or below which a pool with nothing left to hand out moves to half its groups,
    or with ``to_one`` to one group (-1: never, for one group or an MDP of fewer than
    :data:`SHRINK_MIN_ROWS` solver rows)."""
    return (1 if to_one else groups // 2) * lanes if groups > 1 and n_rows >= SHRINK_MIN_ROWS else -1


def drain(run, repack_to, carry, n_rows: int, groups: int, lanes: int, to_one: bool = False):
    """Run a pool (``run(carry, floor, groups)``, whose lane flags are ``carry[3]``) until its lanes
    are idle: once nothing is left to hand out, a pool of fewer groups takes the busy lanes
    (``repack_to(carry, groups)``) as soon as they fit in half the groups, rather than sweeping
    idle lanes to the end of the longest: the smallest halving that holds them, or with ``to_one``
    one group once they fit in it. Returns the last carry."""
    while True:
        floor = shrink_floor(n_rows, groups, lanes, to_one)
        carry = run(carry, jnp.asarray(floor), groups)
        if floor < 0 or not bool(jnp.any(carry[3])):
            return carry
        busy = int(jnp.sum(carry[3]))
        groups = 1 if to_one else groups // 2
        while groups > 1 and busy <= (groups // 2) * lanes:  # no size compiled only to shrink again
            groups //= 2
        carry = repack_to(carry, groups)


def _pool_impl(prep: Prepared, weights, v0, gamma, tol, max_iter, *, groups: int, lanes: int, model: str,
               relax: bool, gate, best, n_live: int):
    dtype = prep.features.dtype
    weights, v0 = jnp.asarray(weights).astype(dtype), jnp.asarray(v0).astype(dtype)
    gamma, tol, max_iter = jnp.asarray(gamma), jnp.asarray(tol), jnp.asarray(max_iter)
    live = jnp.asarray(n_live)
    def run(c, floor, g):
        return _jit_pool_run(prep, weights, v0, c, gamma, tol, max_iter, floor, live, gate, groups=g,
                             lanes=lanes, model=model, relax=relax)

    carry = drain(run, lambda c, g: _repack_pool(c, groups=g),
                  _jit_pool_init(weights, v0, live, best, groups=groups, lanes=lanes), prep.n_rows, groups,
                  lanes, to_one=gate is not None)
    return carry[6], carry[7], carry[8], float(carry[10])


def final_policies(prep: Prepared, weights, v, gamma, *, groups: int, model: str = "maxent"):
    """One more backup for ``[n, K]`` weights and ``[n, rows]`` values (n = groups × lanes).

    Returns ``(v [n, S], log π [n, S, A])`` in state order (scaled values; terminal states 0 and
    -inf, unavailable actions -inf); each log-policy row is normalised by its own
    log-partition, so rows sum to 1 to machine precision even when |q| is large.
    """
    dtype = prep.features.dtype
    return _final_backup(prep, _to_lanes(jnp.asarray(weights, dtype), groups),
                         _to_lanes(jnp.asarray(v, dtype), groups), jnp.asarray(gamma, dtype), model)


# ----------------------------------------------------------------------------- path jumps
#: Plain sweeps between two jumps of :func:`jump_start`.
JUMP_SWEEPS = 2
#: Most jumps one hypothesis makes in :func:`jump_start`.
JUMP_MAX = 60
#: Jumps every hypothesis makes before it must show progress (the first jump often raises the change).
JUMP_GRACE = 4
#: A hypothesis keeps jumping while its change falls below this share of its change two jumps earlier.
JUMP_PROGRESS = 0.9


def doubling_steps(gamma: float) -> int:
    """Doubling steps of a jump: enough that γ^(2^steps) <= 1e-20 (far below any tolerance)."""
    import math

    return max(1, math.ceil(math.log2(math.log(1e-20) / math.log(gamma))))


def _jump(prep: Prepared, w, v, gamma, model: str, steps: int):
    """One lane group's jump: ``(v', change [L])``.

    From values ``v [rows, L]``: the backup ``T v`` (both blocks from ``v``), its largest change
    ``max |T v − v|`` per lane, each state's greedy successor ``s⁺`` (the action of highest Q),
    and ``b = T v − γ v[s⁺]``, so ``T v = b + γ v[s⁺]``. Holding ``b`` and ``s⁺`` fixed, the
    values ``v' = b + γ v'[s⁺]`` — the greedy walk's discounted sum of ``b`` — are computed by
    path doubling in ``steps`` gathers, which carries values along a whole path or round a whole
    loop at once, where sweeps move them a few states per sweep and need ~1/(1−γ) rounds of a loop.
    """
    nb = prep.features.shape[2]
    L = v.shape[1]
    news, succs = [], []
    for b in (0, 1):
        new, lp = block_backup(prep, b, w, v, gamma, model)  # [nb, L], [A, nb, L]
        a = jnp.argmax(lp, axis=0)  # [nb, L]
        rows = jnp.broadcast_to(prep.next_row[b][:, :, None], (prep.next_row.shape[1], nb, L))
        news.append(new)
        succs.append(jnp.take_along_axis(rows, a[None], axis=0)[0])
    zero = v[2 * nb:]
    tv = jnp.concatenate([*news, zero], axis=0)
    succ = jnp.concatenate([*succs, jnp.full((1, L), 2 * nb, succs[0].dtype)], axis=0)
    change = jnp.max(jnp.abs(tv - v), axis=0)
    # Flat indices of each lane's successor in [rows * L] (row-major), so every gather is one take.
    lane = jnp.arange(L, dtype=succ.dtype)
    flat = succ * L + lane
    x = tv - gamma * v.reshape(-1).at[flat].get(mode="promise_in_bounds").reshape(v.shape)  # b
    x = x.at[2 * nb:].set(0.0)  # the zero row: b = 0, and it is its own successor, so it stays 0

    def double(_, c):  # x <- x + γ^(2^i) x[s⁺], s⁺ <- s⁺[s⁺]: paths of twice the length
        x, flat, fac = c
        x = x + fac * x.reshape(-1).at[flat].get(mode="promise_in_bounds").reshape(x.shape)
        return x, flat.reshape(-1).at[flat].get(mode="promise_in_bounds").reshape(flat.shape), fac * fac

    x, _, _ = jax.lax.fori_loop(0, steps, double, (x, flat, gamma))
    return x, change


_jump_groups = jax.vmap(_jump, in_axes=(None, 0, 0, None, None, None))


def hand_out(fin, done_v, state, weights, v0, groups: int):
    """A start pool's refill (:func:`jump_start`, :func:`.level_order.level_start`): lanes that
    finished (``fin``) write ``done_v`` and their count out and take the next hypothesis.

    ``state`` is ``(w, v, lane_h, active, k, next_h, out_v, out_k)``: lane weights and values,
    lane -> hypothesis, busy, per-lane count, next hypothesis, and the outputs (values, counts).
    Returns ``(take, state)``, ``take`` marking the lanes that took a new hypothesis.
    """
    w, v, lane_h, active, k, next_h, out_v, out_k = state
    H = weights.shape[0]
    where = jnp.where(fin, lane_h, H)  # index H is out of range: dropped
    out_v = out_v.at[where].set(_from_lanes(done_v), mode="drop")
    out_k = out_k.at[where].set(k, mode="drop")
    new_h = next_h + jnp.cumsum(fin) - 1
    take = fin & (new_h < H)
    src = jnp.clip(new_h, 0, H - 1)
    take_l = _to_lanes(take, groups)[:, None, :]
    lane_h = jnp.where(take, new_h, lane_h)
    w = jnp.where(take_l, _to_lanes(weights[src], groups), w)
    v = jnp.where(take_l, _to_lanes(v0[src], groups), v)
    k = jnp.where(take, 0, k)
    active = jnp.where(fin, take, active)
    next_h = jnp.minimum(next_h + jnp.sum(fin), H)
    return take, (w, v, lane_h, active, k, next_h, out_v, out_k)


def _jump_impl(prep: Prepared, weights, v0, gamma, thresh, *, groups: int, lanes: int, model: str,
               steps: int):
    dtype = prep.features.dtype
    gamma = gamma.astype(dtype)
    thresh = thresh.astype(dtype)
    weights = weights.astype(dtype)
    v0 = v0.astype(dtype)
    H = weights.shape[0]
    slots = groups * lanes
    lane_h = jnp.arange(slots)
    active = lane_h < H
    lane_h = jnp.where(active, lane_h, 0)
    inf = jnp.full(slots, jnp.inf, dtype)
    init = (
        _to_lanes(weights[lane_h], groups), _to_lanes(v0[lane_h], groups),  # w, v
        lane_h, active, jnp.zeros(slots, jnp.int64), jnp.minimum(slots, H),  # lane -> h, busy, jumps, next h
        _to_lanes(v0[lane_h], groups), inf, inf, inf,  # best values, their change, change 1 and 2 jumps ago
        jnp.zeros_like(v0), jnp.zeros(H, jnp.int64),  # outputs: values, jumps
    )

    def cond(c):
        return jnp.any(c[3])

    def body(c):
        w, v, lane_h, active, k, next_h, best_v, best_d, d1, d2, out_v, out_k = c
        v = jax.lax.fori_loop(0, JUMP_SWEEPS, lambda _, v: _sweep_groups(prep, w, v, gamma, model)[0], v)
        vj, d = _jump_groups(prep, w, v, gamma, model, steps)
        d = _from_lanes(d)
        better = active & (d < best_d)
        best_v = jnp.where(_to_lanes(better, groups)[:, None, :], v, best_v)
        best_d = jnp.where(better, d, best_d)
        k = k + active.astype(k.dtype)
        ok = _from_lanes(jnp.isfinite(vj).all(axis=1))
        go = ok & (d > thresh) & (k < JUMP_MAX) & ((k < JUMP_GRACE) | (d < JUMP_PROGRESS * d2))
        fin = active & ~go
        v = jnp.where(_to_lanes(go, groups)[:, None, :], vj, v)
        d2, d1 = d1, d
        # finished lanes hand their best values out and take the next hypothesis
        take, (w, v, lane_h, active, k, next_h, out_v, out_k) = hand_out(
            fin, best_v, (w, v, lane_h, active, k, next_h, out_v, out_k), weights, v0, groups)
        best_v = jnp.where(_to_lanes(take, groups)[:, None, :], v, best_v)
        best_d, d1, d2 = (jnp.where(take, jnp.inf, x) for x in (best_d, d1, d2))
        return w, v, lane_h, active, k, next_h, best_v, best_d, d1, d2, out_v, out_k

    out = jax.lax.while_loop(cond, body, init)
    return out[10], out[11]


_jump_start = jax.jit(_jump_impl, static_argnames=("groups", "lanes", "model", "steps"))


def jump_start(prep: Prepared, weights, v0, gamma, thresh, *, groups: int, lanes: int = LANES,
               model: str = "maxent"):
    """Starting values for :func:`solve_pool` from greedy path jumps, with a pool of ``groups × lanes``
    lanes that take the next hypothesis as each one stops (as :func:`solve_pool`'s do).

    Each hypothesis alternates :data:`JUMP_SWEEPS` plain sweeps with a jump (:func:`_jump`: the
    greedy walk's values by path doubling). Where the greedy walk is nearly the soft-optimal
    person's (small β: one action carries almost all the probability), a jump takes the values
    almost to the fixed point, however long the paths and however slowly loops contract; where
    it is not (large β), the change stops falling and the hypothesis stops jumping after
    :data:`JUMP_GRACE` jumps. A hypothesis stops when its change ``max |T v − v|`` is at most
    ``thresh``, has not fallen below :data:`JUMP_PROGRESS` times its change two jumps earlier,
    after :data:`JUMP_MAX` jumps, or when a jump is not finite. Nothing here certifies anything:
    the values returned (per hypothesis, the iterate with the smallest change seen) only start
    :func:`solve_pool`, whose plain sweeps certify the tolerance as from any start.

    Each hypothesis' result depends on its own weights and start only, not on its lane or the
    other hypotheses in the pool; each costs its own jumps only.

    Returns ``(v [n, rows], jumps [n])`` for ``weights [n, K']`` and ``v0 [n, rows]``.
    """
    return _jump_start(prep, weights, v0, gamma, thresh, groups=groups, lanes=lanes, model=model,
                       steps=doubling_steps(float(gamma)))
