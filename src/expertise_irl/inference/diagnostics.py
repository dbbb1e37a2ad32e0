"""Diagnostics that speak: convergence statistics, their thresholds, and warnings in words.

Every inference result carries ``diagnostics`` with the statistics below, a list of
``warnings`` (also printed on stderr by the command line) and, for each statistic that
cannot be computed from the run, ``unavailable[name]`` = the reason (the statistic itself
is then ``None``, written as JSON ``null``).

Thresholds (module constants, documented in the README):

- **R-hat** (rank-normalised split R̂, Vehtari et al. 2021): above :data:`R_HAT_MAX` = 1.01 the
  chains (or, for Algorithm 1's single chain, its two halves) have not mixed.
- **Bulk ESS**: below :data:`ESS_PER_CHAIN_MIN` = 100 per chain the posterior means and
  intervals are too noisy to report.
- **Divergences** (NUTS): any divergent transition after warm-up means the sampler missed
  part of the posterior.
- **Acceptance rate** (Algorithm 1): below :data:`ACCEPTANCE_MIN` = 0.05 the walk is stuck.
- **MAP starts**: when fewer than two starts reach within :data:`MAP_AGREE_NATS` = 0.1 nats of
  the best log-posterior, the optimum may be a local one.
- **Discrete β grid edge**: :data:`EDGE_MASS` = 10% or more of the β marginal on the smallest
  (or largest) β of the grid means the person may be more (or less) expert than the grid
  allows: the estimate is the grid's, not the person's.
- **Discrete θ set edge**: half or more (:data:`THETA_EDGE_MASS`) of the θ marginal on the
  largest value of a component that the set keeps below 1 (or the smallest it keeps above 0):
  the person's preference may lie outside the set.
"""

from __future__ import annotations

import math
import warnings as _warnings
from typing import Any

import numpy as np

R_HAT_MAX = 1.01
ESS_PER_CHAIN_MIN = 100
ACCEPTANCE_MIN = 0.05
MAP_AGREE_NATS = 0.1
EDGE_MASS = 0.10
THETA_EDGE_MASS = 0.5
_MIN_DRAWS = 4  # ArviZ's minimum draws per chain for R-hat and ESS


def _fmt_list(values) -> str:
    return ",".join(f"{v:g}" for v in values)


def _param_names(feature_names) -> list[str]:
    return ["beta", *(f"theta[{n}]" for n in feature_names)]


def chain_statistics(theta: np.ndarray, beta: np.ndarray, *, halves: bool = False) -> dict[str, Any]:
    """Split R-hat and bulk ESS of draws ``theta [C, D, K]``, ``beta [C, D]``.

    Returns ``{"r_hat": {"beta": x, "theta": [K]} | None, "ess_bulk": ... | None,
    "unavailable": {name: reason}}``. R-hat needs two chains of at least 4 draws, ESS at
    least 4 draws per chain; otherwise the statistic is ``None`` and the reason is given.
    ``halves``: the input is one chain ``theta [D, K]``, ``beta [D]``; R-hat compares its two
    halves and ESS is that of the whole chain.
    """
    import arviz as az

    if halves:
        n = len(beta) // 2
        out = chain_statistics(theta[:2 * n].reshape(2, n, -1), beta[:2 * n].reshape(2, n))
        if out["r_hat"] is None:
            out["unavailable"]["r_hat"] = (f"R-hat of one chain compares its halves, which need at least "
                                           f"{_MIN_DRAWS} draws each; the chain has {len(beta)}")
        out["unavailable"].pop("ess_bulk", None)
        if len(beta) >= _MIN_DRAWS:
            out["ess_bulk"] = chain_statistics(theta[None], beta[None])["ess_bulk"]
        else:
            out["ess_bulk"] = None
            out["unavailable"]["ess_bulk"] = (f"ESS needs at least {_MIN_DRAWS} draws; "
                                              f"the chain has {len(beta)}")
        return out
    C, D = beta.shape
    out: dict[str, Any] = {"r_hat": None, "ess_bulk": None, "unavailable": {}}

    def per_param(fn) -> dict[str, Any]:
        with _warnings.catch_warnings():
            _warnings.simplefilter("ignore")
            b = float(fn(beta))
            t = [float(fn(theta[..., k])) for k in range(theta.shape[-1])]
        return {"beta": b if math.isfinite(b) else None,
                "theta": [x if math.isfinite(x) else None for x in t]}

    if C >= 2 and D >= _MIN_DRAWS:
        out["r_hat"] = per_param(lambda x: az.rhat(x))
    else:
        out["unavailable"]["r_hat"] = (f"R-hat needs at least 2 chains of at least {_MIN_DRAWS} draws; "
                                       f"this run has {C} chain(s) of {D}")
    if D >= _MIN_DRAWS:
        out["ess_bulk"] = per_param(lambda x: az.ess(x, method="bulk"))
    else:
        out["unavailable"]["ess_bulk"] = (f"ESS needs at least {_MIN_DRAWS} draws per chain; "
                                          f"this run has {D}")
    return out


def _worst(stat: dict | None, feature_names, pick) -> tuple[str, float] | None:
    if stat is None:
        return None
    pairs = [(n, v) for n, v in zip(_param_names(feature_names), [stat["beta"], *stat["theta"]],
                                    strict=True) if v is not None]
    return pick(pairs, key=lambda p: p[1]) if pairs else None


def sampling_warnings(stats: dict[str, Any], *, chains: int, feature_names, more: str,
                      unmixed: str = "the chains have not mixed") -> list[str]:
    """Warnings for statistics that could not be computed, R-hat above :data:`R_HAT_MAX` and bulk
    ESS below :data:`ESS_PER_CHAIN_MIN` per chain; ``more`` names the options that buy more
    draws (e.g. ``--samples``)."""
    out = [f"convergence not checked: {why} (run longer: {more})"
           for why in stats.get("unavailable", {}).values()]
    worst = _worst(stats.get("r_hat"), feature_names, max)
    if worst is not None and worst[1] > R_HAT_MAX:
        out.append(f"R-hat of {worst[0]} is {worst[1]:.3f} (> {R_HAT_MAX}): {unmixed}; "
                   f"the estimates and intervals are not trustworthy (run longer: {more})")
    low = _worst(stats.get("ess_bulk"), feature_names, min)
    need = ESS_PER_CHAIN_MIN * chains
    if low is not None and low[1] < need:
        out.append(f"bulk ESS of {low[0]} is {low[1]:.1f} (< {ESS_PER_CHAIN_MIN} per chain = {need}): "
                   f"posterior means and intervals are noisy (run longer: {more})")
    return out


def nuts_warnings(diag: dict[str, Any], feature_names) -> list[str]:
    """Warnings of a NUTS run: R-hat, ESS, divergences, and R-hat that one chain cannot give."""
    more = "--chains 2 or more, --samples" if diag["chains"] < 2 else "--warmup, --samples"
    out = sampling_warnings(diag, chains=diag["chains"], feature_names=feature_names, more=more)
    if diag["divergences"]:
        n_div = diag["divergences"]
        plural = "s" if n_div != 1 else ""
        out.append(f"{n_div} divergent transition{plural} after warm-up: the sampler missed part "
                   "of the posterior (run a longer --warmup)")
    return out


def birl_warnings(diag: dict[str, Any], feature_names) -> list[str]:
    """Warnings of an Algorithm 1 chain: acceptance rate, split R-hat of its halves, ESS."""
    out = []
    rate = diag["acceptance_rate"]
    if rate < ACCEPTANCE_MIN:
        out.append(f"acceptance rate {rate:.3f} (< {ACCEPTANCE_MIN}): the walk is stuck; "
                   "try a smaller --delta or --beta-step")
    return out + sampling_warnings(diag, chains=1, feature_names=feature_names, more="--iterations",
                                   unmixed="the two halves of the chain disagree")


def map_warnings(diag: dict[str, Any], beta: float, beta_range: tuple[float, float]) -> list[str]:
    """Warnings of a MAP run: starts that disagree, β̂ on the edge of the prior's range."""
    out = []
    optima = np.asarray(diag["optima"], dtype=float)
    if len(optima) >= 2:
        best = float(np.max(optima))
        agree = int(np.sum(optima >= best - MAP_AGREE_NATS))
        if agree < 2:
            gaps = np.sort(best - optima)[1:]
            out.append(f"only 1 of {len(optima)} starts reached the best log-posterior (the others ended "
                       f"{gaps.min():.3g}–{gaps.max():.3g} nats lower): the optimum may be local; "
                       "try more --starts")
    lo, hi = beta_range
    if beta <= lo * (1 + 1e-3) or beta >= hi * (1 - 1e-3):
        out.append(f"β̂ = {beta:.4g} is on the edge of the prior's range [{lo:g}, {hi:g}]: "
                   "the data ask for a β the prior excludes")
    return out


def map_unavailable(n_starts: int) -> dict[str, str]:
    return {} if n_starts >= 2 else {
        "start_agreement": "a single start cannot be checked against others; use --starts 2 or more"}


def discrete_warnings(belief, feature_names=None) -> list[str]:
    """Warnings of a discrete-set posterior: mass on the edge of the β grid or of the θ set."""
    out = []
    betas, pb = belief.marginal_beta()
    if len(betas) >= 2:
        lo_p, hi_p = float(pb[0]), float(pb[-1])
        if lo_p >= EDGE_MASS:
            smaller = [betas[0] / 10, betas[0] / 3]
            out.append(f"{lo_p:.0%} of the β posterior is on the smallest β of the grid ({betas[0]:g}): the "
                       "person may be more expert than the grid allows, so β̂ is the grid's, not theirs; "
                       f"add smaller values, e.g. --betas {_fmt_list([*smaller, *betas])}")
        if hi_p >= EDGE_MASS:
            larger = [betas[-1] * 3, betas[-1] * 10]
            out.append(f"{hi_p:.0%} of the β posterior is on the largest β of the grid ({betas[-1]:g}): the "
                       "person may be noisier than the grid allows, so β̂ is the grid's, not theirs; "
                       f"add larger values, e.g. --betas {_fmt_list([*betas, *larger])}")
    thetas, pt = belief.marginal_theta()
    if len(thetas) >= 2:
        for i in range(thetas.shape[1]):
            col = thetas[:, i]
            name = f"θ_{feature_names[i]}" if feature_names else f"θ_{i + 1}"
            for edge, inner in ((col.max(), col.max() < 1 - 1e-9), (col.min(), col.min() > 1e-9)):
                if not inner:
                    continue
                mass = float(pt[np.isclose(col, edge, atol=1e-9)].sum())
                if mass >= THETA_EDGE_MASS:
                    side = "largest" if edge == col.max() else "smallest"
                    out.append(f"{mass:.0%} of the θ posterior has {name} = {edge:.3g}, the {side} value "
                               "in the set: the person's preference may lie outside it; use a larger "
                               "or denser --thetas")
    return out
