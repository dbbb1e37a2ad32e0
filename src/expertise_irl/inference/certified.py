"""Certified log-likelihoods: solve each hypothesis only as precisely as its posterior needs.

A person's demonstrations put most hypotheses of a set hundreds of nats below the best one;
their values need only be known well enough to prove that. :func:`certified_log_likelihoods`
solves in two stages.

**The bound.** The solver stops a hypothesis when a plain Gauss–Seidel sweep changes its scaled
values v = V/β by at most ``tol·(1 − γ)/γ`` (or by the floating-point floor ``8·eps·max|v|``); a
sweep is a γ-contraction, so the values are then within ``tol_h = max(tol, 8·eps·max|v|·γ/(1 − γ))``
of the solution. A log-probability ``log π(a|s) = q(s, a) − logsumexp_a' q(s, a')`` with ``q =
r + γ v[next]`` is then within ``2γ·tol_h ≤ 2·tol_h`` of the exact one (q moves by at most γ·tol_h
and logsumexp is 1-Lipschitz), so the log-likelihood of N observed actions lies within
``e_h = 2·tol_h·N`` of its exact value: the certified interval ``[LL_h − e_h, LL_h + e_h]``.

**Stage 1 (screen).** Every hypothesis is solved to ``screen_tol`` (by default the tolerance
whose interval is ±:data:`SCREEN_WIDTH` nats wide for these demonstrations, never tighter than
the final one). With log prior weights ``w_h``, the lower bounds give the best certain log mass
``M = max_h (LL_h − e_h + w_h)``; a hypothesis whose upper bound ``LL_h + e_h + w_h`` lies below
``M + ln(elimination / H)`` has posterior probability below ``elimination / H`` whatever its
exact values, and is **eliminated**: it keeps its screened values and stops.

**Stage 2 (finish).** The survivors continue from their screened values to the final tolerance:
``tol`` when given, else the one the demonstrations need for every posterior probability to be
within ``probability_error`` of the exact one: with every log-likelihood within ε of its exact
value, each probability is within ``e^{2ε} − 1`` of it (and the eliminated mass, at most
``elimination``, moves the rest by at most that), so ``ε = ln(1 + probability_error −
elimination)/2`` and ``tol = ε/(2N)``. The result reports the bound actually reached, from each
hypothesis' own ``tol_h``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..mdp import TabularMDP

#: Half-width (nats) of the screening stage's log-likelihood intervals.
SCREEN_WIDTH = 1.0
#: The posterior mass every eliminated hypothesis together may hold at most (relative to the best).
ELIMINATION = 1e-12
#: The default bound on the error of every reported posterior probability.
PROBABILITY_ERROR = 1e-6
#: Batches are padded to 64 × (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, …) hypotheses: a few shapes for JAX to
#: compile, at most a third of padding.
BUCKET = 64
#: The tightest tolerance a data-set tolerance goes to (the values' floating-point floor decides
#: below it anyway).
MIN_TOL = 1e-13


@dataclass(frozen=True, eq=False)
class Certified:
    """Log-likelihoods of H hypotheses with certified error bounds (see the module docstring).

    Attributes:
        log_policy: per map, ``[H, S, A]`` the log-policies (eliminated ones to the screening
            tolerance).
        value: per map, ``[H, S]`` the values (reward units).
        log_likelihood: ``[H]`` log P(Ξ | θ_h, β_h) summed over the maps.
        error: ``[H]`` certified bound on |log_likelihood − exact|.
        eliminated: ``[H]`` whether the hypothesis stopped at the screening stage.
        screen_tol, tol: the two stages' tolerances (nats on V/β).
        probability_error: a bound on the error of every posterior probability computed from
            these log-likelihoods (with the log prior weights given).
        sweeps: ``[H]`` backups spent on each hypothesis, both stages.
    """

    log_policy: tuple[np.ndarray, ...]
    value: tuple[np.ndarray, ...]
    log_likelihood: np.ndarray
    error: np.ndarray
    eliminated: np.ndarray
    screen_tol: float
    tol: float
    probability_error: float
    sweeps: np.ndarray

    def record(self) -> dict:
        """What a result document states about it."""
        return {"eliminated": int(self.eliminated.sum()), "hypotheses": int(self.eliminated.size),
                "screen_tol": self.screen_tol, "tol": self.tol, "probability_error": self.probability_error,
                "max_log_likelihood_error": float(self.error[~self.eliminated].max(initial=0.0)),
                "sweeps": int(self.sweeps.sum())}


def bucket_size(n: int) -> int:
    """The smallest of 64 × (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, …) that holds ``n``."""
    for b in (BUCKET, 2 * BUCKET, 3 * BUCKET):
        if b >= n:
            return b
    scale = 1
    while True:
        for k in (4, 5, 6):
            if BUCKET * k * scale >= n:
                return BUCKET * k * scale
        scale *= 2


def data_tolerance(n_actions: int, probability_error: float = PROBABILITY_ERROR,
                   elimination: float = ELIMINATION) -> float:
    """The tolerance that keeps every posterior probability within ``probability_error`` of the
    exact one for ``n_actions`` observed actions (module docstring)."""
    if not 0 < elimination < probability_error < 1:
        raise InputError(f"need 0 < elimination < probability_error < 1, got {elimination:g} and "
                         f"{probability_error:g}")
    eps = math.log1p(probability_error - elimination) / 2
    return max(eps / (2 * max(n_actions, 1)), MIN_TOL)


def _reached(mdp: TabularMDP, value: np.ndarray, beta: np.ndarray, tol: float) -> np.ndarray:
    """``[H]`` the tolerance each solve certifies: ``tol`` or the floating-point floor of its values."""
    g = mdp.gamma
    vmax = np.max(np.abs(value), axis=1) / beta
    return np.maximum(tol, 8 * np.finfo(np.float64).eps * vmax * g / (1 - g))


def certified_log_likelihoods(tasks: Sequence[tuple[TabularMDP, Sequence]], theta, beta, *,
                              log_prior: np.ndarray | None = None, tol: float | None = None,
                              screen_tol: float | None = None, elimination: float = ELIMINATION,
                              probability_error: float = PROBABILITY_ERROR, v_init=None,
                              best_known: float = -math.inf, progress=None, **solve_kwargs) -> Certified:
    """Two-stage solve of ``(theta [H, K], beta [H])`` on every map of ``tasks`` (``(mdp,
    [Trajectories, ...])`` pairs sharing the features), with certified log-likelihood bounds
    and elimination (module docstring). ``tol``: the survivors' tolerance (default: the data's);
    ``log_prior``: ``[H]`` log prior weights (default equal); ``v_init``: per map ``[H, S]``
    start values; ``best_known``: a log mass (log-likelihood + log prior weight) certainly reached by
    a hypothesis solved before, outside this batch (hypotheses below it are eliminated too);
    ``progress(done, total)`` hears the screening stage; ``solve_kwargs`` go to
    :func:`~expertise_irl.planning.soft_vi.solve`."""
    from ..planning.soft_vi import solve
    from ..planning.table_likelihood import log_likelihood

    theta, beta = np.atleast_2d(np.asarray(theta, float)), np.atleast_1d(np.asarray(beta, float))
    H = len(beta)
    n = sum(len(t.state) for _, shown in tasks for t in shown)
    final = data_tolerance(n, probability_error, elimination) if tol is None else float(tol)
    screen = max(SCREEN_WIDTH / (2 * max(n, 1)), final) if screen_tol is None else max(screen_tol, final)
    prior = np.zeros(H) if log_prior is None else np.asarray(log_prior, float)

    def stage(idx, t, starts, tick=None):
        out = []
        for g, (mdp, shown) in enumerate(tasks):
            v0 = None if starts is None else starts[g][idx]
            sol = solve(mdp, theta[idx], beta[idx], tol=t, v_init=v0, progress=tick, **solve_kwargs)
            lp, v = np.asarray(sol.log_policy), np.asarray(sol.value)
            ll = sum(log_likelihood(lp, tr.state, tr.action) for tr in shown)
            errs = 2 * _reached(mdp, v, beta[idx], t) * sum(len(tr.state) for tr in shown)
            out.append((lp, v, ll, errs, np.asarray(sol.iterations)))
        return out

    first = stage(np.arange(H), screen, v_init, progress)
    ll = sum(o[2] for o in first)
    err = sum(o[3] for o in first)
    sweeps = sum(o[4] for o in first).astype(np.int64)
    lower, upper = ll - err + prior, ll + err + prior
    finite = np.isfinite(lower)
    best = max(lower[finite].max() if finite.any() else -np.inf, best_known)
    gone = upper < best + math.log(elimination / H) if np.isfinite(best) else np.zeros(H, bool)
    keep = np.flatnonzero(~gone)
    policies, values = [o[0].copy() for o in first], [o[1].copy() for o in first]
    if final < screen and keep.size:
        m = keep.size  # padded with the last survivor to a bucket's size: few shapes to compile
        padded = np.concatenate([keep, np.repeat(keep[-1:], bucket_size(m) - m)])
        second = [tuple(x[:m] for x in o) for o in stage(padded, final, values)]
        ll, err = ll.copy(), err.copy()
        ll[keep] = sum(o[2] for o in second)
        err[keep] = sum(o[3] for o in second)
        sweeps[keep] += sum(o[4] for o in second)
        for g, o in enumerate(second):
            policies[g][keep], values[g][keep] = o[0], o[1]
    eps = float(err[keep].max(initial=0.0)) if np.isfinite(err[keep]).all() else math.inf
    bound = math.expm1(2 * eps) + (elimination if gone.any() else 0.0)
    return Certified(tuple(policies), tuple(values), ll, err, gone, screen, final, bound, sweeps)
