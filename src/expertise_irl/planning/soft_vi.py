"""Batched soft value iteration (paper Eqs. 8–9) over many hypotheses at once.

All H hypotheses (θ_h, β_h) are solved together in one JAX ``while_loop``.
The work is done in *scaled* units: with ``r = R / β`` (``R = θ·φ`` plus the MDP's fixed
reward, :meth:`~expertise_irl.mdp.TabularMDP.reward`) the soft Bellman
equations become ``q = r + γ v[next]``, ``v = logsumexp_a q``, and the
true quantities are ``V = β v``, ``Q = β q``. This makes every β from 1e-3 to
100 equally well conditioned and means the stopping tolerance is directly the
error in log-probabilities (nats), which is what inference consumes.

Each hypothesis stops on its own tolerance (it is frozen once converged), and
a hypothesis that does not converge within ``max_iter`` backups raises
:class:`ConvergenceError`. Large hypothesis sets are solved in chunks so that
memory stays bounded; chunks are padded to one shape so JAX compiles once.

Start values (:func:`solve`'s ``method``; default :func:`default_method`, i.e.
:data:`SOLVER_ENV`, else ``"levels"`` on MDPs of at least :data:`LEVELS_MIN_STATES` states and
``"sweeps"`` on smaller ones): ``"sweeps"`` starts the pool from ``v_init`` (or zero);
``"jumps"`` first takes greedy path jumps (:func:`.kernels.jump_start`, float64 only);
``"levels"`` first sweeps the states in order of their distance to the goal, outwards then
inwards (:mod:`.level_order`), which carries values along whole paths and round long loops in
one sweep, starting (without ``v_init``) from the values of the soft walk that only moves
towards the goal, a lower bound on the solution. Either way the pool's plain sweeps certify the
tolerance, so the guarantee on V/β is the same; ``iterations`` counts the jumps' and level
sweeps' cost in sweeps.

Newton's finish (``newton``; by default on a CPU for the soft models on MDPs of at least
:data:`NEWTON_MIN_STATES` states and γ >= :data:`NEWTON_MIN_GAMMA`): the pool sweeps to
:data:`NEWTON_FROM` nats, chord and Newton steps (:mod:`.newton`, sparse LU) take each
hypothesis from there to within a tenth of the tolerance, and the pool's plain sweeps then
certify the tolerance from those values, so the guarantee on V/β is the same; ``newton_steps``
counts the steps.

Two phases (``float32_start``): a float64 solve of at least :data:`FLOAT32_START_MIN`
hypotheses without ``v_init`` first sweeps in float32 down to float32 resolution, then finishes
in float64 from those values. The float64 phase stops on the same contraction bound as a cold
start, so the guarantee on V/β is unchanged. If the float32 phase does not converge (weights
beyond float32's range, say), a cold float64 solve decides. ``iterations`` then counts the
sweeps of both phases. Off by default: with over-relaxation a float32 sweep saves too little on
a CPU to pay for the second phase (docs/performance.md); it may pay where float32 is much faster
than float64.
"""

from __future__ import annotations

import inspect
import math
import os
from collections.abc import Callable
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ..errors import ArgumentError, ConvergenceError, InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL, check_model
from ..numerics import enable_float64
from . import kernels as kernel
from .tuning import lane_width

DEFAULT_TOL = 1e-8
#: With ``float32_start``, sets at least this large are solved in float32 first, then in float64 from there
#: (smaller ones would pay the float32 kernels' compilation for little gain).
FLOAT32_START_MIN = 512
#: Copies of ``[H, rows]`` start values one pass of the solver holds at once (:func:`batch_limit`).
START_COPIES = 8
#: The fewest hypotheses a pass is cut down to for memory: the largest pool of lanes.
MIN_BATCH = 256
#: Sets at least this large measure the machine's lane width if none is known yet
#: (:mod:`expertise_irl.planning.tuning`); smaller ones use the default width.
TUNE_MIN = 64
#: Share of a two-phase solve's time spent in the float32 phase (for progress reports).
_FLOAT32_SHARE = 0.4
#: Solver methods: ``sweeps`` (the sweep pool alone), ``jumps`` (greedy path jumps first, then
#: the pool) and ``levels`` (sweeps in order of the distance to the goal first, then the pool);
#: see :func:`solve`.
METHODS = ("sweeps", "jumps", "levels")
#: Names the method of every solve that does not pass one (``sweeps`` runs the earlier solver
#: from any command, e.g. ``EXPERTISE_IRL_SOLVER=sweeps expertise-irl infer ...``).
SOLVER_ENV = "EXPERTISE_IRL_SOLVER"
#: MDPs of at least this many states are solved with ``levels`` by default, smaller ones with
#: ``sweeps``. Measured on the generated floor plans (docs/performance.md, "Large worlds"), the
#: whole ``infer`` with ``levels`` took 1.22x the time of ``sweeps`` at 4,940 states, 0.92x at
#: 19,760 and 0.74x at 79,040 (the 30 x 30 full set, 883 states: 1.7x).
LEVELS_MIN_STATES = 10_000
#: MDPs of at least this many states and a discount of at least :data:`NEWTON_MIN_GAMMA` finish a
#: soft model's solve by Newton's method on a CPU (:mod:`.newton`; :func:`solve`'s ``newton``).
#: Measured on the floor plans (γ = 0.99, paper-real hypotheses to 1e-8, warm): 1.16 -> 0.70 s at
#: 1,138 states, 4.3 -> 2.2 s at 4,940, 13.0 -> 8.5 s at 19,760; on ``zones30`` (883 states,
#: γ = 0.95: ~5x fewer sweeps per nat) 0.30 -> 0.58 s for 200 hypotheses.
NEWTON_MIN_STATES = 1_000
#: ... and the discount below which sweeps converge fast enough to keep (γ² per sweep).
NEWTON_MIN_GAMMA = 0.98
#: The tolerance the sweeps reach before Newton's method takes over: near enough for the chord
#: method to converge in a few steps on one or two factorisations. Five people at 200 x 200 to
#: 1e-8 took 7.4 s from 1 nat, 8.5 s from 3, 9.1-9.4 s from 0.3 and 0.1.
NEWTON_FROM = 1.0
#: Newton's finish is used for tolerances below this (a screen to 0.14 nats is left to the sweeps:
#: with Newton from 1 nat, the certified screen at 200 x 200 took 48-50 s against 31-37 s).
NEWTON_BELOW = 0.01


def default_method(mdp: TabularMDP | None = None) -> str:
    """The method of a solve that passes none: :data:`SOLVER_ENV` if set, else ``"levels"`` for an
    ``mdp`` of at least :data:`LEVELS_MIN_STATES` states on a CPU and ``"sweeps"`` otherwise.

    On a GPU the level sweeps' many small blocks cost more than the sweeps they save: on an H200,
    95 hypotheses on a 200 × 200 plan took 7.7 s with ``levels`` against 1.1 s with ``sweeps``
    (400 × 400: 27 s against 3.8 s; docs/performance.md)."""
    method = os.environ.get(SOLVER_ENV, "")
    if not method:
        large = mdp is not None and mdp.n_states >= LEVELS_MIN_STATES
        return "levels" if large and _backend() == "cpu" else "sweeps"
    if method not in METHODS:
        raise InputError(f"{SOLVER_ENV}={method!r}: must be one of {', '.join(METHODS)}")
    return method


def _backend() -> str:
    import jax

    return jax.default_backend()


class SoftSolution(NamedTuple):
    """Soft-optimal values and policies for H hypotheses.

    Attributes:
        value: ``[H, S]`` soft state value V (reward units; 0 at terminal states).
        log_policy: ``[H, S, A]`` log π(a|s) = (Q − V)/β; ``-inf`` where the action is
            unavailable and on terminal rows.
        iterations: ``[H]`` backups each hypothesis needed.
        beta: ``[H]`` the temperatures solved for.
        model: the observation model solved (:mod:`expertise_irl.models`).
        newton_steps: ``[H]`` chord and Newton steps each hypothesis took (:mod:`.newton`), or
            None where the solve did not use Newton's method.
        stopped_tol: for :func:`solve_screened`, ``[H]`` the tolerance the values of each
            hypothesis its gate stopped certify (0 where the hypothesis met ``tol``); else None.
        gate_best: for :func:`solve_screened`, the best certain log mass its gate saw.
    """

    value: np.ndarray
    log_policy: np.ndarray
    iterations: np.ndarray
    beta: np.ndarray
    model: str = DEFAULT_MODEL
    newton_steps: np.ndarray | None = None
    stopped_tol: np.ndarray | None = None
    gate_best: float = -math.inf

    @property
    def q(self) -> np.ndarray:
        """``[H, S, A]`` Q-values in reward units (``-inf`` where unavailable).

        Every model's policy is ``softmax(Q/β)``; they differ in V: ``maxent`` Q = V + β log π,
        ``maxent-relative`` Q = V + β (log π + log|A(s)|), ``boltzmann`` (V = max Q)
        Q = V + β (log π − max_a log π).
        """
        lp = self.log_policy
        if self.model == "maxent-relative":
            n = np.isfinite(lp).sum(axis=-1, keepdims=True)
            lp = lp + np.log(np.maximum(n, 1))
        elif self.model == "boltzmann":
            with np.errstate(invalid="ignore"):
                top = np.max(lp, axis=-1, keepdims=True)
            lp = lp - np.where(np.isfinite(top), top, 0.0)
        return self.value[:, :, None] + self.beta[:, None, None] * lp

    @property
    def policy(self) -> np.ndarray:
        """``[H, S, A]`` action probabilities (rows of terminal states are all 0)."""
        return np.exp(self.log_policy)


def _as_hypotheses(mdp: TabularMDP, theta, beta) -> tuple[np.ndarray, np.ndarray]:
    theta = np.asarray(theta, dtype=np.float64)
    beta = np.asarray(beta, dtype=np.float64)
    if theta.ndim == 1:
        theta = theta[None]
    if beta.ndim == 0:
        beta = np.full(theta.shape[0], float(beta))
    if theta.ndim != 2 or theta.shape[1] != mdp.n_features:
        raise ArgumentError(
            f"theta must have shape [H, K] with K = {mdp.n_features} features "
            f"({', '.join(mdp.feature_names)}), got {theta.shape}"
        )
    if beta.shape != (theta.shape[0],):
        raise ArgumentError(f"beta must have shape [H] = [{theta.shape[0]}], got {beta.shape}")
    if not np.all(np.isfinite(theta)):
        raise InputError("theta must be finite")
    if not np.all(np.isfinite(beta)) or np.any(beta <= 0):
        bad = beta[~(np.isfinite(beta) & (beta > 0))][0]
        raise InputError(f"beta must be a finite number > 0, got {bad}")
    with np.errstate(over="ignore"):
        rmax = reward_bound(mdp, theta) / beta
    if not np.all(np.isfinite(rmax)) or np.any(rmax > 1e150):
        h = int(np.flatnonzero(~np.isfinite(rmax) | (rmax > 1e150))[0])
        raise InputError(
            f"hypothesis {h}: reward scale |θ·φ + offset|/β = {rmax[h]:.3g} overflows; "
            "use θ and β of ordinary magnitude"
        )
    return theta, beta


def reward_bound(mdp: TabularMDP, theta: np.ndarray) -> np.ndarray:
    """``[H]`` a bound on |R(s, a)| of each hypothesis: Σ_k |θ_k| max|φ_k| + max|offset|."""
    basis = np.abs(mdp.reward_basis()).max(axis=(0, 1))  # [K']
    return np.abs(mdp.reward_weights(theta)) @ basis


def default_max_iter(mdp: TabularMDP, theta: np.ndarray, beta: np.ndarray, tol: float) -> int:
    """An iteration cap comfortably above the contraction bound for these hypotheses.

    From v = 0, ||v_{n+1} - v_n|| <= γ^n (max|r| + log A), so n >= log(thresh / (max|r| +
    log A)) / log γ backups always suffice in exact arithmetic; we allow twice that plus 100.
    """
    rmax = float(np.max(reward_bound(mdp, theta) / beta))
    g = mdp.gamma
    thresh = tol * (1 - g) / g
    scale = rmax + math.log(mdp.n_actions) + 1.0
    n = math.log(thresh / scale) / math.log(g) if thresh < scale else 1.0
    return int(2 * math.ceil(n) + 100)


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
    model: str = DEFAULT_MODEL,
    over_relax: bool = True,
    float32_start: bool = False,
    lanes: int | None = None,
    method: str | None = None,
    newton: bool | None = None,
) -> SoftSolution:
    """Soft value iteration for every hypothesis ``(theta[h], beta[h])``.

    A pool of ``chunk_size`` lanes sweeps the states in red-black Gauss–Seidel order
    (:mod:`expertise_irl.planning.kernels`); a lane whose hypothesis meets the tolerance hands its
    values back and takes the next hypothesis, so no work is spent on finished ones and
    memory stays bounded by the pool, whatever the number of hypotheses. Lanes whose plain
    sweeps contract slowly switch to over-relaxed sweeps (``over_relax``). Results come back
    in the order the hypotheses were given.

    Args:
        mdp: the task.
        theta: ``[H, K]`` (or ``[K]``) reward weights.
        beta: ``[H]`` (or a scalar) temperatures, > 0.
        tol: bound (nats) on the error of each scaled value V/β; log-probabilities are then
            accurate to within 2·tol. Floored at the floating-point resolution of the values.
        max_iter: sweep cap per hypothesis; default from :func:`default_max_iter`.
        chunk_size: hypotheses in flight at once; default from :func:`.kernels.default_chunk_size`.
        dtype: ``"float64"`` (default) or ``"float32"`` (an explicit speed option; values are then
            accurate to about 1e-4 relative, limited by float32 resolution over ~1/(1-γ) backups).
        v_init: optional ``[H, S]`` warm start for V (reward units).
        progress: called as ``progress(done, total)`` as batches of hypotheses complete.
        model: the observation model (:mod:`expertise_irl.models`): ``"maxent"`` (the paper's),
            ``"maxent-relative"`` or ``"boltzmann"``. For ``boltzmann`` the hard values are
            solved once per distinct θ (at its smallest β, so every β meets ``tol``) and
            rescaled for the others; ``v_init`` is then ignored.
        over_relax: let a hypothesis whose sweeps contract at about γ² per sweep (a wanderer)
            switch to over-relaxed sweeps while they beat plain ones (:func:`.kernels.solve_pool`);
            the guarantee on V/β is the same. Not used for ``boltzmann`` (it slows hard values).
        float32_start: sweep in float32 first, then finish in float64 (the module's "Two phases").
        lanes: hypotheses along the vector axis of one lane group; default: the width chosen for
            this machine (:func:`expertise_irl.planning.tuning.lane_width`), narrowed to the largest
            power of two <= H for fewer hypotheses on a map of at least
            :data:`.kernels.SHRINK_MIN_ROWS` states. Only the speed depends on it.
        method: how the pool's start values are found: ``"sweeps"``, ``"jumps"`` or ``"levels"``
            (the module's "Start values"; default :func:`default_method`); the guarantee is the same.
        newton: finish by Newton's method (the module's "Newton's finish"). Default (None): on a
            CPU, for ``maxent`` and ``maxent-relative`` in float64, on MDPs of at least
            :data:`NEWTON_MIN_STATES` states with γ >= :data:`NEWTON_MIN_GAMMA`, for ``tol`` below
            :data:`NEWTON_BELOW`; ``False`` never; ``True`` where model, dtype and ``tol`` allow.

    Returns:
        The values, log-policies and iteration counts of every hypothesis, in the order given.

    Raises:
        InputError: non-finite θ, β <= 0, θ/β too large, or an unknown option.
        ArgumentError: θ, β or ``v_init`` of the wrong shape, or ``v_init`` not finite.
        ConvergenceError: a hypothesis did not converge within ``max_iter`` sweeps.
    """
    enable_float64()
    theta, beta = _as_hypotheses(mdp, theta, beta)
    check_model(model)
    method = _check_method(mdp, method)
    if model == "boltzmann":  # hard values: SOR trials fail and cost sweeps
        return _solve_hard(mdp, theta, beta, tol=tol, max_iter=max_iter, chunk_size=chunk_size,
                           dtype=dtype, progress=progress, lanes=lanes, method=method)
    opts = {"tol": tol, "max_iter": max_iter, "chunk_size": chunk_size, "model": model,
            "over_relax": over_relax, "lanes": lanes, "method": method}
    if _uses_newton(mdp, model, dtype, tol, newton):
        return _solve_newton(mdp, theta, beta, v_init, progress, opts)
    if not (float32_start and dtype == "float64" and v_init is None and len(theta) >= FLOAT32_START_MIN):
        return _solve(mdp, theta, beta, dtype=dtype, v_init=v_init, progress=progress, **opts)
    return _solve_two_phase(mdp, theta, beta, progress, opts)


def _uses_newton(mdp: TabularMDP, model: str, dtype: str, tol: float, newton: bool | None) -> bool:
    """Whether a solve finishes by Newton's method (:func:`solve`'s ``newton``)."""
    from .newton import SOFT_MODELS

    if newton is False or model not in SOFT_MODELS or dtype != "float64" or not tol < NEWTON_BELOW:
        return False
    large = mdp.n_states >= NEWTON_MIN_STATES and mdp.gamma >= NEWTON_MIN_GAMMA
    return bool(newton) or (large and _backend() == "cpu")


def _solve_newton(mdp, theta, beta, v_init, progress, opts) -> SoftSolution:
    """Sweeps to :data:`NEWTON_FROM` (none where ``v_init`` is that close already: one backup
    each, counted as a sweep), Newton's method from there, then one backup that certifies ``tol``
    (:func:`.newton.newton_finish`) or, where it does not, the pool's plain sweeps to ``tol``;
    ``iterations`` counts both sweeps, ``newton_steps`` the steps."""
    from .newton import newton_finish, residuals

    g, model = mdp.gamma, opts["model"]
    start = None if v_init is None else np.asarray(v_init, float)
    if start is not None and start.shape == (len(beta), mdp.n_states) and np.isfinite(start).all():
        start = np.where(mdp.terminal, 0.0, start)  # (the sweeps ignore a start's terminal values)
    else:  # none, or of the wrong shape or not finite: _solve says so
        start = None
    if start is not None and np.all(residuals(mdp, theta, beta, start, model=model)
                                    <= NEWTON_FROM * (1 - g) / g):
        rough_sweeps = np.ones(len(beta), np.int64)
    else:
        rough = _solve(mdp, theta, beta, dtype="float64", v_init=v_init, progress=progress,
                       **{**opts, "tol": NEWTON_FROM, "max_iter": None})
        start, rough_sweeps = rough.value, rough.iterations
    values, log_pi, steps = newton_finish(mdp, theta, beta, start, opts["tol"], model=model)
    if log_pi is not None:  # one backup each certified them: two backups, counted as sweeps
        return SoftSolution(values, log_pi, rough_sweeps + 2, beta.copy(), model, newton_steps=steps)
    sol = _solve(mdp, theta, beta, dtype="float64", v_init=values, progress=None,
                 **{**opts, "method": "sweeps"})
    return sol._replace(iterations=sol.iterations + rough_sweeps, newton_steps=steps)


def _check_method(mdp: TabularMDP, method: str | None) -> str:
    """``method``, or :func:`default_method`'s for ``mdp`` when None; InputError if unknown."""
    if method is None:
        method = default_method(mdp)
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    return method


def _solve_hard(mdp, theta, beta, *, progress, **opts) -> SoftSolution:
    """``boltzmann``: hard values in reward units do not depend on β, so each distinct θ is solved
    once, at its smallest β (the tightest tolerance in scaled units), and every hypothesis
    finishes from those values; the pool's own stopping rule still certifies each one."""
    uniq, inv = np.unique(theta, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    bmin = np.full(len(uniq), np.inf)
    np.minimum.at(bmin, inv, beta)
    opts = {**opts, "over_relax": False, "model": "boltzmann"}
    hard = _solve(mdp, uniq, bmin, v_init=None, progress=progress, **opts)
    sol = _solve(mdp, theta, beta, v_init=hard.value[inv], progress=None, **{**opts, "method": "sweeps"})
    return sol._replace(iterations=sol.iterations + hard.iterations[inv])


def _solve_two_phase(mdp, theta, beta, progress, opts) -> SoftSolution:
    """``float32_start``: sweep in float32 down to its resolution, then finish in float64."""
    H = len(theta)
    try:
        rough = _solve(mdp, theta, beta, dtype="float32", v_init=None, **{**opts, "chunk_size": None},
                       progress=None if progress is None else
                       (lambda done, _: progress(int(_FLOAT32_SHARE * done), H)))
    except ConvergenceError:  # float32 could not settle: a cold float64 solve decides
        return _solve(mdp, theta, beta, dtype="float64", v_init=None, progress=progress, **opts)
    sol = _solve(mdp, theta, beta, dtype="float64", v_init=rough.value, **opts,
                 progress=None if progress is None else
                 (lambda done, _: progress(int(_FLOAT32_SHARE * H + (1 - _FLOAT32_SHARE) * done), H)))
    return sol._replace(iterations=sol.iterations + rough.iterations)


def batch_limit(mdp: TabularMDP, memory: int | None = None) -> int:
    """The most hypotheses one pass of the solver takes at once: as many as keep their
    :data:`START_COPIES` copies of ``[H, rows]`` start values (the caller's start, the level or jump
    phase's input, output and padding, the pool's input and output) within
    :data:`.kernels.MEMORY_SHARE` of ``memory`` (default: :func:`.kernels.available_memory`), and
    never fewer than :data:`MIN_BATCH` (a whole pool of lanes)."""
    memory = kernel.available_memory() if memory is None else memory
    per_hypothesis = START_COPIES * (mdp.n_states + 1) * 8
    return max(MIN_BATCH, int(kernel.MEMORY_SHARE * memory) // per_hypothesis)


def solve_screened(mdp: TabularMDP, theta, beta, gate, *, tol: float, v_init: np.ndarray | None = None,
                   progress: Callable[[int, int], None] | None = None, **kw) -> SoftSolution:
    """:func:`solve` (same keywords) with certified elimination in the sweeps: ``gate``
    (:class:`.screening.Gate`, its ``base`` for these hypotheses in this order) stops each
    hypothesis whose log-likelihood is certainly too low as soon as that is certain, with values
    whose tolerance ``stopped_tol`` reports. Where Newton's finish applies, the gated sweeps go to
    :data:`NEWTON_FROM` and the hypotheses they did not stop finish by it. Where the gate does not
    apply (``boltzmann``, float32, ``float32_start``) this is :func:`solve`, ``stopped_tol`` all 0."""
    enable_float64()
    theta, beta = _as_hypotheses(mdp, theta, beta)
    model, dtype = kw.pop("model", DEFAULT_MODEL), kw.pop("dtype", "float64")
    check_model(model)
    if model == "boltzmann" or dtype != "float64" or kw.get("float32_start"):
        sol = solve(mdp, theta, beta, tol=tol, v_init=v_init, progress=progress, model=model, dtype=dtype,
                    **kw)
        return sol._replace(stopped_tol=np.zeros(len(beta)))
    known = set(inspect.signature(solve).parameters) - {"mdp", "theta", "beta", "tol", "v_init", "progress"}
    if set(kw) - known:
        raise TypeError(f"solve_screened got unexpected keywords {sorted(set(kw) - known)}")
    opts = {"tol": tol, "max_iter": kw.get("max_iter"), "chunk_size": kw.get("chunk_size"), "model": model,
            "over_relax": kw.get("over_relax", True), "lanes": kw.get("lanes"),
            "method": _check_method(mdp, kw.get("method"))}
    if not _uses_newton(mdp, model, dtype, tol, kw.get("newton")):
        return _solve(mdp, theta, beta, dtype=dtype, v_init=v_init, progress=progress, gate=gate, **opts)
    sol = _solve(mdp, theta, beta, dtype=dtype, v_init=v_init, progress=progress, gate=gate,
                 **{**opts, "tol": max(tol, NEWTON_FROM), "max_iter": None})
    live = sol.stopped_tol == 0
    steps = np.zeros(len(beta), np.int64)
    if tol < NEWTON_FROM and live.any():
        fin = _solve_newton(mdp, theta[live], beta[live], sol.value[live], None, opts)
        sol.value[live], sol.log_policy[live], steps[live] = fin.value, fin.log_policy, fin.newton_steps
        sol.iterations[live] += fin.iterations
    return sol._replace(newton_steps=steps)


def _solve(mdp, theta, beta, *, v_init, progress, gate=None, **opts) -> SoftSolution:
    """:func:`_solve_all` in batches of at most :func:`batch_limit` hypotheses, in the order given,
    into one answer (each hypothesis' sweeps are its own lane's, so batching changes no result; a
    gate's best carries from batch to batch)."""
    H, limit = len(beta), batch_limit(mdp)
    if H <= limit:
        return _solve_all(mdp, theta, beta, v_init=v_init, progress=progress, gate=gate, **opts)
    value, log_pi = np.empty((H, mdp.n_states)), np.empty((H, mdp.n_states, mdp.n_actions))
    iters, stopped = np.empty(H, dtype=np.int64), np.zeros(H)
    best = -math.inf if gate is None else gate.best
    for lo in range(0, H, limit):
        hi = min(lo + limit, H)
        tick = None if progress is None else (lambda done, _, lo=lo: progress(lo + done, H))
        part_gate = None if gate is None else gate._replace(base=np.asarray(gate.base)[lo:hi], best=best)
        part = _solve_all(mdp, theta[lo:hi], beta[lo:hi], v_init=None if v_init is None else v_init[lo:hi],
                          progress=tick, gate=part_gate, **opts)
        value[lo:hi], log_pi[lo:hi], iters[lo:hi] = part.value, part.log_policy, part.iterations
        if gate is not None:
            stopped[lo:hi], best = part.stopped_tol, part.gate_best
        del part
    return SoftSolution(value, log_pi, iters, beta.copy(), opts["model"],
                        stopped_tol=None if gate is None else stopped, gate_best=best)


def _solve_all(mdp, theta, beta, *, tol, max_iter, chunk_size, dtype, v_init, progress, model,
               over_relax, lanes, method="sweeps", gate=None) -> SoftSolution:
    if not (tol > 0 and math.isfinite(tol)):
        raise InputError(f"tol must be a positive number, got {tol}")
    if dtype not in ("float64", "float32"):
        raise InputError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    H, S = theta.shape[0], mdp.n_states
    if max_iter is None:
        max_iter = default_max_iter(mdp, theta, beta, tol)
    if lanes is None:  # small sets take the default rather than pause to measure one
        lanes = lane_width(dtype, measure=H >= TUNE_MIN)
        if H < lanes and S >= kernel.SHRINK_MIN_ROWS:
            # a few hypotheses on a large map (simulate, live): idle lanes would cost as much as
            # busy ones, so the lanes narrow to the largest power of two <= H (one hypothesis at
            # 200 x 200: 1.5-2x faster per sweep than 4 lanes)
            lanes = 1 << (H.bit_length() - 1)
    elif isinstance(lanes, bool) or not (isinstance(lanes, int | np.integer) and lanes >= 1):
        raise InputError(f"lanes must be a whole number >= 1, got {lanes!r}")
    lanes = int(lanes)
    if chunk_size is None:
        chunk_size = kernel.default_chunk_size(mdp, np.dtype(dtype), lanes=lanes)
    groups = max(1, -(-min(int(chunk_size), H) // lanes))
    prep = kernel.prepared(mdp, dtype)
    scaled0 = np.zeros((H, prep.n_rows))
    if v_init is not None:
        v_init = np.asarray(v_init, dtype=np.float64)
        if v_init.shape != (H, S):
            raise ArgumentError(f"v_init must have shape [H, S] = [{H}, {S}], got {v_init.shape}")
        if not np.all(np.isfinite(v_init)):
            raise ArgumentError("v_init must be finite")
        scaled0[:, prep.rows] = v_init / beta[:, None]
        scaled0[:, -1] = 0.0
    weights = mdp.reward_weights(theta) / beta[:, None]
    # Hand out the slow (high-β) hypotheses first so the pool does not end on a long tail.
    order = np.argsort(-beta, kind="stable")
    gate = gate if dtype == "float64" else None
    jdtype = jnp.float64 if dtype == "float64" else jnp.float32
    consts = (jnp.asarray(mdp.gamma, dtype=jdtype), jnp.asarray(tol, dtype=jdtype), jnp.asarray(max_iter))
    pool = _Pool(mdp, prep, weights, beta, theta, consts, groups, lanes, model, over_relax, gate)
    if method == "levels" or (method == "jumps" and dtype == "float64"):
        scaled0, pool.start_sweeps, pool.stopped, pool.best = _pool_starts(
            method, mdp, prep, dtype, weights, scaled0, order, consts, groups, lanes, model,
            cold=v_init is None, gate=gate, best=pool.best)
    if gate is not None:  # hypotheses the start pool eliminated go last, and the sweep pool skips them
        order = np.concatenate([order[pool.stopped[order] == 0], order[pool.stopped[order] > 0]])
    # Batches only exist to report progress; all have one size, so JAX compiles once.
    n_batches = 1 if progress is None else max(1, min(20, H // (4 * groups * lanes)))
    size = -(-H // n_batches)
    for start in range(0, H, size):
        pool.run(order[start:start + size], size, scaled0)
        if progress is not None:
            progress(min(start + size, H), H)
    return pool.solution()


class _Pool:
    """The sweep pool's batches of one :func:`_solve_all` and what they write: values, log-policies,
    sweeps and (with a gate) each stopped hypothesis' tolerance and the best certain log mass."""

    def __init__(self, mdp, prep, weights, beta, theta, consts, groups, lanes, model, over_relax, gate):
        self.mdp, self.prep, self.weights, self.beta, self.theta = mdp, prep, weights, beta, theta
        self.consts, self.groups, self.lanes, self.model = consts, groups, lanes, model
        self.relax, self.gate = over_relax, gate
        H, S, A = theta.shape[0], mdp.n_states, mdp.n_actions
        self.value = np.empty((H, S))
        self.log_pi = np.empty((H, S, A))  # every row is written below, -inf included
        self.iters = np.empty(H, dtype=np.int64)
        self.start_sweeps = np.zeros(H, dtype=np.int64)  # the start pool's cost, counted in sweeps
        self.stopped = np.zeros(H)  # tol_h of the hypotheses a gate stopped
        self.best = -math.inf if gate is None else float(gate.best)

    def run(self, idx: np.ndarray, size: int, scaled0: np.ndarray) -> None:
        """Solve hypotheses ``idx`` (those a start pool's gate stopped last) from ``scaled0``, padded
        to ``size``, and write their results."""
        from .screening import gate_arrays

        n, slots = len(idx), self.groups * self.lanes
        padded = np.concatenate([idx, np.repeat(idx[-1:], size - n)])  # one shape for every batch
        live = int(np.sum(self.stopped[idx] == 0))
        g = None if self.gate is None else gate_arrays(self.gate, self.prep.rows, padded, jnp.float64,
                                                       self.prep.n_rows - 1)
        v, it, delta, self.best = kernel.solve_pool(
            self.prep, jnp.asarray(self.weights[padded]), jnp.asarray(scaled0[padded]), *self.consts,
            groups=self.groups, lanes=self.lanes, model=self.model, relax=self.relax, gate=g, best=self.best,
            n_live=live)
        v, it, delta = np.array(v), np.array(it), np.array(delta)[:n]
        v[live:n], it[live:n], delta[live:] = scaled0[idx[live:]], 0, -self.stopped[idx[live:]]
        self._check(idx, delta)
        self.stopped[idx] = np.maximum(-delta, 0.0)
        self.iters[idx] = it[:n] + self.start_sweeps[idx]
        n_final = -(-size // slots) * slots  # the final backup runs on whole lane pools
        v = np.concatenate([v, np.repeat(v[-1:], n_final - size, 0)]) if n_final > size else v
        w_final = self.weights[np.concatenate([padded, np.repeat(padded[-1:], n_final - size)])]
        for lo in range(0, n, slots):  # one more backup gives normalised log-policies
            vf, lp = kernel.final_policies(self.prep, w_final[lo:lo + slots], jnp.asarray(v[lo:lo + slots]),
                                           self.mdp.gamma, groups=self.groups, model=self.model)
            m = min(slots, n - lo)
            hs = idx[lo:lo + m]
            self.value[hs] = np.asarray(vf)[:m] * self.beta[hs, None]  # terminal states: 0
            self.log_pi[hs] = np.asarray(lp)[:m]  # [m, S, A] in state order, -inf where unavailable

    def _check(self, idx: np.ndarray, delta: np.ndarray) -> None:
        """ConvergenceError unless every hypothesis met its tolerance (0) or was stopped (< 0)."""
        if np.all(delta <= 0):  # also catches NaN
            return
        j = int(np.flatnonzero(~(delta <= 0))[0])
        h, theta, beta = int(idx[j]), self.theta, self.beta
        raise ConvergenceError(
            f"soft value iteration did not converge for hypothesis {h} "
            f"(theta={np.round(theta[h], 6).tolist()}, beta={beta[h]:g}) within {int(self.consts[2])} "
            f"sweeps: last change {delta[j]:.3g} nats (tol {float(self.consts[1]):g}); raise max_iter or tol"
        )

    def solution(self) -> SoftSolution:
        stopped = None if self.gate is None else self.stopped
        return SoftSolution(self.value, self.log_pi, self.iters, self.beta.copy(), self.model,
                            stopped_tol=stopped, gate_best=self.best)


def _pool_starts(method, mdp, prep, dtype, weights, scaled0, order, consts, groups, lanes, model, cold,
                 gate=None, best=-math.inf):
    """Start values for the sweep pool from ``method``'s start pool (``jumps``:
    :func:`.kernels.jump_start`; ``levels``: :func:`.level_order.level_start`, from
    :func:`.level_order.approach_start` when ``cold``, i.e. without the caller's ``v_init``),
    hypotheses handed out in the solve's order, and what they cost ``[H]`` in sweeps (a jump: its
    sweeps and one backup; a symmetric level sweep: two; the approach pass: one).

    With a ``gate`` (:mod:`.screening`), ``levels`` hands the hypotheses out in the order of their
    log-likelihood sums at the start values, likeliest first (the best certain bound then comes
    early), and stops those it eliminates. Returns ``(values, cost, stopped tol_h [H] (0: not
    stopped), best certain log mass)``."""
    gamma, tol = consts[0], consts[1]
    thresh = tol * (1.0 - gamma) / gamma
    stopped = np.zeros(len(order))
    w, v0 = jnp.asarray(weights[order]), jnp.asarray(scaled0[order])
    if method == "jumps":
        v, k = kernel.jump_start(prep, w, v0, gamma, thresh, groups=groups, lanes=lanes, model=model)
        per = kernel.JUMP_SWEEPS + 1
    else:
        from . import level_order
        from .screening import gate_arrays, rough_log_likelihood

        lv = level_order.levels_of(mdp, prep, dtype)
        if cold:
            v0 = level_order.approach_start(lv, w, v0, gamma, lanes=lanes, model=model)
        g = None
        if gate is not None:  # permuted in NumPy: a JAX gather would compile for each new shape
            v0 = np.asarray(v0)
            likely = np.argsort(-rough_log_likelihood(gate._replace(base=np.asarray(gate.base)[order]), v0,
                                                      prep.rows), kind="stable")
            order, w, v0 = order[likely], weights[order[likely]], v0[likely]
            g = gate_arrays(gate, prep.rows, order, jnp.float64, prep.n_rows - 1)
        v, k, tol_h, best = level_order.level_start(lv, w, v0, gamma, thresh, groups=groups, lanes=lanes,
                                                    model=model, gate=g, best=best, rising=cold)
        stopped[order] = tol_h
        per = 2
    out = np.empty_like(scaled0)
    cost = np.empty(len(order), dtype=np.int64)
    out[order] = np.asarray(v)
    cost[order] = per * np.asarray(k) + (method == "levels" and cold)
    return out, cost, stopped, best
