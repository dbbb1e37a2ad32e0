"""``expertise-irl study --population``: the study's participants as one population.

The model is :mod:`expertise_irl.inference.population` (each participant's (θ, β) on the study's
grid, drawn from a population: log β ~ Normal(μ_g, σ_g²) on the grid's cells per group g, θ ~
Dirichlet(α·m) at the set's points), fitted to the per-participant grid log-likelihoods the
study's shared solves already gave (:func:`run_population`): NUTS over the hyperparameters with
every participant marginalised exactly, type-II ML beside it, each participant's shrunk
posterior (averaged over the hyperparameter draws) and the held-out comparison. What it writes:

- ``population.json`` (:func:`population_document`): the hyperparameters' posterior (mean, median,
  90% interval, R-hat, bulk ESS), type-II ML's ψ̂, the population of β per group, the population
  mean of θ, how much the participants were pulled in (``shrinkage``), group comparisons
  (``--group-by``: P(μ_A < μ_B) and μ_A − μ_B), and ``heldout_nats_per_action`` =
  ``{population, independent, pooled, split}`` with the per-participant values;
- in ``study.csv`` (:func:`population_columns`): ``beta_hat_pooled``, ``beta_q05_pooled``,
  ``beta_q95_pooled``, ``theta_<feature>_pooled``, and ``heldout_population``,
  ``heldout_independent``, ``heldout_pooled`` (nats per action; empty without a held-out split);
- in each ``result.json``: ``population`` with the same values;
- ``population.png`` (:func:`expertise_irl.plots.population.render_population_png`);
- a section of ``study.md`` (:func:`population_markdown`).

The held-out split is the study's (:func:`.posteriors.heldout_units`: leave-one-episode-out, else
leave-one-task-out); the population's prediction for participant i uses type-II ML on the
other participants, so no participant's own data informs their prior.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from itertools import combinations
from typing import Any

import numpy as np

from ..errors import InputError
from . import posteriors
from .groups import group_name

#: NUTS over the hyperparameters: chains, warm-up and draws per chain, and its seed (a 100-person
#: study's smallest bulk ESS was ~500 of the 1,200 draws), and the draws the pooled posteriors
#: average over (every k-th, at most this many).
CHAINS, WARMUP, SAMPLES, SEED = 4, 300, 300, 0
SHRINK_DRAWS = 400


def population_columns(feature_names: Sequence[str]) -> list[str]:
    """The columns ``--population`` adds to ``study.csv``."""
    return ["beta_hat_pooled", "beta_q05_pooled", "beta_q95_pooled",
            *(f"theta_{f}_pooled" for f in feature_names),
            "heldout_population", "heldout_independent", "heldout_pooled"]


def check_population(method: str, share: str) -> None:
    """``--population`` needs the discrete set and one (θ, β) per participant."""
    if method != "discrete":
        raise InputError(f"--population needs --method discrete (got --method {method}): the population "
                         "is fitted to each participant's likelihood over the discrete set")
    if share != "both":
        raise InputError("--population needs --share both (one (θ, β) per participant)")


def _participant_lls(manifest, ells, estimates):
    """``(hyp, names, [H] per participant, allowed [n_theta] per participant, units per participant,
    splits)``; every participant must be on the same hypothesis set."""
    ks = {len(manifest.tasks_of(p)[0].mdp.feature_names) for p in manifest.participants}
    if len(ks) > 1:
        raise InputError(f"--population needs every participant on the same features; this study has "
                         f"maps with {' and '.join(str(k) for k in sorted(ks))} features")
    first = manifest.tasks_of(manifest.participants[0])[0]
    names = tuple(first.mdp.feature_names)
    lls, allowed, units, splits = [], [], [], []
    hyp = None
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        if tuple(mine[0].mdp.feature_names) != names:
            raise InputError(f"--population needs every participant on the same features; participant "
                             f"{pid} has {', '.join(mine[0].mdp.feature_names)}, participant "
                             f"{manifest.participants[0]} has {', '.join(names)}")
        est = estimates[pid]
        hyp = est["hypotheses"]
        episode_ll = [ells[t.index] for t in mine]
        task_ll = [e.sum(axis=0) for e in episode_ll]
        lls.append(np.sum(task_ll, axis=0))
        allowed.append(np.isfinite(posteriors.log_prior_theta(hyp, est["zero_features"])))
        split, where = posteriors.heldout_units([len(e) for e in episode_ll], "both")
        mine_units = []
        for t, e in where:
            unit = task_ll[t] if e is None else episode_ll[t][e]
            rest = [x for j, x in enumerate(task_ll) if j != t]
            if e is not None:
                rest.append(np.delete(episode_ll[t], e, axis=0).sum(axis=0))
            n = (len(mine[t].trajectories) if e is None
                 else len(list(mine[t].trajectories.episodes())[e][0]))
            mine_units.append((np.sum(rest, axis=0), unit, n))
        units.append(mine_units)
        splits.append(split)
    return hyp, names, lls, allowed, units, splits


def run_population(manifest, ells, estimates, group_by: str | None = None, *, chains: int = CHAINS,
                   warmup: int = WARMUP, samples: int = SAMPLES, seed: int = SEED) -> dict[str, Any]:
    """Fit the population to a discrete study (``ells``: ``{manifest row: [E, H]}``, ``estimates``:
    the independent estimates, for each participant's hypothesis set and kept-at-zero features).

    Returns ``{"document": population.json, "participants": {pid: {column: value}}, "data",
    "posterior", "shrunk", "independent"}`` (the last four for the figure)."""
    from ..inference import population as pop
    from ..inference.posterior import beta_quantile

    t0 = time.perf_counter()
    hyp, names, lls, allowed, units, splits = _participant_lls(manifest, ells, estimates)
    # A participant whom every hypothesis gives probability 0 has no place in the population.
    keep = [i for i, (ll, ok) in enumerate(zip(lls, allowed, strict=True))
            if np.isfinite(ll.reshape(hyp.n_theta, hyp.n_beta)[ok]).any()]
    left_out = [manifest.participants[i] for i in range(len(lls)) if i not in keep]
    if not keep:
        raise InputError("--population: every hypothesis of the set gives every participant's data "
                         "probability 0; there is no population to fit")
    lls, allowed, units, splits = ([x[i] for i in keep] for x in (lls, allowed, units, splits))
    pids = [manifest.participants[i] for i in keep]
    groups = None
    if group_by is not None:
        groups = [group_name(";".join(dict.fromkeys(t.extra[group_by] for t in manifest.tasks_of(p))))
                  for p in pids]
    data = pop.population_data(lls, hyp, allowed=allowed, groups=groups, participants=pids)
    if groups is not None:  # groups sorted by name, as --group-by lists them
        order = tuple(sorted(data.group_names))
        index = np.array([order.index(data.group_names[g]) for g in data.groups])
        data = dataclasses.replace(data, groups=index, group_names=order)
    fit = pop.type2_ml(data, n_starts=4, rng=seed)
    t_fit = time.perf_counter()
    post = pop.sample_population(data, num_warmup=warmup, num_samples=samples, num_chains=chains, seed=seed)
    t_nuts = time.perf_counter()
    draws = post.draws()
    draws = draws[::max(1, -(-len(draws) // SHRINK_DRAWS))]  # every k-th, at most SHRINK_DRAWS
    shrunk = pop.shrunk_posteriors(data, draws)
    independent = pop.independent_posteriors(data)
    held = pop.heldout_comparison(data, units, fit=fit)
    t_held = time.perf_counter()

    betas = hyp.betas
    per: dict[str, dict[str, Any]] = {}
    widths = {"independent": [], "pooled": []}
    moved = []
    for i, pid in enumerate(pids):
        pb, pt = shrunk[i].sum(axis=0), shrunk[i].sum(axis=1)
        ib = independent[i].sum(axis=0)
        row = held["per_participant"][i]
        per[pid] = {
            "beta_hat_pooled": float(pb @ betas),
            "beta_q05_pooled": float(beta_quantile(betas, pb, 0.05)),
            "beta_q95_pooled": float(beta_quantile(betas, pb, 0.95)),
            **{f"theta_{f}_pooled": float(v) for f, v in zip(names, pt @ hyp.thetas, strict=True)},
            "heldout_population": _nan_if_none(row["population"]),
            "heldout_independent": _nan_if_none(row["independent"]),
            "heldout_pooled": _nan_if_none(row["pooled"]),
        }
        for kind, p in (("independent", ib), ("pooled", pb)):
            widths[kind].append(math.log(beta_quantile(betas, p, 0.95) / beta_quantile(betas, p, 0.05)))
        moved.append(abs(math.log(float(pb @ betas)) - math.log(float(ib @ betas))))
    doc = population_document(data, fit, post, draws, held, splits, widths, moved, names, group_by)
    if left_out:
        doc["diagnostics"]["warnings"].append(
            f"left out of the population: {', '.join(left_out)} (every hypothesis of the set gives their "
            "data probability 0)")
        doc["left_out"] = left_out
        per.update({pid: dict.fromkeys(population_columns(names), math.nan) for pid in left_out})
    doc["timing_s"] = {"type2_ml": t_fit - t0, "nuts": t_nuts - t_fit,
                       "shrinkage_and_heldout": t_held - t_nuts, "total": time.perf_counter() - t0}
    return {"document": doc, "participants": per, "data": data, "posterior": post, "shrunk": shrunk,
            "independent": independent}


def _nan_if_none(x) -> float:
    """``x`` as a float, NaN for None (a held-out score that could not be computed)."""
    return math.nan if x is None else float(x)


def _stats(x: np.ndarray) -> dict[str, float]:
    x = np.asarray(x, dtype=float).reshape(-1)
    return {"mean": float(x.mean()), "median": float(np.median(x)), "q05": float(np.quantile(x, 0.05)),
            "q95": float(np.quantile(x, 0.95))}


def population_document(data, fit, post, draws, held, splits, widths, moved, names,
                        group_by) -> dict[str, Any]:
    """``population.json`` (see the module docstring)."""
    from .. import __version__ as version
    from ..inference import population as pop

    hyp = data.hypotheses
    hyper = {}
    for name, x in post.scalars().items():
        hyper[name] = {**_stats(x), "r_hat": post.r_hat[name], "ess_bulk": post.ess_bulk[name]}
    # The population mean of θ over the set: E_ψ[Σ_j P(θ_j | α, m) θ_j] (all θ's allowed).
    means = np.asarray([pop.population_theta_prior(hyp, psi) @ hyp.thetas for psi in draws])
    theta_mean = {f: _stats(means[:, c]) for c, f in enumerate(names)}
    beta_pop = {g: {"median_beta": _stats(np.exp(post.mu[..., k])),
                    "sigma_log_beta": _stats(post.sigma[..., k]),
                    "n": int(np.sum(data.groups == k))}
                for k, g in enumerate(data.group_names)}
    comparisons = []
    for a, b in combinations(range(data.n_groups), 2):
        d = (post.mu[..., a] - post.mu[..., b]).reshape(-1)
        comparisons.append({"a": data.group_names[a], "b": data.group_names[b],
                            "p_mu_a_lt_mu_b": float(np.mean(d < 0)), "mu_diff": _stats(d),
                            "beta_ratio_median": float(np.exp(np.median(d)))})
    kinds = {s: splits.count(s) for s in ("episode", "task", "none") if splits.count(s)}
    split = next(iter(kinds)) if len(kinds) == 1 else "mixed"
    tot = held["total"]
    return {
        "version": version,
        "participants": data.n,
        "group_by": group_by,
        "groups": list(data.group_names),
        "model": {
            "beta": "log β_i ~ Normal(μ_g, σ_g²), its density at the grid's cells normalised (g: the "
                    "participant's group)",
            "theta": f"θ_i ~ Dirichlet(α·m), evaluated at θ̃ = (1 − {pop.THETA_SHRINK:g})·θ + "
                     f"{pop.THETA_SHRINK:g}/K over the set's θ's (kept-at-zero features respected)",
            "hyperprior": post.hyperprior.text(),
            "fit": f"NUTS, {post.alpha.shape[0]} chains × {post.alpha.shape[1]} draws after warm-up, "
                   "participants marginalised exactly; type-II ML beside it",
            "n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "beta_grid": hyp.betas.tolist(),
        },
        "hyperparameters": hyper,
        "type2_ml": {**fit.psi.to_dict(data.group_names), "log_marginal": fit.log_marginal},
        "population_beta": beta_pop,
        "theta_population_mean": theta_mean,
        "comparisons": comparisons,
        "shrinkage": {
            "log_beta_interval_width_median": {k: float(np.median(v)) for k, v in widths.items()},
            "log_beta_interval_width_ratio_median": float(np.median(
                np.asarray(widths["pooled"]) / np.maximum(np.asarray(widths["independent"]), 1e-12))),
            "beta_hat_moved_log_median": float(np.median(moved)),
        },
        "heldout_nats_per_action": {"population": tot["population"], "independent": tot["independent"],
                                    "pooled": tot["pooled"], "split": split, "split_counts": kinds,
                                    "actions": held["actions"],
                                    "rule": posteriors.HELDOUT_RULE + "; the population's prior for a "
                                    "participant is type-II ML on the other participants"},
        "heldout_per_participant": held["per_participant"],
        "diagnostics": {"divergences": post.divergences, "warnings": list(post.warnings),
                        "chains": int(post.alpha.shape[0]), "draws_per_chain": int(post.alpha.shape[1])},
    }


def _mean_interval(s: dict[str, float], digits: int = 3) -> str:
    """A summary ``{"mean", "q05", "q95"}`` as ``mean [q05, q95]``, ``digits`` significant."""
    return f"{s['mean']:.{digits}g} [{s['q05']:.{digits}g}, {s['q95']:.{digits}g}]"


def population_markdown(doc: dict[str, Any], feature_names: Sequence[str]) -> str:
    """``study.md``'s section: what was pooled and by how much."""
    lines = ["## Population (--population)", "",
             f"Each participant's (θ, β) is taken as drawn from a population learned from all "
             f"{doc['participants']} participants: {doc['model']['beta']}; {doc['model']['theta']}. "
             f"Hyperprior: {doc['model']['hyperprior']}. {doc['model']['fit']}. Each participant's "
             "pooled estimate (`*_pooled` in study.csv) is their posterior under that population; the "
             "independent one (`beta_hat`, `theta_*`) keeps the uniform prior. Figure: population.png.", ""]
    lines += ["| group | n | population median β, exp μ [90%] | spread σ of log β [90%] |",
              "|---|---|---|---|"]
    for g, b in doc["population_beta"].items():
        lines.append(f"| {g} | {b['n']} | {_mean_interval(b['median_beta'])} | "
                     f"{_mean_interval(b['sigma_log_beta'])} |")
    lines += ["", "Population mean of θ [90%]: " + ", ".join(
        f"{f} {_mean_interval(doc['theta_population_mean'][f], 2)}" for f in feature_names)
        + f"; concentration α {_mean_interval(doc['hyperparameters']['alpha'])}.", ""]
    sh = doc["shrinkage"]
    w = sh["log_beta_interval_width_median"]
    lines += [f"**By how much:** the median participant's 90% interval of β spans a factor "
              f"{math.exp(w['independent']):.3g} alone and {math.exp(w['pooled']):.3g} pooled (median "
              f"ratio of the log widths {sh['log_beta_interval_width_ratio_median']:.2f}); the median β̂ "
              f"moved by a factor {math.exp(sh['beta_hat_moved_log_median']):.3g}.", ""]
    h = doc["heldout_nats_per_action"]
    if h["actions"]:
        lines += [f"**Held-out** ({h['split']} split, {h['actions']} actions; log-likelihood per held-out "
                  "action, higher is better): population "
                  f"{h['population']:.4f}, independent {h['independent']:.4f}, fully pooled "
                  f"{h['pooled']:.4f}. The population's prior for each participant is fitted to the "
                  "others only.", ""]
    else:
        lines += ["**Held-out:** no participant has two episodes or two tasks to hold one out.", ""]
    if doc["comparisons"]:
        lines += [f"**Groups** (--group-by {doc['group_by']}): each group its own (μ, σ), θ's population "
                  "shared.", "", "| A | B | P(μ_A < μ_B) | μ_A − μ_B [90%] | β_A/β_B (median) |",
                  "|---|---|---|---|---|"]
        for c in doc["comparisons"]:
            lines.append(f"| {c['a']} | {c['b']} | {c['p_mu_a_lt_mu_b']:.3f} | "
                         f"{_mean_interval(c['mu_diff'])} | {c['beta_ratio_median']:.3g} |")
        lines.append("")
    if doc["diagnostics"]["warnings"]:
        lines += ["Sampler warnings: " + "; ".join(doc["diagnostics"]["warnings"]) + ".", ""]
    return "\n".join(lines) + "\n"
