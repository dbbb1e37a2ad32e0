"""Run a continuous-space method (Algorithm 1, MAP or NUTS) and describe its result.

One entry point, :func:`run_method`, turns a method name and its options into the
common fields the command line writes: posterior means (``theta_hat``, ``beta_hat``;
for ``map`` the optimum), the ``map`` point, posterior ``samples`` for the sampling
methods, 90% ``credible_intervals`` and ``diagnostics``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL, check_model
from .diagnostics import birl_warnings, chain_statistics, map_unavailable, map_warnings, nuts_warnings
from .priors import BETA_RANGE, DEFAULT_PRIOR, PRIORS

METHODS = ("discrete", "birl", "map", "nuts")
CREDIBLE = 0.9


@dataclass(frozen=True)
class MethodOptions:
    """Options of the continuous methods (defaults follow the paper where it gives them)."""

    iterations: int = 1000  # birl: Algorithm 1's K
    delta: float = 0.05  # birl: θ grid step
    beta_step: float = 0.1  # birl: β grid step
    variant: str = "box"  # birl: "box" (as printed) or "simplex"
    starts: int = 4  # map: random starts
    chains: int = 4  # nuts
    warmup: int = 500  # nuts
    samples: int = 500  # nuts: draws per chain
    prior: str = DEFAULT_PRIOR  # birl, map, nuts: "log-uniform" or "paper"
    model: str = DEFAULT_MODEL  # observation model


    def validate(self) -> None:
        """Raise :class:`InputError` naming the command-line option that is out of range."""
        from .birl import VARIANTS

        for name, x in (("--delta", self.delta), ("--beta-step", self.beta_step)):
            if not (math.isfinite(x) and x > 0):
                raise InputError(f"{name} must be a finite number > 0, got {x:g}")
        n = 1.0 / self.delta
        if abs(n - round(n)) > 1e-9 * max(1.0, n):
            raise InputError(f"--delta must divide 1 (1/--delta an integer), got {self.delta:g}")
        lo, hi = BETA_RANGE
        if lo + self.beta_step > hi:
            raise InputError(f"--beta-step {self.beta_step:g} leaves a single β in the prior's range "
                             f"[{lo:g}, {hi:g}]")
        if self.variant not in VARIANTS:
            raise InputError(f"--variant must be one of {', '.join(VARIANTS)}, got {self.variant!r}")
        if self.prior not in PRIORS:
            raise InputError(f"--prior must be one of {', '.join(PRIORS)}, got {self.prior!r}")
        check_model(self.model, "--model")


def run_method(method: str, mdp: TabularMDP | Sequence[TabularMDP],
               trajs: Trajectories | Sequence[Trajectories], opts: MethodOptions,
               seed: int, *, progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Run ``method`` and return its result fields, plus ``draws`` (chain, θ, β) if it samples.

    ``mdp`` and ``trajs`` may be equal-length lists, one per task of the same person (map and
    nuts sum the log-likelihoods; Algorithm 1 takes one task).

    ``diagnostics`` holds each method's statistics, ``warnings`` (see
    :mod:`expertise_irl.inference.diagnostics` for the thresholds) and ``unavailable``
    (statistic -> why it could not be computed). ``progress(done, total)`` follows
    Algorithm 1's iterations, MAP's starts and NUTS's iterations (warm-up included).
    """
    from .task_likelihood import as_tasks  # imports JAX: not at module level (the CLI's --help)

    opts.validate()
    t0 = time.perf_counter()
    names = as_tasks(mdp, trajs)[0][0].feature_names
    if method == "birl" and not isinstance(mdp, TabularMDP):
        raise InputError("--method birl (Algorithm 1) takes one task; use map or nuts for several")
    if method == "birl":
        from .birl import extended_birl
        from .gradient import credible_intervals

        r = extended_birl(mdp, trajs, n_iter=opts.iterations, delta=opts.delta,
                          beta_step=opts.beta_step, variant=opts.variant,
                          rng=np.random.default_rng(seed), progress=progress, prior=opts.prior,
                          model=opts.model)
        keep = slice(r.n_burn, None)
        theta, beta = r.theta[keep], r.beta[keep]
        stats = chain_statistics(theta, beta, halves=True)  # one chain: R-hat compares its halves
        diag = {"acceptance_rate": r.acceptance_rate, "out_of_bounds": r.n_out_of_bounds,
                "burn_in": r.n_burn, "solves": r.n_solves, "sweeps": r.n_sweeps,
                "variant": r.variant, "moves": r.moves, "r_hat": stats["r_hat"],
                "r_hat_method": "split halves of the kept chain", "ess_bulk": stats["ess_bulk"],
                "unavailable": stats["unavailable"]}
        diag["warnings"] = birl_warnings(diag, names)
        out = {
            "theta_hat": r.mean_theta.tolist(), "beta_hat": float(r.mean_beta),
            "theta_hat_normalized": r.mean_theta_normalized.tolist(),
            "beta_hat_normalized": float(r.mean_beta_normalized),
            "map": {"theta": r.best_theta.tolist(), "beta": float(r.best_beta),
                    "log_posterior": float(r.best_log_posterior)},
            "credible_intervals": credible_intervals(theta, beta, CREDIBLE),
            "diagnostics": diag,
            "draws": (np.zeros(len(beta), dtype=int), theta, beta),
        }
    elif method == "map":
        from .gradient import map_estimate

        r = map_estimate(mdp, trajs, n_starts=opts.starts, rng=np.random.default_rng(seed),
                         progress=progress, prior=opts.prior, model=opts.model)
        diag = {"starts": r.starts.tolist(), "optima": r.optima.tolist(), "evaluations": r.evaluations,
                "unavailable": map_unavailable(opts.starts)}
        diag["warnings"] = map_warnings(diag, r.beta, PRIORS[opts.prior].beta_range)
        out = {
            "theta_hat": r.theta.tolist(), "beta_hat": r.beta,
            "map": {"theta": r.theta.tolist(), "beta": r.beta, "log_posterior": r.log_posterior},
            "diagnostics": diag,
        }
    elif method == "nuts":
        from .nuts import nuts_posterior

        r = nuts_posterior(mdp, trajs, num_warmup=opts.warmup, num_samples=opts.samples,
                           num_chains=opts.chains, seed=seed, progress=progress,
                           prior=opts.prior, model=opts.model)
        C, D, K = r.theta.shape
        theta, beta = r.theta.reshape(-1, K), r.beta.reshape(-1)
        best = int(np.argmax(r.log_density.reshape(-1)))
        diag = {"r_hat": r.r_hat, "ess_bulk": r.ess, "divergences": r.divergences,
                "chains": C, "draws_per_chain": D, "mean_tree_size": r.mean_tree_size,
                "mean_accept_prob": r.mean_accept_prob, "unavailable": dict(r.unavailable)}
        diag["warnings"] = nuts_warnings(diag, names)
        out = {
            "theta_hat": r.mean_theta.tolist(), "beta_hat": r.mean_beta,
            "map": {"theta": theta[best].tolist(), "beta": float(beta[best]),
                    "log_posterior": float(r.log_density.reshape(-1)[best])},
            "credible_intervals": r.credible_intervals(CREDIBLE),
            "diagnostics": diag,
            "draws": (np.repeat(np.arange(C), D), theta, beta),
        }
    else:
        raise InputError(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    out["run_time_s"] = time.perf_counter() - t0
    return out
