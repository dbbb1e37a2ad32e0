"""Each participant's estimate from the engine's rows: the discrete posterior over their tasks
(``--share both`` or ``beta``, the held-out check, ``--expertise changing``'s curve), its
refinement from the study's set, or the continuous method's fit; ``--population``'s pooled values.

An estimate is a dict: ``result`` (the participant's :class:`~expertise_irl.result.Result`, its
settings still empty) or ``doc`` (a ``--share beta`` or continuous document), ``groups``,
``per_task`` (each task's own estimate, or None), ``task_theta`` (the θ̂ each task's costs are
taken under), ``zero_features``, ``hypotheses`` (the discrete set) and ``notes``.
"""

from __future__ import annotations

import json
import os
from dataclasses import replace
from typing import Any

import numpy as np

from ..hypotheses import GROUP_NAMES
from ..result import Result, freeze, thaw
from ..results import finite_or_null
from . import posteriors
from .identity import ReportOptions, StudyOptions, task_map_key
from .manifest import Manifest, StudyTask
from .report import posterior_modes


class _Marginals:
    """The two marginals :func:`~..inference.diagnostics.discrete_warnings` reads."""

    def __init__(self, betas, pb, thetas, pt):
        self._b, self._t = (np.asarray(betas), np.asarray(pb)), (np.asarray(thetas), np.asarray(pt))

    def marginal_beta(self):
        return self._b

    def marginal_theta(self):
        return self._t


def _constant(mine: list[StudyTask], names) -> tuple[list[int], list[str]]:
    """The features constant on every task of a participant: those that are 0 everywhere (kept at
    θ_i = 0) and a warning for each."""
    from .diagnostics import constant_feature_warning, constant_features

    found = constant_features([t.mdp for t in mine])
    zero = [i for i, v in found if v is not None and v == 0]
    return zero, [constant_feature_warning(names[i], v) for i, v in found]


def _participant(mine: list[StudyTask], hyps) -> tuple[tuple[str, ...], Any, list[int], list[str],
                                                     dict[str, int]]:
    """A participant's feature names, hypothesis set, features kept at θ_i = 0, the data's warnings and
    counts."""
    names = tuple(mine[0].mdp.feature_names)
    hyp = hyps[len(names)]
    zero, warnings = _constant(mine, names)
    if zero and not posteriors.allows_zero(hyp, zero):
        warnings.append(f"no θ of the set has θ = 0 on {', '.join(names[i] for i in zero)}, so the "
                        "study could not keep them at 0; use a --thetas whose values include 0")
        zero = []
    data = {"tasks": len(mine), "episodes": sum(t.trajectories.n_episodes for t in mine),
            "actions": sum(len(t.trajectories) for t in mine)}
    return names, hyp, zero, warnings, data


def discrete_estimates(manifest: Manifest, ells, hyps, share: str,
                       expertise: str = "stationary") -> dict[str, dict[str, Any]]:
    from ..inference.belief import DiscreteBelief
    from ..inference.diagnostics import discrete_warnings
    from ..inference.multitask import MultiTaskBelief

    out = {}
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        names, hyp, zero, warnings, data = _participant(mine, hyps)
        H = len(hyp)
        notes = list(warnings)  # the warnings of the data, before the posterior's
        task_ll = [ells[t.index].sum(axis=0) for t in mine]
        lp = posteriors.log_prior_joint(hyp, zero)
        beliefs = [DiscreteBelief(hyp, np.zeros((H, 0, 4)), lp, ll, len(t.trajectories))
                   for ll, t in zip(task_ll, mine, strict=True)]
        held = posteriors.heldout_check([ells[t.index] for t in mine],
                                        [[len(s) for s, _ in t.trajectories.episodes()] for t in mine],
                                        hyp, share, zero)
        episode_ll = [ells[t.index] for t in mine]
        curve = changing_doc(episode_ll, mine, hyp, zero) if expertise == "changing" else {}
        if share == "both":
            joint = MultiTaskBelief(tuple(beliefs)).joint()
            result = participant_result(joint, names, data, {"share": share, "heldout": held, **curve},
                                        warnings + discrete_warnings(joint, names), [names[i] for i in zero])
            out[pid] = {"result": result, "groups": joint.group_probabilities(),
                        "per_task": [{"beta_hat": b.mean_beta, "theta_hat": b.mean_theta.tolist(),
                                      "groups": b.group_probabilities()} for b in beliefs],
                        "task_theta": [list(result.theta_hat)] * len(mine),
                        "zero_features": zero, "hypotheses": hyp, "notes": notes}
        else:
            out[pid] = _shared_beta_estimate(mine, hyp, zero, task_ll, data,
                                             {"heldout": held, **curve}, warnings, notes)
    return out


def teaching_estimates(manifest: Manifest, tlls, hyps, lambdas) -> dict[str, dict[str, Any]]:
    """``--model pedagogical``: each participant's posterior over Ψ × Λ (:mod:`.teaching`, ``--share
    both``), their result's β̂ and θ̂ λ's marginal and its ``teaching`` record; ``tlls[row]`` is a row's
    ``[E, L, H]`` log-likelihoods."""
    from ..inference.diagnostics import discrete_warnings
    from .teaching import participant_posterior

    out = {}
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        names, hyp, zero, warnings, data = _participant(mine, hyps)
        notes = list(warnings)
        episode_ll = [tlls[t.index] for t in mine]
        tp, flat, prior = participant_posterior(episode_ll, hyp, zero, lambdas, data["actions"])
        held = posteriors.heldout_check(flat, [[len(s) for s, _ in t.trajectories.episodes()] for t in mine],
                                        hyp, "both", zero, log_prior=prior)
        empty = np.zeros((len(hyp), 0, mine[0].mdp.n_actions))
        joint = tp.belief(empty)
        result = participant_result(joint, names, data, {"share": "both", "heldout": held,
                                                         "teaching": tp.record(empty)},
                                    warnings + discrete_warnings(joint, names) + tp.warnings(),
                                    [names[i] for i in zero])
        per_task = []
        for e in episode_ll:
            b, _, _ = participant_posterior([e], hyp, zero, lambdas, 0)
            own = b.belief(empty)
            per_task.append({"beta_hat": own.mean_beta, "theta_hat": own.mean_theta.tolist(),
                             "groups": own.group_probabilities()})
        out[pid] = {"result": result, "groups": joint.group_probabilities(), "per_task": per_task,
                    "task_theta": [list(result.theta_hat)] * len(mine), "zero_features": zero,
                    "hypotheses": hyp, "notes": notes}
    return out


def _shared_beta_estimate(mine: list[StudyTask], hyp, zero: list[int], task_ll, data, extra: dict[str, Any],
                          warnings: list[str], notes: list[str]) -> dict[str, Any]:
    """A participant's ``--share beta`` estimate: one β and a θ per task (a document: a
    :class:`~expertise_irl.result.Result` holds one θ̂); ``extra``: the held-out check and the curve."""
    from ..inference.diagnostics import discrete_warnings
    from .summaries import beta_summary_grid

    names = tuple(mine[0].mdp.feature_names)
    sb = posteriors.shared_beta_posterior(task_ll, hyp, zero)
    doc = _shared_beta_doc(sb, names, data)
    warnings = warnings + discrete_warnings(_Marginals(hyp.betas, sb.beta_probabilities, hyp.thetas[:1],
                                                       [1.0]))
    for j, t in enumerate(mine):
        warnings += [f"task {j + 1} (line {t.line}): {w}" for w in discrete_warnings(
            _Marginals(hyp.betas[:1], [1.0], hyp.thetas, sb.theta_probabilities[j]), names)]
    groups = sb.group_probabilities()
    task_theta = sb.mean_thetas.tolist()
    per_task = [{"beta_hat": sb.mean_beta, "theta_hat": task_theta[j], "groups": groups,
                 "theta_marginal": {"values": hyp.thetas.tolist(),
                                    "probabilities": sb.theta_probabilities[j].tolist()}}
                for j in range(len(mine))]
    doc["share"] = "beta"
    doc["beta_summary"] = beta_summary_grid(*doc_beta_marginal(doc))
    doc["heldout"] = extra.pop("heldout")
    doc.update(extra)
    doc["diagnostics"] = {"warnings": warnings, "unavailable": {},
                          "kept_at_zero": [names[i] for i in zero]}
    return {"doc": doc, "groups": groups, "per_task": per_task, "task_theta": task_theta,
            "zero_features": zero, "hypotheses": hyp, "notes": notes}


def participant_result(joint, names, data, extra: dict[str, Any], warnings: list[str], kept: list[str],
                       refinement=None) -> Result:
    """A participant's joint posterior ``joint`` (one (θ, β) for their tasks) as their
    :class:`~expertise_irl.result.Result`, built by the pipeline's constructor
    (:func:`~expertise_irl.pipeline.discrete_result`), its settings empty until the reports: the
    study's entries (``extra``: ``share``, ``heldout``, ``--expertise changing``'s curve) beside the
    posterior's modes and β summary, and the diagnostics (``warnings``, the features ``kept`` at 0)."""
    from ..pipeline import discrete_result
    from .summaries import beta_summary_grid

    result = discrete_result(joint, feature_names=names, settings={}, data=data, refinement=refinement,
                             warnings=warnings, extra={"modes": posterior_modes(joint), **extra})
    m = result.posterior.marginals
    summary = beta_summary_grid(list(m.beta_values), list(m.beta_probabilities))
    result = result.with_extra(beta_summary=summary)
    return result.replace(diagnostics=replace(result.diagnostics, unavailable=freeze({}),
                                              details=freeze({"kept_at_zero": kept})))


def refine_estimates(manifest: Manifest, ells, estimates, opts: StudyOptions,
                     workers: int | None = None) -> None:
    """Each participant's joint posterior (``--share both``) over their set refined from the study's
    (:func:`..inference.adaptive.refine_tasks`, starting from the sweep's log-likelihoods): the
    estimate, modes, warnings and ``refinement`` of their result; the per-task estimates, the
    held-out check, ``--models`` and ``--population`` stay on the study's set. The participants are
    refined in ``workers`` local processes (default one per core; 1: here)."""
    jobs = {}
    for pid in manifest.participants:
        mine, est = manifest.tasks_of(pid), estimates[pid]
        maps: dict[str, Any] = {}  # one object per map: refine_tasks solves each once
        tasks = [(maps.setdefault(task_map_key(t), t.mdp), t.trajectories) for t in mine]
        known = np.sum([ells[t.index].sum(axis=0) for t in mine], axis=0)
        jobs[pid] = (tasks, est["hypotheses"], known, tuple(est["zero_features"]), opts.model)
    for pid, r in _refinements(jobs, workers).items():
        _use_refined(manifest.tasks_of(pid), estimates[pid], r)


def refine_participant(tasks, start, known, zero, model: str):
    """One participant's refinement (a worker's job: module level, plain arguments)."""
    from ..inference.adaptive import refine_tasks
    from ..planning.jax_cache import enable_jax_cache

    enable_jax_cache()
    return refine_tasks(tasks, start, start_log_likelihood=known, keep_policies=False, zero_features=zero,
                        solve_kwargs={"model": model})


def _refinements(jobs: dict[str, tuple], workers: int | None) -> dict[str, Any]:
    """``{participant: Refined}``, on a ``spawn`` pool of ``workers`` processes (here when 1)."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from ..experiments.workers import _exit_with_parent
    from .figures import cores

    n = min(workers or cores(), len(jobs))
    if n <= 1:
        return {pid: refine_participant(*job) for pid, job in jobs.items()}
    with ProcessPoolExecutor(max_workers=n, mp_context=mp.get_context("spawn"), initializer=_exit_with_parent,
                             initargs=(os.getpid(),)) as pool:
        futures = {pid: pool.submit(refine_participant, *job) for pid, job in jobs.items()}
        return {pid: f.result() for pid, f in futures.items()}


def _use_refined(mine: list[StudyTask], est: dict[str, Any], r) -> None:
    """A participant's estimate, result document and warnings from their refined set ``r``."""
    from ..inference.belief import DiscreteBelief
    from ..inference.diagnostics import discrete_warnings

    names = tuple(mine[0].mdp.feature_names)
    hyp, old = r.hypotheses, est["result"]
    log_prior = np.log(r.prior / r.prior.sum())
    joint = DiscreteBelief(hyp, np.zeros((len(hyp), 0, mine[0].mdp.n_actions)), log_prior,
                           r.log_likelihood, old.data["actions"])
    kept = {k: thaw(old.extra[k]) for k in ("share", "heldout")}
    result = participant_result(joint, names, thaw(old.data), kept,
                                r.warnings + est["notes"] + discrete_warnings(joint, names),
                                list(old.diagnostics.details["kept_at_zero"]), refinement=r.record)
    est.update(result=result, groups=joint.group_probabilities(), refined=r,
               task_theta=[list(result.theta_hat)] * len(mine))


def changing_doc(episode_ll, mine: list[StudyTask], hyp, zero) -> dict[str, Any]:
    """``--expertise changing``: the participant's episodes in task order (the manifest's rows, then
    each file's episodes) as one learning curve (:mod:`..inference.changing`), θ shared and kept at
    0 on the participant's all-zero features; ``beta_hat`` stays the one-β estimate."""
    from ..inference.changing import changing_posterior, changing_summary, expertise_by_episode, trend_summary

    cp = changing_posterior(np.concatenate(episode_ll), hyp,
                            log_prior_theta=posteriors.log_prior_theta(hyp, zero))
    curve = expertise_by_episode(cp)
    k = 0
    for t in mine:
        for label in t.trajectories.episode_ids:
            curve[k].update(task=t.index, line=t.line, task_episode=int(label))
            k += 1
    return {"expertise_by_episode": curve, "changing": changing_summary(cp), "trend": trend_summary(cp)}


def doc_beta_marginal(doc) -> tuple[list[float], list[float]]:
    b = doc["marginals"]["beta"]
    return b["values"], b["probabilities"]


def _shared_beta_doc(sb, names, data) -> dict[str, Any]:
    """The result document of a ``--share beta`` discrete posterior (θ per task: in ``tasks``)."""
    from .. import __version__ as version
    from ..hypotheses import expertise_group

    hyp = sb.hypotheses
    j = int(np.nanargmax(sb.beta_probabilities)) if np.isfinite(sb.beta_probabilities).all() else 0
    return finite_or_null({
        "version": version, "method": "discrete", "feature_names": list(names),
        "beta_hat": sb.mean_beta, "theta_hat": None,
        "theta_hat_by_task": sb.mean_thetas.tolist(),
        "expertise_group": expertise_group(sb.mean_beta) if np.isfinite(sb.mean_beta) else None,
        "group_probabilities": sb.group_probabilities(),
        "map": {"beta": float(hyp.betas[j]), "probability": float(sb.beta_probabilities[j])},
        "log_evidence": sb.log_evidence,
        "marginals": {"beta": {"values": hyp.betas.tolist(),
                               "probabilities": sb.beta_probabilities.tolist()}},
        "data": data,
    })


#: Why ``--method map|nuts`` has no held-out check.
CONTINUOUS_HELDOUT = ("the held-out check needs --method discrete: there one solve gives every episode's "
                      "likelihood, while with map or nuts each held-out unit would need a fit of its own")


def continuous_estimates(manifest: Manifest, rows, share: str) -> dict[str, dict[str, Any]]:
    from ..hypotheses import expertise_group
    from .summaries import beta_summary_draws, beta_summary_point

    by = dict(zip(rows["participant"], rows["result"], strict=True))
    out = {}
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        res = json.loads(by[pid])
        _, warnings = _constant(mine, tuple(mine[0].mdp.feature_names))
        groups = None
        draws = res.get("draws")
        if draws:
            g = [expertise_group(b) for b in draws["beta"]]
            groups = {k: g.count(k) / len(g) for k in GROUP_NAMES}
            summary = beta_summary_draws(np.asarray(draws["beta"], dtype=float))
        else:
            summary = beta_summary_point(float(res["beta_hat"]))
        diag = res.setdefault("diagnostics", {})
        diag["warnings"] = list(diag.get("warnings") or []) + warnings
        res["beta_summary"] = summary
        res["share"] = share
        res["heldout"] = {"split": "none", "units": 0, "actions": 0, "log_likelihood": None,
                          "per_action": None, "unavailable": CONTINUOUS_HELDOUT}
        for row in res.get("expertise_by_episode") or []:  # --expertise changing: the manifest's names
            t = mine[row["task"]]
            row.update(task=t.index, line=t.line)
        if share == "beta":
            task_theta = [list(t) for t in res["theta_hat"]]
            res["theta_hat_by_task"], res["theta_hat"] = task_theta, None
        else:
            task_theta = [list(res["theta_hat"])] * len(mine)
        per_task = ([{"beta_hat": res["beta_hat"], "theta_hat": th, "groups": groups} for th in task_theta]
                    if share == "beta" else None)
        out[pid] = {"doc": res, "groups": groups, "per_task": per_task, "task_theta": task_theta,
                    "zero_features": [], "hypotheses": None}
    return out


def add_population(manifest: Manifest, ells, estimates, report: ReportOptions) -> dict[str, Any]:
    """``--population``: the population fit, each participant's pooled values put in their result."""
    from .population import run_population

    population = run_population(manifest, ells, estimates, report.group_by)
    for pid, values in population["participants"].items():
        est = estimates[pid]
        if "result" in est:
            est["result"] = est["result"].with_extra(population=values)
        else:
            est["doc"]["population"] = values
    return population
