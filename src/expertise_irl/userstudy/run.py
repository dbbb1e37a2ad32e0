"""``expertise-irl study``: every participant of a manifest, on the experiment engine.

Steps (each engine phase is resumable: a finished task is not run again):

1. read the manifest and every floor plan, recording and demonstrations file (any problem
   stops here, naming the manifest line);
2. inference on the engine, in ``DIR/engine/inference``: for ``discrete`` one task per
   distinct floor plan (one solve of the hypothesis set, shared by every participant on it),
   for ``map`` / ``nuts`` one task per participant (all their tasks' log-likelihoods summed);
3. the joint posterior of each participant (the product over their tasks); with
   ``--models`` (discrete only), the same inference phase once per other model, in
   ``DIR/engine/inference-<model>``, and each participant's evidence per model
   (:mod:`.evidence`);
4. optimal paths on the engine, in ``DIR/engine/optimal``: one task per floor plan, β = 0.001
   with each participant's θ̂, from the start of each of their episodes;
5. the reports: ``DIR/study.csv``, ``DIR/study.md``, ``DIR/tasks.csv`` (``DIR/models.csv``
   with ``--models``) and, per participant,
   ``DIR/participants/ID/result.json`` and ``DIR/participants/ID/ID.png``.

``DIR/study.json`` records what the study is (inputs with their digests, options); a
second run on the same DIR with the same inputs and options resumes, anything else is
refused.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .. import __version__
from ..errors import InputError
from ..experiments import engine
from ..hypotheses import GROUP_NAMES
from ..results import file_digest, finite_or_null, map_digest, write_json
from . import evidence as model_evidence
from .manifest import Manifest, StudyTask, read_manifest
from .paths import COUNTS, OPTIMAL_BETA, path_counts
from .report import (
    GROUP_COLUMNS,
    posterior_modes,
    study_columns,
    study_markdown,
    task_columns,
    write_csv,
)
from .study import CONTINUOUS, DISCRETE, OPTIMAL, UserStudyConfig

STUDY_FILE = "study.json"
LAYOUT = 1


@dataclass(frozen=True)
class StudyOptions:
    thetas: str = "paper-real"
    betas: str = "paper-real"
    method: str = "discrete"
    rate: float = 1.0
    max_dt: float | None = None
    fill_gaps: bool = False
    snap: bool = False
    model: str = "maxent"
    models: tuple[str, ...] = ()  # --models: observation models to compare (discrete only)


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


def map_key(plan) -> str:
    return "map-" + map_digest(plan).split(":", 1)[1][:16]


def _plan_entry(plan) -> dict[str, Any]:
    return {
        "text": plan.to_text(),
        "name": Path(plan.name).name,
        "cell_size": plan.cell_size,
        "goal_bonus": plan.goal_bonus,
        "gamma": plan.gamma,
        "y_up": plan.y_up,
        "goal_reward_mode": plan.goal_reward_mode,
    }


def study_data(manifest: Manifest) -> dict[str, Any]:
    """The study's data for the engine: floor plans by key and every row's pairs."""
    maps: dict[str, Any] = {}
    tasks = []
    for t in manifest.tasks:
        key = map_key(t.plan)
        maps.setdefault(key, _plan_entry(t.plan))
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
        files[str(t.map_path)] = map_digest(t.plan)
    options = asdict(opts)
    if not opts.models:  # a study without --models keeps the identity it had before the option
        del options["models"]
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
        for kind, p in ((t.kind, t.source), ("floor plan", t.map_path)):
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
) -> StudyOutcome:
    """Run (or resume) the study of ``manifest_path`` into ``out`` (see the module docstring)."""
    from ..inference.methods import DiscreteOptions
    from ..models import check_model

    t0 = time.perf_counter()
    check_model(opts.model, "--model")
    cfg_probe = UserStudyConfig(data="{}", method=opts.method)  # a bad --method is reported first
    del cfg_probe
    model_evidence.check_models(opts.models, opts.method)
    manifest = read_manifest(
        manifest_path, rate=opts.rate, max_dt=opts.max_dt, fill_gaps=opts.fill_gaps, snap=opts.snap
    )
    names = tuple(manifest.tasks[0].plan.to_mdp().feature_names)
    hyp = None
    if opts.method == "discrete":
        hyp = DiscreteOptions(thetas=opts.thetas, betas=opts.betas).hypotheses(len(names))
    out = Path(out)
    ident = _identity(manifest, opts)
    _open_out(out, ident, manifest)
    data = study_data(manifest)
    if opts.models:  # the held-out split rides on the inference phase as extra rows
        data["tasks"] += model_evidence.split_rows(data["tasks"])
    cfg = UserStudyConfig(
        data=json.dumps(data, sort_keys=True),
        thetas=opts.thetas,
        betas=opts.betas,
        model=opts.model,
        method=opts.method,
    )
    study = DISCRETE if opts.method == "discrete" else CONTINUOUS
    s1 = _run_phase(study, out / "engine" / "inference", cfg, "inference", workers, scheduler, on_task)
    rows = engine.load(out / "engine" / "inference")
    estimates = (
        _discrete_estimates(manifest, rows, hyp)
        if opts.method == "discrete"
        else _continuous_estimates(manifest, rows)
    )
    evidence, s_models = None, []
    if opts.models:
        lls = {}
        for m in opts.models:
            where = out / "engine" / ("inference" if m == opts.model else f"inference-{m}")
            if m != opts.model:
                s_models.append(_run_phase(DISCRETE, where, replace(cfg, model=m), f"inference ({m})",
                                           workers, scheduler, on_task))
            lls[m] = _log_likelihoods(rows if m == opts.model else engine.load(where))
        evidence = model_evidence.participant_evidence(data["tasks"], lls, hyp)
        data["tasks"] = [t for t in data["tasks"] if "part" not in t]
    # Optimal paths: each row's θ̂ is its participant's (joint) θ̂.
    for t in data["tasks"]:
        t["theta_hat"] = list(estimates[t["participant"]]["doc"]["theta_hat"])
        t["starts"] = [int(s) for s, _ in _starts(manifest.tasks[t["task"]])]
        for k in ("episodes", "steps", "states", "actions"):
            del t[k]
    cfg2 = UserStudyConfig(data=json.dumps(data, sort_keys=True), model=opts.model, method=opts.method)
    s2 = _run_phase(OPTIMAL, out / "engine" / "optimal", cfg2, "optimal", workers, scheduler, on_task)
    optimal = engine.load(out / "engine" / "optimal")
    participants = _reports(out, manifest, estimates, optimal, opts, hyp, names, evidence)
    ran = s1.ran + s2.ran + sum(s.ran for s in s_models)
    skipped = s1.skipped + s2.skipped + sum(s.skipped for s in s_models)
    return StudyOutcome(out, participants, ran, skipped, time.perf_counter() - t0, names, evidence)


def _log_likelihoods(rows) -> dict[int, np.ndarray]:
    """``{engine row: [H] log-likelihoods}`` of a discrete inference sweep."""
    return {int(k): g.sort_values("hypothesis")["log_likelihood"].to_numpy() for k, g in rows.groupby("task")}


def _starts(task: StudyTask) -> list[tuple[int, int]]:
    """``(start state, episode label)`` of each episode of a row."""
    tr = task.trajectories
    return [(int(s[0]), int(e)) for (s, _), e in zip(tr.episodes(), tr.episode_ids, strict=True)]


# ------------------------------------------------------------------------ estimates
def _discrete_estimates(manifest: Manifest, rows, hyp) -> dict[str, dict[str, Any]]:
    from ..inference.belief import DiscreteBelief
    from ..inference.multitask import MultiTaskBelief
    from ..results import discrete_result

    H = len(hyp)
    ll = _log_likelihoods(rows)
    log_prior = np.full(H, -np.log(H))
    out = {}
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        beliefs = [
            DiscreteBelief(hyp, np.zeros((H, 0, 4)), log_prior, ll[t.index], len(t.trajectories))
            for t in mine
        ]
        joint = MultiTaskBelief(tuple(beliefs)).joint()
        names = mine[0].plan.to_mdp().feature_names
        doc = discrete_result(
            joint,
            feature_names=names,
            settings={},
            data={
                "tasks": len(mine),
                "episodes": sum(t.trajectories.n_episodes for t in mine),
                "actions": joint.n_observed,
            },
        )
        doc["modes"] = posterior_modes(joint)
        out[pid] = {
            "doc": doc,
            "groups": joint.group_probabilities(),
            "per_task": [
                {
                    "beta_hat": b.mean_beta,
                    "theta_hat": b.mean_theta.tolist(),
                    "groups": b.group_probabilities(),
                }
                for b in beliefs
            ],
        }
    return out


def _continuous_estimates(manifest: Manifest, rows) -> dict[str, dict[str, Any]]:
    from ..hypotheses import expertise_group

    by = dict(zip(rows["participant"], rows["result"], strict=True))
    out = {}
    for pid in manifest.participants:
        res = json.loads(by[pid])
        groups = None
        draws = res.get("draws")
        if draws:
            g = [expertise_group(b) for b in draws["beta"]]
            groups = {k: g.count(k) / len(g) for k in GROUP_NAMES}
        out[pid] = {"doc": res, "groups": groups, "per_task": None}
    return out


# -------------------------------------------------------------------------- reports
def _cells_of(plan, mdp, states, actions) -> np.ndarray:
    s = np.append(states, mdp.next_state[states[-1], actions[-1]]) if len(states) else states
    return plan.state_cells()[s]


class _TaskReport(NamedTuple):
    """One manifest row's share of the reports."""

    panel: dict[str, Any]  # its panel of the participant's figure
    row: dict[str, Any]  # its row of tasks.csv
    doc: dict[str, Any]  # its entry in the participant's result.json
    counts: dict[str, int]  # Table V counts of the observed moves
    optimal_counts: dict[str, int]  # the same of the optimal paths
    reached: int  # optimal paths that reach a goal


def _task_report(pid: str, t: StudyTask, optimal, pt: dict[str, Any] | None, feats) -> _TaskReport:
    """The counts, panel, ``tasks.csv`` row and result entry of row ``t`` (``pt``: its own estimate)."""
    mdp = t.plan.to_mdp()
    tr = t.trajectories
    counts = path_counts(t.plan, mdp, tr.state, tr.action)
    opt = optimal[optimal["task"] == t.index]
    counts_opt = path_counts(t.plan, mdp, opt["state"].to_numpy(), opt["action"].to_numpy())
    ok = int(opt.groupby("episode")["reached_goal"].first().sum()) if len(opt) else 0
    observed = [_cells_of(t.plan, mdp, s, a) for s, a in tr.episodes()]
    opt_cells = [_cells_of(t.plan, mdp, g["state"].to_numpy(), g["action"].to_numpy())
                 for _, g in opt.groupby("episode")]
    title = f"{Path(t.map_path).name} ({t.source.name})"
    panel = {"plan": t.plan, "title": title, "observed": observed, "optimal": opt_cells}
    ingestion = {"filled_gaps": t.filled_gaps, "snapped_samples": t.snapped_samples}
    row = {
        "participant": pid, "task": t.index, "line": t.line, "map": str(t.map_path),
        "recording": str(t.source) if t.kind == "recording" else "",
        "demos": str(t.source) if t.kind == "demos" else "",
        "episodes": tr.n_episodes,
        "beta_hat": pt["beta_hat"] if pt else float("nan"),
        **{f"theta_{f}": (pt["theta_hat"][i] if pt else float("nan")) for i, f in enumerate(feats)},
        **{c: (pt["groups"][c[2:]] if pt else float("nan")) for c in GROUP_COLUMNS},
        **counts,
        **{f"optimal_{k}": v for k, v in counts_opt.items()},
        "optimal_reached_goal": ok,
        **ingestion,
    }
    doc = {
        "task": t.index, "line": t.line, "map": str(t.map_path), "map_digest": map_digest(t.plan),
        t.kind: str(t.source), f"{t.kind}_digest": file_digest(t.source),
        "episodes": tr.n_episodes, "actions": len(tr),
        "counts": counts, "optimal_counts": counts_opt, "optimal_reached_goal": ok,
        **ingestion,
        **({"discretised": t.discretised.summary()} if t.discretised is not None else {}),
        **({"beta_hat": pt["beta_hat"], "theta_hat": pt["theta_hat"], "group_probabilities": pt["groups"]}
           if pt else {}),
    }
    return _TaskReport(panel, row, doc, counts, counts_opt, ok)


def _settings(manifest: Manifest, pid: str, opts: StudyOptions, hyp, mine) -> dict[str, Any]:
    """The ``settings`` of a participant's result.json."""
    settings = {
        "command": "study", "manifest": str(manifest.path), "participant": pid,
        "method": opts.method, "model": opts.model, "rate": opts.rate, "max_dt": opts.max_dt,
        "fill_gaps": opts.fill_gaps, "snap": opts.snap, "optimal_beta": OPTIMAL_BETA,
        **({"models": list(opts.models)} if opts.models else {}),
    }
    if opts.method == "discrete":
        settings.update({"thetas": opts.thetas, "betas": opts.betas, "n_theta": hyp.n_theta,
                         "n_beta": hyp.n_beta, "n_hypotheses": len(hyp), "prior": "uniform",
                         "gamma": [t.plan.gamma for t in mine]})
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
    if res.get("draws"):  # stored as JSON; continuous_result takes (chain, θ, β) arrays
        dr = res["draws"]
        res["draws"] = (np.asarray(dr["chain"]), np.asarray(dr["theta"]), np.asarray(dr["beta"]))
    doc = continuous_result(res, method=opts.method, feature_names=names, settings=settings,
                            data={"tasks": n_tasks, "episodes": episodes},
                            samples_path=samples_path_for(d / "result.json"))
    doc["modes"] = []
    return doc


def _participant_report(pdir: Path, manifest: Manifest, pid: str, est, optimal, opts: StudyOptions, hyp,
                        names, evidence) -> tuple[dict[str, Any], list[dict[str, Any]], list]:
    """Write ``pdir/ID/result.json`` and ``pdir/ID/ID.png``; return the participant's ``study.csv``
    row, their ``tasks.csv`` rows and the modes of their posterior."""
    from ..plots.userstudy import render_participant_png

    feats = list(names)
    mine = manifest.tasks_of(pid)
    parts = [_task_report(pid, t, optimal, est["per_task"][j] if est["per_task"] else None, feats)
             for j, t in enumerate(mine)]
    total = {k: sum(p.counts[k] for p in parts) for k in COUNTS}
    total_opt = {k: sum(p.optimal_counts[k] for p in parts) for k in COUNTS}
    reached = sum(p.reached for p in parts)
    filled, snapped = sum(t.filled_gaps for t in mine), sum(t.snapped_samples for t in mine)
    episodes = sum(t.trajectories.n_episodes for t in mine)
    settings = _settings(manifest, pid, opts, hyp, mine)
    d = pdir / pid
    d.mkdir(exist_ok=True)
    doc = _result_doc(est, opts, settings, names, len(mine), episodes, d)
    doc["participant"] = pid
    doc["tasks"] = [p.doc for p in parts]
    doc["counts"] = total
    doc["optimal_counts"] = total_opt
    doc["filled_gaps"], doc["snapped_samples"] = filled, snapped
    if evidence is not None:
        doc["model_evidence"] = finite_or_null(evidence[pid])
    write_json(d / "result.json", doc)
    render_participant_png(d / f"{pid}.png", pid, [p.panel for p in parts], doc)
    groups = est["groups"]
    row = {
        "participant": pid, "tasks": len(mine), "episodes": episodes,
        "beta_hat": float(doc["beta_hat"]),
        **{f"theta_{f}": float(doc["theta_hat"][i]) for i, f in enumerate(feats)},
        **{c: (groups[c[2:]] if groups else float("nan")) for c in GROUP_COLUMNS},
        **total,
        **{f"optimal_{k}": v for k, v in total_opt.items()},
        "optimal_reached_goal": reached, "filled_gaps": filled, "snapped_samples": snapped,
    }
    return row, [p.row for p in parts], doc.get("modes", [])


def _reports(out: Path, manifest: Manifest, estimates, optimal, opts: StudyOptions, hyp, names,
             evidence=None) -> list[dict[str, Any]]:
    """Every participant's files, then ``study.csv``, ``tasks.csv``, ``study.md`` (and ``models.csv``)."""
    pdir = out / "participants"
    pdir.mkdir(exist_ok=True)
    study_rows, task_rows, modes = [], [], {}
    for pid in manifest.participants:
        row, rows, modes[pid] = _participant_report(pdir, manifest, pid, estimates[pid], optimal, opts, hyp,
                                                    names, evidence)
        study_rows.append(row)
        task_rows += rows
    feats = list(names)
    write_csv(out / "study.csv", study_rows, study_columns(feats))
    write_csv(out / "tasks.csv", task_rows, task_columns(feats))
    md = study_markdown(study_rows, feats, method=opts.method, n_hypotheses=len(hyp) if hyp else None,
                        modes=modes, title=f"Study {manifest.path.name}")
    if evidence is not None:
        write_csv(out / "models.csv", model_evidence.models_rows(evidence),
                  model_evidence.models_columns(opts.models))
        md += model_evidence.evidence_markdown(evidence, opts.models, opts.model)
    (out / "study.md").write_text(md, encoding="utf-8")
    return study_rows
