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
DEFAULT_CHUNK_BYTES = 512 * 2**20
_WORK_ARRAYS = 4  # r, q, exp(q - m) and the output log-policy live at once per chunk


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
    features: jnp.ndarray  # [S, A, K]
    next_idx: jnp.ndarray  # [S, A] successor, unavailable -> own state (masked anyway)
    avail: jnp.ndarray  # [S, A] action may be taken (terminal: only a zero self-loop)
    out_mask: jnp.ndarray  # [S, A] mdp.available (False on terminal rows)


def _prepare(mdp: TabularMDP, dtype) -> _Prepared:
    S, A = mdp.n_states, mdp.n_actions
    ns = mdp.next_state
    term = mdp.terminal
    self_idx = np.broadcast_to(np.arange(S)[:, None], (S, A))
    next_idx = np.where(ns >= 0, ns, self_idx)
    avail = (ns >= 0) & ~term[:, None]
    # A terminal state keeps value exactly 0: one zero-reward self-loop.
    next_idx = np.where(term[:, None], self_idx, next_idx)
    avail = avail.copy()
    avail[term, 0] = True
    feats = np.where(term[:, None, None], 0.0, mdp.features)
    return _Prepared(
        jnp.asarray(feats, dtype=dtype),
        jnp.asarray(next_idx, dtype=jnp.int32),
        jnp.asarray(avail),
        jnp.asarray(mdp.available),
    )


@jax.jit
def _solve_chunk(prep: _Prepared, theta, beta, gamma, tol, max_iter, v0):
    """Solve one chunk in scaled units. Returns (v [H,S], log_pi [H,S,A], iters [H], delta [H])."""
    dtype = prep.features.dtype
    eps = jnp.finfo(dtype).eps
    r = jnp.einsum("sak,hk->hsa", prep.features, theta.astype(dtype)) / beta.astype(dtype)[:, None, None]
    r = jnp.where(prep.avail[None], r, -jnp.inf)
    gamma = gamma.astype(dtype)
    # Stop when ||v_{n+1} - v_n|| <= tol (1-γ)/γ, which bounds ||v_{n+1} - v*|| by tol;
    # floored at the floating-point resolution of the values themselves.
    base_thresh = tol * (1.0 - gamma) / gamma

    def backup(v):
        q = r + gamma * v[:, prep.next_idx]
        m = jnp.max(q, axis=-1, keepdims=True)
        z = q - m
        log_norm = jnp.log(jnp.sum(jnp.exp(z), axis=-1, keepdims=True))
        return (m + log_norm)[..., 0], z - log_norm

    def cond(carry):
        _, it, done, _ = carry
        return jnp.logical_and(~jnp.all(done), jnp.max(it) < max_iter)

    def body(carry):
        v, it, done, delta = carry
        v_new, _ = backup(v)
        d = jnp.max(jnp.abs(v_new - v), axis=-1)
        thresh = jnp.maximum(base_thresh, 8.0 * eps * jnp.max(jnp.abs(v_new), axis=-1))
        v = jnp.where(done[:, None], v, v_new)
        delta = jnp.where(done, delta, d)
        it = it + (~done).astype(it.dtype)
        done = done | (d <= thresh)
        return v, it, done, delta

    H = theta.shape[0]
    init = (v0.astype(dtype), jnp.zeros(H, jnp.int64), jnp.zeros(H, bool), jnp.full(H, jnp.inf, dtype))
    v, it, done, delta = jax.lax.while_loop(cond, body, init)
    # One more backup; the log-policy is (q - m) - log Σ exp(q - m), normalised by its own
    # log-partition, so rows sum to 1 to machine precision even when |q| is large.
    v, log_pi = backup(v)
    log_pi = jnp.where(prep.out_mask[None], log_pi, -jnp.inf)
    return v, log_pi, it, jnp.where(done, 0.0, delta)


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
    """Largest number of hypotheses whose work arrays fit in ``budget_bytes``."""
    per = mdp.n_states * mdp.n_actions * np.dtype(dtype).itemsize * _WORK_ARRAYS
    return max(1, int(budget_bytes // per))


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

    Args:
        mdp: the task.
        theta: ``[H, K]`` (or ``[K]``) reward weights.
        beta: ``[H]`` (or a scalar) temperatures, > 0.
        tol: bound (nats) on the error of each scaled value V/β; log-probabilities are then
            accurate to within 2·tol. Floored at the floating-point resolution of the values.
        max_iter: backup cap per hypothesis; default from :func:`default_max_iter`.
        chunk_size: hypotheses solved at once; default from :func:`default_chunk_size`.
        dtype: ``"float64"`` (default) or ``"float32"`` (an explicit speed option; values are then
            accurate to about 1e-4 relative, limited by float32 resolution over ~1/(1-γ) backups).
        v_init: optional ``[H, S]`` warm start for V (reward units).
        progress: called as ``progress(done, total)`` after each chunk.

    Raises:
        InputError: bad shapes, non-finite θ, or β <= 0.
        ConvergenceError: a hypothesis did not converge within ``max_iter`` backups.
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
    if v_init is not None:
        v_init = np.asarray(v_init, dtype=np.float64)
        if v_init.shape != (H, S):
            raise InputError(f"v_init must have shape [H, S] = [{H}, {S}], got {v_init.shape}")
        if not np.all(np.isfinite(v_init)):
            raise InputError("v_init must be finite")
        v_scaled0 = v_init / beta[:, None]
    else:
        v_scaled0 = np.zeros((H, S))
    prep = _prepare(mdp, jdtype)
    value = np.empty((H, S))
    log_pi = np.empty((H, S, A))
    iters = np.empty(H, dtype=np.int64)
    for start in range(0, H, chunk):
        stop = min(start + chunk, H)
        pad = chunk - (stop - start)
        sl = slice(start, stop)
        th, be, v0 = theta[sl], beta[sl], v_scaled0[sl]
        if pad:  # keep one compiled shape: repeat the last hypothesis
            th = np.concatenate([th, np.repeat(th[-1:], pad, 0)])
            be = np.concatenate([be, np.repeat(be[-1:], pad, 0)])
            v0 = np.concatenate([v0, np.repeat(v0[-1:], pad, 0)])
        v, lp, it, delta = _solve_chunk(
            prep, jnp.asarray(th), jnp.asarray(be), jnp.asarray(mdp.gamma),
            jnp.asarray(tol), jnp.asarray(max_iter), jnp.asarray(v0),
        )
        n = stop - start
        delta = np.asarray(delta)[:n]
        if not np.all(delta == 0):  # also catches NaN
            h = int(np.flatnonzero(~(delta == 0))[0])
            raise ConvergenceError(
                f"soft value iteration did not converge for hypothesis {start + h} "
                f"(theta={np.round(theta[start + h], 6).tolist()}, beta={beta[start + h]:g}) "
                f"within {max_iter} backups: last change {delta[h]:.3g} nats (tol {tol:g}); "
                "raise max_iter or tol"
            )
        value[sl] = np.asarray(v)[:n] * be[:n, None]
        log_pi[sl] = np.asarray(lp)[:n]
        iters[sl] = np.asarray(it)[:n]
        if progress is not None:
            progress(stop, H)
    return SoftSolution(value, log_pi, iters, beta.copy())


def pair_log_likelihoods(log_policy: np.ndarray, states, actions) -> np.ndarray:
    """``[H, N]`` log π_h(a_n | s_n) for observed pairs (``-inf`` if impossible)."""
    states = np.asarray(states, dtype=np.int64)
    actions = np.asarray(actions, dtype=np.int64)
    return log_policy[:, states, actions]


def log_likelihood(log_policy: np.ndarray, states, actions) -> np.ndarray:
    """``[H]`` log P(Ξ | θ_h, β_h) of Eq. 11: the sum of pair log-likelihoods."""
    return pair_log_likelihoods(log_policy, states, actions).sum(axis=1)
