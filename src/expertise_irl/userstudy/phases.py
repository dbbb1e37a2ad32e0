"""A study's engine phases: the data they read, the discrete sets they solve, running one
(resumable; failures raise :class:`StudyFailed`), ``--models``' extra inference phases and the
optimal paths' phase. The teaching model (``pedagogical``) has a sweep of its own
(``user-study-pedagogical``: every episode at every λ); its λ = 0 values serve ``maxent`` in
``--models`` when ``--model pedagogical`` is the main one, and its optimal paths and ``--betas auto``
are ``maxent``'s (a teacher plans as a doer)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .. import options
from ..errors import ExpertiseIRLError
from ..experiments import engine
from ..models import PEDAGOGICAL
from . import evidence as model_evidence
from .identity import AUTO_BETAS, StudyOptions, task_map_key
from .manifest import Manifest, StudyTask
from .study import DEFAULT_LAMBDAS, DISCRETE, OPTIMAL, TEACHING, UserStudyConfig, world_entry
from .teaching import solved_model


class StudyFailed(ExpertiseIRLError):
    """Some engine tasks failed (their messages in ``failures``: ``(task key, message)``)."""

    def __init__(self, phase: str, failures: list[tuple[str, str]]):
        self.phase, self.failures = phase, failures
        super().__init__(f"{len(failures)} {phase} task(s) failed")


def study_data(manifest: Manifest) -> dict[str, Any]:
    """The study's data for the engine: maps by key and every row's pairs."""
    maps: dict[str, Any] = {}
    tasks = []
    for t in manifest.tasks:
        key = task_map_key(t)
        if key not in maps:
            raw = t.map_path.read_bytes() if t.world is None else None
            maps[key] = world_entry(t.world, raw, t.map_path.name)
        tr = t.trajectories
        tasks.append(
            {
                "task": t.index,
                "participant": t.participant,
                "map": key,
                "episodes": tr.episode.tolist(),
                "steps": tr.step.tolist(),
                "states": tr.state.tolist(),
                "actions": tr.action.tolist(),
            }
        )
    return {"maps": maps, "tasks": tasks}


def run_phase(study, where: Path, cfg, phase: str, workers, scheduler, on_task) -> engine.RunSummary:
    summary = engine.run(
        study,
        where,
        config=cfg,
        workers=workers,
        scheduler=scheduler,
        retry_failed=True,
        on_start=(lambda total, todo: on_task(phase, total, todo, None)) if on_task else None,
        on_result=(lambda res, rows: on_task(phase, None, None, res)) if on_task else None,
    )
    if summary.failed:
        raise StudyFailed(phase, engine.status(where).failures)
    return summary


def evidence_phases(out: Path, manifest: Manifest, main_lls, cfg, hyp, estimates, opts: StudyOptions, run):
    """``--models``: the inference phase once per other model (``run``: workers, scheduler, on_task) and
    each participant's evidence per model; ``(None, [])`` without it. ``main_lls``: the main sweep's
    (:func:`episode_lls`, or :func:`teaching_lls` for ``--model pedagogical``)."""
    if not opts.models:
        return None, []
    lls, summaries = {}, []
    for m in opts.models:
        where = out / "engine" / f"inference-{m}"
        if m == opts.model:
            lls[m] = main_lls
        elif m == "maxent" and opts.model == PEDAGOGICAL:  # λ = 0 of the teaching sweep: no other solve
            lls[m] = {k: v[:, 0, :] for k, v in main_lls.items()}
        elif m == PEDAGOGICAL:
            summaries.append(run_phase(TEACHING, where, replace(cfg, model=m, lambdas=opts.lambdas),
                                       f"inference ({m})", *run))
            lls[m] = teaching_lls(engine.load(where))
        else:
            summaries.append(run_phase(DISCRETE, where, replace(cfg, model=m, lambdas=DEFAULT_LAMBDAS),
                                       f"inference ({m})", *run))
            lls[m] = episode_lls(engine.load(where))
    evidence = model_evidence.participant_evidence(manifest, lls, hyp, opts.share,
                                                   {p: e["zero_features"] for p, e in estimates.items()},
                                                   lambdas=opts.lambdas)
    return evidence, summaries


def optimal_phase(out: Path, manifest: Manifest, data, estimates, opts: StudyOptions, refined: bool, run):
    """The optimal paths' engine phase (``run``: workers, scheduler, on_task): each row's θ̂ is its
    participant's (joint) θ̂, or with --share beta the task's own. A refined θ̂ has a phase of its
    own, rounded to 9 decimals: the phase resumes by value, and a refinement's last digits may differ
    between machines."""
    for t in data["tasks"]:
        est = estimates[t["participant"]]
        j = next(i for i, x in enumerate(manifest.tasks_of(t["participant"])) if x.index == t["task"])
        theta = list(est["task_theta"][j])
        t["theta_hat"] = [round(x, 9) for x in theta] if refined else theta
        t["starts"] = [int(s) for s, _ in episode_starts(manifest.tasks[t["task"]])]
        for k in ("episodes", "steps", "states", "actions"):
            del t[k]
    cfg2 = UserStudyConfig(data=json.dumps(data, sort_keys=True), model=solved_model(opts.model),
                           method=opts.method)
    where = out / "engine" / ("optimal-refined" if refined else "optimal")
    summary = run_phase(OPTIMAL, where, cfg2, "optimal", *run)
    return summary, engine.load(where)


def hypothesis_sets(manifest: Manifest, opts: StudyOptions):
    """The discrete set for each number of features K in the study (one β grid for all) and, for
    ``--betas auto``, the grid and where it came from (:func:`.diagnostics.auto_beta_grid`, pooled
    over the study's distinct maps, each with the θ set of its K)."""
    from ..inference.methods import DiscreteOptions
    from .diagnostics import auto_beta_grid

    mdps = list({task_map_key(t): t.mdp for t in manifest.tasks}.values())
    Ks = sorted({m.n_features for m in mdps})
    if opts.betas != AUTO_BETAS:
        return {K: DiscreteOptions(thetas=opts.thetas, betas=opts.betas).hypotheses(K) for K in Ks}, None
    thetas = {K: DiscreteOptions(thetas=opts.thetas, betas=options.Preset.PAPER_REAL).hypotheses(K).thetas
              for K in Ks}
    betas, info = auto_beta_grid(mdps, thetas, model=solved_model(opts.model))
    spec = ",".join(f"{b:g}" for b in betas)
    return ({K: DiscreteOptions(thetas=opts.thetas, betas=spec).hypotheses(K) for K in Ks},
            {"betas": spec, **info})


def episode_lls(rows) -> dict[int, np.ndarray]:
    """``{manifest row: [E, H] log-likelihoods}`` of a discrete inference sweep."""
    out = {}
    for k, g in rows.groupby("task"):
        g = g.sort_values(["episode", "hypothesis"])
        E = int(g["episode"].max()) + 1
        out[int(k)] = g["log_likelihood"].to_numpy().reshape(E, -1)
    return out


def teaching_lls(rows) -> dict[int, np.ndarray]:
    """``{manifest row: [E, L, H] log-likelihoods}`` of a teaching sweep (``user-study-pedagogical``)."""
    out = {}
    L = int(rows["lambda"].max()) + 1 if len(rows) else 0
    for k, g in rows.groupby("task"):
        g = g.sort_values(["episode", "lambda", "hypothesis"])
        E = int(g["episode"].max()) + 1
        out[int(k)] = g["log_likelihood"].to_numpy().reshape(E, L, -1)
    return out


def episode_starts(task: StudyTask) -> list[tuple[int, int]]:
    """``(start state, episode label)`` of each episode of a row."""
    tr = task.trajectories
    return [(int(s[0]), int(e)) for (s, _), e in zip(tr.episodes(), tr.episode_ids, strict=True)]
