"""Algorithm 1 as several independent chains, run for a fixed budget or until they agree.

The paper says each inference "was run 4 times" (Sec. VII-A). :func:`birl_chains` reads that as
four independent chains of Algorithm 1 (:func:`expertise_irl.inference.birl.extended_birl`'s
sampler, each from its own uniform start), whose kept points are pooled into one estimate. They
share one target, so a lattice point solved by one chain is known to all (the log-likelihood
cache). The chains run in blocks of ``block`` iterations; with ``rhat_below`` they stop after the
first block at which the split R-hat (arviz's rank-normalised version) of β and of every
component of θ/‖θ‖₁ over the chains' kept points is below it, or at ``max_iter`` iterations per
chain, whichever comes first. The result records how many iterations each chain ran and the
R-hat reached.

Burn-in: the first ``burn_in`` fraction of each chain's points, as for one chain. A chain
continued past a block keeps its state (the point and its log posterior); only the warm start
of its next solve is lost (the likelihood cache is not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..numerics import enable_float64
from .birl import _check_args
from .birl_kernel import ChainState, LatticePosterior, draw_moves, initial_state, make_lattice, sample_chain
from .priors import DEFAULT_PRIOR, get_prior, log_prior_numpy


@dataclass(frozen=True, eq=False)
class BIRLChains:
    """Pooled estimate of several chains of Algorithm 1.

    Attributes:
        theta, beta: ``[C, T, K]``, ``[C, T]`` every chain's points (T = iterations + 1).
        n_burn: points discarded at the start of each chain.
        mean_theta, mean_beta: means over every chain's kept points.
        mean_theta_normalized, mean_beta_normalized: means of θ/‖θ‖₁ and β/‖θ‖₁ over them.
        acceptance_rate: accepted moves / iterations, all chains.
        iterations: iterations each chain ran.
        max_rhat: the largest split R-hat of β and θ/‖θ‖₁ over the chains' kept points (inf when a
            chain never moved in some parameter; NaN with one chain).
        converged: ``rhat_below`` was reached (False without one).
        n_solves, n_cache_hits: soft value iterations run, proposals already known (all chains).
    """

    theta: np.ndarray
    beta: np.ndarray
    n_burn: int
    mean_theta: np.ndarray
    mean_beta: float
    mean_theta_normalized: np.ndarray
    mean_beta_normalized: float
    acceptance_rate: float
    iterations: int
    max_rhat: float
    converged: bool
    n_solves: int
    n_cache_hits: int


def max_rhat(theta: np.ndarray, beta: np.ndarray) -> float:
    """Largest split R-hat of ``beta [C, D]`` and of each component of θ/‖θ‖₁ (``theta [C, D, K]``):
    inf when a chain never moved in a parameter, NaN with fewer than two chains or four draws."""
    from .diagnostics import chain_statistics

    if theta.shape[0] < 2 or theta.shape[1] < 4:
        return math.nan
    stats = chain_statistics(theta / theta.sum(axis=-1, keepdims=True), beta)
    if stats["r_hat"] is None:
        return math.nan
    values = [stats["r_hat"]["beta"], *stats["r_hat"]["theta"]]
    return math.inf if any(v is None for v in values) else float(max(values))


def birl_chains(mdp, trajs, *, chains: int = 4, n_iter: int = 1000, rhat_below: float | None = None,
                max_iter: int = 20_000, block: int = 1000, rng: np.random.Generator, variant: str = "box",
                moves: str | None = None, delta: float = 0.05, beta_step: float = 0.1,
                beta_ratio: float | None = None, theta_max: float = 1.0,
                beta_range: tuple[float, float] = (0.01, 10.0), lam: float = 1.0, burn_in: float = 0.2,
                tol: float = 1e-6, prior: str = DEFAULT_PRIOR, model: str = "maxent") -> BIRLChains:
    """``chains`` independent chains of Algorithm 1 (see the module docstring), pooled.

    Without ``rhat_below`` every chain runs ``n_iter`` iterations; with it, blocks of ``block``
    until the chains' max split R-hat is below ``rhat_below`` or ``max_iter`` is reached. The
    other arguments are :func:`~expertise_irl.inference.birl.extended_birl`'s.

    Raises:
        InputError: a bad parameter (named) or demonstrations impossible in ``mdp``.
    """
    enable_float64()
    for name, x in (("chains", chains), ("block", block), ("max_iter", max_iter)):
        if isinstance(x, bool) or not isinstance(x, int | np.integer) or x < 1:
            raise InputError(f"{name} must be an integer >= 1, got {x!r}")
    if rhat_below is not None and not (isinstance(rhat_below, int | float) and rhat_below > 1):
        raise InputError(f"rhat_below must be a number > 1, got {rhat_below!r}")
    rng = _check_args(mdp, trajs, n_iter, delta, beta_step, theta_max, beta_range, lam, variant, moves,
                      None, burn_in, rng, tol, beta_ratio)
    get_prior(prior)
    rng_range = (float(beta_range[0]), float(beta_range[1]))
    moves = moves or ("both" if variant == "box" else "either")
    lattice = make_lattice(mdp.n_features, variant, delta, beta_step, theta_max, beta_range, lam, beta_ratio)
    target = LatticePosterior(mdp, trajs, lattice,
                              lambda t, b: log_prior_numpy(prior, t, b, rng_range), tol=tol, model=model,
                              warm_start=True, cache=True)
    rngs = rng.spawn(chains)
    states = [initial_state(r, target) for r in rngs]
    parts: list[list] = [[] for _ in range(chains)]
    done, accepted, converged, rhat = 0, 0, False, math.nan
    while True:
        size = n_iter if rhat_below is None else min(block, max_iter - done)
        for c in range(chains):
            ch = sample_chain(states[c], target, moves, draw_moves(rngs[c], lattice, size))
            parts[c].append((ch.m if done == 0 else ch.m[1:], ch.j if done == 0 else ch.j[1:]))
            accepted += int(ch.accepted.sum())
            states[c] = ChainState(ch.m[-1], int(ch.j[-1]), float(ch.log_posterior[-1]), None)
        done += size
        theta, beta, n_burn = _stacked(parts, lattice, burn_in)
        rhat = max_rhat(theta[:, n_burn:], beta[:, n_burn:])
        converged = rhat_below is not None and rhat < rhat_below
        if rhat_below is None or converged or done >= max_iter:
            break
    kt, kb = theta[:, n_burn:].reshape(-1, theta.shape[-1]), beta[:, n_burn:].reshape(-1)
    l1 = kt.sum(axis=1)
    return BIRLChains(theta, beta, n_burn, kt.mean(axis=0), float(kb.mean()), (kt / l1[:, None]).mean(axis=0),
                      float((kb / l1).mean()), accepted / (chains * done), done, rhat, converged,
                      target.n_solves, target.n_cache_hits)


def _stacked(parts, lattice, burn_in: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Every chain's points so far as ``theta [C, T, K]``, ``beta [C, T]``, and the burn-in."""
    m = np.stack([np.concatenate([p[0] for p in chain]) for chain in parts])
    j = np.stack([np.concatenate([p[1] for p in chain]) for chain in parts])
    return lattice.theta(m), lattice.beta(j), math.floor(burn_in * m.shape[1])
