"""Diagnostics that speak: convergence statistics, their thresholds, and warnings in words.

Every inference result carries ``diagnostics`` with the statistics below, a list of
``warnings`` (also printed on stderr by the command line) and, for each statistic that
cannot be computed from the run, ``unavailable[name]`` = the reason (the statistic itself
is then ``None``, written as JSON ``null``).

Thresholds (module constants, documented in the README):

- **A chain that did not move** in a parameter (every draw of that chain the same value): no
  posterior to summarise there, whatever the other chains did. ArviZ would call a constant series
  of n draws n effective draws and give it a NaN R-hat; here its bulk ESS is 0, its R-hat ``None``
  and its 90% interval withheld (:func:`withhold_intervals`), each with the reason, and one warning
  (:func:`stuck_warnings`) names the chain, the parameters and their values.
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
#: β̂ within this relative margin of the prior's range's edge is on the edge.
MAP_EDGE_MARGIN = 0.05
EDGE_MASS = 0.10
THETA_EDGE_MASS = 0.5
_MIN_DRAWS = 4  # ArviZ's minimum draws per chain for R-hat and ESS


def _fmt_list(values) -> str:
    return ",".join(f"{v:g}" for v in values)


def _param_names(feature_names) -> list[str]:
    return ["β", *(f"θ[{n}]" for n in feature_names)]


def _path(i: int) -> str:
    """Where parameter ``i`` (0 = β, then θ's components) sits in a ``{"beta", "theta": [K]}`` entry."""
    return "beta" if i == 0 else f"theta[{i - 1}]"


def _count(x: float) -> str:
    return f"{x:.0f}" if x >= 10 else f"{x:.1f}"


def stuck_parameters(theta: np.ndarray, beta: np.ndarray) -> dict[int, dict[int, float]]:
    """The parameters that some chain never moved, of draws ``theta [C, D, K]``, ``beta [C, D]``.

    Returns ``{i: {chain: value}}`` with ``i`` = 0 for β and ``k + 1`` for θ_k: in each listed
    chain every draw of that parameter is the same ``value``. Such a chain says nothing about the
    posterior's spread; ArviZ reports the ESS of a constant series as its length and its R-hat as
    NaN. Chains shorter than the statistics' minimum (:data:`_MIN_DRAWS`) are not judged, nor is a
    θ that the parameterisation fixes (one feature on the simplex: θ = [1] in every draw).
    """
    C, D = beta.shape
    if D < _MIN_DRAWS:
        return {}
    K = theta.shape[-1]
    fixed = K == 1 and np.all(theta == 1.0)  # one feature on the simplex: θ = [1] by definition
    series = [beta, *(() if fixed else (theta[..., k] for k in range(K)))]
    out: dict[int, dict[int, float]] = {}
    for i, x in enumerate(series):
        per_chain = {c: float(x[c, 0]) for c in range(C) if np.all(x[c] == x[c, 0])}
        if per_chain:
            out[i] = per_chain
    return out


def _who(chains, n_chains: int) -> str:
    if n_chains == 1:
        return "the chain"
    listed = ", ".join(str(c) for c in chains)
    return f"chain{'s' if len(chains) > 1 else ''} {listed} (of 0–{n_chains - 1})"


def stuck_reason(i: int, per_chain: dict[int, float], n_chains: int, feature_names) -> str:
    """Why the statistics and the interval of stuck parameter ``i`` are withheld, in one line."""
    name = _param_names(feature_names)[i]
    values = sorted(set(per_chain.values()))
    at = f"always {values[0]:.4g}" if len(values) == 1 else "each at one value"
    return f"{_who(sorted(per_chain), n_chains)} did not move in {name} ({at}): no posterior to summarise"


def _apply_stuck(out: dict[str, Any], stuck, n_chains: int, feature_names) -> None:
    """Bulk ESS 0 and R-hat None (with the reason) for stuck parameters; a reason for every other None."""
    for stat in ("r_hat", "ess_bulk"):
        values = out[stat]
        if values is None:
            continue
        for i in range(1 + len(values["theta"])):
            key = f"{stat}.{_path(i)}"
            if i in stuck:
                new = 0.0 if stat == "ess_bulk" else None
                if new is None:
                    out["unavailable"][key] = stuck_reason(i, stuck[i], n_chains, feature_names)
            else:
                new = values["beta"] if i == 0 else values["theta"][i - 1]
                if new is None:
                    label = "R-hat" if stat == "r_hat" else "bulk ESS"
                    out["unavailable"][key] = (f"{label} of {_param_names(feature_names)[i]} is not a finite "
                                               "number for this run")
            if i == 0:
                values["beta"] = new
            else:
                values["theta"][i - 1] = new


def chain_statistics(theta: np.ndarray, beta: np.ndarray, *, halves: bool = False,
                     feature_names=None) -> dict[str, Any]:
    """Split R-hat and bulk ESS of draws ``theta [C, D, K]``, ``beta [C, D]``.

    Returns ``{"r_hat": {"beta": x, "theta": [K]} | None, "ess_bulk": ... | None,
    "unavailable": {name: reason}, "stuck": {i: {chain: value}}}``. R-hat needs two chains of at
    least 4 draws, ESS at least 4 draws per chain; otherwise the statistic is ``None`` and the
    reason is given. A parameter that some chain never moved (:func:`stuck_parameters`, listed
    in ``stuck``) has bulk ESS 0 and R-hat ``None`` (``unavailable["r_hat.beta"]``,
    ``["r_hat.theta[k]"]`` say why), whatever the other chains did; any other value that comes out
    NaN is ``None`` with a reason too. ``feature_names`` name θ's components in the reasons.
    ``halves``: the input is one chain ``theta [D, K]``, ``beta [D]``; R-hat compares its two
    halves and ESS is that of the whole chain.
    """
    if feature_names is None:
        feature_names = [str(k) for k in range(theta.shape[-1])]
    if halves:
        theta, beta = theta[None], beta[None]
        out = _halves(theta[0], beta[0])
    else:
        out = _statistics(theta, beta)
    out["stuck"] = stuck_parameters(theta, beta)
    _apply_stuck(out, out["stuck"], beta.shape[0], feature_names)
    return out


def _halves(theta: np.ndarray, beta: np.ndarray) -> dict[str, Any]:
    n = len(beta) // 2
    out = _statistics(theta[:2 * n].reshape(2, n, -1), beta[:2 * n].reshape(2, n))
    if out["r_hat"] is None:
        out["unavailable"]["r_hat"] = (f"R-hat of one chain compares its halves, which need at least "
                                       f"{_MIN_DRAWS} draws each; the chain has {len(beta)}")
    out["unavailable"].pop("ess_bulk", None)
    if len(beta) >= _MIN_DRAWS:
        out["ess_bulk"] = _statistics(theta[None], beta[None])["ess_bulk"]
    else:
        out["ess_bulk"] = None
        out["unavailable"]["ess_bulk"] = (f"ESS needs at least {_MIN_DRAWS} draws; "
                                          f"the chain has {len(beta)}")
    return out


def _statistics(theta: np.ndarray, beta: np.ndarray) -> dict[str, Any]:
    import arviz as az

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


def withhold_intervals(intervals: dict[str, Any], stuck, n_chains: int, feature_names,
                       unavailable: dict[str, str]) -> dict[str, Any]:
    """``intervals`` (``{"beta": [lo, hi], "theta": [[lo, hi], ...]}``) with ``None`` for each stuck
    parameter, the reason in ``unavailable["credible_intervals.beta"]`` (or ``.theta[k]``): the
    quantiles of a value repeated by a chain that never moved are not a posterior's."""
    out = {"beta": intervals["beta"], "theta": list(intervals["theta"])}
    for i, per_chain in stuck.items():
        if i == 0:
            out["beta"] = None
        else:
            out["theta"][i - 1] = None
        unavailable[f"credible_intervals.{_path(i)}"] = stuck_reason(i, per_chain, n_chains, feature_names)
    return out


def _worst(stat: dict | None, feature_names, pick, skip=()) -> tuple[str, float] | None:
    if stat is None:
        return None
    values = [stat["beta"], *stat["theta"]]
    pairs = [(n, v) for i, (n, v) in enumerate(zip(_param_names(feature_names), values, strict=True))
             if v is not None and i not in skip]
    return pick(pairs, key=lambda p: p[1]) if pairs else None


def stuck_warnings(stuck, *, chains: int, feature_names, draws: str, remedy: str) -> list[str]:
    """One warning per set of chains that did not move in some parameters: which, at what value,
    what is withheld and ``remedy`` (what to run instead). ``draws`` names the draws judged."""
    by_chains: dict[tuple[int, ...], list[int]] = {}
    for i, per_chain in sorted(stuck.items()):
        by_chains.setdefault(tuple(sorted(per_chain)), []).append(i)
    names = _param_names(feature_names)
    out = []
    for which, params in by_chains.items():
        listed = ", ".join(names[i] for i in params)
        if len(which) == 1:
            values = ", ".join(f"{names[i]} = {stuck[i][which[0]]:.4g}" for i in params)
            where = f"every {draws} has {values}"
        else:
            where = f"each repeats one value in every {draws}"
        estimate = ("the estimate is that one value" if len(which) == chains else
                    "the estimate pools chains that did not move")
        out.append(f"{_who(which, chains)} did not move in {listed}: {where}, so there is no posterior to "
                   f"summarise there (ESS 0; R-hat and 90% interval null; {estimate}); {remedy}")
    return out


def sampling_warnings(stats: dict[str, Any], *, chains: int, feature_names, more: str,
                      unmixed: str = "the chains have not mixed", stuck=None) -> list[str]:
    """Warnings for statistics that could not be computed, R-hat above :data:`R_HAT_MAX` and bulk
    ESS below :data:`ESS_PER_CHAIN_MIN` per chain; ``more`` names the options that buy more
    draws (e.g. ``--samples``). Parameters in ``stuck`` (:func:`stuck_parameters`) have their own
    warning (:func:`stuck_warnings`) and are left out of these."""
    stuck = stuck or {}
    explained = {f"{stat}.{_path(i)}" for i in stuck for stat in ("r_hat", "ess_bulk", "credible_intervals")}
    out = [f"convergence not checked: {why} (run longer: {more})"
           for key, why in stats.get("unavailable", {}).items() if key not in explained]
    worst = _worst(stats.get("r_hat"), feature_names, max, stuck)
    if worst is not None and worst[1] > R_HAT_MAX:
        out.append(f"R-hat of {worst[0]} is {worst[1]:.3f} (> {R_HAT_MAX}): {unmixed}; "
                   f"the estimates and intervals are not trustworthy (run longer: {more})")
    low = _worst(stats.get("ess_bulk"), feature_names, min, stuck)
    need = ESS_PER_CHAIN_MIN * chains
    if low is not None and low[1] < need:
        why = f" ({ESS_PER_CHAIN_MIN} per chain × {chains} chains)" if chains > 1 else ""
        out.append(f"bulk ESS of {low[0]} is {_count(low[1])}, below {need}{why}: "
                   f"posterior means and intervals are noisy (run longer: {more})")
    return out


def nuts_warnings(diag: dict[str, Any], feature_names, stuck=None) -> list[str]:
    """Warnings of a NUTS run: chains that did not move (``stuck``, :func:`stuck_parameters`), R-hat,
    ESS, divergences, and R-hat that one chain cannot give."""
    more = "--chains 2 or more, --samples" if diag["chains"] < 2 else "--warmup, --samples"
    out = stuck_warnings(stuck or {}, chains=diag["chains"], feature_names=feature_names,
                         draws="draw after warm-up", remedy="run a longer --warmup or another --seed")
    out += sampling_warnings(diag, chains=diag["chains"], feature_names=feature_names, more=more, stuck=stuck)
    if diag["divergences"]:
        n_div = diag["divergences"]
        plural = "s" if n_div != 1 else ""
        out.append(f"{n_div} divergent transition{plural} after warm-up: the sampler missed part "
                   "of the posterior (run a longer --warmup)")
    return out


def birl_warnings(diag: dict[str, Any], feature_names, stuck=None) -> list[str]:
    """Warnings of an Algorithm 1 chain: parameters it did not move (``stuck``, :func:`stuck_parameters`),
    acceptance rate, split R-hat of its halves, ESS."""
    out = stuck_warnings(stuck or {}, chains=1, feature_names=feature_names, draws="kept draw",
                         remedy="try a smaller --beta-step or --delta, or more --iterations")
    rate = diag["acceptance_rate"]
    if rate < ACCEPTANCE_MIN:
        out.append(f"acceptance rate {rate:.3f} (< {ACCEPTANCE_MIN}): the walk is stuck; "
                   "try a smaller --delta or --beta-step")
    return out + sampling_warnings(diag, chains=1, feature_names=feature_names, more="--iterations",
                                   unmixed="the two halves of the chain disagree", stuck=stuck)


def map_warnings(diag: dict[str, Any], beta: float, beta_range: tuple[float, float],
                 laplace: dict[str, Any] | None = None) -> list[str]:
    """Warnings of a MAP run: starts that disagree, β̂ within :data:`MAP_EDGE_MARGIN` of an edge of
    the prior's range, and from ``laplace`` (:func:`~.laplace.laplace_summary`) a flat ridge or a
    Hessian that is not positive definite."""
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
    interval = "" if not (laplace or {}).get("positive_definite") else (
        "; its Laplace 90% interval is [{:.3g}, {:.3g}]".format(*laplace["credible_intervals"]["beta"]))
    if beta <= lo * (1 + MAP_EDGE_MARGIN) or beta >= hi / (1 + MAP_EDGE_MARGIN):
        side = "lower" if beta <= lo * (1 + MAP_EDGE_MARGIN) else "upper"
        out.append(f"β̂ = {beta:.4g} is on the {side} edge of the prior's range [{lo:g}, {hi:g}]: the data "
                   f"ask for a β the prior excludes, so β̂ is the prior's bound, not the data's{interval}")
    if laplace is not None and not laplace["positive_definite"]:
        out.append(f"the Laplace Hessian at the MAP is not positive definite (curvature "
                   f"{laplace['min_curvature']:.3g}): the point may be a saddle or on a flat ridge; "
                   "no interval")
    elif laplace is not None and laplace.get("ridge"):
        r = laplace["ridge"]
        out.append(f"the MAP lies on a flat ridge (Laplace curvature {r['curvature']:.2g} along one "
                   "direction, "
                   f"whose 90% interval moves θ by up to {r['theta_change']:.2f} and β by a factor "
                   f"{r['beta_factor']:.3g}): many nearly equally likely points; see credible_intervals or "
                   "use --method nuts")
    return out


def map_description(r, n_starts: int, beta_range: tuple[float, float]) -> dict[str, Any]:
    """A MAP run's ``diagnostics`` (starts, optima, evaluations, the Laplace approximation's
    summary, warnings) and, where its Hessian is positive definite, its Laplace 90%
    ``credible_intervals``; ``r`` has ``starts``, ``optima``, ``evaluations``, ``beta`` and
    ``laplace`` (:func:`~.laplace.laplace_summary`)."""
    lap = r.laplace
    diag: dict[str, Any] = {
        "starts": r.starts.tolist(), "optima": r.optima.tolist(), "evaluations": r.evaluations,
        "unavailable": map_unavailable(n_starts),
        "log_posterior_coordinates": "z, log β (θ = softmax(z)): the mode of the density there",
        "intervals": "Laplace: Normal(mode, Hessian⁻¹) in (z, log β), mapped to (θ, β)",
        "laplace": {k: lap[k] for k in ("positive_definite", "edge", "sd_log_beta", "ridge", "theta_mean",
                                        "beta_mean", "min_curvature") if k in lap}}
    if not lap["positive_definite"]:
        diag["unavailable"]["credible_intervals"] = "the Laplace Hessian is not positive definite"
    diag["warnings"] = map_warnings(diag, r.beta, beta_range, lap)
    out: dict[str, Any] = {"diagnostics": diag}
    if lap["positive_definite"]:
        out["credible_intervals"] = lap["credible_intervals"]
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
