"""Algorithm 1's pieces: the lattice, the log posterior on it, one Metropolis step, the chain.

The layering is NumPyro's and BlackJAX's: a potential (:class:`LatticePosterior`, the log
posterior of a lattice point), a step kernel (:func:`step`, from one :class:`ChainState` to
the next, given that iteration's random numbers), and a driver (:func:`sample_chain`) that
runs the kernel and records the chain. :func:`expertise_irl.inference.birl.extended_birl`
assembles them and summarises the chain; its module docstring says why each choice is made.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..planning.soft_vi import solve

START_TRIES = 1000
GRID_RTOL = 1e-9


# ----------------------------------------------------------------------------- lattice
class Lattice(NamedTuple):
    """The state space: θ = δ·m with integer m ∈ {0..M}^K, β = βmin + j·beta_step, j < n_beta
    (or, with ``beta_ratio`` > 0, β = βmin·beta_ratio^j: a log-spaced β).

    ``variant="box"``: Σm ≤ L and m ≠ 0; ``"simplex"``: Σm = L (= 1/δ).
    """

    variant: str
    K: int
    M: int
    L: int
    n_beta: int
    delta: float
    beta_min: float
    beta_step: float
    beta_ratio: float = 0.0  # > 1: multiplicative β steps; 0: additive (beta_step)

    def theta(self, m: np.ndarray) -> np.ndarray:
        return m * self.delta

    def beta(self, j):
        if self.beta_ratio:
            return self.beta_min * self.beta_ratio ** j
        return self.beta_min + j * self.beta_step

    def log_beta_cell(self, j) -> float:
        """log of the width of β's lattice cell, up to a constant: each lattice point stands for
        the prior mass of its cell, density × width, and a log-spaced cell's width grows with β."""
        return math.log(self.beta(j)) if self.beta_ratio else 0.0

    def contains(self, m: np.ndarray, j: int) -> bool:
        if not 0 <= j < self.n_beta or m.min() < 0:
            return False
        if self.variant == "simplex":
            return True  # transfers keep Σm = L; m_i <= L follows
        s = int(m.sum())
        return m.max() <= self.M and 0 < s <= self.L


def _grid_count(span: float, step: float, message: str) -> int:
    """``span / step`` as an integer >= 1, or InputError(message) if it is not one."""
    n = span / step
    if abs(n - round(n)) > GRID_RTOL * max(1.0, n) or round(n) < 1:
        raise InputError(message)
    return round(n)


def make_lattice(K: int, variant: str, delta: float, beta_step: float, theta_max: float,
                 beta_range: tuple[float, float], lam: float, beta_ratio: float | None = None) -> Lattice:
    """The lattice of ``variant``; :class:`InputError` if δ does not divide the box or simplex.
    ``beta_ratio``: β steps multiply by it (log-spaced, from βmin up to βmax) instead of adding
    ``beta_step``."""
    delta, beta_step = float(delta), float(beta_step)
    b_lo, b_hi = (float(b) for b in beta_range)
    if beta_ratio:
        n_beta = math.floor(math.log(b_hi / b_lo) / math.log(beta_ratio) * (1 + GRID_RTOL)) + 1
    else:
        n_beta = math.floor((b_hi - b_lo) / beta_step * (1 + GRID_RTOL)) + 1
    if variant == "simplex":
        L = _grid_count(1.0, delta, f"delta must divide 1 in the simplex variant, got {delta:g}")
        M = L
    else:
        M = _grid_count(float(theta_max), delta,
                        f"theta_max must be an integer multiple of delta = {delta:g}, got {theta_max:g}")
        L = min(K * M, math.floor(lam / delta * (1 + GRID_RTOL)))
        if L < 1:
            raise InputError(f"lam = {lam:g} must be >= delta = {delta:g} (else only θ = 0 fits)")
    return Lattice(variant, K, M, L, n_beta, delta, b_lo, beta_step, float(beta_ratio or 0.0))


def _count_table(K: int, M: int, L: int, exact: bool) -> list[list[int]]:
    """``c[k][r]``: integer vectors (m_k..m_{K−1}) in {0..M} with sum == r (exact) or <= r."""
    c = [[0] * (L + 1) for _ in range(K + 1)]
    c[K] = [1] * (L + 1) if not exact else [1] + [0] * L
    for k in range(K - 1, -1, -1):
        prefix = [0]
        for x in c[k + 1]:
            prefix.append(prefix[-1] + x)
        c[k] = [prefix[r + 1] - prefix[max(0, r - M)] for r in range(L + 1)]
    return c


def _uniform_lattice_point(rng: np.random.Generator, K: int, M: int, L: int, exact: bool) -> np.ndarray:
    """Exactly uniform m ∈ {0..M}^K with Σm == L (exact) or Σm <= L."""
    c = _count_table(K, M, L, exact)
    m = np.zeros(K, dtype=np.int64)
    r = L
    for k in range(K):
        w = [c[k + 1][r - v] for v in range(min(M, r) + 1)]
        total = sum(w)
        v = int(rng.choice(len(w), p=np.array([x / total for x in w])))
        m[k] = v
        r -= v
    return m


# ----------------------------------------------------------------------------- potential
class LatticePosterior:
    """log P(Ξ | θ, β) + log P(θ, β) of lattice points, by one soft value iteration each.

    The demonstrations enter as counts N[s, a] over the observed pairs. With ``cache`` each
    point's log-likelihood is remembered; with ``warm_start`` a solve starts from a given value
    function, rescaled to the new β. Counts ``n_solves``, ``n_sweeps`` and ``n_cache_hits``.
    """

    def __init__(self, mdp: TabularMDP, trajs: Trajectories, lattice: Lattice,
                 log_prior: Callable[[np.ndarray, float], float], *, tol: float, model: str,
                 warm_start: bool, cache: bool) -> None:
        A = mdp.n_actions
        flat, counts = np.unique(trajs.state * A + trajs.action, return_counts=True)
        self._pairs, self._counts = (flat // A, flat % A), counts.astype(np.float64)
        self.mdp, self.lattice, self.prior = mdp, lattice, log_prior
        self.tol, self.model, self.warm_start, self.cache = tol, model, warm_start, cache
        self._known: dict[tuple, float] = {}
        self.n_solves = self.n_sweeps = self.n_cache_hits = 0

    def log_prior(self, m: np.ndarray, j: int) -> float:
        """The prior's log density at the point; InputError if it is NaN or +∞."""
        theta, beta = self.lattice.theta(m), self.lattice.beta(j)
        lp = float(self.prior(theta, beta))
        if math.isnan(lp) or lp == math.inf:
            raise InputError(f"log_prior returned {lp} at theta={theta.tolist()}, beta={beta:g}")
        return lp + self.lattice.log_beta_cell(j)

    def log_likelihood(self, m: np.ndarray, j: int, warm: tuple[np.ndarray, float] | None
                       ) -> tuple[float, np.ndarray | None]:
        """log P(Ξ | θ, β) and the value function it was solved with (None if remembered).

        ``warm`` is ``(value, β)`` of a solved point to start from (used with ``warm_start``).
        """
        key = (*m.tolist(), j)
        if self.cache and key in self._known:
            self.n_cache_hits += 1
            return self._known[key], None
        b = self.lattice.beta(j)
        v0 = warm[0][None] * (b / warm[1]) if self.warm_start and warm is not None else None
        sol = solve(self.mdp, self.lattice.theta(m), b, tol=self.tol, v_init=v0, model=self.model)
        self.n_solves += 1
        self.n_sweeps += int(sol.iterations[0])
        ll = float(np.sum(self._counts * sol.log_policy[0, self._pairs[0], self._pairs[1]]))
        if self.cache:
            self._known[key] = ll
        return ll, sol.value[0]


# ----------------------------------------------------------------------------- kernel
class ChainState(NamedTuple):
    """Where the chain is: lattice point ``(m [K], j)``, its log posterior, and the value
    function ``warm`` (with its β) of the last solved point on the chain's path."""

    m: np.ndarray
    j: int
    log_posterior: float
    warm: tuple[np.ndarray, float] | None


class Moves(NamedTuple):
    """Every iteration's random numbers (``[n_iter]`` each), drawn up front."""

    pick: np.ndarray  # θ move: axis and sign (box) or ordered pair (simplex)
    beta_sign: np.ndarray  # ±1
    which: np.ndarray  # moves="either": 0 = θ, 1 = β
    log_u: np.ndarray  # log of the Metropolis uniform


class StepInfo(NamedTuple):
    """What one step did: the proposal, its log posterior (−∞ if not evaluated), the outcome."""

    m: np.ndarray
    j: int
    log_posterior: float
    accepted: bool
    out_of_bounds: bool


def initial_state(rng: np.random.Generator, target: LatticePosterior) -> ChainState:
    """A lattice point drawn uniformly (θ = 0 excluded in the box) where the prior is positive."""
    lat = target.lattice
    for _ in range(START_TRIES):
        m = _uniform_lattice_point(rng, lat.K, lat.M, lat.L, exact=lat.variant == "simplex")
        while m.sum() == 0:
            m = _uniform_lattice_point(rng, lat.K, lat.M, lat.L, exact=False)
        j = int(rng.integers(lat.n_beta))
        lp_prior = target.log_prior(m, j)
        if lp_prior > -math.inf:
            break
    else:
        raise InputError(f"log_prior is -inf at {START_TRIES} random lattice points; no start found")
    ll, v = target.log_likelihood(m, j, None)
    return ChainState(m, j, ll + lp_prior, (v, lat.beta(j)))


def draw_moves(rng: np.random.Generator, lattice: Lattice, n_iter: int) -> Moves:
    """All random numbers up front: reproducible and cheap."""
    K = lattice.K
    if lattice.variant == "simplex":
        pick = rng.integers(K * (K - 1), size=n_iter) if K > 1 else np.zeros(n_iter, np.int64)
    else:
        pick = rng.integers(2 * K, size=n_iter)
    beta_sign = 2 * rng.integers(2, size=n_iter) - 1
    which = rng.integers(2, size=n_iter)
    return Moves(pick, beta_sign, which, np.log(rng.random(n_iter)))


def propose(lattice: Lattice, moves: str, m: np.ndarray, j: int, pick: int, beta_sign: int,
            which: int) -> tuple[np.ndarray, int]:
    """The proposed point: an axis neighbour (box) or a transfer (simplex) of θ, and/or β ± step."""
    m_new = m.copy()
    if moves == "both" or which == 0:
        if lattice.variant == "simplex":
            K = lattice.K
            if K > 1:
                src, dst = divmod(pick, K - 1)
                dst += dst >= src  # ordered pair (src, dst), src != dst
                m_new[src] -= 1
                m_new[dst] += 1
        else:
            m_new[pick // 2] += 1 if pick % 2 else -1
    j_new = j + beta_sign if moves == "both" or which == 1 else j
    return m_new, j_new


def step(state: ChainState, target: LatticePosterior, moves: str, pick: int, beta_sign: int, which: int,
         log_u: float) -> tuple[ChainState, StepInfo]:
    """One Metropolis iteration: propose, reject off the lattice, else accept with min(1, p̃/p)."""
    m_new, j_new = propose(target.lattice, moves, state.m, state.j, pick, beta_sign, which)
    if not target.lattice.contains(m_new, j_new):
        return state, StepInfo(m_new, j_new, -math.inf, False, True)
    lp_prior = target.log_prior(m_new, j_new)
    if lp_prior == -math.inf:
        return state, StepInfo(m_new, j_new, -math.inf, False, False)
    ll, v = target.log_likelihood(m_new, j_new, state.warm)
    new = ll + lp_prior
    if not log_u < new - state.log_posterior:
        return state, StepInfo(m_new, j_new, new, False, False)
    warm = (v, target.lattice.beta(j_new)) if v is not None else state.warm
    return ChainState(m_new, j_new, new, warm), StepInfo(m_new, j_new, new, True, False)


# ----------------------------------------------------------------------------- driver
class Chain(NamedTuple):
    """The recorded chain (T = n_iter + 1 points, the start first) and its best point."""

    m: np.ndarray  # [T, K]
    j: np.ndarray  # [T]
    log_posterior: np.ndarray  # [T]
    accepted: np.ndarray  # [n_iter]
    n_out_of_bounds: int
    best: tuple[float, np.ndarray, int]  # (log posterior, m, j): the highest evaluated


def sample_chain(state: ChainState, target: LatticePosterior, moves: str, draws: Moves,
                 progress: Callable[[int, int], None] | None = None) -> Chain:
    """Run :func:`step` once per entry of ``draws``, recording every point of the chain.

    ``progress(done, n_iter)`` is called about a hundred times.
    """
    n_iter = len(draws.log_u)
    T = n_iter + 1
    ms = np.empty((T, target.lattice.K), dtype=np.int64)
    js = np.empty(T, dtype=np.int64)
    lps = np.empty(T)
    accepted = np.zeros(n_iter, dtype=bool)
    ms[0], js[0], lps[0] = state.m, state.j, state.log_posterior
    best = (state.log_posterior, state.m.copy(), state.j)
    n_oob = 0
    report_every = max(1, n_iter // 100)
    for i in range(n_iter):
        state, info = step(state, target, moves, int(draws.pick[i]), int(draws.beta_sign[i]),
                           int(draws.which[i]), draws.log_u[i])
        n_oob += info.out_of_bounds
        accepted[i] = info.accepted
        if info.log_posterior > best[0]:
            best = (info.log_posterior, info.m.copy(), info.j)
        ms[i + 1], js[i + 1], lps[i + 1] = state.m, state.j, state.log_posterior
        if progress is not None and (i + 1 == n_iter or (i + 1) % report_every == 0):
            progress(i + 1, n_iter)
    return Chain(ms, js, lps, accepted, n_oob, best)
