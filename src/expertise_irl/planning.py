"""Batched soft value iteration (paper Eqs. 8–9) over many hypotheses at once.

All H hypotheses (θ_h, β_h) are solved together in one JAX ``while_loop``.
The work is done in *scaled* units: with ``r = θ·φ / β`` the soft Bellman
equations become ``q = r + γ v[next]``, ``v = logsumexp_a q``, and the
true quantities are ``V = β v``, ``Q = β q``. This makes every β from 1e-3 to
100 equally well conditioned and means the stopping tolerance is directly the
error in log-probabilities (nats), which is what inference consumes.

Each hypothesis stops on its own tolerance (it is frozen once converged), and
a hypothesis that does not converge within ``max_iter`` backups raises
:class:`ConvergenceError`. Large hypothesis sets are solved in chunks so that
memory stays bounded; chunks are padded to one shape so JAX compiles once.
"""

from __future__ import annotations

import math
import os
from collections import deque
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .errors import InputError
from .mdp import TabularMDP

jax.config.update("jax_enable_x64", True)

DEFAULT_TOL = 1e-8
#: Memory budget for one chunk of hypotheses (bytes of [H, S, A] work arrays).
DEFAULT_CHUNK_BYTES = 4 * 2**20
_WORK_ARRAYS = 1  # the [A, S, chunk] reward array; values and temporaries are smaller


class ConvergenceError(RuntimeError):
    """Soft value iteration did not reach its tolerance within ``max_iter`` backups."""


class SoftSolution(NamedTuple):
    """Soft-optimal values and policies for H hypotheses.

    Attributes:
        value: ``[H, S]`` soft state value V (reward units; 0 at terminal states).
        log_policy: ``[H, S, A]`` log π(a|s) = (Q − V)/β; ``-inf`` where the action is
            unavailable and on terminal rows.
        iterations: ``[H]`` backups each hypothesis needed.
        beta: ``[H]`` the temperatures solved for.
    """

    value: np.ndarray
    log_policy: np.ndarray
    iterations: np.ndarray
    beta: np.ndarray

    @property
    def q(self) -> np.ndarray:
        """``[H, S, A]`` soft Q = V + β log π (``-inf`` where unavailable)."""
        return self.value[:, :, None] + self.beta[:, None, None] * self.log_policy

    @property
    def policy(self) -> np.ndarray:
        """``[H, S, A]`` action probabilities (rows of terminal states are all 0)."""
        return np.exp(self.log_policy)


class _Prepared(NamedTuple):
    """The MDP in the solver's layout: two blocks of states, each padded to ``n_block`` rows.

    Solver rows: block 0 (rows ``0 .. n_block-1``), block 1 (``n_block .. 2 n_block-1``),
    then one row that is always 0 (terminal states and padding point there).
    """

    features: jnp.ndarray  # [2, A, n_block, K]
    next_row: jnp.ndarray  # [2, A, n_block] solver row of the successor (unavailable: zero row)
    avail: jnp.ndarray  # [2, A, n_block] (padding rows: one zero-reward move to the zero row)
    rows: np.ndarray  # [S] solver row of each state (terminal: the zero row)
    n_block: int


def sweep_blocks(mdp: TabularMDP) -> np.ndarray:
    """``[S]`` block (0 or 1) of each state for the Gauss–Seidel sweep; -1 for terminal states.

    The block is the parity of the shortest distance to a terminal state. In a grid world,
    where every move changes the parity of x + y, no move stays inside a block, so a sweep
    (block 0, then block 1 with the fresh block-0 values) is an exact red-black Gauss–Seidel
    sweep. In any other MDP the split is still a valid block Gauss–Seidel sweep (each sweep is
    a γ-contraction with the same fixed point); moves within a block use the previous sweep's
    values, as in plain value iteration.
    """
    S = mdp.n_states
    avail = mdp.available
    src, act = np.nonzero(avail)
    dst = mdp.next_state[src, act]
    preds: list[list[int]] = [[] for _ in range(S)]
    for a, b in zip(src.tolist(), dst.tolist(), strict=True):
        preds[b].append(a)
    dist = np.full(S, -1, dtype=np.int64)
    frontier = np.flatnonzero(mdp.terminal).tolist()
    dist[frontier] = 0
    d = 0
    while frontier:
        d += 1
        nxt = []
        for t in frontier:
            for u in preds[t]:
                if dist[u] < 0:
                    dist[u] = d
                    nxt.append(u)
        frontier = nxt
    return np.where(mdp.terminal, -1, dist % 2)


def _prepare(mdp: TabularMDP, dtype) -> _Prepared:
    block = sweep_blocks(mdp)
    members = [np.flatnonzero(block == b) for b in (0, 1)]
    n_block = max(1, max(len(m) for m in members))
    zero_row = 2 * n_block
    rows = np.full(mdp.n_states, zero_row, dtype=np.int64)
    for b, m in enumerate(members):
        rows[m] = b * n_block + np.arange(len(m))
    A, K = mdp.n_actions, mdp.n_features
    avail = mdp.available
    feats = np.zeros((2, A, n_block, K))
    next_row = np.full((2, A, n_block), zero_row, dtype=np.int64)
    ok = np.zeros((2, A, n_block), dtype=bool)
    ok[:, 0, :] = True  # padding rows: a single zero-reward move to the zero row (value stays 0)
    for b, m in enumerate(members):
        n = len(m)
        feats[b, :, :n] = np.transpose(mdp.features[m], (1, 0, 2))
        next_row[b, :, :n] = np.where(avail[m], rows[np.maximum(mdp.next_state[m], 0)], zero_row).T
        ok[b, :, :n] = avail[m].T
    return _Prepared(jnp.asarray(feats, dtype=dtype), jnp.asarray(next_row, dtype=jnp.int32),
                     jnp.asarray(ok), rows, n_block)


def _backup(r, next_row, v, gamma):
    """Soft backup of one block: (new values [n, H], log-policy [A, n, H])."""
    q = r + gamma * v.at[next_row].get(mode="promise_in_bounds")  # [A, n, H]
    m = jnp.max(q, axis=0)
    z = q - m
    log_norm = jnp.log(jnp.sum(jnp.exp(z), axis=0))
    return m + log_norm, z - log_norm


def _solve_group(prep: _Prepared, theta, beta, gamma, tol, max_iter, v0):
    """Red-black (block Gauss–Seidel) soft value iteration for one group of lanes, scaled units.

    Hypotheses are the minor axis (``LANES`` of them). Returns (v [rows, H],
    log_pi [2, A, n_block, H], sweeps [H], last change [H] (0 where converged)).
    """
    dtype = prep.features.dtype
    eps = jnp.finfo(dtype).eps
    w = (theta / beta[:, None]).T.astype(dtype)  # [K, H]: reward weights in scaled units
    r = jnp.where(prep.avail[..., None], jnp.einsum("bask,kh->bash", prep.features, w), -jnp.inf)
    gamma = gamma.astype(dtype)
    nb = prep.features.shape[2]
    H = theta.shape[0]
    # Each sweep is a γ-contraction, so ||v_n+1 - v_n|| <= tol (1-γ)/γ bounds ||v_n+1 - v*|| by
    # tol; the threshold is floored at the floating-point resolution of the values themselves.
    base_thresh = tol * (1.0 - gamma) / gamma

    def sweep(v, done):
        delta = jnp.zeros(H, dtype)
        for b in (0, 1):
            new, _ = _backup(r[b], prep.next_row[b], v, gamma)
            old = v[b * nb:(b + 1) * nb]
            new = jnp.where(done[None], old, new)
            delta = jnp.maximum(delta, jnp.max(jnp.abs(new - old), axis=0))
            v = jax.lax.dynamic_update_slice_in_dim(v, new, b * nb, axis=0)
        return v, delta

    def cond(carry):
        _, it, done, _ = carry
        return jnp.logical_and(~jnp.all(done), jnp.max(it) < max_iter)

    def body(carry):
        v, it, done, delta = carry
        v, d = sweep(v, done)
        thresh = jnp.maximum(base_thresh, 8.0 * eps * jnp.max(jnp.abs(v), axis=0))
        delta = jnp.where(done, delta, d)
        it = it + (~done).astype(it.dtype)
        done = done | (d <= thresh)
        return v, it, done, delta

    init = (v0.astype(dtype), jnp.zeros(H, jnp.int64), jnp.zeros(H, bool), jnp.full(H, jnp.inf, dtype))
    v, it, done, delta = jax.lax.while_loop(cond, body, init)
    # One more (Jacobi) backup; each log-policy row is normalised by its own log-partition,
    # so rows sum to 1 to machine precision even when |q| is large.
    v0_, lp0 = _backup(r[0], prep.next_row[0], v, gamma)
    v1_, lp1 = _backup(r[1], prep.next_row[1], v, gamma)
    v = jnp.concatenate([v0_, v1_, v[2 * nb:]], axis=0)
    return v, jnp.stack([lp0, lp1]), it, jnp.where(done, 0.0, delta)


#: Hypotheses along the minor (vector) axis of one group. XLA's CPU code is fastest when a
#: row of hypotheses is one AVX-512 vector of float64 (measured: ~2x faster than 16 or more).
LANES = 8
# A chunk is several groups side by side; XLA spreads the groups over the cores.
_solve_chunk = jax.jit(jax.vmap(_solve_group, in_axes=(None, 0, 0, None, None, None, 0)))


def _as_hypotheses(mdp: TabularMDP, theta, beta) -> tuple[np.ndarray, np.ndarray]:
    theta = np.asarray(theta, dtype=np.float64)
    beta = np.asarray(beta, dtype=np.float64)
    if theta.ndim == 1:
        theta = theta[None]
    if beta.ndim == 0:
        beta = np.full(theta.shape[0], float(beta))
    if theta.ndim != 2 or theta.shape[1] != mdp.n_features:
        raise InputError(
            f"theta must have shape [H, K] with K = {mdp.n_features} features "
            f"({', '.join(mdp.feature_names)}), got {theta.shape}"
        )
    if beta.shape != (theta.shape[0],):
        raise InputError(f"beta must have shape [H] = [{theta.shape[0]}], got {beta.shape}")
    if not np.all(np.isfinite(theta)):
        raise InputError("theta must be finite")
    if not np.all(np.isfinite(beta)) or np.any(beta <= 0):
        bad = beta[~(np.isfinite(beta) & (beta > 0))][0]
        raise InputError(f"beta must be a finite number > 0, got {bad}")
    fmax = float(np.abs(mdp.features).max())
    with np.errstate(over="ignore"):
        rmax = np.abs(theta).sum(axis=1) * fmax / beta
    if not np.all(np.isfinite(rmax)) or np.any(rmax > 1e150):
        h = int(np.flatnonzero(~np.isfinite(rmax) | (rmax > 1e150))[0])
        raise InputError(
            f"hypothesis {h}: reward scale |θ|·|φ|/β = {rmax[h]:.3g} overflows; "
            "use θ and β of ordinary magnitude (only θ/β matters)"
        )
    return theta, beta


def default_max_iter(mdp: TabularMDP, theta: np.ndarray, beta: np.ndarray, tol: float) -> int:
    """An iteration cap comfortably above the contraction bound for these hypotheses.

    From v = 0, ||v_{n+1} - v_n|| <= γ^n (max|r| + log A), so n >= log(thresh / (max|r| +
    log A)) / log γ backups always suffice in exact arithmetic; we allow twice that plus 100.
    """
    rmax = float(np.max(np.abs(mdp.features).sum(-1, keepdims=False).max() * np.abs(theta).max(-1) / beta))
    g = mdp.gamma
    thresh = tol * (1 - g) / g
    scale = rmax + math.log(mdp.n_actions) + 1.0
    n = math.log(thresh / scale) / math.log(g) if thresh < scale else 1.0
    return int(2 * math.ceil(n) + 100)


def default_chunk_size(mdp: TabularMDP, dtype=np.float64, budget_bytes: int = DEFAULT_CHUNK_BYTES) -> int:
    """Hypotheses per chunk: the chunk's ``[A, S, chunk]`` work arrays stay near ``budget_bytes``.

    A multiple of :data:`LANES`, at least 2 groups (one per core on a 2-core machine) and at
    most 256 hypotheses.
    """
    per = mdp.n_states * mdp.n_actions * np.dtype(dtype).itemsize * _WORK_ARRAYS * LANES
    return int(LANES * min(256 // LANES, max(2, budget_bytes // per)))


def _in_flight() -> int:
    """Chunks dispatched at once: enough to keep every core busy, few enough to bound memory."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(2, cores)


def solve(
    mdp: TabularMDP,
    theta,
    beta,
    *,
    tol: float = DEFAULT_TOL,
    max_iter: int | None = None,
    chunk_size: int | None = None,
    dtype: str = "float64",
    v_init: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SoftSolution:
    """Soft value iteration for every hypothesis ``(theta[h], beta[h])``.

    Hypotheses are grouped into chunks of similar temperature (which converge in similar
    numbers of sweeps), each chunk runs red-black Gauss–Seidel sweeps (see :func:`sweep_blocks`)
    until each of its hypotheses meets the tolerance, and several chunks run concurrently so
    that every core is used. Results come back in the order the hypotheses were given.

    Args:
        mdp: the task.
        theta: ``[H, K]`` (or ``[K]``) reward weights.
        beta: ``[H]`` (or a scalar) temperatures, > 0.
        tol: bound (nats) on the error of each scaled value V/β; log-probabilities are then
            accurate to within 2·tol. Floored at the floating-point resolution of the values.
        max_iter: sweep cap per hypothesis; default from :func:`default_max_iter`.
        chunk_size: hypotheses solved together; default from :func:`default_chunk_size`.
        dtype: ``"float64"`` (default) or ``"float32"`` (an explicit speed option; values are then
            accurate to about 1e-4 relative, limited by float32 resolution over ~1/(1-γ) backups).
        v_init: optional ``[H, S]`` warm start for V (reward units).
        progress: called as ``progress(done, total)`` as chunks complete.

    Raises:
        InputError: bad shapes, non-finite θ, or β <= 0.
        ConvergenceError: a hypothesis did not converge within ``max_iter`` sweeps.
    """
    theta, beta = _as_hypotheses(mdp, theta, beta)
    if not (tol > 0 and math.isfinite(tol)):
        raise InputError(f"tol must be a positive number, got {tol}")
    if dtype not in ("float64", "float32"):
        raise InputError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    jdtype = jnp.float64 if dtype == "float64" else jnp.float32
    H, S, A = theta.shape[0], mdp.n_states, mdp.n_actions
    if max_iter is None:
        max_iter = default_max_iter(mdp, theta, beta, tol)
    if chunk_size is None:
        chunk_size = default_chunk_size(mdp, np.dtype(dtype))
    chunk = max(1, min(int(chunk_size), H))
    lanes = min(LANES, chunk)
    groups = -(-chunk // lanes)
    prep = _prepare(mdp, jdtype)
    if v_init is not None:
        v_init = np.asarray(v_init, dtype=np.float64)
        if v_init.shape != (H, S):
            raise InputError(f"v_init must have shape [H, S] = [{H}, {S}], got {v_init.shape}")
        if not np.all(np.isfinite(v_init)):
            raise InputError("v_init must be finite")
        v_scaled0 = np.zeros((H, 2 * prep.n_block + 1))
        v_scaled0[:, prep.rows] = v_init / beta[:, None]
        v_scaled0[:, -1] = 0.0
    else:
        v_scaled0 = None
    # Similar temperatures converge in similar numbers of sweeps: chunk them together.
    perm = np.lexsort((*theta.T[::-1], beta))
    value = np.empty((H, S))
    log_pi = np.full((H, S, A), -np.inf)
    iters = np.empty(H, dtype=np.int64)
    consts = (jnp.asarray(mdp.gamma, dtype=jdtype), jnp.asarray(tol, dtype=jdtype), jnp.asarray(max_iter))
    n_rows = 2 * prep.n_block + 1
    active = np.flatnonzero(~mdp.terminal)
    act_rows = prep.rows[active]

    def launch(start: int):
        idx = perm[start:start + chunk]
        pad = groups * lanes - len(idx)
        if pad:  # keep one compiled shape: repeat the last hypothesis
            idx = np.concatenate([idx, np.repeat(idx[-1:], pad)])
        shape = (groups, lanes)
        v0 = (np.zeros((groups, n_rows, lanes)) if v_scaled0 is None
              else v_scaled0[idx].reshape(groups, lanes, n_rows).transpose(0, 2, 1))
        out = _solve_chunk(prep, jnp.asarray(theta[idx].reshape(*shape, -1)),
                           jnp.asarray(beta[idx].reshape(shape)), *consts, jnp.asarray(v0, dtype=jdtype))
        return start, out

    def collect(start: int, out) -> int:
        v, lp, it, delta = out
        # Flatten the (group, lane) axes back to one hypothesis axis, last.
        v = np.asarray(v, dtype=np.float64).transpose(1, 0, 2).reshape(n_rows, -1)
        lp = np.asarray(lp, dtype=np.float64).transpose(1, 2, 3, 0, 4)
        lp = lp.reshape(*lp.shape[:3], -1)
        it = np.asarray(it).reshape(-1)
        delta = np.asarray(delta).reshape(-1)
        idx = perm[start:start + chunk]
        n = len(idx)
        delta = delta[:n]
        if not np.all(delta == 0):  # also catches NaN
            h = int(idx[np.flatnonzero(~(delta == 0))[0]])
            raise ConvergenceError(
                f"soft value iteration did not converge for hypothesis {h} "
                f"(theta={np.round(theta[h], 6).tolist()}, beta={beta[h]:g}) "
                f"within {max_iter} sweeps: last change {delta[np.flatnonzero(idx == h)[0]]:.3g} "
                f"nats (tol {tol:g}); raise max_iter or tol"
            )
        v = v[:, :n]  # [rows, n]
        value[idx] = (v[prep.rows] * beta[idx][None, :]).T
        lp = lp[..., :n]  # [2, A, n_block, n]
        lp = np.concatenate([lp[0], lp[1]], axis=1)  # [A, 2 n_block, n] by solver row
        log_pi[np.ix_(idx, active)] = np.transpose(lp[:, act_rows], (2, 1, 0))
        iters[idx] = it[:n]
        return n

    pending: deque = deque()
    finished = 0
    for start in [*range(0, H, chunk), None]:
        if start is not None:
            pending.append(launch(start))
        while pending and (start is None or len(pending) >= _in_flight()):
            finished += collect(*pending.popleft())
            if progress is not None:
                progress(finished, H)
    log_pi[:, ~mdp.available] = -np.inf
    value[:, mdp.terminal] = 0.0
    return SoftSolution(value, log_pi, iters, beta.copy())


def pair_log_likelihoods(log_policy: np.ndarray, states, actions) -> np.ndarray:
    """``[H, N]`` log π_h(a_n | s_n) for observed pairs (``-inf`` if impossible)."""
    states = np.asarray(states, dtype=np.int64)
    actions = np.asarray(actions, dtype=np.int64)
    return log_policy[:, states, actions]


def log_likelihood(log_policy: np.ndarray, states, actions) -> np.ndarray:
    """``[H]`` log P(Ξ | θ_h, β_h) of Eq. 11: the sum of pair log-likelihoods."""
    return pair_log_likelihoods(log_policy, states, actions).sum(axis=1)
