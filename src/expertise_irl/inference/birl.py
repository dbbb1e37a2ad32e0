"""Extended BIRL (paper Algorithm 1): a grid-walk Metropolis sampler over (θ, β).

The paper's optimisation-based inference (Sec. IV-B) approximates the posterior
P(θ, β | Ξ) ∝ P(Ξ | θ, β) P(θ, β) (Eqs. 11, 14) with the grid MCMC of Ramachandran and
Amir's BIRL, extended to move β as well, and reports the chain's mean as the point
estimate (Sec. VII-B). Algorithm 1 leaves several details open; this module fixes them
as follows.

State space (a lattice).
    ``variant="box"`` (the algorithm as printed): θ = δ·m with integer m ∈ {0..M}^K,
    M = θmax/δ (must be an integer), subject to ‖θ‖₁ ≤ λ (Eq. 14), i.e. Σm ≤ ⌊λ/δ⌋.
    The default λ = 1 makes the constraint active (with λ ≥ K·θmax it is not).
    θ = 0 is excluded: it is the uniform-random policy for every β, its direction is
    undefined (the normalised estimates below divide by ‖θ‖₁), and on a continuum it has
    prior mass zero. β = βmin + j·beta_step, j = 0, 1, ... while β ≤ βmax; the lattice is
    anchored at βmin so that the paper's most expert level 0.01 is on it (defaults: 0.01,
    0.11, ..., 9.91). Note the paper's β step is coarse at small β: 0.01 → 0.11 is an
    11-fold change of θ/β. Algorithm 1 names the β step "λ" (neighbours of β̂ in
    [0, βmax]/λ) and uses λ for the ‖θ‖₁ bound in Eq. 14; here the two are separate
    parameters, ``beta_step`` and ``lam``. With ``beta_ratio`` (not in the paper) the β lattice is
    log-spaced instead, β = βmin·beta_ratio^j, and each point carries its cell's prior mass
    (the prior's density × β, a cell being β·ln(beta_ratio) wide): the target stays the
    continuum posterior restricted to the lattice, and a step changes θ/β by the same factor
    at every β.

    ``variant="simplex"``: θ = δ·m with Σm = 1/δ (must be an integer), i.e. ‖θ‖₁ = 1,
    which fixes the scale (only θ/β enters the likelihood); ``theta_max`` and ``lam`` are unused.

Start. m is drawn uniformly over the lattice points of the variant (exactly, by counting
points with a small dynamic programme and drawing coordinates in sequence; for the box a
draw of θ = 0 is redrawn), j uniformly over the β lattice. A uniform draw of
β ~ U(βmin, βmax) snapped to the nearest lattice point would give the two end points half
weight; the exact lattice-uniform draw is what "a random point of the grid" means.
If the start has log posterior −∞ (a user prior that vanishes there) it is redrawn,
up to 1,000 times.

Proposal. The paper moves θ and β at once (``moves="both"``, the box default): θ̃ is one of
the 2K axis neighbours of θ (a coordinate uniformly, a sign uniformly), or in the simplex
variant one of the K(K−1) transfers θ_i −= δ, θ_j += δ (ordered pair i ≠ j uniformly);
β̃ = β ± beta_step (sign uniformly). A proposal off the lattice (outside the box, above
the ‖θ‖₁ bound, θ = 0, any θ_i < 0, β outside [βmin, βmax]) is rejected and counted in
``n_out_of_bounds``; the chain stays. Every move's reverse is proposed with the same
probability, so the proposal is symmetric and plain Metropolis is exact for the target
restricted to the lattice: accept with probability min(1, exp(log p̃ − log p)).

Parity. With ``moves="both"`` each box move changes Σm by ±1 *and* j by ±1, so the
parity of Σm + j never changes: the box chain as printed is reducible and samples the
posterior restricted to the half of the lattice (a checkerboard) that holds its start.
The same holds for the simplex with K = 2 (m₁ + j); with K ≥ 3 a cycle of three transfers
returns θ in an odd number of moves and the simplex chain is irreducible.
``moves="either"`` (not in the paper) moves θ or β, each with probability 1/2, and
reaches every lattice point. It is the simplex default: there, joint moves trap the chain
at a vertex such as θ = (1, 0, ..., 0). At a vertex only K − 1 of the K(K − 1) transfers
stay on the simplex, and each costs likelihood (measured on ``corridor`` at β ≈ 7: about
7.5 nats, while a β step gains about 2.4), so the chain can lower β only through pairs
of unlikely moves; from a random start it stayed at the vertex for 3,000 iterations.

Likelihood. Eq. 11 by soft value iteration (:func:`expertise_irl.planning.soft_vi.solve`; its
fixed point is the one soft policy evaluation/iteration of the paper's [28] reaches)
for the single proposed hypothesis, warm-started from the value function of the
current point (``warm_start``). The solver works in scaled units v = V/β; we hand it
V·β̃/β, so that it starts from the current point's *scaled* values exactly (any start is
valid; this one is the closer: on ``crossroads`` with neighbour moves it needed 10–25 %
fewer sweeps than passing V unchanged, e.g. 106 vs 136 at β ≈ 7, 139 vs 154 at β ≈ 0.5,
against 176 and 166 cold). The demonstrations enter as counts N[s, a]:
log P(Ξ | θ, β) = Σ N[s, a] log π(a | s) over the observed pairs.
Each lattice point's log-likelihood is kept (``cache``, on by default): the target is a
fixed function of the point, so re-proposing a point (frequent after rejections) costs
no solve. When the chain moves to a cached point the warm start stays the value function
of the last solved point on the chain's path, a few lattice steps away.

Prior. Pluggable ``log_prior(theta, beta) -> float`` (up to a constant; −∞ = excluded), or
a named one (``prior``, :mod:`expertise_irl.inference.priors`): ``"log-uniform"`` (the
default: θ uniform on the lattice, p(β) ∝ 1/β on the lattice's β range) or ``"paper"``
(Sec. VII-A: θ uniform, β ~ Normal(5.005, 1.5) truncated to [0.01, 10]), which the
reproduction of the paper passes explicitly.

Output. The chain (start included), its log posterior, acceptance rate (accepted moves /
iterations, out-of-bounds proposals counting as rejections), the posterior mean after
discarding the first ``⌊burn_in·(n_iter + 1)⌋`` chain points (default 20 %), and the
best point: the highest log posterior among every point evaluated, accepted or not.

Scale. In the box variant (θ, β) and (cθ, cβ) are the same policy, so the posterior has a
ridge along the scale and E[θ], E[β] mix scales (and are pulled by the β prior and the
‖θ‖₁ bound). To compare point estimates across variants use ``mean_theta_normalized`` =
E[θ/‖θ‖₁] and ``mean_beta_normalized`` = E[β/‖θ‖₁] (per sample, then averaged); in the
simplex variant they equal ``mean_theta`` and ``mean_beta``. In the box β/‖θ‖₁ can exceed
βmax. On an MDP with a fixed reward (``TabularMDP.reward_offset``, e.g. a map with
``goal_reward_mode = "fixed"``) (cθ, cβ) is another policy, there is no ridge, and the
registry's ``birl`` reports no normalised estimates.

Mixing. The walk is local (one δ or one β step per move), so a chain needs many
iterations to cross the β range (from β ≈ 8 to 0.5 takes ≥ 75 accepted β moves) and can
stay for thousands of iterations in a secondary mode; the β step of 0.1 is coarse at
small β, where a step changes θ/β by 20–50 %. On ``corridor`` with 40 episodes about one
chain in six (2,000 iterations, simplex) stayed in such a mode. Run several chains (the
paper runs each inference 4 times) and compare their log posteriors. Measured acceptance
rates, 40 episodes, defaults: box 0.09–0.15, simplex 0.13–0.27.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..demos.trajectories import Trajectories, validate
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL, check_model
from ..numerics import enable_float64
from .birl_kernel import (
    GRID_RTOL,
    Chain,
    Lattice,
    LatticePosterior,
    draw_moves,
    initial_state,
    make_lattice,
    sample_chain,
)
from .priors import DEFAULT_PRIOR, get_prior, log_prior_numpy

VARIANTS = ("box", "simplex")
MOVES = ("both", "either")

LogPrior = Callable[[np.ndarray, float], float]


def paper_log_prior(theta: np.ndarray, beta: float) -> float:
    """Sec. VII-A prior up to a constant: flat in θ >= 0, β ~ Normal(5.005, 1.5) truncated to [0.01, 10].

    The paper's θ prior, uniform on [0, 1]^K, is flat on the default box (θmax = 1).
    """
    return log_prior_numpy("paper", theta, beta)


@dataclass(frozen=True, eq=False)
class BIRLResult:
    """A chain of :func:`extended_birl` and its summaries (T = n_iter + 1 chain points).

    Attributes:
        theta: ``[T, K]`` θ at each step (row 0 = the start).
        beta: ``[T]`` β at each step.
        log_posterior: ``[T]`` log P(Ξ | θ, β) + log P(θ, β) of the chain's point.
        accepted: ``[n_iter]`` whether iteration i moved the chain.
        acceptance_rate: accepted moves / n_iter.
        n_out_of_bounds: proposals rejected for leaving the lattice.
        n_burn: chain points discarded before the means (the first ``n_burn`` rows).
        mean_theta, mean_beta: posterior means over the kept points (the paper's estimate).
        mean_theta_normalized: ``[K]`` mean of θ/‖θ‖₁ over the kept points (None from the
            registry's ``birl`` on an MDP with a fixed reward, where the rescaled point is
            another policy).
        mean_beta_normalized: mean of β/‖θ‖₁ over the kept points (None likewise).
        best_theta, best_beta, best_log_posterior: highest log posterior evaluated.
        n_solves: soft value iterations run; n_sweeps: their total sweeps.
        n_cache_hits: proposals whose log-likelihood was already known.
        variant, moves, delta, beta_step, beta_ratio: the settings (``beta_ratio`` None: additive
            β steps).
    """

    theta: np.ndarray
    beta: np.ndarray
    log_posterior: np.ndarray
    accepted: np.ndarray
    acceptance_rate: float
    n_out_of_bounds: int
    n_burn: int
    mean_theta: np.ndarray
    mean_beta: float
    mean_theta_normalized: np.ndarray | None
    mean_beta_normalized: float | None
    best_theta: np.ndarray
    best_beta: float
    best_log_posterior: float
    n_solves: int
    n_sweeps: int
    n_cache_hits: int
    variant: str
    moves: str
    delta: float
    beta_step: float
    beta_ratio: float | None = None

    @property
    def kept_theta(self) -> np.ndarray:
        """``[T − n_burn, K]`` chain points used for the means."""
        return self.theta[self.n_burn:]

    @property
    def kept_beta(self) -> np.ndarray:
        """``[T − n_burn]``."""
        return self.beta[self.n_burn:]

    @property
    def sweeps_per_solve(self) -> float:
        return self.n_sweeps / self.n_solves if self.n_solves else 0.0


# ----------------------------------------------------------------------------- checks
def _check_args(mdp, trajs, n_iter, delta, beta_step, theta_max, beta_range, lam, variant, moves,
                log_prior, burn_in, rng, tol, beta_ratio=None) -> np.random.Generator:
    if not isinstance(mdp, TabularMDP):
        raise InputError(f"mdp must be a TabularMDP, got {type(mdp).__name__}")
    if not isinstance(trajs, Trajectories):
        raise InputError(f"trajs must be Trajectories, got {type(trajs).__name__}")
    validate(trajs, mdp)
    if isinstance(n_iter, bool) or not isinstance(n_iter, int | np.integer) or n_iter < 1:
        raise InputError(f"n_iter must be an integer >= 1, got {n_iter!r}")
    for name, x in (("delta", delta), ("beta_step", beta_step), ("theta_max", theta_max),
                    ("lam", lam), ("tol", tol)):
        if isinstance(x, bool) or not isinstance(x, int | float | np.number) or not (
                math.isfinite(x) and x > 0):
            raise InputError(f"{name} must be a finite number > 0, got {x!r}")
    try:
        lo, hi = (float(b) for b in beta_range)
    except (TypeError, ValueError):
        raise InputError(f"beta_range must be a pair (low, high), got {beta_range!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise InputError(f"beta_range must satisfy 0 < low < high (finite), got {beta_range!r}")
    if beta_ratio is not None:
        if isinstance(beta_ratio, bool) or not isinstance(beta_ratio, int | float | np.number) or not (
                math.isfinite(beta_ratio) and beta_ratio > 1):
            raise InputError(f"beta_ratio must be a finite number > 1, got {beta_ratio!r}")
        if lo * beta_ratio > hi * (1 + GRID_RTOL):
            raise InputError(f"beta_ratio = {beta_ratio:g} leaves a single β in beta_range {beta_range!r}")
    elif lo + beta_step > hi * (1 + GRID_RTOL):
        raise InputError(f"beta_step = {beta_step:g} leaves a single β in beta_range {beta_range!r}")
    if variant not in VARIANTS:
        raise InputError(f"variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    if moves is not None and moves not in MOVES:
        raise InputError(f"moves must be one of {', '.join(MOVES)}, got {moves!r}")
    if log_prior is not None and not callable(log_prior):
        raise InputError(f"log_prior must be a callable log_prior(theta, beta), got {log_prior!r}")
    if isinstance(burn_in, bool) or not isinstance(burn_in, int | float | np.number) or not 0 <= burn_in < 1:
        raise InputError(f"burn_in must be a fraction in [0, 1), got {burn_in!r}")
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer) or rng < 0:
        raise InputError(f"rng must be a numpy Generator or a seed >= 0, got {rng!r}")
    return np.random.default_rng(int(rng))


# ----------------------------------------------------------------------------- sampler
def extended_birl(
    mdp: TabularMDP,
    trajs: Trajectories,
    *,
    n_iter: int = 1000,
    delta: float = 0.05,
    beta_step: float = 0.1,
    theta_max: float = 1.0,
    beta_range: tuple[float, float] = (0.01, 10.0),
    lam: float = 1.0,
    variant: str = "box",
    moves: str | None = None,
    log_prior: LogPrior | None = None,
    burn_in: float = 0.2,
    rng: np.random.Generator | int,
    tol: float = 1e-6,
    warm_start: bool = True,
    cache: bool = True,
    progress: Callable[[int, int], None] | None = None,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
    beta_ratio: float | None = None,
) -> BIRLResult:
    """Sample P(θ, β | Ξ) with Algorithm 1 (see the module docstring for every choice made).

    Args:
        mdp: the task.
        trajs: the demonstrations Ξ (checked with
            :func:`~expertise_irl.demos.trajectories.validate`).
        n_iter: iterations K of Algorithm 1.
        delta: θ lattice step δ.
        beta_step: β lattice step.
        theta_max: box side (box variant; a multiple of ``delta``).
        beta_range: (βmin, βmax).
        lam: bound λ on ‖θ‖₁ (box variant; ≥ delta).
        variant: ``"box"`` (as printed) or ``"simplex"`` (‖θ‖₁ = 1).
        moves: ``"both"`` (θ and β each step, as printed) or ``"either"`` (one of them);
            default ``"both"`` for the box, ``"either"`` for the simplex.
        log_prior: ``log_prior(theta, beta) -> float``; default: the prior named ``prior``.
        prior: ``"log-uniform"`` (default) or ``"paper"`` (:func:`paper_log_prior`), restricted
            to ``beta_range``; ignored when ``log_prior`` is given.
        model: the observation model (:mod:`expertise_irl.models`).
        burn_in: fraction of the chain discarded before the means.
        rng: numpy Generator (or a seed) for all randomness.
        tol: solver tolerance (nats on V/β; log-likelihood error ≤ 2·tol per pair).
        warm_start: warm-start each solve from the current point's value function.
        cache: remember each lattice point's log-likelihood.
        progress: called as ``progress(done, n_iter)`` about a hundred times during the walk.
        beta_ratio: multiplicative β steps (β_{j+1} = β_j·beta_ratio from βmin; > 1) instead of the
            additive ``beta_step``: a lattice even in log β, whose points carry the prior mass of
            their cells (density × β). Not the paper's; see the module docstring.

    Returns:
        The chain's means, its walk and its acceptance statistics.

    Raises:
        InputError: a bad parameter (the message names it) or demonstrations impossible in ``mdp``.
    """
    enable_float64()
    rng = _check_args(mdp, trajs, n_iter, delta, beta_step, theta_max, beta_range, lam, variant, moves,
                      log_prior, burn_in, rng, tol, beta_ratio)
    get_prior(prior)
    check_model(model)
    if log_prior is None:
        b_range = (float(beta_range[0]), float(beta_range[1]))

        def log_prior(theta, beta, _name=prior, _range=b_range):
            return log_prior_numpy(_name, theta, beta, _range)
    if moves is None:
        moves = "both" if variant == "box" else "either"
    lattice = make_lattice(mdp.n_features, variant, delta, beta_step, theta_max, beta_range, lam, beta_ratio)
    target = LatticePosterior(mdp, trajs, lattice, log_prior, tol=tol, model=model, warm_start=warm_start,
                              cache=cache)
    start = initial_state(rng, target)
    chain = sample_chain(start, target, moves, draw_moves(rng, lattice, int(n_iter)), progress)
    return _summarise(chain, lattice, target, moves, burn_in)


def _summarise(chain: Chain, lattice: Lattice, target: LatticePosterior, moves: str, burn_in: float
               ) -> BIRLResult:
    """The chain in (θ, β), its acceptance, means after burn-in and its best point."""
    theta, beta = lattice.theta(chain.m), lattice.beta(chain.j)
    n_burn = math.floor(burn_in * len(beta))
    kt, kb = theta[n_burn:], beta[n_burn:]
    l1 = kt.sum(axis=1)
    best_lp, best_m, best_j = chain.best
    return BIRLResult(
        theta=theta, beta=beta, log_posterior=chain.log_posterior, accepted=chain.accepted,
        acceptance_rate=float(chain.accepted.mean()), n_out_of_bounds=chain.n_out_of_bounds, n_burn=n_burn,
        mean_theta=kt.mean(axis=0), mean_beta=float(kb.mean()),
        mean_theta_normalized=(kt / l1[:, None]).mean(axis=0), mean_beta_normalized=float((kb / l1).mean()),
        best_theta=lattice.theta(best_m), best_beta=lattice.beta(best_j), best_log_posterior=float(best_lp),
        n_solves=target.n_solves, n_sweeps=target.n_sweeps, n_cache_hits=target.n_cache_hits,
        variant=lattice.variant, moves=moves, delta=lattice.delta, beta_step=lattice.beta_step,
        beta_ratio=lattice.beta_ratio or None,
    )
