"""Certified log-likelihoods: solve each hypothesis only as precisely as its posterior needs.

A person's demonstrations put most hypotheses of a set hundreds of nats below the best one;
their values need only be known well enough to prove that. :func:`certified_log_likelihoods`
solves in stages.

**The values' bound.** The solver stops a hypothesis when a plain Gauss–Seidel sweep changes its
scaled values v = V/β by at most ``tol·(1 − γ)/γ`` (or by the floating-point floor
``8·eps·max|v|``); a sweep is a γ-contraction, so the values are then within ``tol_h = max(tol,
8·eps·max|v|·γ/(1 − γ))`` of the solution: ``|e(s)| ≤ tol_h`` with ``e = v − v*``, and ``e = 0``
exactly at terminal states (the solver's zero row).

**The log-likelihood's bound, telescoped** (``maxent`` and ``maxent-relative``). At the solution
these models' log-policy is ``log π*(a|s) = r(s, a) + γ v*(s') − v*(s) − c(s)``, with ``s'`` the
move's successor, ``r = R/β`` and ``c(s) = 0`` (``maxent``) or ``log |A(s)|`` (``maxent-relative``).
So the log-likelihood of the observed moves ``(s_t, a_t, s'_t)`` is a linear function of the
values, and the same sum taken with the solver's values,

    LL = Σ_t [r(s_t, a_t) + γ v(s'_t) − v(s_t) − c(s_t)] = Σ_t [r − c] + Σ_s w_s v(s),
    w_s = γ·#{t: s'_t = s} − #{t: s_t = s},

differs from the exact one by ``Σ_s w_s e(s)``, at most ``tol_h·Σ_s |w_s|`` over the non-terminal
states. Along a path each state is left once and reached once, so its weight is ``γ − 1``: a
demonstration of N moves in E episodes has ``Σ|w| ≈ 2E + (1 − γ)·N``, against ``2N`` for the
bound of the log-policy table (each ``log π = q − logsumexp q`` within ``2γ·tol_h``), which is what
``boltzmann`` (``v = max q``, so the sum does not telescope) keeps: there ``LL`` is the table's sum
and the bound ``2·tol_h·N``. At γ = 0.99 with 1,500 moves in 3 episodes that is 21·tol_h against
3,000·tol_h. Where an observed action is unavailable, LL is −inf either way. The bound adds the
rounding of the sums (``64·eps`` times the sum of their terms' magnitudes).

**Screening stages.** Every hypothesis is solved to the tolerance whose interval is
±``SCREEN_WIDTHS[0]`` nats wide for these demonstrations; with log prior weights ``l_h``, the
lower bounds give the best certain log mass ``M = max_h (LL_h − err_h + l_h)``, and a hypothesis
whose upper bound ``LL_h + err_h + l_h`` lies below ``M + ln(elimination / H)`` has posterior
probability below ``elimination / H`` whatever its exact values, and is **eliminated**: it keeps
its values and stops. The others continue from their values to the next, narrower width, and the
test is made again (no stage is tighter than the final tolerance; ``screen_tol`` gives one stage).
On one map under a telescoping model the first stage's sweeps make the same test at every check
(:mod:`expertise_irl.planning.screening`): a hypothesis stops there as soon as its elimination is
certain, with values whose own ``tol_h`` its bound uses (``stopped_tol``).

**Finish.** The survivors continue to the final tolerance: ``tol`` when given, else the one the
demonstrations need for every posterior probability to be within ``probability_error`` of the
exact one: with every log-likelihood within ε of its exact value, each probability is within
``e^{2ε} − 1`` of it (and the eliminated mass, at most ``elimination``, moves the rest by at most
that), so ``ε = ln(1 + probability_error − elimination)/2`` and ``tol = 0.99·ε/Σ|w|`` (1% of ε
left for the rounding). The result reports
the bound actually reached, from each hypothesis' own ``tol_h``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..mdp import TabularMDP

#: Half-widths (nats) of the screening stages' log-likelihood intervals, widest first. One stage:
#: at 100 × 100 and 200 × 200 more stages (30 then 1 nats, 300 then 10 then 1) saved sweeps but
#: cost more in the new shapes compiled for the few hypotheses each later stage solves.
SCREEN_WIDTHS = (3.0,)
#: The last (narrowest) screening width.
SCREEN_WIDTH = SCREEN_WIDTHS[-1]
#: The models whose log-likelihood telescopes along a path (module docstring).
TELESCOPING_MODELS = ("maxent", "maxent-relative")
#: The posterior mass every eliminated hypothesis together may hold at most (relative to the best).
ELIMINATION = 1e-12
#: The default bound on the error of every reported posterior probability.
PROBABILITY_ERROR = 1e-6
#: Batches are padded to 64 × (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, …) hypotheses: a few shapes for JAX to
#: compile, at most a third of padding.
BUCKET = 64
#: The smallest Σ|w| a tolerance is set from (one action's table bound): without demonstrations,
#: or with moves only into terminal states, the values are still solved to a useful tolerance.
MIN_WEIGHT = 2.0
#: The share of the data's log-likelihood error ε that the solve may use; the rest is left for the
#: rounding of the sums.
ROUNDING_SHARE = 0.99
#: The tightest tolerance a data-set tolerance goes to (the values' floating-point floor decides
#: below it anyway).
MIN_TOL = 1e-13


@dataclass(frozen=True, eq=False)
class Certified:
    """Log-likelihoods of H hypotheses with certified error bounds (see the module docstring).

    Attributes:
        log_policy: per map, ``[H, S, A]`` the log-policies (eliminated ones to their screening
            tolerance).
        value: per map, ``[H, S]`` the values (reward units).
        log_likelihood: ``[H]`` log P(Ξ | θ_h, β_h) summed over the maps (telescoped for
            :data:`TELESCOPING_MODELS`, else the log-policy table's sum).
        error: ``[H]`` certified bound on |log_likelihood − exact|.
        eliminated: ``[H]`` whether the hypothesis stopped at a screening stage.
        screen_tol: the first (loosest) screening stage's tolerance (nats on V/β).
        tol: the survivors' final tolerance.
        probability_error: a bound on the error of every posterior probability computed from
            these log-likelihoods (with the log prior weights given).
        sweeps: ``[H]`` backups spent on each hypothesis, all stages.
        screen_tols: every screening stage's tolerance, loosest first.
        error_weight: Σ|w| of the demonstrations: each log-likelihood is within ``error_weight·tol_h``
            of the exact one (module docstring).
        newton_steps: ``[H]`` chord and Newton steps each hypothesis took in the solver's finish
            (:mod:`expertise_irl.planning.newton`; 0 where none).
        stopped_tol: ``[H]`` for each hypothesis eliminated in the first stage's sweeps
            (:mod:`expertise_irl.planning.screening`) the tolerance its values certify; 0 for the others.
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
    screen_tols: tuple[float, ...] = ()
    error_weight: float = math.nan
    newton_steps: np.ndarray | None = None
    stopped_tol: np.ndarray | None = None

    def record(self) -> dict:
        """What a result document states about it."""
        stopped = 0 if self.stopped_tol is None else int(np.sum(self.stopped_tol > 0))
        return {"eliminated": int(self.eliminated.sum()), "hypotheses": int(self.eliminated.size),
                "eliminated_in_sweeps": stopped,
                "screen_tol": self.screen_tol, "screen_tols": list(self.screen_tols), "tol": self.tol,
                "probability_error": self.probability_error, "error_weight": self.error_weight,
                "max_log_likelihood_error": float(self.error[~self.eliminated].max(initial=0.0)),
                "sweeps": int(self.sweeps.sum()),
                "newton_steps": 0 if self.newton_steps is None else int(self.newton_steps.sum())}


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


def stage_size(n: int) -> int:
    """The padded size of a later stage of ``n`` hypotheses: the next power of two below
    :data:`BUCKET` (a padded copy is solved in full, so few survivors must not fill 64 lanes), else
    :func:`bucket_size`."""
    return 1 << max(n - 1, 0).bit_length() if n < BUCKET else bucket_size(n)


def data_tolerance(n_actions: int, probability_error: float = PROBABILITY_ERROR,
                   elimination: float = ELIMINATION, *, error_weight: float | None = None) -> float:
    """The tolerance that keeps every posterior probability within ``probability_error`` of the
    exact one for ``n_actions`` observed actions (module docstring): ``ε/error_weight``, with the
    table's weight ``2·n_actions`` when ``error_weight`` (:func:`error_weight`) is not given."""
    if not 0 < elimination < probability_error < 1:
        raise InputError(f"need 0 < elimination < probability_error < 1, got {elimination:g} and "
                         f"{probability_error:g}")
    eps = ROUNDING_SHARE * math.log1p(probability_error - elimination) / 2
    weight = 2 * max(n_actions, 1) if error_weight is None else max(float(error_weight), MIN_WEIGHT)
    return max(eps / weight, MIN_TOL)


def _moves(mdp: TabularMDP, shown) -> tuple[np.ndarray, np.ndarray]:
    """The observed states and actions of ``shown`` (a list of Trajectories), concatenated."""
    states = np.concatenate([np.asarray(t.state, np.int64) for t in shown] or [np.zeros(0, np.int64)])
    actions = np.concatenate([np.asarray(t.action, np.int64) for t in shown] or [np.zeros(0, np.int64)])
    return states, actions


def state_weights(mdp: TabularMDP, shown) -> np.ndarray:
    """``[S]`` the weights ``w_s = γ·#{t: s'_t = s} − #{t: s_t = s}`` of the telescoped
    log-likelihood (module docstring), 0 at terminal states; moves whose action is unavailable
    (impossible under every hypothesis) are left out."""
    states, actions = _moves(mdp, shown)
    nxt = mdp.next_state[states, actions] if len(states) else np.zeros(0, np.int64)
    ok = (nxt >= 0) & ~mdp.terminal[states]
    w = mdp.gamma * np.bincount(nxt[ok], minlength=mdp.n_states) - np.bincount(states, minlength=mdp.n_states)
    return np.where(mdp.terminal, 0.0, w)


def error_weight(mdp: TabularMDP, shown, model: str = "maxent", weights: np.ndarray | None = None) -> float:
    """The factor F with |LL − exact| ≤ F·tol_h for values within ``tol_h`` (module docstring):
    ``Σ_s |w_s|`` for :data:`TELESCOPING_MODELS`, ``2N`` for the others. ``weights``:
    :func:`state_weights` of ``shown``, when the caller has them."""
    if model in TELESCOPING_MODELS:
        return float(np.abs(state_weights(mdp, shown) if weights is None else weights).sum())
    return 2.0 * sum(len(t.state) for t in shown)


def _fixed_terms(mdp: TabularMDP, shown, theta, beta, model: str) -> tuple[np.ndarray, np.ndarray, int]:
    """``([H] Σ_t (r_t − c_t), [H] the sum of its terms' magnitudes, N)``: the part of the
    telescoped log-likelihood that does not depend on the values (``r = R/β``; module docstring)."""
    states, actions = _moves(mdp, shown)
    basis = mdp.reward_basis()[states, actions].sum(axis=0)  # [K'] the observed moves' features
    rw = mdp.reward_weights(theta)
    const = 0.0
    if model == "maxent-relative":
        const = float(np.log(np.maximum(mdp.available[states].sum(axis=1), 1)).sum())
    return rw @ basis / beta - const, np.abs(rw) @ np.abs(basis) / beta + const, len(states)


def telescoped_log_likelihood(mdp: TabularMDP, shown, theta, beta, value, model: str = "maxent",
                              weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``([H] LL, [H] rounding bound)``: the telescoped log-likelihood of the moves of ``shown``
    (Trajectories) from values ``value [H, S]`` (reward units) of ``(theta [H, K], beta [H])``;
    finite even where a move is impossible (the caller takes −inf from the table). ``weights``:
    :func:`state_weights` of ``shown``, when the caller has them."""
    fixed, magnitude, n = _fixed_terms(mdp, shown, theta, beta, model)
    w = state_weights(mdp, shown) if weights is None else weights
    support = np.flatnonzero(w)
    vw = value[:, support] * w[support]
    ll = fixed + vw.sum(axis=1) / beta
    scale = magnitude + np.abs(vw).sum(axis=1) / beta
    return ll, 64 * np.finfo(np.float64).eps * (scale + n)


def screening_gate(mdp: TabularMDP, shown, theta, beta, *, model: str = "maxent",
                   log_prior: np.ndarray | None = None, elimination: float = ELIMINATION,
                   best_known: float = -math.inf, weights: np.ndarray | None = None):
    """The :class:`~expertise_irl.planning.screening.Gate` that eliminates hypotheses ``(theta [H, K],
    beta [H])`` in the sweeps for the moves of ``shown`` on one map, or None where it cannot: a
    model whose log-likelihood does not telescope, or an observed action unavailable (every
    hypothesis' log-likelihood is then −inf). ``weights``: :func:`state_weights` of ``shown``."""
    from ..planning.screening import Gate

    if model not in TELESCOPING_MODELS:
        return None
    states, actions = _moves(mdp, shown)
    if len(states) and not (mdp.available[states, actions].all() and (~mdp.terminal[states]).all()):
        return None
    w = state_weights(mdp, shown) if weights is None else weights
    prior = np.zeros(len(beta)) if log_prior is None else np.asarray(log_prior, float)
    fixed, magnitude, n = _fixed_terms(mdp, shown, theta, beta, model)
    support = np.flatnonzero(w)
    return Gate(support, w[support], fixed + prior, float(np.abs(w).sum()), float(w[w > 0].sum()),
                math.log(elimination / len(beta)), best_known, n, magnitude + np.abs(prior))


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
    """Staged solve of ``(theta [H, K], beta [H])`` on every map of ``tasks`` (``(mdp,
    [Trajectories, ...])`` pairs sharing the features), with certified log-likelihood bounds
    and elimination (module docstring). ``tol``: the survivors' tolerance (default: the data's);
    ``screen_tol``: one screening stage at this tolerance (default: one per :data:`SCREEN_WIDTHS`);
    ``log_prior``: ``[H]`` log prior weights (default equal); ``v_init``: per map ``[H, S]``
    start values; ``best_known``: a log mass (log-likelihood + log prior weight) certainly reached by
    a hypothesis solved before, outside this batch (hypotheses below it are eliminated too);
    ``progress(done, total)`` hears the first screening stage; ``solve_kwargs`` go to
    :func:`~expertise_irl.planning.soft_vi.solve`."""
    theta, beta = np.atleast_2d(np.asarray(theta, float)), np.atleast_1d(np.asarray(beta, float))
    H = len(beta)
    st = _Stages(tasks, theta, beta, solve_kwargs, H)
    weight = sum(st.factor)
    n = sum(len(t.state) for _, shown in tasks for t in shown)
    final = float(tol) if tol is not None else data_tolerance(n, probability_error, elimination,
                                                              error_weight=weight)
    if screen_tol is None:
        screens = sorted({max(w / max(weight, MIN_WEIGHT), final) for w in SCREEN_WIDTHS}, reverse=True)
    else:
        screens = [max(screen_tol, final)]
    prior = np.zeros(H) if log_prior is None else np.asarray(log_prior, float)
    st.run(np.arange(H), screens[0], v_init, progress, gate=st.gate(prior, elimination, best_known))
    gone = st.stopped > 0  # eliminated in the sweeps, certified there (planning/screening.py)
    best_known = max(best_known, st.gate_best)
    for t in [*screens[1:], final]:
        gone |= st.eliminated(prior, best_known, elimination) & ~gone
        keep = np.flatnonzero(~gone)
        if t < st.tol_of[keep].max(initial=0.0) and keep.size:
            st.run(keep, t, st.values, None)
    keep = np.flatnonzero(~gone)
    eps = float(st.err[keep].max(initial=0.0)) if np.isfinite(st.err[keep]).all() else math.inf
    bound = math.expm1(2 * eps) + (elimination if gone.any() else 0.0)
    return Certified(tuple(st.policies), tuple(st.values), st.ll, st.err, gone, screens[0], final, bound,
                     st.sweeps, tuple(screens), weight, st.newton, st.stopped)


class _Stages:
    """The running state of a staged solve: every hypothesis' latest values, log-policies,
    log-likelihood and bound, and the tolerance it was last solved to."""

    def __init__(self, tasks, theta, beta, solve_kwargs, H):
        self.tasks, self.theta, self.beta, self.kw = tasks, theta, beta, solve_kwargs
        self.model = solve_kwargs.get("model", "maxent")
        # per map: the telescoped sum's state weights and the log-likelihood's error per unit tol_h
        self.weights = [state_weights(mdp, shown) for mdp, shown in tasks]
        self.factor = [error_weight(mdp, shown, self.model, w) for w, (mdp, shown) in zip(self.weights, tasks,
                                                                                          strict=True)]
        self.ll, self.err = np.zeros(H), np.zeros(H)
        self.sweeps = np.zeros(H, np.int64)
        self.newton = np.zeros(H, np.int64)
        self.tol_of = np.full(H, math.inf)
        self.stopped = np.zeros(H)  # tol_h of the hypotheses a gate eliminated in the sweeps
        self.gate_best = -math.inf
        self.policies: list[np.ndarray] = []
        self.values: list[np.ndarray] = []

    def gate(self, prior: np.ndarray, elimination: float, best_known: float):
        """The first stage's :func:`screening_gate`, or None with several maps (each solve sees
        one map's share of the log-likelihood)."""
        if len(self.tasks) != 1:
            return None
        mdp, shown = self.tasks[0]
        return screening_gate(mdp, shown, self.theta, self.beta, model=self.model, log_prior=prior,
                              elimination=elimination, best_known=best_known, weights=self.weights[0])

    def run(self, idx: np.ndarray, tol: float, starts, progress, gate=None) -> None:
        """Solve hypotheses ``idx`` to ``tol`` from ``starts`` (per map, ``[H, S]`` or None), with
        ``gate`` (the first stage's, for every hypothesis) eliminating in the sweeps; a later stage
        is padded with its last hypothesis to :func:`stage_size` (few shapes to compile)."""
        from ..planning.soft_vi import solve, solve_screened
        from ..planning.table_likelihood import log_likelihood

        m = idx.size
        padded = idx if not self.values else np.concatenate([idx, np.repeat(idx[-1:], stage_size(m) - m)])
        th, be = self.theta[padded], self.beta[padded]
        ll, err, sweeps = np.zeros(m), np.zeros(m), np.zeros(m, np.int64)
        for g, (mdp, shown) in enumerate(self.tasks):
            v0 = None if starts is None else starts[g][padded]
            if gate is None:
                sol = solve(mdp, th, be, tol=tol, v_init=v0, progress=progress, **self.kw)
            else:
                sol = solve_screened(mdp, th, be, gate, tol=tol, v_init=v0, progress=progress, **self.kw)
                self.stopped[idx], self.gate_best = sol.stopped_tol, sol.gate_best
            lp, v = np.asarray(sol.log_policy)[:m], np.asarray(sol.value)[:m]
            table = sum(log_likelihood(lp, tr.state, tr.action) for tr in shown)
            reached = np.maximum(_reached(mdp, v, be[:m], tol), self.stopped[idx])
            if self.model in TELESCOPING_MODELS:
                tele, rounding = telescoped_log_likelihood(mdp, shown, th[:m], be[:m], v, self.model,
                                                           self.weights[g])
                ll += np.where(np.isfinite(table), tele, -np.inf)
                err += reached * self.factor[g] + rounding
            else:
                ll += table
                err += reached * self.factor[g]
            sweeps += np.asarray(sol.iterations)[:m]
            if sol.newton_steps is not None:
                self.newton[idx] += np.asarray(sol.newton_steps)[:m]
            if len(self.policies) <= g:
                self.policies.append(lp)  # the solve's own arrays: no other reference to them
                self.values.append(v)
            else:
                self.policies[g][idx], self.values[g][idx] = lp, v
        self.ll[idx], self.err[idx], self.tol_of[idx] = ll, err, np.maximum(tol, self.stopped[idx])
        self.sweeps[idx] += sweeps

    def eliminated(self, prior: np.ndarray, best_known: float, elimination: float) -> np.ndarray:
        """``[H]`` whether each hypothesis' upper bound lies below the best lower bound by enough
        that its posterior probability is certainly below ``elimination / H``."""
        H = self.ll.size
        lower, upper = self.ll - self.err + prior, self.ll + self.err + prior
        finite = np.isfinite(lower)
        best = max(lower[finite].max() if finite.any() else -np.inf, best_known)
        if not np.isfinite(best):
            return np.zeros(H, bool)
        return upper < best + math.log(elimination / H)
