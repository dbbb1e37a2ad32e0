"""A participant's documents: their ``result.json`` (settings, tasks, counts, the misspecification
checks), their row of ``study.csv``, their rows of ``tasks.csv`` and their figure's job."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..models import PEDAGOGICAL
from ..result import Settings, freeze
from ..results import file_digest, finite_or_null, write_json
from .identity import StudyOptions, task_map_digest
from .manifest import Manifest, StudyTask
from .paths import OPTIMAL_BETA, task_counts
from .report import GROUP_COLUMNS
from .teaching import asks_teaching, teaching_columns


def _path_states(mdp, states, actions) -> np.ndarray:
    """The states a path visits, the final one (where its last move lands) included."""
    states = np.asarray(states, dtype=np.int64)
    if not len(states):
        return states
    return np.append(states, mdp.next_state[states[-1], actions[-1]])


class _TaskReport(NamedTuple):
    """One manifest row's share of the reports."""

    panel: dict[str, Any]  # its panel of the participant's figure
    row: dict[str, Any]  # its row of tasks.csv
    doc: dict[str, Any]  # its entry in the participant's result.json
    counts: dict[str, Any]  # every world's counts of the observed moves (+ Table V's on a floor plan)
    optimal_counts: dict[str, Any]  # the same of the optimal paths
    reached: int  # optimal paths that reach a goal


def _task_report(pid: str, t: StudyTask, optimal, pt: dict[str, Any] | None, theta) -> _TaskReport:
    """The counts, panel, ``tasks.csv`` row and result entry of row ``t`` (``pt``: its own estimate,
    ``theta``: the θ̂ its costs are taken under)."""
    mdp = t.mdp
    tr = t.trajectories
    counts = task_counts(t.plan, mdp, tr.state, tr.action, tr.episode, theta)
    opt = optimal[optimal["task"] == t.index]
    counts_opt = task_counts(t.plan, mdp, opt["state"].to_numpy(), opt["action"].to_numpy(),
                             opt["episode"].to_numpy(), theta)
    ok = int(opt.groupby("episode")["reached_goal"].first().sum()) if len(opt) else 0
    observed = [_path_states(mdp, s, a) for s, a in tr.episodes()]
    opt_states = [_path_states(mdp, g["state"].to_numpy(), g["action"].to_numpy())
                  for _, g in opt.groupby("episode")]
    title = f"{t.map_path.name} ({t.source.name})"
    panel = {"world": t.world, "mdp": mdp, "title": title, "observed": observed, "optimal": opt_states,
             "theta_hat": list(theta),
             "theta_marginal": pt.get("theta_marginal") if pt else None}
    ingestion = {"filled_gaps": t.filled_gaps, "snapped_samples": t.snapped_samples}
    row = {
        "participant": pid, **t.extra, "task": t.index, "line": t.line, "map": str(t.map_path),
        "recording": str(t.source) if t.kind == "recording" else "",
        "demos": str(t.source) if t.kind == "demos" else "",
        "episodes": tr.n_episodes,
        "beta_hat": pt["beta_hat"] if pt else float("nan"),
        **{f"theta_{f}": (pt["theta_hat"][i] if pt else math.nan) for i, f in enumerate(mdp.feature_names)},
        **{c: (pt["groups"][c[2:]] if pt and pt["groups"] else float("nan")) for c in GROUP_COLUMNS},
        **counts,
        **{f"optimal_{k}": v for k, v in counts_opt.items()},
        "optimal_reached_goal": ok,
        **ingestion,
    }
    doc = {
        "task": t.index, "line": t.line, "map": str(t.map_path), "map_digest": task_map_digest(t),
        t.kind: str(t.source), f"{t.kind}_digest": file_digest(t.source),
        "episodes": tr.n_episodes, "actions": len(tr),
        **({"extra": t.extra} if t.extra else {}),
        "counts": finite_or_null(counts), "optimal_counts": finite_or_null(counts_opt),
        "optimal_reached_goal": ok,
        **ingestion,
        **({"discretised": t.discretised.summary()} if t.discretised is not None else {}),
        **({"beta_hat": pt["beta_hat"], "theta_hat": pt["theta_hat"]} if pt else {}),
        **({"group_probabilities": pt["groups"]} if pt and pt["groups"] else {}),
        **({"marginals": {"theta": pt["theta_marginal"]}} if pt and pt.get("theta_marginal") else {}),
    }
    return _TaskReport(panel, row, doc, counts, counts_opt, ok)


def _settings(manifest: Manifest, pid: str, opts: StudyOptions, hyp, mine, grid,
              refined=None) -> dict[str, Any]:
    """The ``settings`` of a participant's result.json (``hyp``: their hypothesis set, discrete;
    ``refined``: the set refined from it, if it was)."""
    settings = {
        "command": "study", "manifest": str(manifest.path), "participant": pid,
        "method": opts.method, "model": opts.model, "share": opts.share, "rate": opts.rate,
        "max_dt": opts.max_dt, "fill_gaps": opts.fill_gaps, "snap": opts.snap, "optimal_beta": OPTIMAL_BETA,
        **({"models": list(opts.models)} if opts.models else {}),
        **(_teaching_settings(opts) if asks_teaching(opts) else {}),
    }
    if opts.method == "discrete":
        settings.update({"thetas": opts.thetas, "betas": opts.betas, "n_theta": hyp.n_theta,
                         "n_beta": hyp.n_beta, "n_hypotheses": len(hyp), "prior": "uniform",
                         "beta_grid": hyp.betas.tolist(),
                         "beta_grid_source": ({k: v for k, v in grid.items() if k != "betas"} if grid
                                              else f"--betas {opts.betas}"),
                         "gamma": [t.mdp.gamma for t in mine], "hypotheses": "fixed"})
    if refined is not None:  # beta_grid and its source stay: the start of the refinement
        h = refined.hypotheses
        settings.update({"hypotheses": "adaptive", "n_theta": h.n_theta, "n_beta": h.n_beta,
                         "n_hypotheses": len(h), "prior": refined.record["prior"],
                         "start": {"n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "n_hypotheses": len(hyp)}})
    return settings


def _teaching_settings(opts: StudyOptions) -> dict[str, Any]:
    """The teaching model's λ grid, its prior and the literal observer (``--model pedagogical`` or
    pedagogical in ``--models``)."""
    from ..inference.pedagogical import parse_lambdas

    return {"lambdas": parse_lambdas(opts.lambdas).tolist(),
            "lambda_prior": "P(λ = 0) = 1/2, the rest uniform over the grid's λ > 0",
            "observer": "literal: maxent over the study's set with a uniform prior, on each map"}


def _result_doc(est, opts: StudyOptions, settings, names, n_tasks: int, episodes: int, d: Path):
    """The participant's result document with ``settings``: their typed result (one (θ, β): the
    pipeline's :class:`~expertise_irl.result.Result`), the ``--share beta`` document, or the
    continuous method's result fields (draws written beside ``d/result.json``)."""
    from ..results import continuous_result, samples_path_for

    if "result" in est:
        return est["result"].replace(settings=Settings(freeze(settings))).to_json()
    if opts.method == "discrete":
        doc = est["doc"]
        doc["settings"] = settings
        return doc
    res = dict(est["doc"])
    shape = None
    if res.get("draws"):  # stored as JSON; continuous_result takes (chain, θ, β) arrays
        dr = res["draws"]
        theta = np.asarray(dr["theta"], dtype=float)
        shape = theta.shape[1:]
        res["draws"] = (np.asarray(dr["chain"]), theta.reshape(len(theta), -1), np.asarray(dr["beta"]))
    per_task = shape is not None and len(shape) == 2
    cols = [f"task{j + 1}_{f}" for j in range(shape[0]) for f in names] if per_task else names
    doc = continuous_result(res, method=opts.method, feature_names=cols, settings=settings,
                            data={"tasks": n_tasks, "episodes": episodes},
                            samples_path=samples_path_for(d / "result.json"))
    doc["feature_names"] = list(names)
    if per_task and isinstance(doc.get("samples"), dict):
        doc["samples"]["theta"] = np.asarray(doc["samples"]["theta"]).reshape(-1, *shape).tolist()
    doc["modes"] = []
    return doc


def _sum_counts(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """A participant's counts over their tasks: sums, the mean steps to goal over the episodes that
    reached one, and Table V's counts only when every task defines them."""
    out: dict[str, Any] = {}
    for k in parts[0]:
        vals = [p[k] for p in parts]
        if k == "steps_to_goal":
            n = [p["goal_reached"] for p in parts]
            out[k] = (sum(v * m for v, m in zip(vals, n, strict=True) if m) / sum(n)) if sum(n) else math.nan
        elif any(isinstance(v, float) and math.isnan(v) for v in vals):
            out[k] = math.nan
        else:
            out[k] = sum(vals)
    return out


def _joined(values: list[str]) -> str:
    """A participant's value of an extra column: the value when their rows agree, else the distinct
    values in row order joined by ``;``."""
    return ";".join(dict.fromkeys(values))


def participant_report(pdir: Path, manifest: Manifest, pid: str, est, optimal, opts: StudyOptions,
                       evidence, grid,
                       check: str = "off") -> tuple[dict[str, Any], list[dict[str, Any]], list, tuple]:
    """Write ``pdir/ID/result.json``; return the participant's ``study.csv`` row, their ``tasks.csv``
    rows, the modes of their posterior and their figure's job."""
    mine = manifest.tasks_of(pid)
    names = tuple(mine[0].mdp.feature_names)
    hyp = est["hypotheses"]
    parts = [_task_report(pid, t, optimal, est["per_task"][j] if est["per_task"] else None,
                          est["task_theta"][j])
             for j, t in enumerate(mine)]
    total = _sum_counts([p.counts for p in parts])
    total_opt = _sum_counts([p.optimal_counts for p in parts])
    reached = sum(p.reached for p in parts)
    filled, snapped = sum(t.filled_gaps for t in mine), sum(t.snapped_samples for t in mine)
    episodes = sum(t.trajectories.n_episodes for t in mine)
    settings = _settings(manifest, pid, opts, hyp, mine, grid, est.get("refined"))
    d = pdir / pid
    d.mkdir(exist_ok=True)
    doc = _result_doc(est, opts, settings, names, len(mine), episodes, d)
    doc["participant"] = pid
    extra = {c: _joined([t.extra[c] for t in mine]) for c in manifest.extra_columns}
    if extra:
        doc["extra"] = extra
    doc["tasks"] = [p.doc for p in parts]
    doc["counts"] = finite_or_null(total)
    doc["optimal_counts"] = finite_or_null(total_opt)
    doc["filled_gaps"], doc["snapped_samples"] = filled, snapped
    if evidence is not None:
        doc["model_evidence"] = finite_or_null(evidence[pid])
    _misspecification(doc, mine, opts, check, d / "result.json")
    doc = finite_or_null(doc)
    write_json(d / "result.json", doc)
    groups = est["groups"]
    theta = doc["theta_hat"]
    bs = doc["beta_summary"]
    held = doc["heldout"]
    row = {
        "participant": pid, **extra, "tasks": len(mine), "episodes": episodes,
        "beta_hat": _f(doc["beta_hat"]),
        **{f"theta_{f}": (_f(theta[i]) if theta is not None else math.nan) for i, f in enumerate(names)},
        **{c: (groups[c[2:]] if groups else math.nan) for c in GROUP_COLUMNS},
        **total,
        **{f"optimal_{k}": v for k, v in total_opt.items()},
        "optimal_reached_goal": reached, "filled_gaps": filled, "snapped_samples": snapped,
        **{f"beta_{k}": _f(bs[k]) for k in ("mean", "median", "geomean", "q05", "q95")},
        "share": opts.share,
        "heldout_split": held["split"], "heldout_actions": held["actions"],
        "heldout_log_likelihood_per_action": _f(held["per_action"]),
        "warnings": len(doc.get("diagnostics", {}).get("warnings") or []),
        "misspecification": (doc.get("diagnostics", {}).get("misspecification") or {}).get("verdict", ""),
        **changing_columns(doc),
        **(teaching_columns(doc.get("teaching")) if opts.model == PEDAGOGICAL else {}),
    }
    job = (d / f"{pid}.png", pid, [p.panel for p in parts], doc)
    return row, [p.row for p in parts], doc.get("modes", []), job


def changing_columns(doc) -> dict[str, float]:
    """``--expertise changing``'s columns of ``study.csv`` (absent otherwise)."""
    if "changing" not in doc:
        return {}
    ch, tr = doc["changing"], doc["trend"]  # map: a point estimate, no probabilities
    return {"changing_log_bf": _f(ch["log_bayes_factor"]), "p_changing": _f(ch["p_changing"]),
            "trend_p_falls": _f(tr.get("p_falls")), "trend_p_rises": _f(tr.get("p_rises")),
            "trend_log_ratio": _f(tr["log_ratio_mean"])}


def _f(x) -> float:
    return math.nan if x is None else float(x)


def _misspecification(doc: dict[str, Any], mine: list[StudyTask], opts: StudyOptions, check: str,
                      path: Path) -> None:
    """``diagnostics.misspecification`` of a participant (:mod:`..inference.misspecification`) over
    their tasks, from their posterior: the discrete set's hypotheses, the draws, or MAP's point."""
    from ..inference.misspecification import add_to_result
    from ..results import load_samples

    if check == "off":
        return
    doc["settings"]["check"] = check
    if opts.share != "both":
        doc.setdefault("diagnostics", {}).setdefault("unavailable", {})["misspecification"] = (
            "the checks simulate one θ for all tasks; --share beta has a θ per task")
        return
    if opts.model == PEDAGOGICAL:
        doc.setdefault("diagnostics", {}).setdefault("unavailable", {})["misspecification"] = (
            "the checks' replicates of a teacher need the teaching policy of each posterior draw on every "
            "state of each map, which the study's sweep does not keep (infer --model pedagogical runs them)")
        return
    if doc.get("hypotheses"):
        hs = doc["hypotheses"]
        posterior = {"theta": np.array([h["theta"] for h in hs]), "beta": np.array([h["beta"] for h in hs]),
                     "weights": np.array([h["probability"] for h in hs])}
    elif doc.get("samples") is not None:
        _, beta, theta = load_samples(doc, path)
        posterior = {"theta": theta, "beta": beta, "weights": None}
    else:
        posterior = {"theta": np.array([doc["map"]["theta"]]), "beta": np.array([doc["map"]["beta"]]),
                     "weights": None, "draws_note": "the MAP point (no posterior draws): a plug-in check"}
    from .study import participant_seed

    seed = participant_seed(str(doc.get("participant", "")))
    add_to_result(doc, [(t.mdp, t.trajectories) for t in mine], posterior, check=check, model=opts.model,
                  seed=seed)
