"""What a study is: its options, its inputs' digests, and ``DIR/study.json`` that records them.

:class:`StudyOptions` are the study's identity (another value on the same DIR is refused, naming
the options and the manifest lines that differ); :class:`ReportOptions` are not (a rerun with
others redraws the reports). :func:`check_options` refuses bad options before anything is read;
:func:`open_out` creates the study's folder or checks that it holds this study.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from .. import __version__, options
from ..errors import InputError
from ..models import DEFAULT_MODEL, PEDAGOGICAL
from ..options import Expertise, Share, choose
from ..results import file_digest, map_digest, write_json
from . import evidence as model_evidence
from .manifest import Manifest, StudyTask
from .report import study_columns, task_columns
from .study import DEFAULT_LAMBDAS, UserStudyConfig
from .teaching import check_teaching

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
    lambdas: str = DEFAULT_LAMBDAS  # --lambdas: the pedagogical model's λ grid (study.lambdas_spec)


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
    if opts.model == PEDAGOGICAL:  # the literal observer's set is fixed (check_teaching refuses --refine)
        return False
    if report.refine is None:
        return one and (opts.thetas, opts.betas) == DEFAULT_SET
    if report.refine and not one:
        raise InputError("--refine needs --method discrete, --share both and --expertise stationary "
                         "(it refines one (θ, β) per participant)")
    return report.refine


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


def identity(manifest: Manifest, opts: StudyOptions) -> dict[str, Any]:
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
    if opts.lambdas == DEFAULT_LAMBDAS:  # (nor without --lambdas)
        del options["lambdas"]
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


def open_out(out: Path, ident: dict[str, Any], manifest: Manifest) -> None:
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


def check_options(opts: StudyOptions, report: ReportOptions) -> bool:
    """Refuse bad options before reading anything; whether the participants' sets are refined."""
    from ..models import check_model

    check_model(opts.model, solvable=False)
    UserStudyConfig(data="{}", method=opts.method, share=opts.share)  # a bad --method/--share first
    check_expertise(opts)
    check_teaching(opts, report)
    refined = refines(opts, report)
    if report.population:
        from .population import check_population

        check_population(opts.method, opts.share)
    model_evidence.check_models(opts.models, opts.method)
    return refined


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
