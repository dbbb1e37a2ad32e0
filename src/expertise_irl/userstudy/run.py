"""``expertise-irl study``: every participant of a manifest, on the experiment engine.

Steps (each engine phase is resumable: a finished task is not run again):

1. read the manifest and every map (floor plan, zone map, bundled map or MDP archive),
   recording and demonstrations file (any problem stops here, naming the manifest line);
   with ``--betas auto`` (the default) choose the β grid from the maps' optimal values Q*
   (:func:`.diagnostics.auto_beta_grid`);
2. inference on the engine, in ``DIR/engine/inference``: for ``discrete`` one task per
   distinct map (one solve of the hypothesis set, shared by every participant on it; the
   log-likelihood of every episode; ``--model pedagogical``: at every teaching weight λ, in
   :mod:`.teaching`'s sweep), for ``map`` / ``nuts`` one task per participant;
3. each participant's posterior over their tasks (:mod:`.posteriors`: ``--share both``, one
   (θ, β), or ``--share beta``, one β and a θ per task), the held-out check, the warnings; with
   ``--models`` (discrete only), the same inference phase once per other model, in
   ``DIR/engine/inference-<model>``, and each participant's evidence per model (:mod:`.evidence`);
   when no set is named (``--share both``, stationary expertise), each participant's joint
   posterior refined from the study's set (:func:`..inference.adaptive.refine_tasks`, from the
   sweep's log-likelihoods);
4. optimal paths on the engine, in ``DIR/engine/optimal`` (``DIR/engine/optimal-refined`` for
   refined estimates): one task per map, β = 0.001 with each participant's θ̂ (their task's with
   ``--share beta``), from the start of each of their episodes;
5. the reports: ``DIR/study.csv``, ``DIR/study.md``, ``DIR/tasks.csv`` (``DIR/models.csv``
   with ``--models``), ``DIR/study.png`` and, per participant,
   ``DIR/participants/ID/result.json`` and (``--figures``) ``DIR/participants/ID/ID.png``,
   drawn in parallel; with the teaching model (``--model pedagogical`` or in ``--models``),
   ``study.md``'s verdicts, teaching or doing, one per participant (:mod:`.teaching`).

``DIR/study.json`` records what the study is (inputs with their digests, options); a
second run on the same DIR with the same inputs and options resumes, anything else is
refused (:mod:`.identity`). The report options (``--figures``, ``--group-by``, ``--check``,
``--refine``) are not part of it: a rerun with others redraws the reports from the finished engine
phases.

The steps live in :mod:`.identity` (what a study is), :mod:`.phases` (the engine phases),
:mod:`.estimates` (each participant's posterior) and :mod:`.documents` (each participant's
result, rows and figure); this module runs them and writes the study's reports.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..atomic import write_atomic
from ..experiments import engine
from ..inference.pedagogical import parse_lambdas
from ..models import PEDAGOGICAL
from ..results import finite_or_null, write_json
from . import evidence as model_evidence
from .documents import changing_columns, participant_report
from .estimates import (
    CONTINUOUS_HELDOUT,
    add_population,
    changing_doc,
    continuous_estimates,
    discrete_estimates,
    doc_beta_marginal,
    refine_estimates,
    refine_participant,
    teaching_estimates,
)
from .identity import (
    AUTO_BETAS,
    DEFAULT_SET,
    LAYOUT,
    STUDY_FILE,
    ReportOptions,
    StudyOptions,
    check_expertise,
    check_extra_columns,
    check_options,
    identity,
    map_key,
    open_out,
    refines,
    task_map_digest,
    task_map_key,
)
from .manifest import Manifest, read_manifest
from .phases import (
    StudyFailed,
    episode_lls,
    evidence_phases,
    hypothesis_sets,
    optimal_phase,
    run_phase,
    study_data,
    teaching_lls,
)
from .report import (
    CHANGING_COLUMNS,
    changing_markdown,
    misspecification_markdown,
    study_columns,
    study_markdown,
    task_columns,
    write_csv,
)
from .study import CONTINUOUS, DEFAULT_LAMBDAS, DISCRETE, TEACHING, UserStudyConfig
from .teaching import TEACHING_COLUMNS, teaching_markdown

__all__ = [
    "AUTO_BETAS", "CONTINUOUS_HELDOUT", "DEFAULT_SET", "LAYOUT", "STUDY_FILE", "ReportOptions",
    "StudyFailed", "StudyOptions", "StudyOutcome", "changing_columns", "changing_doc", "check_expertise",
    "check_extra_columns", "doc_beta_marginal", "map_key", "refine_participant", "refines", "run_study",
    "study_data", "task_map_digest", "task_map_key",
]


@dataclass
class StudyOutcome:
    out: Path
    participants: list[dict[str, Any]]
    tasks_run: int
    tasks_skipped: int
    wall_time_s: float
    feature_names: tuple[str, ...]
    evidence: dict[str, dict[str, Any]] | None = None  # --models: per participant
    # seconds: setup (inputs, β grid), inference (engine phases), reports, figures
    timing: dict[str, float] | None = None
    population: dict[str, Any] | None = None  # --population: population.json
    # the pedagogical model (--model or --models): each participant's teaching record (None: none fits)
    teaching: dict[str, dict[str, Any] | None] | None = None


def run_study(
    manifest_path: str | Path,
    out: str | Path,
    opts: StudyOptions = StudyOptions(),  # noqa: B008  (frozen)
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    on_task: Callable | None = None,
    report: ReportOptions = ReportOptions(),  # noqa: B008  (frozen)
    on_figure: Callable[[int, int], None] | None = None,
) -> StudyOutcome:
    """Run (or resume) the study of ``manifest_path`` into ``out`` (see the module docstring).

    ``on_figure(done, total)`` hears the figures being drawn."""
    from .figures import select_figures

    t0 = time.perf_counter()
    refined = check_options(opts, report)
    manifest = read_manifest(
        manifest_path, rate=opts.rate, max_dt=opts.max_dt, fill_gaps=opts.fill_gaps, snap=opts.snap
    )
    check_extra_columns(manifest)
    figures_for = select_figures(manifest.participants, report.figures)
    if report.group_by is not None:
        from .groups import _check_column

        _check_column([], report.group_by, list(manifest.extra_columns))
    names = manifest.feature_names
    hyp, grid = {}, None
    if opts.method == "discrete":
        hyp, grid = hypothesis_sets(manifest, opts)
    out = Path(out)
    ident = identity(manifest, opts)
    open_out(out, ident, manifest)
    data = study_data(manifest)
    cfg = UserStudyConfig(
        data=json.dumps(data, sort_keys=True),
        thetas=opts.thetas,
        betas=grid["betas"] if grid else opts.betas,
        model=opts.model,
        method=opts.method,
        share=opts.share,
        # the discrete set's curve comes from the per-episode log-likelihoods, not from the engine
        expertise="stationary" if opts.method == "discrete" else opts.expertise,
        lambdas=opts.lambdas if opts.model == PEDAGOGICAL else DEFAULT_LAMBDAS,
    )
    study = (TEACHING if opts.model == PEDAGOGICAL else DISCRETE) if opts.method == "discrete" else CONTINUOUS
    t_inf = time.perf_counter()
    s1 = run_phase(study, out / "engine" / "inference", cfg, "inference", workers, scheduler, on_task)
    rows = engine.load(out / "engine" / "inference")
    ells, estimates = _estimates(manifest, rows, study, hyp, opts, refined, workers)
    evidence, s_models = evidence_phases(out, manifest, ells, cfg, hyp, estimates, opts,
                                          (workers, scheduler, on_task))
    s2, optimal = optimal_phase(out, manifest, data, estimates, opts, refined, (workers, scheduler, on_task))
    inference_s = time.perf_counter() - t_inf
    population = add_population(manifest, ells, estimates, report) if report.population else None
    t_rep = time.perf_counter()
    participants, jobs, teaching = _reports(out, manifest, estimates, optimal, opts, hyp, names, evidence,
                                            grid, report, population)
    report_s = time.perf_counter() - t_rep
    t_fig = time.perf_counter()
    _draw(out, jobs, figures_for, participants, names, manifest, workers, scheduler, on_figure, population)
    figures_s = time.perf_counter() - t_fig
    ran = s1.ran + s2.ran + sum(s.ran for s in s_models)
    skipped = s1.skipped + s2.skipped + sum(s.skipped for s in s_models)
    return StudyOutcome(out, participants, ran, skipped, time.perf_counter() - t0, names, evidence,
                        {"setup_s": t_inf - t0, "inference_s": inference_s, "reports_s": report_s,
                         "figures_s": figures_s, "figures": len(figures_for),
                         **({"population_s": population["document"]["timing_s"]["total"]}
                            if population else {})},
                        population["document"] if population else None, teaching)


def _estimates(manifest: Manifest, rows, study, hyp, opts: StudyOptions, refined: bool, workers):
    """``(lls, estimates)``: the main sweep's per-episode log-likelihoods (:func:`.phases.episode_lls`,
    :func:`.phases.teaching_lls` for the teaching model, None for map/nuts) and each participant's
    estimate."""
    if study is TEACHING:
        ells = teaching_lls(rows)
        return ells, teaching_estimates(manifest, ells, hyp, parse_lambdas(opts.lambdas))
    if opts.method != "discrete":
        return None, continuous_estimates(manifest, rows, opts.share)
    ells = episode_lls(rows)
    estimates = discrete_estimates(manifest, ells, hyp, opts.share, opts.expertise)
    if refined:
        refine_estimates(manifest, ells, estimates, opts, workers)
    return ells, estimates


def _teaching_records(opts: StudyOptions, jobs, evidence) -> tuple[dict[str, Any] | None, str]:
    """Each participant's ``teaching`` record and where it comes from: their result's with ``--model
    pedagogical``, else the pedagogical entry of their ``model_evidence``; ``(None, "")`` without the
    teaching model."""
    if opts.model == PEDAGOGICAL:
        return {j[1]: j[3].get("teaching") for j in jobs}, "--model pedagogical (each result.json's teaching)"
    if evidence is not None and PEDAGOGICAL in opts.models:
        return ({pid: next(f for f in doc["models"] if f["model"] == PEDAGOGICAL).get("teaching")
                 for pid, doc in evidence.items()}, "--models (each result.json's model_evidence)")
    return None, ""


def _reports(out: Path, manifest: Manifest, estimates, optimal, opts: StudyOptions, hyps, names,
             evidence, grid, report: ReportOptions,
             population: dict[str, Any] | None = None) -> tuple[list[dict[str, Any]], list[tuple], Any]:
    """Every participant's result, then ``study.csv``, ``tasks.csv``, ``study.md`` (and ``models.csv``);
    returns the ``study.csv`` rows, the figures' jobs and the teaching records (:func:`_teaching_records`)."""
    pdir = out / "participants"
    pdir.mkdir(exist_ok=True)
    study_rows, task_rows, modes, warnings, jobs = [], [], {}, {}, []
    for pid in manifest.participants:
        row, rows, modes[pid], job = participant_report(pdir, manifest, pid, estimates[pid], optimal, opts,
                                                         evidence, grid, report.check)
        warnings[pid] = job[3].get("diagnostics", {}).get("warnings") or []
        if population is not None:
            row.update(population["participants"][pid])
        study_rows.append(row)
        task_rows += rows
        jobs.append(job)
    feats = list(names)
    extra = list(manifest.extra_columns)
    pop_columns = []
    if population is not None:
        from .population import population_columns

        pop_columns = population_columns(feats)
    write_csv(out / "study.csv", study_rows, study_columns(feats, extra=extra)
              + (list(CHANGING_COLUMNS) if opts.expertise == "changing" else [])
              + (list(TEACHING_COLUMNS) if opts.model == PEDAGOGICAL else []) + pop_columns)
    write_csv(out / "tasks.csv", task_rows, task_columns(feats, extra=extra))
    any_hyp = next(iter(hyps.values()), None)
    sections = misspecification_markdown(study_rows, report.check, opts.share)
    if opts.expertise == "changing":
        sections += changing_markdown(study_rows)
    if population is not None:
        from .population import population_markdown

        write_json(out / "population.json", finite_or_null(population["document"]))
        sections += population_markdown(population["document"], feats)
    if report.group_by is not None:
        from .groups import group_markdown

        sections += group_markdown(study_rows, report.group_by, columns=extra)
    n_hyp = " / ".join(str(len(h)) for h in hyps.values()) or None
    if n_hyp and any(e.get("refined") for e in estimates.values()):
        n_hyp = f"a set refined for each participant (adaptive) from {n_hyp}"
    md = study_markdown(study_rows, feats, method=opts.method, n_hypotheses=n_hyp,
                        modes=modes, title=f"Study {manifest.path.name}", share=opts.share,
                        warnings=warnings, grid=grid, betas=any_hyp.betas.tolist() if any_hyp else None,
                        heldout_unavailable={j[1]: j[3]["heldout"].get("unavailable") for j in jobs},
                        sections=sections)
    if evidence is not None:
        write_csv(out / "models.csv", model_evidence.models_rows(evidence),
                  model_evidence.models_columns(opts.models))
        md += model_evidence.evidence_markdown(evidence, opts.models, opts.model)
    teaching, where = _teaching_records(opts, jobs, evidence)
    if teaching is not None:
        md += "\n" + teaching_markdown(teaching, where)
    write_atomic(out / "study.md", md)
    return study_rows, jobs, teaching


def _draw(out: Path, jobs, chosen: list[str], rows, names, manifest: Manifest, workers, scheduler,
          on_figure, population=None) -> None:
    """The participants' figures chosen by ``--figures`` (in parallel), the study's figure and
    (``--population``) the population's."""
    from ..plots.study_overview import render_study_png
    from .figures import draw_figures

    pick = set(chosen)
    todo = [j for j in jobs if j[1] in pick]
    if todo:
        draw_figures(todo, workers=workers, scheduler=scheduler, on_progress=on_figure)
    render_study_png(out / "study.png", rows, list(names), title=f"Study {manifest.path.name}")
    if population is not None:
        from ..plots.population import render_population_png

        render_population_png(out / "population.png", population, list(names),
                              title=f"Population of {manifest.path.name}")
