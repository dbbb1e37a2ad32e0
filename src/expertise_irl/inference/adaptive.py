"""Adaptive hypothesis sets: refine Θ × B where the posterior's mass is, until the estimate settles.

A person's preferences and expertise lie on no grid. A coarse set forces the posterior onto its
nearest points, and a β between two grid values is then read partly as a different θ (the policy
depends on θ/β only). :func:`refine` starts from a coarse set and refines it in rounds:

- **β**, log-spaced: every β of the smallest set holding 99.9% of the β marginal gets the two
  values half its spacing away (in log β), down to :data:`BETA_MIN_STEP` decades; an end of the
  set holding :data:`EDGE_MASS` or more of the mass is extended by a coarse step, within
  :data:`BETA_LIMITS` (widened to the start set's range when it reaches past them).
- **θ**, on the simplex: every θ of the smallest set holding 95% of the θ marginal (at most
  :data:`MAX_THETA_REFINE` a round) gets its neighbours θ ± (h/2)(e_i − e_j) at half its spacing
  h, down to :data:`THETA_MIN_STEP`, unless a neighbour lies past the posterior's 99.9% interval
  of a component by more than h.

After each round only the new hypotheses are solved; θ and β whose posterior mass fell below
:data:`PRUNE_MASS` leave the set (their mass is recorded). The rounds stop when β̂, E[θ] and the
90% intervals change less than the :class:`Refinement` tolerances from one round to the next, or
at a cap (hypotheses solved, policy memory, seconds, rounds), which stops with a warning and the
best posterior so far, never an error.

**Several tasks** (:func:`refine_tasks`): one person's tasks share one (θ, β); a hypothesis'
log-likelihood is the sum over them, each map solved once per round. The start set's
log-likelihoods may be given (a study has them from its sweep), and the policies need not be kept.

**The prior.** Each hypothesis weighs the cell it stands for: a θ refined ``l`` times weighs
2^-(K−1)·l of a start θ (its lattice cell at half the spacing per refinement), a β refined ``l``
times 2^-l of a start β (its cell in log β). Over the start set this is the uniform prior of the
paper's sets; as the set refines it stays (approximately, the cells being lattice cells) uniform
on the simplex and log-uniform in β over the range the set covers. The posterior is exact
(Eq. 13) over the final set with these weights.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import logsumexp

from ..demos.trajectories import Trajectories
from ..errors import InputError, plural
from ..hypotheses import HypothesisSet
from ..mdp import TabularMDP
from .certified import bucket_size

#: The coarse start of β: half-decade steps from 0.01 to 10 (7 values).
START_BETAS = tuple(float(10.0 ** e) for e in np.arange(-2.0, 1.01, 0.5))
#: Spacing of the start β (decades of β).
START_BETA_STEP = 0.5
#: The range an extended set may reach: down to the continuous methods' 0.001, up to the paper's 10.
#: Above 10 a person's choices at ‖θ‖₁ = 1 are so near uniform that the likelihood is flat (the paper
#: found β* > 5 indistinguishable from 5): a set reaching 100 turns that flat tail into an E[β] of
#: 20–40 for people of β* = 3–9 (benchmarks/off_grid.py), where the paper's grid reads 6–7.
BETA_LIMITS = (1e-3, 10.0)
#: Memory the solved hypotheses' values may take to start the next round's solves (above it, cold starts).
WARM_VALUE_BYTES = 512 * 2**20
#: The finest β spacing refinement makes (decades; 0.0156 ≈ 3.6% in β).
BETA_MIN_STEP = 0.5 / 2**5
#: The finest θ spacing refinement makes (per component).
THETA_MIN_STEP = 1 / 64
#: At most this many θ are refined in one round (the most probable first).
MAX_THETA_REFINE = 4
#: At most this many β are refined in one round.
MAX_BETA_REFINE = 4
#: Mass of the β and θ marginals that refinement covers (the rest is its tail).
BETA_COVER, THETA_COVER = 0.999, 0.95
#: An end of the β set holding this share of the β marginal is extended.
EDGE_MASS = 0.01
#: θ and β whose marginal mass falls below this leave the set.
PRUNE_MASS = 1e-10
#: The start θ lattice holds at most this many directions.
START_THETAS_MAX = 100
#: Default cap on the policy tables the final set holds (bytes).
MAX_POLICY_BYTES = 2 * 2**30
#: A change smaller than this share of the posterior's spread (sd of ln β, of θ) counts as settled,
#: whatever the tolerance: it is small next to what the data leave unknown.
SPREAD_SHARE = 0.25
#: Credible mass of the intervals whose change stops the refinement.
CREDIBLE = 0.9
#: New θ stay within half a step of the current posterior's intervals of this mass (per component).
BOUNDS = 0.999


@dataclass(frozen=True)
class Refinement:
    """When refinement stops.

    Attributes:
        tol_beta: largest change of log β̂ (natural log: 0.05 is 5% of β̂) between rounds.
        tol_theta: largest change of any component of E[θ] between rounds.
        tol_interval: largest change of an end of the 90% intervals (log β for β, θ units for θ_i).
        max_rounds: refinement rounds after the start set.
        max_hypotheses: hypotheses solved in all, the start set included.
        max_seconds: wall-clock seconds (None: no limit).
        max_policy_bytes: memory of the policy tables the set holds at once.
    """

    tol_beta: float = 0.05
    tol_theta: float = 0.02
    tol_interval: float = 0.1
    max_rounds: int = 8
    max_hypotheses: int = 20_000
    max_seconds: float | None = None
    max_policy_bytes: int = MAX_POLICY_BYTES

    def __post_init__(self) -> None:
        for name in ("tol_beta", "tol_theta", "tol_interval"):
            x = getattr(self, name)
            if not (math.isfinite(x) and x > 0):
                raise InputError(f"{name} must be a finite number > 0, got {x!r}")
        for name in ("max_rounds", "max_hypotheses", "max_policy_bytes"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.max_seconds is not None and not self.max_seconds > 0:
            raise InputError(f"max_seconds must be > 0, got {self.max_seconds!r}")


# ----------------------------------------------------------------------------- the start set
def simplex_lattice(n_features: int, resolution: int) -> np.ndarray:
    """``[M, K]`` every θ with components k_i / resolution (k_i ≥ 0 integers summing to it)."""
    if n_features == 1:
        return np.ones((1, 1))
    rows = []

    def walk(prefix: list[int], left: int) -> None:
        if len(prefix) == n_features - 1:
            rows.append([*prefix, left])
            return
        for k in range(left, -1, -1):
            walk([*prefix, k], left - k)

    walk([], resolution)
    return np.asarray(rows, dtype=np.float64) / resolution


def start_resolution(n_features: int) -> int:
    """The finest lattice (at most 8 steps per component, at least 2) of at most
    :data:`START_THETAS_MAX` directions."""
    n = 2
    while n < 8 and math.comb(n + 1 + n_features - 1, n_features - 1) <= START_THETAS_MAX:
        n += 1
    return n


def start_set(n_features: int) -> HypothesisSet:
    """The coarse start: the simplex lattice of :func:`start_resolution` × :data:`START_BETAS`."""
    return HypothesisSet(simplex_lattice(n_features, start_resolution(n_features)), START_BETAS)


def _spacing(points: np.ndarray, fallback: float) -> np.ndarray:
    """Each point's distance to its nearest other point (max-norm; ``fallback`` alone)."""
    if len(points) < 2:
        return np.full(len(points), fallback)
    d = np.abs(points[:, None, :] - points[None, :, :]).max(axis=-1)
    np.fill_diagonal(d, np.inf)
    return np.maximum(d.min(axis=1), 1e-6)


# ----------------------------------------------------------------------------- the pool
def _key(theta: np.ndarray) -> bytes:
    return (np.round(theta, 9) + 0.0).tobytes()


@dataclass
class _Pool:
    """Every θ and β proposed so far, their spacings and levels, and the solved hypotheses."""

    thetas: list[np.ndarray]
    theta_step: list[float]  # h of each θ at level 0
    theta_level: list[int]
    betas: list[float]
    beta_step: list[float]  # spacing in decades at level 0
    beta_level: list[int]
    active_t: list[int] = field(default_factory=list)
    active_b: list[int] = field(default_factory=list)
    ll: dict[tuple[int, int], float] = field(default_factory=dict)
    policy: dict[tuple[int, int], np.ndarray] = field(default_factory=dict)
    value: dict[tuple[int, int], tuple[np.ndarray, ...]] = field(default_factory=dict)  # warm starts
    keys: dict[bytes, int] = field(default_factory=dict)
    sweeps: int = 0  # backups spent on the hypotheses solved (padding not counted)
    parent: dict[int, int] = field(default_factory=dict)  # a refined θ: the θ it was halved from
    err: dict[tuple[int, int], float] = field(default_factory=dict)  # certified |log-likelihood error|
    screened: set = field(default_factory=set)  # solved only to the screening tolerance (eliminated)
    eliminated: int = 0
    elimination_rounds: int = 0  # rounds that eliminated any (each ≤ ELIMINATION of the mass)
    limits: tuple[float, float] = BETA_LIMITS  # where β may go: BETA_LIMITS, widened to the start's range
    zero: tuple[int, ...] = ()  # components kept at 0

    @classmethod
    def of(cls, hyp: HypothesisSet, theta_step: float | None) -> _Pool:
        th = hyp.thetas
        h = np.full(len(th), theta_step) if theta_step is not None else _spacing(th, 0.5)
        logb = np.log10(hyp.betas)
        s = _spacing(logb[:, None], START_BETA_STEP)
        pool = cls(list(th), h.tolist(), [0] * len(th), hyp.betas.tolist(), s.tolist(), [0] * len(logb))
        pool.active_t, pool.active_b = list(range(len(th))), list(range(len(logb)))
        pool.keys = {_key(t): i for i, t in enumerate(th)}
        pool.limits = (min(BETA_LIMITS[0], float(hyp.betas.min())),
                       max(BETA_LIMITS[1], float(hyp.betas.max())))
        return pool

    def log_weights(self, n_features: int, betas: list[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """log prior weights of the active θ and of ``betas`` (default: the active β), unnormalised."""
        lt = np.array([self.log_theta_weight(i, n_features) for i in self.active_t])
        order = self.active_b if betas is None else betas
        lb = np.array([self.log_beta_weight(j) for j in order])
        return lt, lb

    def log_theta_weight(self, i: int, n_features: int) -> float:
        """θ ``i``'s log cell weight: 2^-(K−1) per halving of its spacing."""
        return -(n_features - 1) * self.theta_level[i] * math.log(2)

    def log_beta_weight(self, j: int) -> float:
        """β ``j``'s log cell weight: 1/2 per halving of its spacing (in log β)."""
        return -self.beta_level[j] * math.log(2)

    def missing(self) -> list[tuple[int, int]]:
        return [(i, j) for i in self.active_t for j in self.active_b if (i, j) not in self.ll]

    def add_theta(self, theta: np.ndarray, step: float, level: int, parent: int | None = None) -> None:
        key = _key(theta)
        if key in self.keys:
            return
        if parent is not None:
            self.parent[len(self.thetas)] = parent
        self.keys[key] = len(self.thetas)
        self.thetas.append(theta)
        self.theta_step.append(step)
        self.theta_level.append(level)
        self.active_t.append(len(self.thetas) - 1)

    def add_beta(self, beta: float, step: float, level: int) -> None:
        lo, hi = self.limits
        if not lo * (1 - 1e-9) <= beta <= hi * (1 + 1e-9):
            return
        if any(abs(math.log10(b) - math.log10(beta)) < 1e-9 for b in self.betas):
            return
        self.betas.append(float(beta))
        self.beta_step.append(step)
        self.beta_level.append(level)
        self.active_b.append(len(self.betas) - 1)

    def snapshot(self) -> tuple:
        return (len(self.thetas), len(self.betas), list(self.theta_level), list(self.beta_level),
                list(self.active_t), list(self.active_b))

    def restore(self, snap: tuple) -> None:
        nt, nb, tl, bl, at, ab = snap
        for t in self.thetas[nt:]:
            del self.keys[_key(t)]
        for i in [i for i in self.parent if i >= nt]:
            del self.parent[i]
        del self.thetas[nt:], self.theta_step[nt:], self.betas[nb:], self.beta_step[nb:]
        self.theta_level, self.beta_level, self.active_t, self.active_b = tl, bl, at, ab

    def theta_h(self, i: int) -> float:
        return self.theta_step[i] / 2 ** self.theta_level[i]

    def beta_s(self, j: int) -> float:
        return self.beta_step[j] / 2 ** self.beta_level[j]


# ----------------------------------------------------------------------------- the posterior
@dataclass(frozen=True)
class _Stats:
    """The posterior over the active set and what stops the refinement."""

    log_posterior: np.ndarray  # [n_theta, n_beta], active order
    beta_marginal: np.ndarray
    theta_marginal: np.ndarray
    beta_hat: float
    theta_hat: np.ndarray
    beta_interval: tuple[float, float]
    theta_intervals: np.ndarray  # [K, 2]
    theta_bounds: np.ndarray  # [K, 2] the 99.9% intervals: where new θ may go
    beta_sd: float  # posterior sd of log10 β, each β spread over its cell
    log_beta_mean: float  # E[ln β]
    theta_sd: float  # root mean square of the components' posterior sds, each θ spread over its cell

    def changes(self, prev: _Stats) -> dict[str, float]:
        """How far this round moved the estimate from ``prev``'s, each change divided by the larger of
        its tolerance and :data:`SPREAD_SHARE` of the posterior's spread (≤ 1: settled)."""
        ends = np.log(np.asarray(self.beta_interval) / np.asarray(prev.beta_interval))
        return {"beta": abs(self.log_beta_mean - prev.log_beta_mean),
                "theta": float(np.max(np.abs(self.theta_hat - prev.theta_hat))),
                "beta_interval": float(np.max(np.abs(ends))),
                "theta_interval": float(np.max(np.abs(self.theta_intervals - prev.theta_intervals))),
                "beta_spread": self.beta_sd * math.log(10), "theta_spread": self.theta_sd}


def _mixture_quantiles(centres: np.ndarray, widths: np.ndarray, p: np.ndarray, grid: np.ndarray,
                       qs: tuple[float, ...]) -> list[float]:
    """Quantiles of the mixture of uniforms on [centre ± width/2] with weights ``p``, read on ``grid``."""
    a, b = centres - widths / 2, centres + widths / 2
    cdf = np.clip((grid[:, None] - a[None, :]) / (b - a)[None, :], 0.0, 1.0) @ p
    return [float(grid[min(int(np.searchsorted(cdf, q - 1e-12)), len(grid) - 1)]) for q in qs]


def _stats(pool: _Pool, n_features: int) -> _Stats | None:
    """The posterior over the active product set (None if no hypothesis can produce the data)."""
    lt, lb = pool.log_weights(n_features)
    ll = np.array([[pool.ll[(i, j)] for j in pool.active_b] for i in pool.active_t])
    logw = ll + lt[:, None] + lb[None, :]
    if not np.isfinite(logw).any():
        return None
    lp = logw - logsumexp(logw)
    p = np.exp(lp)
    pb, pt = p.sum(axis=0), p.sum(axis=1)
    betas = np.array([pool.betas[j] for j in pool.active_b])
    thetas = np.array([pool.thetas[i] for i in pool.active_t])
    qs = ((1 - CREDIBLE) / 2, (1 + CREDIBLE) / 2)
    s = np.array([pool.beta_s(j) for j in pool.active_b])
    grid = np.linspace(math.log10(pool.limits[0]) - 0.5, math.log10(pool.limits[1]) + 0.5, 6001)
    blo, bhi = (10.0**x for x in _mixture_quantiles(np.log10(betas), s, pb, grid, qs))
    h = np.array([pool.theta_h(i) for i in pool.active_t])
    tgrid = np.linspace(0.0, 1.0, 2001)
    qs = (*qs, (1 - BOUNDS) / 2, (1 + BOUNDS) / 2)
    tq = np.clip([_mixture_quantiles(thetas[:, k], h, pt, tgrid, qs) for k in range(n_features)], 0.0, 1.0)
    lb, mt = np.log10(betas), pt @ thetas
    beta_sd = math.sqrt(pb @ ((lb - pb @ lb) ** 2 + s**2 / 12))
    theta_sd = math.sqrt(np.mean(pt @ ((thetas - mt) ** 2 + (h**2 / 12)[:, None])))
    return _Stats(lp, pb, pt, float(pb @ betas), mt, (blo, bhi), tq[:, :2], tq[:, 2:], beta_sd,
                  float(pb @ np.log(betas)), theta_sd)


def _beta_settled(ch: dict[str, float], settings: Refinement) -> bool:
    spread = SPREAD_SHARE * ch["beta_spread"]
    return ch["beta"] <= max(settings.tol_beta, spread) and ch["beta_interval"] <= max(settings.tol_interval,
                                                                                      spread)


def _theta_settled(ch: dict[str, float], settings: Refinement) -> bool:
    spread = SPREAD_SHARE * ch["theta_spread"]
    return (ch["theta"] <= max(settings.tol_theta, spread)
            and ch["theta_interval"] <= max(settings.tol_interval / 2, spread))


def _converged(ch: dict[str, float], settings: Refinement) -> bool:
    return _beta_settled(ch, settings) and _theta_settled(ch, settings)


# ----------------------------------------------------------------------------- one round
def _covering(p: np.ndarray, cover: float, cap: int) -> np.ndarray:
    """Positions of the most probable entries of ``p`` that hold ``cover`` of its mass (at most ``cap``)."""
    order = np.argsort(-p, kind="stable")
    n = int(np.searchsorted(np.cumsum(p[order]), cover * p.sum() - 1e-15)) + 1
    return order[:min(n, cap, len(p))]


def _edges(pool: _Pool, st: _Stats) -> list[float]:
    """β one coarse step past an end of the set that holds :data:`EDGE_MASS` or more of the mass."""
    active = list(pool.active_b)
    values = np.array([pool.betas[j] for j in active])
    out = []
    for pick, sign, end in ((int(np.argmin(values)), -1, min(pool.betas)), (int(np.argmax(values)), 1,
                                                                             max(pool.betas))):
        b = pool.betas[active[pick]]
        new = b * 10 ** (sign * START_BETA_STEP)
        lo, hi = pool.limits
        if b == end and st.beta_marginal[pick] >= EDGE_MASS and lo * (1 - 1e-9) <= new <= hi * (1 + 1e-9):
            out.append(new)
    return out


def _beta_todo(pool: _Pool, st: _Stats, force: bool) -> list[int]:
    """The β that hold the mass and are spaced wider than the posterior's spread (all of them with
    ``force``), down to :data:`BETA_MIN_STEP`."""
    out = []
    for pos in _covering(st.beta_marginal, BETA_COVER, MAX_BETA_REFINE):
        j = pool.active_b[pos]
        s = pool.beta_s(j)
        if s / 2 >= BETA_MIN_STEP * (1 - 1e-9) and (force or s > st.beta_sd):
            out.append(j)
    return out


def _theta_todo(pool: _Pool, st: _Stats, force: bool) -> list[int]:
    """The θ that hold the mass and are spaced wider than twice the posterior's spread (all of them
    with ``force``), down to :data:`THETA_MIN_STEP`."""
    out = []
    for pos in _covering(st.theta_marginal, THETA_COVER, MAX_THETA_REFINE):
        i = pool.active_t[pos]
        h = pool.theta_h(i)
        if h / 2 >= THETA_MIN_STEP * (1 - 1e-9) and (force or h > 2 * st.theta_sd):
            out.append(i)
    return out


def _halve_betas(pool: _Pool, todo: list[int]) -> None:
    """The two β half a spacing away from each of ``todo`` (in log β)."""
    for j in todo:
        s = pool.beta_s(j)
        pool.beta_level[j] += 1
        for sign in (-1, 1):
            pool.add_beta(pool.betas[j] * 10 ** (sign * s / 2), pool.beta_step[j], pool.beta_level[j])


def _halve_thetas(pool: _Pool, st: _Stats, todo: list[int], n_features: int) -> None:
    """The neighbours θ ± (h/2)(e_a − e_b) of each of ``todo`` that stay near the posterior's bulk."""
    for i in todo:
        h = pool.theta_h(i) / 2
        pool.theta_level[i] += 1
        t = pool.thetas[i]
        lo, hi = st.theta_bounds[:, 0] - h - 1e-12, st.theta_bounds[:, 1] + h + 1e-12
        for a in range(n_features):
            for b in range(n_features):
                if a == b or a in pool.zero or t[b] < h - 1e-12:
                    continue
                new = t.copy()
                new[a] += h
                new[b] = max(new[b] - h, 0.0)
                new /= new.sum()
                if np.all((new >= lo) & (new <= hi)):
                    pool.add_theta(new, pool.theta_step[i], pool.theta_level[i], parent=i)


def _prune(pool: _Pool, st: _Stats) -> float:
    """Drop the θ and β whose marginal mass is below :data:`PRUNE_MASS`; the mass dropped."""
    keep_t = st.theta_marginal >= PRUNE_MASS
    keep_b = st.beta_marginal >= PRUNE_MASS
    dropped = float(st.theta_marginal[~keep_t].sum() + st.beta_marginal[~keep_b].sum())
    gone_t = {i for i, k in zip(pool.active_t, keep_t, strict=True) if not k}
    gone_b = {j for j, k in zip(pool.active_b, keep_b, strict=True) if not k}
    pool.active_t = [i for i in pool.active_t if i not in gone_t]
    pool.active_b = [j for j in pool.active_b if j not in gone_b]
    for store in (pool.policy, pool.value):
        for key in [k for k in store if k[0] in gone_t or k[1] in gone_b]:
            del store[key]
    return dropped


# ----------------------------------------------------------------------------- the rounds
@dataclass(frozen=True)
class Refined:
    """What :func:`refine` and :func:`refine_tasks` return.

    Attributes:
        hypotheses: the final set Θ × B.
        log_policy: ``[H, S, A]`` its solved policies (θ-major, as :class:`HypothesisSet` orders them);
            with several maps a tuple of them, one per distinct map in the order of the tasks; None
            when the policies were not kept.
        prior: ``[H]`` the prior weight of each hypothesis (the cell it stands for).
        record: the refinement as the result records it (rounds, costs, why it stopped).
        warnings: a cap that stopped it, in one line each.
        log_likelihood: ``[H]`` each hypothesis' log-likelihood of the demonstrations (summed over
            the tasks).
        log_likelihood_error: ``[H]`` a certified bound on each log-likelihood's error (0 for
            known start log-likelihoods given by the caller).
        eliminated: ``[H]`` whether the hypothesis stopped at the screening tolerance
            (:mod:`.certified`): its posterior mass is certainly negligible.
    """

    hypotheses: HypothesisSet
    log_policy: Any
    prior: np.ndarray
    record: dict[str, Any]
    warnings: list[str]
    log_likelihood: np.ndarray | None = None
    log_likelihood_error: np.ndarray | None = None
    eliminated: np.ndarray | None = None


@dataclass(frozen=True)
class _Tasks:
    """A person's tasks: each distinct map (by identity) once, with the demonstrations shown on it."""

    maps: list[tuple[TabularMDP, list[Trajectories]]]
    keep_policies: bool

    @classmethod
    def of(cls, tasks, keep_policies: bool) -> _Tasks:
        maps: dict[int, tuple[TabularMDP, list[Trajectories]]] = {}
        for mdp, trajs in tasks:
            maps.setdefault(id(mdp), (mdp, []))[1].append(trajs)
        return cls(list(maps.values()), keep_policies)

    @property
    def cells(self) -> int:
        """State-action cells of one hypothesis' policies (every map)."""
        return sum(m.n_states * m.n_actions for m, _ in self.maps)


def _solve_missing(pool: _Pool, tasks: _Tasks, solve_kwargs: dict, progress: Callable | None,
                   done: int) -> int:
    """Solve the active hypotheses not solved yet on every map; how many that was.

    Each new hypothesis starts from the values of its nearest solved one (:func:`_warm_starts`),
    and the batch is padded to a bucket's size with solved hypotheses started from their own
    values, which settle in a sweep or two. The solve is certified (:mod:`.certified`): a
    hypothesis whose log-likelihood is certainly too low to matter, against this batch and the
    best one solved before, stops at the screening tolerance; the others finish at the
    tolerance the demonstrations need (or ``solve_kwargs["tol"]`` when given).
    """
    from .certified import certified_log_likelihoods

    pairs = pool.missing()
    if not pairs:
        return 0
    n = len(pairs)
    bucket = bucket_size(n)  # a few shapes, each compiled once
    padded, starts = _warm_starts(pool, pairs, bucket)
    theta = np.array([pool.thetas[i] for i, _ in padded])
    beta = np.array([pool.betas[j] for _, j in padded])
    K = theta.shape[1]
    tick = None if progress is None else (lambda d, t: progress(done + min(d * n // t, n), done + n))
    cert = certified_log_likelihoods(tasks.maps, theta, beta, log_prior=_log_prior_of(pool, padded, K),
                                     v_init=starts, best_known=_best_known(pool, K), progress=tick,
                                     **solve_kwargs)
    pool.sweeps += int(np.sum(cert.sweeps[:n]))
    pool.eliminated += int(np.sum(cert.eliminated[:n]))
    pool.elimination_rounds += bool(np.any(cert.eliminated[:n]))
    keep_values = _value_bytes(pool, tasks, n) <= WARM_VALUE_BYTES
    for k, key in enumerate(pairs):
        pool.ll[key] = float(cert.log_likelihood[k])
        pool.err[key] = float(cert.error[k])
        if cert.eliminated[k]:
            pool.screened.add(key)
        if tasks.keep_policies:
            pool.policy[key] = tuple(lp[k] for lp in cert.log_policy)
        if keep_values:
            pool.value[key] = tuple(v[k] for v in cert.value)
    return len(pairs)


def _log_prior_of(pool: _Pool, pairs: list[tuple[int, int]], K: int) -> np.ndarray:
    """Each pair's log prior weight: its θ's and its β's cells (:meth:`_Pool.log_weights`)."""
    return np.array([pool.log_theta_weight(i, K) + pool.log_beta_weight(j) for i, j in pairs])


def _best_known(pool: _Pool, K: int) -> float:
    """The largest certified lower bound of log-likelihood + log prior weight among the solved
    active hypotheses (-inf when none)."""
    keys = [(i, j) for i in pool.active_t for j in pool.active_b if (i, j) in pool.ll]
    if not keys:
        return -math.inf
    prior = _log_prior_of(pool, keys, K)
    return float(max(pool.ll[k] - pool.err.get(k, 0.0) + w for k, w in zip(keys, prior, strict=True)))


def _warm_starts(pool: _Pool, pairs: list[tuple[int, int]], bucket: int
                 ) -> tuple[list[tuple[int, int]], list[np.ndarray] | None]:
    """``pairs`` padded to ``bucket``, and per map the ``[bucket, S]`` values that start them.

    A new hypothesis starts from its θ's solved values (a new θ: those of the θ it was halved
    from): interpolated in ln β between the two solved β around its own (a halving's midpoint: the
    error is second order in the spacing), else those of the nearest solved β; with none, cold
    (zeros). The padding repeats solved hypotheses, each started from its own values, so it costs
    a sweep or two. Before anything is solved (or when the values are not kept) every start is
    cold (None) and the padding repeats the last pair.
    """
    if not pool.value:
        return pairs + [pairs[-1]] * (bucket - len(pairs)), None
    by_theta: dict[int, list[tuple[float, tuple[int, int]]]] = {}
    for key in pool.value:
        by_theta.setdefault(key[0], []).append((math.log(pool.betas[key[1]]), key))
    solved = list(pool.value)
    fill = [solved[k % len(solved)] for k in range(bucket - len(pairs))]
    starts = []
    for g in range(len(pool.value[solved[0]])):
        zero = np.zeros_like(pool.value[solved[0]][g])
        rows = []
        for i, j in pairs:
            near = by_theta.get(i) or by_theta.get(pool.parent.get(i, -1)) or []
            v = _from_neighbours(pool, near, math.log(pool.betas[j]), g)
            rows.append(zero if v is None else v)
        starts.append(np.stack(rows + [pool.value[k][g] for k in fill]))
    return pairs + fill, starts


def _from_neighbours(pool: _Pool, same_theta: list, b: float, g: int) -> np.ndarray | None:
    """Map ``g``'s values at ln β = ``b`` from one θ's solved β (``same_theta``: (ln β, key) pairs):
    interpolated between the nearest below and above, else the nearest; None when there are none."""
    if not same_theta:
        return None
    lo = max((x for x in same_theta if x[0] < b), default=None, key=lambda x: x[0])
    hi = min((x for x in same_theta if x[0] > b), default=None, key=lambda x: x[0])
    if lo is None or hi is None:
        return pool.value[min(same_theta, key=lambda x: abs(x[0] - b))[1]][g]
    w = (b - lo[0]) / (hi[0] - lo[0])
    return (1 - w) * pool.value[lo[1]][g] + w * pool.value[hi[1]][g]


def _value_bytes(pool: _Pool, tasks: _Tasks, new: int) -> int:
    """Bytes the kept start values would take with ``new`` more hypotheses."""
    return (len(pool.value) + new) * sum(m.n_states for m, _ in tasks.maps) * 8


def _round_entry(r: int, pool: _Pool, st: _Stats, solved: int, sweeps: int, seconds: float,
                 ch: dict[str, float] | None) -> dict[str, Any]:
    return {"round": r, "n_theta": len(pool.active_t), "n_beta": len(pool.active_b), "solved": solved,
            "sweeps": sweeps, "seconds": seconds, "beta_hat": st.beta_hat, "theta_hat": st.theta_hat.tolist(),
            "beta_interval": list(st.beta_interval), "theta_intervals": st.theta_intervals.tolist(),
            "changes": ch}


def _cap(pool: _Pool, settings: Refinement, solved: int, started: float, n_cells: int) -> str | None:
    """The cap the next round would pass (None: none; ``n_cells``: 0 when no policy is kept)."""
    todo = len(pool.missing())
    if solved + todo > settings.max_hypotheses:
        return (f"the next round would solve {todo} more hypotheses, past the cap of "
                f"{settings.max_hypotheses} (--max-hypotheses)")
    held = len(pool.active_t) * len(pool.active_b) * n_cells * 8
    if held > settings.max_policy_bytes:
        return f"the set's policies would take {held / 2**30:.2f} GiB, past the cap of " \
               f"{settings.max_policy_bytes / 2**30:.2f} GiB"
    if settings.max_seconds is not None and time.perf_counter() - started > settings.max_seconds:
        return f"the refinement has run {settings.max_seconds:g} s, its time cap (--max-seconds)"
    return None


IMPOSSIBLE = "no hypothesis of the start set can produce the demonstrations"
RESOLVED = ("the set resolves the posterior (every β and θ holding its mass is spaced finer than its "
            "spread) and the last round moved β̂, E[θ] and the 90% intervals less than the tolerances")
FINEST = "the mass lies on the finest spacing refinement makes"


def refine(mdp: TabularMDP, trajs: Trajectories, start: HypothesisSet, *,
           settings: Refinement = Refinement(), theta_step: float | None = None,
           solve_kwargs: dict | None = None, progress: Callable[[int, int], None] | None = None) -> Refined:
    """Refine ``start`` where the posterior of ``trajs`` has its mass (see the module docstring).

    ``theta_step``: the spacing of ``start``'s θ (a lattice's 1/resolution); by default each θ's
    distance to its nearest neighbour. ``solve_kwargs`` go to :func:`~expertise_irl.planning.soft_vi.solve`
    (tol, chunk_size, model); ``progress(done, total)`` counts hypotheses solved (the total grows
    with the rounds).
    """
    return refine_tasks([(mdp, trajs)], start, settings=settings, theta_step=theta_step,
                        solve_kwargs=solve_kwargs, progress=progress)


def refine_tasks(tasks: Sequence[tuple[TabularMDP, Trajectories]], start: HypothesisSet, *,
                 settings: Refinement = Refinement(), theta_step: float | None = None,
                 solve_kwargs: dict | None = None, progress: Callable[[int, int], None] | None = None,
                 start_log_likelihood: np.ndarray | None = None, keep_policies: bool = True,
                 zero_features: Sequence[int] = ()) -> Refined:
    """:func:`refine` over several tasks of one person: ``(mdp, trajs)`` pairs whose maps share the
    features; a hypothesis' log-likelihood is the sum over the tasks (one (θ, β) for all of them).

    ``start_log_likelihood``: ``[len(start)]`` the start set's log-likelihoods of the tasks, already
    known, so the start is not solved again (needs ``keep_policies=False``). ``keep_policies=False``:
    the final set's policies are not kept (``log_policy`` None; the policy memory cap then does not
    apply). ``zero_features``: components kept at 0 (the start's θ with another value there leave
    the set, and refinement adds none).
    """
    if settings.max_hypotheses < len(start):
        raise InputError(f"--max-hypotheses {settings.max_hypotheses} is below the {len(start)} hypotheses "
                         "of the set the refinement starts from")
    pool, jobs = _start_pool(tasks, start, theta_step, start_log_likelihood, keep_policies, zero_features)
    K, kw, t0 = start.thetas.shape[1], dict(solve_kwargs or {}), time.perf_counter()
    cells = jobs.cells if keep_policies else 0
    solved = _solve_missing(pool, jobs, kw, progress, 0)
    known = len(start) if start_log_likelihood is not None else 0  # counts towards the cap as solved
    st = _stats(pool, K)
    rounds = [] if st is None else [_round_entry(0, pool, st, solved, pool.sweeps, time.perf_counter() - t0,
                                                 None)]
    stop, warnings, pruned, converged = IMPOSSIBLE, [], 0.0, False
    for r in range(1, settings.max_rounds + 2):  # the last pass only asks whether it settled
        if st is None:
            break
        dropped = _prune(pool, st)
        if dropped > 0 or len(pool.active_t) * len(pool.active_b) < st.log_posterior.size:
            pruned, st = pruned + dropped, _stats(pool, K)
        last = rounds[-1]["changes"]
        ext = _edges(pool, st)
        bt = _beta_todo(pool, st, last is not None and not _beta_settled(last, settings))
        tt = _theta_todo(pool, st, last is not None and not _theta_settled(last, settings))
        if not (ext or bt or tt):
            converged = last is None or _converged(last, settings)
            stop = RESOLVED if converged else FINEST
            break
        if r > settings.max_rounds:
            stop = f"{plural(settings.max_rounds, 'round')} (the cap) without settling"
            warnings.append(_cap_warning(stop, settings.max_rounds, last))
            break
        snap = pool.snapshot()
        for b in ext:
            pool.add_beta(b, START_BETA_STEP, 0)
        _halve_betas(pool, bt)
        _halve_thetas(pool, st, tt, K)
        cap = _cap(pool, settings, solved + known, t0, cells)
        if cap is not None:
            pool.restore(snap)
            stop = cap
            warnings.append(_cap_warning(cap, r - 1, last))
            break
        t1, s1 = time.perf_counter(), pool.sweeps
        n = _solve_missing(pool, jobs, kw, progress, solved)
        solved += n
        prev, st = st, _stats(pool, K)
        rounds.append(_round_entry(r, pool, st, n, pool.sweeps - s1, time.perf_counter() - t1,
                                   st.changes(prev)))
    return _finish(pool, K, rounds, {"converged": converged, "stop_reason": stop, "solved": solved,
                                     "sweeps": pool.sweeps, "eliminated": pool.eliminated,
                                     "pruned_mass": pruned, "seconds": time.perf_counter() - t0,
                                     "settings": settings}, warnings, keep_policies)


def _start_pool(tasks, start: HypothesisSet, theta_step: float | None, start_ll, keep_policies: bool,
                zero_features: Sequence[int]) -> tuple[_Pool, _Tasks]:
    """The pool of ``start`` (its known log-likelihoods filled in) and the tasks, checked."""
    K = start.thetas.shape[1]
    if not tasks:
        raise InputError("refinement needs at least one task")
    for mdp, _ in tasks:
        if mdp.n_features != K:
            raise InputError(f"hypotheses have {K} features but the MDP has {mdp.n_features} "
                             f"({', '.join(mdp.feature_names)})")
    if start_ll is not None and keep_policies:
        raise InputError("known start log-likelihoods come without policies: use keep_policies=False")
    keep = np.ones(start.n_theta, dtype=bool)
    for i in zero_features:
        keep &= np.isclose(start.thetas[:, i], 0.0, atol=1e-12)
    if not keep.any():
        raise InputError("no θ of the start set is 0 on every feature kept at 0")
    hyp = start if keep.all() else HypothesisSet(start.thetas[keep], start.betas)
    pool = _Pool.of(hyp, theta_step)
    pool.zero = tuple(int(i) for i in zero_features)
    if start_ll is not None:
        ll = np.asarray(start_ll, dtype=np.float64)
        if ll.shape != (len(start),):
            raise InputError(f"start log-likelihoods must be {len(start)} values, got shape {ll.shape}")
        for i, row in enumerate(ll.reshape(start.n_theta, start.n_beta)[keep]):
            for j, v in enumerate(row):
                pool.ll[(i, j)] = float(v)
    return pool, _Tasks.of(tasks, keep_policies)


def _cap_warning(reason: str, rounds: int, changes: dict[str, float] | None) -> str:
    moved = "" if changes is None else (
        f"; the last round moved β̂ by {math.expm1(changes['beta']):.1%} and E[θ] by {changes['theta']:.3g}")
    return (f"the hypothesis set was refined {rounds} time(s) and stopped before the estimate settled: "
            f"{reason}{moved}; the posterior is the best so far")


def _probability_error(pool: _Pool, pairs, pruned: float) -> float:
    """A bound on the error of every probability of the final posterior: from the largest certified
    log-likelihood error of a hypothesis not eliminated (each probability within e^{2ε} − 1), plus
    the mass the eliminated (≤ 1e-12 a round) and pruned hypotheses may hold."""
    from .certified import ELIMINATION

    errs = [pool.err.get(k, 0.0) for k in pairs if k not in pool.screened]
    eps = max(errs, default=0.0)
    return math.expm1(2 * eps) + ELIMINATION * pool.elimination_rounds + pruned


def _finish(pool: _Pool, K: int, rounds: list, info: dict[str, Any], warnings: list[str],
            keep_policies: bool = True) -> Refined:
    """The final set, its policies (when kept), prior and log-likelihoods, and the refinement's record."""
    order_b = sorted(pool.active_b, key=lambda j: pool.betas[j])
    thetas = np.array([pool.thetas[i] for i in pool.active_t])
    betas = np.array([pool.betas[j] for j in order_b])
    hyp = HypothesisSet(thetas, betas)
    pairs = [(i, j) for i in pool.active_t for j in order_b]
    log_policy = None
    if keep_policies:
        per_map = [np.stack(m) for m in zip(*(pool.policy[k] for k in pairs), strict=True)]
        log_policy = per_map[0] if len(per_map) == 1 else tuple(per_map)
    lt, lb = pool.log_weights(K, order_b)
    logw = (lt[:, None] + lb[None, :]).ravel()
    prior = np.exp(logw - logw.max())
    s = info.pop("settings")
    info["probability_error"] = _probability_error(pool, pairs, info.get("pruned_mass", 0.0))
    record = {**info, "n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "n_hypotheses": len(hyp),
              "rounds": rounds, "betas": betas.tolist(),
              "tolerances": {"beta": s.tol_beta, "theta": s.tol_theta, "beta_interval": s.tol_interval,
                             "theta_interval": s.tol_interval / 2},
              "caps": {"rounds": s.max_rounds, "hypotheses": s.max_hypotheses, "seconds": s.max_seconds,
                       "policy_bytes": s.max_policy_bytes},
              "prior": "each θ weighs its lattice cell (2^-(K-1) per halving of its spacing), each β its "
                       "cell in log β (1/2 per halving): uniform on the simplex and log-uniform in β over "
                       "the range the set covers"}
    errors = np.array([pool.err.get(k, 0.0) for k in pairs])
    return Refined(hyp, log_policy, prior, record, warnings, np.array([pool.ll[k] for k in pairs]), errors,
                   np.array([k in pool.screened for k in pairs]))
