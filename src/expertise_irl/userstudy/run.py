"""``expertise-irl study``: every participant of a manifest, on the experiment engine.

Steps (each engine phase is resumable: a finished task is not run again):

1. read the manifest and every map (floor plan, zone map, bundled map or MDP archive),
   recording and demonstrations file (any problem stops here, naming the manifest line);
   with ``--betas auto`` (the default) choose the β grid from the maps' optimal values Q*
   (:func:`.diagnostics.auto_beta_grid`);
2. inference on the engine, in ``DIR/engine/inference``: for ``discrete`` one task per
   distinct map (one solve of the hypothesis set, shared by every participant on it; the
   log-likelihood of every episode), for ``map`` / ``nuts`` one task per participant;
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
   drawn in parallel.

``DIR/study.json`` records what the study is (inputs with their digests, options); a
second run on the same DIR with the same inputs and options resumes, anything else is
refused. The report options (``--figures``, ``--group-by``, ``--check``, ``--refine``) are not
part of it: a rerun with others redraws the reports from the finished engine phases.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .. import __version__, options
from ..atomic import write_atomic
from ..errors import InputError
from ..experiments import engine
from ..hypotheses import GROUP_NAMES
from ..models import DEFAULT_MODEL
from ..options import Expertise, Share, choose
from ..results import file_digest, finite_or_null, map_digest, write_json
from . import evidence as model_evidence
from . import posteriors
from .manifest import Manifest, StudyTask, read_manifest
from .paths import OPTIMAL_BETA, task_counts
from .report import (
    CHANGING_COLUMNS,
    GROUP_COLUMNS,
    changing_markdown,
    misspecification_markdown,
    posterior_modes,
    study_columns,
    study_markdown,
    task_columns,
    write_csv,
)
from .study import CONTINUOUS, DISCRETE, OPTIMAL, UserStudyConfig, world_entry

STUDY_FILE = "study.json"
#: 2: any map, per-episode log-likelihoods, --share, the β grid of --betas auto.
LAYOUT = 2


#: ``--betas auto``: the study's β grid from the maps' optimal values Q*
#: (:func:`.diagnostics.auto_beta_grid`).
AUTO_BETAS = options.AUTO_BETAS


@dataclass(frozen=True)
class StudyOptions:
    """What a study computes (its identity: another value on the same DIR is refused)."""

    thetas: str = options.DEFAULT_THETAS
    betas: str = AUTO_BETAS
    method: str = options.DEFAULT_METHOD
    rate: float = 1.0
    max_dt: float | None = None
    fill_gaps: bool = False
    snap: bool = False
    model: str = DEFAULT_MODEL
    models: tuple[str, ...] = ()  # --models: observation models to compare (discrete only)
    share: str = options.DEFAULT_SHARE  # --share: both (one θ, β per participant) or beta (a θ per task)
    expertise: str = options.DEFAULT_EXPERTISE  # --expertise changing: a β per episode, in task order


@dataclass(frozen=True)
class ReportOptions:
    """How a study is reported (not part of its identity: a rerun may change them)."""

    figures: str = "all"  # --figures all|none|N
    group_by: str | None = None  # --group-by COLUMN
    population: bool = False  # --population: the hierarchical model over the participants
    # --check off|fast|full: diagnostics.misspecification of each participant
    check: str = options.DEFAULT_CHECK
    # --refine/--no-refine: refine each participant's set (inference.adaptive); None: when no set is named
    refine: bool | None = None


#: The set a study solves when none is named (``--thetas`` / ``--betas``).
DEFAULT_SET = (options.DEFAULT_THETAS, AUTO_BETAS)


def refines(opts: StudyOptions, report: ReportOptions) -> bool:
    """Whether each participant's posterior is refined from the study's set: as ``--refine`` asks, else
    when no set is named and the posterior is one (θ, β) per participant (``--share both``,
    stationary expertise, the discrete method)."""
    one = opts.method == "discrete" and opts.share == "both" and opts.expertise == "stationary"
    if report.refine is None:
        return one and (opts.thetas, opts.betas) == DEFAULT_SET
    if report.refine and not one:
        raise InputError("--refine needs --method discrete, --share both and --expertise stationary "
                         "(it refines one (θ, β) per participant)")
    return report.refine


class StudyFailed(Exception):
    """Some engine tasks failed (their messages in ``failures``)."""

    def __init__(self, phase: str, failures: list[tuple[str, str]]):
        self.phase, self.failures = phase, failures
        super().__init__(f"{len(failures)} {phase} task(s) failed")


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


def map_key(world) -> str:
    """The engine's key of a map: from its content digest (a floor plan or zone map)."""
    return "map-" + map_digest(world).split(":", 1)[1][:16]


def task_map_key(t: StudyTask) -> str:
    """The engine's key of a task's map; an MDP archive's from its bytes."""
    if t.world is None:
        return "mdp-" + file_digest(t.map_path).split(":", 1)[1][:16]
    return map_key(t.world)


def task_map_digest(t: StudyTask) -> str:
    return file_digest(t.map_path) if t.world is None else map_digest(t.world)


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


def _identity(manifest: Manifest, opts: StudyOptions) -> dict[str, Any]:
    files = {"manifest": file_digest(manifest.path)}
    for t in manifest.tasks:
        files[str(t.source)] = file_digest(t.source)
        files[str(t.map_path)] = task_map_digest(t)
    options = asdict(opts)
    if not opts.models:  # a study without --models keeps the identity it had before the option
        del options["models"]
    if opts.share == "both":  # (nor does one without --share beta)
        del options["share"]
    if opts.expertise == "stationary":  # (nor without --expertise changing)
        del options["expertise"]
    ident = {"layout": LAYOUT, "options": options, "inputs": files}
    ident["hash"] = hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()
    return ident


def _flag(name: str, value: Any) -> str:
    """An option as the command line gives it: ``--model maxent``, ``--fill-gaps``, ``no --snap``."""
    flag = "--" + name.replace("_", "-")
    if isinstance(value, list | tuple):
        value = ",".join(map(str, value))
    if value is None or value is False or value == "":
        return f"no {flag}"
    return flag if value is True else f"{flag} {value:g}" if isinstance(value, float) else f"{flag} {value}"


def _changed_options(old: dict[str, Any], new: dict[str, Any]) -> list[tuple[str, str]]:
    """``(there, here)`` for each option that differs (an option missing from an older study.json
    counts as its default)."""
    out = []
    for name, default in asdict(StudyOptions()).items():
        a, b = old.get(name, default), new.get(name, default)
        if (list(a) if isinstance(a, list | tuple) else a) != (list(b) if isinstance(b, list | tuple) else b):
            out.append((_flag(name, a), _flag(name, b)))
    return out


def _rel(path: str | Path, base: Path) -> str:
    p = Path(path)
    return (p.relative_to(base) if p.is_relative_to(base) else p).as_posix()


def _relative(inputs: dict[str, str], manifest_path: str) -> dict[str, str]:
    """A study's input digests keyed by path relative to its manifest's folder (``manifest`` as is),
    so that a study started from another working directory compares equal."""
    base = Path(manifest_path).parent
    return {(k if k == "manifest" else _rel(k, base)): digest for k, digest in inputs.items()}


def _changed_inputs(old: dict[str, str], new: dict[str, str], manifest: Manifest) -> list[str]:
    """What differs between two studies' inputs (keyed by :func:`_relative`), naming manifest lines."""
    base = manifest.path.parent
    lines: dict[str, str] = {}
    for t in manifest.tasks:
        for kind, p in ((t.kind, t.source), ("map", t.map_path)):
            rel = _rel(p, base)
            lines.setdefault(rel, f"the {kind} of manifest line {t.line} ({rel})")
    out = []
    for key in sorted(set(old) | set(new), key=lambda k: (k != "manifest", k)):
        what = "the manifest" if key == "manifest" else lines.get(key, key)
        if key not in old:
            out.append(f"{what} is new")
        elif key not in new:
            out.append(f"the study read {key}, this command does not")
        elif old[key] != new[key]:
            out.append(f"{what} changed")
    return out


def _mismatch(out: Path, old: dict[str, Any], ident: dict[str, Any], manifest: Manifest) -> str | None:
    """Why the study in ``out`` (its ``study.json``: ``old``) is not this one; None when it is (the
    same options and inputs, the manifest perhaps named from another working directory)."""
    fresh = f"use another --out, or delete {out} to start again"
    if not isinstance(old.get("options"), dict) or not isinstance(old.get("inputs"), dict) \
            or old.get("layout") != ident["layout"]:
        return (f"{out}: holds a study of other inputs or options (written by expertise-irl "
                f"{old.get('version', '?')}); {fresh}")
    options = _changed_options(old["options"], ident["options"])
    inputs = _changed_inputs(_relative(old["inputs"], str(old.get("manifest", ""))),
                             _relative(ident["inputs"], str(manifest.path)), manifest)
    if not options and not inputs:
        return None
    said = "; ".join(inputs[:3]) + (f"; {len(inputs) - 3} more input(s)" if len(inputs) > 3 else "")
    if not options:
        return f"{out}: holds a study of other inputs ({said}); {fresh}"
    there, here = (", ".join(x) for x in zip(*options, strict=True))
    also = f" (and {said})" if inputs else ""
    return f"{out}: holds a study run with {there}; this command has {here}{also}; {fresh}"


def _open_out(out: Path, ident: dict[str, Any], manifest: Manifest) -> None:
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    marker = out / STUDY_FILE
    if marker.is_file():
        try:
            old = json.loads(marker.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise InputError(f"{marker}: unreadable; use another --out") from None
        if not isinstance(old, dict):
            raise InputError(f"{marker}: not a study record; use another --out")
        if old.get("hash") != ident["hash"] and (why := _mismatch(out, old, ident, manifest)):
            raise InputError(why)
        return
    if out.exists() and any(out.iterdir()):
        raise InputError(f"{out}: directory is not empty and holds no study; use another --out")
    out.mkdir(parents=True, exist_ok=True)
    write_json(
        marker,
        {
            **ident,
            "manifest": str(manifest.path),
            "version": __version__,
            "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        },
    )


def _run_phase(study, where: Path, cfg, phase: str, workers, scheduler, on_task) -> engine.RunSummary:
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


def run_study(
    manifest_path: str | Path,
    out: str | Path,
    opts: StudyOptions = StudyOptions(),
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    on_task: Callable | None = None,
    report: ReportOptions = ReportOptions(),
    on_figure: Callable[[int, int], None] | None = None,
) -> StudyOutcome:
    """Run (or resume) the study of ``manifest_path`` into ``out`` (see the module docstring).

    ``on_figure(done, total)`` hears the figures being drawn."""
    from .figures import select_figures

    t0 = time.perf_counter()
    refined = _check_options(opts, report)
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
        hyp, grid = _hypothesis_sets(manifest, opts)
    out = Path(out)
    ident = _identity(manifest, opts)
    _open_out(out, ident, manifest)
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
    )
    study = DISCRETE if opts.method == "discrete" else CONTINUOUS
    t_inf = time.perf_counter()
    s1 = _run_phase(study, out / "engine" / "inference", cfg, "inference", workers, scheduler, on_task)
    rows = engine.load(out / "engine" / "inference")
    if opts.method == "discrete":
        ells = _episode_lls(rows)
        estimates = _discrete_estimates(manifest, ells, hyp, opts.share, opts.expertise)
        if refined:
            _refine_estimates(manifest, ells, estimates, opts, workers)
    else:
        estimates = _continuous_estimates(manifest, rows, opts.share)
    evidence, s_models = _evidence_phases(out, manifest, rows, cfg, hyp, estimates, opts,
                                          (workers, scheduler, on_task))
    s2, optimal = _optimal_phase(out, manifest, data, estimates, opts, refined, (workers, scheduler, on_task))
    inference_s = time.perf_counter() - t_inf
    population = _population(manifest, ells, estimates, report) if report.population else None
    t_rep = time.perf_counter()
    participants, jobs = _reports(out, manifest, estimates, optimal, opts, hyp, names, evidence, grid, report,
                                  population)
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
                        population["document"] if population else None)


def _population(manifest: Manifest, ells, estimates, report: ReportOptions) -> dict[str, Any]:
    """``--population``: the population fit, each participant's pooled values put in their result."""
    from .population import run_population

    population = run_population(manifest, ells, estimates, report.group_by)
    for pid, values in population["participants"].items():
        estimates[pid]["doc"]["population"] = values
    return population


def _check_options(opts: StudyOptions, report: ReportOptions) -> bool:
    """Refuse bad options before reading anything; whether the participants' sets are refined."""
    from ..models import check_model

    check_model(opts.model, "--model")
    UserStudyConfig(data="{}", method=opts.method, share=opts.share)  # a bad --method/--share first
    check_expertise(opts)
    refined = refines(opts, report)
    if report.population:
        from .population import check_population

        check_population(opts.method, opts.share)
    model_evidence.check_models(opts.models, opts.method)
    return refined


def _evidence_phases(out: Path, manifest: Manifest, rows, cfg, hyp, estimates, opts: StudyOptions, run):
    """``--models``: the inference phase once per other model (``run``: workers, scheduler, on_task) and
    each participant's evidence per model; ``(None, [])`` without it."""
    if not opts.models:
        return None, []
    lls, summaries = {}, []
    for m in opts.models:
        where = out / "engine" / ("inference" if m == opts.model else f"inference-{m}")
        if m != opts.model:
            summaries.append(_run_phase(DISCRETE, where, replace(cfg, model=m), f"inference ({m})", *run))
        lls[m] = _episode_lls(rows if m == opts.model else engine.load(where))
    evidence = model_evidence.participant_evidence(manifest, lls, hyp, opts.share,
                                                   {p: e["zero_features"] for p, e in estimates.items()})
    return evidence, summaries


def _optimal_phase(out: Path, manifest: Manifest, data, estimates, opts: StudyOptions, refined: bool, run):
    """The optimal paths' engine phase (``run``: workers, scheduler, on_task): each row's θ̂ is its
    participant's (joint) θ̂, or with --share beta the task's own. A refined θ̂ has a phase of its
    own, rounded to 9 decimals: the phase resumes by value, and a refinement's last digits may differ
    between machines."""
    for t in data["tasks"]:
        est = estimates[t["participant"]]
        j = next(i for i, x in enumerate(manifest.tasks_of(t["participant"])) if x.index == t["task"])
        theta = list(est["task_theta"][j])
        t["theta_hat"] = [round(x, 9) for x in theta] if refined else theta
        t["starts"] = [int(s) for s, _ in _starts(manifest.tasks[t["task"]])]
        for k in ("episodes", "steps", "states", "actions"):
            del t[k]
    cfg2 = UserStudyConfig(data=json.dumps(data, sort_keys=True), model=opts.model, method=opts.method)
    where = out / "engine" / ("optimal-refined" if refined else "optimal")
    summary = _run_phase(OPTIMAL, where, cfg2, "optimal", *run)
    return summary, engine.load(where)


def check_expertise(opts: StudyOptions) -> None:
    """``--expertise changing`` needs one θ for all of a person's tasks."""
    choose(Expertise, opts.expertise, "expertise")
    if opts.expertise == Expertise.CHANGING and opts.share != Share.BOTH:
        raise InputError("--expertise changing needs --share both (its θ is shared by every episode)")


def check_extra_columns(manifest: Manifest) -> None:
    """An extra manifest column may not take the name of a column the study writes."""
    feats = manifest.feature_names
    taken = set(study_columns(feats)) | set(task_columns(feats))
    for c in manifest.extra_columns:
        if c in taken:
            raise InputError(f"{manifest.path}:1: column {c!r} is a column the study writes; rename it "
                             "in the manifest")


def _hypothesis_sets(manifest: Manifest, opts: StudyOptions):
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
    betas, info = auto_beta_grid(mdps, thetas, model=opts.model)
    spec = ",".join(f"{b:g}" for b in betas)
    return ({K: DiscreteOptions(thetas=opts.thetas, betas=spec).hypotheses(K) for K in Ks},
            {"betas": spec, **info})


def _episode_lls(rows) -> dict[int, np.ndarray]:
    """``{manifest row: [E, H] log-likelihoods}`` of a discrete inference sweep."""
    out = {}
    for k, g in rows.groupby("task"):
        g = g.sort_values(["episode", "hypothesis"])
        E = int(g["episode"].max()) + 1
        out[int(k)] = g["log_likelihood"].to_numpy().reshape(E, -1)
    return out


def _starts(task: StudyTask) -> list[tuple[int, int]]:
    """``(start state, episode label)`` of each episode of a row."""
    tr = task.trajectories
    return [(int(s[0]), int(e)) for (s, _), e in zip(tr.episodes(), tr.episode_ids, strict=True)]


# ------------------------------------------------------------------------ estimates
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


def _discrete_estimates(manifest: Manifest, ells, hyps, share: str,
                        expertise: str = "stationary") -> dict[str, dict[str, Any]]:
    from ..inference.belief import DiscreteBelief
    from ..inference.diagnostics import discrete_warnings
    from ..inference.multitask import MultiTaskBelief
    from ..results import discrete_result
    from .summaries import beta_summary_grid

    out = {}
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        names = tuple(mine[0].mdp.feature_names)
        hyp = hyps[len(names)]
        H = len(hyp)
        zero, warnings = _constant(mine, names)
        if zero and not posteriors.allows_zero(hyp, zero):
            warnings.append(f"no θ of the set has θ = 0 on {', '.join(names[i] for i in zero)}, so the "
                            "study could not keep them at 0; use a --thetas whose values include 0")
            zero = []
        notes = list(warnings)  # the warnings of the data, before the posterior's
        task_ll = [ells[t.index].sum(axis=0) for t in mine]
        data = {"tasks": len(mine), "episodes": sum(t.trajectories.n_episodes for t in mine),
                "actions": sum(len(t.trajectories) for t in mine)}
        lp = posteriors.log_prior_joint(hyp, zero)
        beliefs = [DiscreteBelief(hyp, np.zeros((H, 0, 4)), lp, ll, len(t.trajectories))
                   for ll, t in zip(task_ll, mine, strict=True)]
        if share == "both":
            joint = MultiTaskBelief(tuple(beliefs)).joint()
            doc = discrete_result(joint, feature_names=names, settings={}, data=data)
            doc["modes"] = posterior_modes(joint)
            warnings += discrete_warnings(joint, names)
            groups = joint.group_probabilities()
            task_theta = [list(doc["theta_hat"])] * len(mine)
            per_task = [{"beta_hat": b.mean_beta, "theta_hat": b.mean_theta.tolist(),
                         "groups": b.group_probabilities()} for b in beliefs]
        else:
            sb = posteriors.shared_beta_posterior(task_ll, hyp, zero)
            doc = _shared_beta_doc(sb, names, data)
            warnings += discrete_warnings(_Marginals(hyp.betas, sb.beta_probabilities, hyp.thetas[:1], [1.0]))
            for j, t in enumerate(mine):
                warnings += [f"task {j + 1} (line {t.line}): {w}" for w in discrete_warnings(
                    _Marginals(hyp.betas[:1], [1.0], hyp.thetas, sb.theta_probabilities[j]), names)]
            groups = sb.group_probabilities()
            task_theta = sb.mean_thetas.tolist()
            per_task = [{"beta_hat": sb.mean_beta, "theta_hat": task_theta[j], "groups": groups,
                         "theta_marginal": {"values": hyp.thetas.tolist(),
                                            "probabilities": sb.theta_probabilities[j].tolist()}}
                        for j in range(len(mine))]
        doc["share"] = share
        doc["beta_summary"] = beta_summary_grid(*doc_beta_marginal(doc))
        held = posteriors.heldout_check([ells[t.index] for t in mine],
                                        [[len(s) for s, _ in t.trajectories.episodes()] for t in mine],
                                        hyp, share, zero)
        doc["heldout"] = held
        if expertise == "changing":
            doc.update(changing_doc([ells[t.index] for t in mine], mine, hyp, zero))
        doc["diagnostics"] = {"warnings": warnings, "unavailable": {},
                              "kept_at_zero": [names[i] for i in zero]}
        out[pid] = {"doc": doc, "groups": groups, "per_task": per_task, "task_theta": task_theta,
                    "zero_features": zero, "hypotheses": hyp, "notes": notes}
    return out


def _refine_estimates(manifest: Manifest, ells, estimates, opts: StudyOptions,
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
    from ..results import discrete_result
    from .summaries import beta_summary_grid

    names = tuple(mine[0].mdp.feature_names)
    hyp, old = r.hypotheses, est["doc"]
    log_prior = np.log(r.prior / r.prior.sum())
    joint = DiscreteBelief(hyp, np.zeros((len(hyp), 0, mine[0].mdp.n_actions)), log_prior,
                           r.log_likelihood, old["data"]["actions"])
    doc = discrete_result(joint, feature_names=names, settings={}, data=old["data"])
    doc.update(modes=posterior_modes(joint), share=old["share"], heldout=old["heldout"], refinement=r.record)
    doc["beta_summary"] = beta_summary_grid(*doc_beta_marginal(doc))
    doc["diagnostics"] = {**old["diagnostics"],
                          "warnings": r.warnings + est["notes"] + discrete_warnings(joint, names)}
    est.update(doc=doc, groups=joint.group_probabilities(), refined=r,
               task_theta=[list(doc["theta_hat"])] * len(mine))


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


def _continuous_estimates(manifest: Manifest, rows, share: str) -> dict[str, dict[str, Any]]:
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


# -------------------------------------------------------------------------- reports
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


def _result_doc(est, opts: StudyOptions, settings, names, n_tasks: int, episodes: int, d: Path):
    """The participant's result document: the discrete one as it is, or the continuous method's
    result fields (draws written beside ``d/result.json``)."""
    from ..results import continuous_result, samples_path_for

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


def _participant_report(pdir: Path, manifest: Manifest, pid: str, est, optimal, opts: StudyOptions,
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


def _reports(out: Path, manifest: Manifest, estimates, optimal, opts: StudyOptions, hyps, names,
             evidence, grid, report: ReportOptions,
             population: dict[str, Any] | None = None) -> tuple[list[dict[str, Any]], list[tuple]]:
    """Every participant's result, then ``study.csv``, ``tasks.csv``, ``study.md`` (and ``models.csv``);
    returns the ``study.csv`` rows and the figures' jobs."""
    pdir = out / "participants"
    pdir.mkdir(exist_ok=True)
    study_rows, task_rows, modes, warnings, jobs = [], [], {}, {}, []
    for pid in manifest.participants:
        row, rows, modes[pid], job = _participant_report(pdir, manifest, pid, estimates[pid], optimal, opts,
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
              + (list(CHANGING_COLUMNS) if opts.expertise == "changing" else []) + pop_columns)
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
    write_atomic(out / "study.md", md)
    return study_rows, jobs


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
