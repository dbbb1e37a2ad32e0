"""Certified elimination inside the sweeps: a hypothesis whose log-likelihood is certainly too low
stops sweeping as soon as that is certain.

:func:`expertise_irl.inference.certified.certified_log_likelihoods` screens every hypothesis of a
set to a few nats, then eliminates those whose posterior probability is certainly negligible. A
person's demonstrations put most hypotheses hundreds or thousands of nats below the best one, and
that is certain long before their values are known to a few nats: for the telescoping models the
log-likelihood is an affine function of the scaled values, ``LL_h = b_h + Σ_s w_s v(s)``, within
``F·tol_h`` of the exact one when ``|v − v*| ≤ tol_h`` (``F = Σ_s |w_s|``), and a sweep pool knows
``tol_h`` at every check from the sweep's change: ``γ/(1 − γ)`` times the change of a plain
Gauss–Seidel sweep, ``γ²/(1 − γ²)`` times that of a symmetric one (two Gauss–Seidel passes). A
:class:`Gate` makes the pools (:func:`.kernels.solve_pool`, :func:`.level_order.level_start`)
keep the best certain lower bound ``max_h (LL_h − F·tol_h + l_h)`` seen so far (``l_h`` the log
prior weight, counted in ``b_h``) and stop a lane at a check when its upper bound
``LL_h + F·tol_h + l_h`` lies below that best by more than ``−margin``: the same test the
screening stage makes afterwards, made earlier. The lane hands back its values with the
``tol_h`` they certify, which the caller uses for the hypothesis' bound.

**Values below the solution.** Where a lane's values are certainly below the solution, ``−tol_h
≤ e ≤ 0`` with ``e = v − v*``, the exact log-likelihood ``LL − Σ_s w_s e(s)`` lies in ``[LL −
W₋·tol_h, LL + W₊·tol_h]`` with ``W₊ = Σ_{w_s > 0} w_s`` and ``W₋ = Σ_{w_s < 0} |w_s|``. Along a
path every visited state is left as often as it is reached, so its weight is ``−(1 − γ)`` per
visit; only an episode's last state, where it did not reach a goal, has a positive weight (γ).
So ``W₊`` is at most the number of episodes, against ``Σ|w| ≈ 2E + (1 − γ)N``: the upper bound
that elimination needs is several times tighter. Values are below the solution when a plain
Gauss–Seidel sweep lowered none of them (each state's backup then read values no higher than the
new ones, so ``v ≤ T v``, and ``T`` is monotone), and all along the level sweeps from
:func:`.level_order.approach_start`, which is below the solution and from which the sweeps rise.
Rounding can leave such values above the solution by a few units of their last place per backup,
``8·eps·max|v|/(1 − γ)`` at most over the backups' geometric memory: the upper bound adds that
much for every unit of ``W₋``, and every sum its own rounding (``64·eps`` times the magnitudes of
its terms).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

#: The support of a gate is padded to a power of two of at least this many states (zero weights),
#: so that few shapes are compiled.
MIN_SUPPORT = 8


class Gate(NamedTuple):
    """What a sweep pool needs to eliminate hypotheses as it sweeps (module docstring).

    Attributes:
        states: ``[k]`` the states of non-zero weight.
        weights: ``[k]`` their weights ``w_s`` in the telescoped log-likelihood.
        base: ``[H]`` per hypothesis the rest of its log-likelihood and its log prior weight:
            ``Σ_t (r_t − c_t) + l_h`` in scaled units (``r = R/β``).
        factor: ``Σ_s |w_s|``, the log-likelihood's error per unit ``tol_h``.
        positive: ``Σ_{w_s > 0} w_s``: from values below the solution the exact log-likelihood is
            at most ``positive·tol_h`` above the sum (module docstring).
        margin: how far (nats, < 0) below the best certain lower bound an upper bound must lie.
        best: a log mass (log-likelihood + log prior weight) already certain (−inf: none).
        n_moves: the observed moves (for the rounding bound of the sums).
        scale: ``[H]`` the sum of the magnitudes of ``base``'s terms (for its rounding bound;
            default ``|base|``).
    """

    states: np.ndarray
    weights: np.ndarray
    base: np.ndarray
    factor: float
    positive: float
    margin: float
    best: float = -np.inf
    n_moves: int = 0
    scale: np.ndarray | None = None


class GateArrays(NamedTuple):
    """A :class:`Gate` in a pool's layout: support rows, weights, ``base`` in the pool's order."""

    rows: jnp.ndarray
    weights: jnp.ndarray
    base: jnp.ndarray
    factor: jnp.ndarray
    positive: jnp.ndarray
    margin: jnp.ndarray
    n_moves: jnp.ndarray
    scale: jnp.ndarray


def gate_arrays(gate: Gate, state_rows: np.ndarray, order: np.ndarray, dtype, zero_row: int) -> GateArrays:
    """``gate`` for a pool whose hypothesis ``i`` is the gate's ``order[i]``, on an MDP whose state
    ``s`` is solver row ``state_rows[s]``; the support padded with zero weights on the solver's
    ``zero_row`` (:data:`MIN_SUPPORT`)."""
    k = max(len(gate.states), 1)
    size = max(MIN_SUPPORT, 1 << (k - 1).bit_length())
    rows = np.full(size, zero_row, np.int32)
    w = np.zeros(size)
    rows[:len(gate.states)] = state_rows[np.asarray(gate.states, np.int64)]
    w[:len(gate.states)] = gate.weights
    base = np.asarray(gate.base)[order]
    scale = np.abs(base) if gate.scale is None else np.asarray(gate.scale)[order]
    return GateArrays(jnp.asarray(rows), jnp.asarray(w, dtype), jnp.asarray(base, dtype),
                      jnp.asarray(gate.factor, dtype), jnp.asarray(gate.positive, dtype),
                      jnp.asarray(gate.margin, dtype), jnp.asarray(gate.n_moves, dtype),
                      jnp.asarray(scale, dtype))


def rough_log_likelihood(gate: Gate, values: np.ndarray, state_rows: np.ndarray) -> np.ndarray:
    """``[H]`` the gate's log-likelihood sums from scaled values ``[H, rows]`` (no bound: an order)."""
    return np.asarray(gate.base) + values[:, state_rows[np.asarray(gate.states, np.int64)]] @ gate.weights


def gate_check(g: GateArrays, v_slots, d, vmax, lane_h, active, best, ratio, below):
    """One check of a pool's lanes: ``(stop [slots], best, tol_h [slots])``.

    ``v_slots``: ``[slots, k]`` the lanes' scaled values at the support rows; ``d``: ``[slots]``
    each lane's change over the sweep just made; ``vmax``: ``[slots]`` its largest |value|;
    ``ratio``: ``γ/(1 − γ)`` for a plain sweep, ``γ²/(1 − γ²)`` for a symmetric one; ``below``:
    ``[slots]`` whether the lane's values are certainly below the solution (module docstring);
    ``best``: the best certain log mass so far. A lane stops when its upper bound is below
    ``best + margin``; ``best`` rises with every busy lane's lower bound.
    """
    eps = jnp.finfo(v_slots.dtype).eps
    terms = v_slots * g.weights
    ll = g.base[lane_h] + terms.sum(axis=1)
    tol_h = jnp.maximum(d, 8.0 * eps * vmax) * ratio
    # values below the solution may exceed it by rounding, 8·eps·max|v|/(1 − γ) at most (module
    # docstring): 1/(1 − γ) is ratio + 1 for a plain sweep, at most 2·(ratio + 1) for a symmetric one
    above = 16.0 * eps * vmax * (ratio + 1.0)
    rounding = 64.0 * eps * (g.scale[lane_h] + jnp.abs(terms).sum(axis=1) + g.n_moves)
    up = jnp.where(below, g.positive * tol_h + (g.factor - g.positive) * above, g.factor * tol_h) + rounding
    down = jnp.where(below, g.factor - g.positive, g.factor) * tol_h + rounding
    ok = active & jnp.isfinite(ll) & jnp.isfinite(up) & jnp.isfinite(down)
    best = jnp.maximum(best, jnp.max(jnp.where(ok, ll - down, -jnp.inf)))
    stop = ok & (ll + up < best + g.margin)
    return stop, best, tol_h
