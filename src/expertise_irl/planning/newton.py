"""Newton's method (soft policy iteration) to finish soft value iteration on large maps.

For the soft models (``maxent``, ``maxent-relative``) the Bellman operator ``T v = logsumexp_a
(r + γ v[next])`` (minus ``log |A(s)|`` for ``maxent-relative``) is smooth, with Jacobian ``γ P_π``:
``P_π`` the walk of the policy ``π = softmax q`` the values ``v`` give. Newton's step for
``v = T v`` on the non-terminal states,

    v ← v − (I − γ P_π)⁻¹ (v − T v),

is one step of soft policy iteration (an exact evaluation of ``π``) and converges quadratically
near the solution, in a few steps whatever γ, where a sweep contracts the slowest modes of a large
map by only about γ² (docs/performance.md, "Large worlds"). A step's cost is a sparse LU
factorisation of ``I − γ P_π`` (SuperLU, COLAMD order: 0.4 s at 79,040 states), so from values
already near the solution the **chord method** keeps one factorisation: each further step is a
backup and two triangular solves (~20 ms there), and converges linearly at the rate the policy has
moved since. A step that does not halve the largest residual ``|v − T v|`` refactorises at the
current values (an exact Newton step). A hypothesis that has not converged within
:data:`MAX_STEPS`, or whose values turn non-finite, keeps the values of the smallest residual it
reached (those it came with if no step helped).

Nothing here is certified: :func:`expertise_irl.planning.soft_vi.solve` hands the values back to
its pool of sweeps, whose plain sweeps certify the tolerance as from any start.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from scipy.special import logsumexp

from ..mdp import TabularMDP

__all__ = ["MAX_STEPS", "SOFT_MODELS", "newton_finish", "newton_values", "residuals"]

#: The models whose backup is smooth (a log-sum-exp): Newton's method applies.
SOFT_MODELS = ("maxent", "maxent-relative")
#: Chord and Newton steps per hypothesis before it is left to the sweeps.
MAX_STEPS = 30
#: The chord stops when the largest residual is this share of the sweeps' stopping threshold
#: ``tol·(1 − γ)/γ``, so that the sweeps certify it in their first few sweeps.
MARGIN = 0.1
#: ... or when it is within this many ulps of the largest value: the residual's rounding floor.
FLOOR = 4


class _Walk:
    """One hypothesis' scaled rewards on one MDP, and its backups."""

    def __init__(self, mdp: TabularMDP, theta, beta: float, model: str):
        self.mdp, self.g = mdp, mdp.gamma
        self.act = ~mdp.terminal
        self.avail = mdp.available[self.act]
        self.nxt = np.where(mdp.available, mdp.next_state, 0)[self.act]
        self.r = np.where(self.avail, mdp.reward(theta)[self.act] / beta, -np.inf)
        n = self.avail.sum(axis=1)
        self.shift = np.log(np.maximum(n, 1)) if model == "maxent-relative" else 0.0
        index = np.full(mdp.n_states, -1)
        index[np.flatnonzero(self.act)] = np.arange(self.act.sum())
        rows, acts = np.nonzero(self.avail)
        dest = index[self.nxt[rows, acts]]  # row of each move's successor (-1: terminal, value 0)
        keep = dest >= 0
        self.rows, self.acts, self.dest = rows[keep], acts[keep], dest[keep]

    def backup(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(T v, π)`` on the non-terminal states (``v [S]`` scaled, 0 at terminal states)."""
        q = np.where(self.avail, self.r + self.g * v[self.nxt], -np.inf)
        top = logsumexp(q, axis=1)
        return top - self.shift, np.exp(q - top[:, None])

    def finish(self, v: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Certify scaled values ``v [S]`` without a pool of sweeps: one Jacobi backup ``v₁ = T v``;
        ``T`` is a γ-contraction, so where it changes them by at most ``tol·(1 − γ)/γ`` (or the
        floating-point floor ``8·eps·max|v|``, as the sweeps stop) ``|v₁ − v*| ≤ tol``. One more
        backup gives the values ``T v₁`` and the normalised log-policy of ``v₁``, as the pool's last
        backup does: ``(values [S], log-policy [S, A])`` scaled (terminal rows 0 and −inf), or None
        where the first backup changed the values by more."""
        g, act = self.g, self.act
        v1 = np.zeros_like(v)
        v1[act] = self.backup(v)[0]
        floor = 8 * np.finfo(float).eps * np.max(np.abs(v), initial=0.0)
        if np.max(np.abs(v1 - v), initial=0.0) > max(tol * (1 - g) / g, floor):
            return None
        q = np.where(self.avail, self.r + g * v1[self.nxt], -np.inf)
        top = logsumexp(q, axis=1)
        value, log_pi = np.zeros_like(v), np.full((v.size, self.avail.shape[1]), -np.inf)
        value[act], log_pi[act] = top - self.shift, q - top[:, None]
        return value, log_pi

    def jacobian(self, p: np.ndarray):
        """``I − γ P_π`` on the non-terminal states (moves into terminal states drop out: value 0)."""
        n = int(self.act.sum())
        P = sp.csr_matrix((p[self.rows, self.acts], (self.rows, self.dest)), shape=(n, n))
        return (sp.identity(n, format="csr") - self.g * P).tocsc()


def _chord(walk: _Walk, v: np.ndarray, threshold: float) -> tuple[np.ndarray, int]:
    """Chord steps from ``v`` (scaled, ``[S]``) until the largest residual is below ``threshold``
    (or the floating-point floor of the values): ``(values, steps)``, the values of the smallest
    residual seen if it does not get there (``v`` itself if no step helped)."""
    act = walk.act
    lu, last, out = None, np.inf, v.copy()
    best, best_change = v, np.inf
    for step in range(MAX_STEPS + 1):
        tv, p = walk.backup(out)
        res = out[act] - tv
        change = float(np.max(np.abs(res), initial=0.0))
        if not np.isfinite(change):
            break
        if change < best_change:
            best, best_change = out.copy(), change
        if change <= max(threshold, FLOOR * np.finfo(float).eps * float(np.max(np.abs(out), initial=0.0))):
            return out, step
        if step == MAX_STEPS:
            break
        if lu is None or change > 0.5 * last:  # the first step, or the chord stalls: an exact step
            lu = splu(walk.jacobian(p))
        last = change
        out[act] -= lu.solve(res)
    return best, step


def residuals(mdp: TabularMDP, theta, beta, value, *, model: str = "maxent",
              threads: int | None = None) -> np.ndarray:
    """``[H]`` the largest change ``max_s |v − T v|`` one Jacobi backup makes to each hypothesis'
    scaled values ``v = value/β`` (``value [H, S]`` in reward units), over the non-terminal states."""
    def one(walk: _Walk, v: np.ndarray) -> float:
        return float(np.max(np.abs(v[walk.act] - walk.backup(v)[0]), initial=0.0))

    return np.array(_each(mdp, theta, beta, value, model, one, threads))


def newton_values(mdp: TabularMDP, theta, beta, value, tol: float, *, model: str = "maxent",
                  threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Values of every hypothesis ``(theta [H, K], beta [H])`` taken from ``value [H, S]`` (reward
    units) towards the solution by chord and Newton steps, until each residual is within
    :data:`MARGIN` of the sweeps' threshold for ``tol`` (module docstring).

    Args:
        mdp: the task.
        theta: ``[H, K]`` reward weights.
        beta: ``[H]`` temperatures.
        value: ``[H, S]`` start values in reward units (0 at terminal states), e.g. a solve to a
            loose tolerance.
        tol: the tolerance (nats on V/β) the caller's sweeps will certify.
        model: one of :data:`SOFT_MODELS`.
        threads: hypotheses worked on at once (SuperLU releases the interpreter while it
            factorises and solves); default: the machine's cores.

    Returns:
        ``([H, S] values in reward units, [H] steps taken)``; a hypothesis that did not converge
        has the values of the smallest residual it reached.

    Raises:
        ValueError: a model without a smooth backup.
    """
    threshold = MARGIN * tol * (1 - mdp.gamma) / mdp.gamma
    done = _each(mdp, theta, beta, value, model, lambda walk, v: _chord(walk, v, threshold), threads)
    return _scaled_back(np.array([v for v, _ in done]), beta), np.array([k for _, k in done], np.int64)


def newton_finish(mdp: TabularMDP, theta, beta, value, tol: float, *, model: str = "maxent",
                  threads: int | None = None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`newton_values`, then each hypothesis certified by one backup (:meth:`_Walk.finish`),
    on the same thread and walk: ``([H, S] values in reward units, [H, S, A] log-policies or None,
    [H] steps)``. With the log-policies the values are within ``tol`` of the solution (reported one
    backup further, as the pool reports them); None where any hypothesis' backup did not certify
    ``tol``, and the values are then :func:`newton_values`' (for the sweeps to finish)."""
    threshold = MARGIN * tol * (1 - mdp.gamma) / mdp.gamma

    def one(walk: _Walk, v: np.ndarray):
        v, steps = _chord(walk, v, threshold)
        return v, steps, walk.finish(v, tol)

    done = _each(mdp, theta, beta, value, model, one, threads)
    steps = np.array([k for _, k, _ in done], np.int64)
    if any(f is None for _, _, f in done):
        return _scaled_back(np.array([v for v, _, _ in done]), beta), None, steps
    log_pi = np.array([f[1] for _, _, f in done])
    return _scaled_back(np.array([f[0] for _, _, f in done]), beta), log_pi, steps


def _scaled_back(values: np.ndarray, beta) -> np.ndarray:
    """Scaled values ``[H, S]`` in reward units."""
    return values * np.atleast_1d(np.asarray(beta, float))[:, None]


def _each(mdp: TabularMDP, theta, beta, value, model: str, fn, threads: int | None) -> list:
    """``[fn(walk_h, value[h]/β_h) for every hypothesis h]``, on threads (SuperLU releases the
    interpreter), each distinct hypothesis and start once (a padded batch repeats one)."""
    if model not in SOFT_MODELS:
        raise ValueError(f"Newton's method needs a smooth backup ({', '.join(SOFT_MODELS)}), got {model!r}")
    theta, beta = np.atleast_2d(theta), np.atleast_1d(np.asarray(beta, float))
    value = np.asarray(value, float)
    seen: dict[bytes, int] = {}  # bitwise-equal rows (np.unique(axis=0) took 0.3 s at 79,040 states)
    inverse = [seen.setdefault(row.tobytes(), len(seen)) for row in np.column_stack([theta, beta, value])]
    first = [inverse.index(i) for i in range(len(seen))]

    def one(h: int):
        return fn(_Walk(mdp, theta[h], float(beta[h]), model), value[h] / beta[h])

    workers = max(1, min(len(first), threads or os.cpu_count() or 1))
    with ThreadPoolExecutor(max_workers=workers) as pool:
        done = list(pool.map(one, first))
    return [done[i] for i in inverse]
