"""``expertise-irl study``: every participant of a user study, Tables V–VI and Figs. 10–11."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ._app import ModelOption, _say, app, err, handles_errors, prepare_solver
from .recordings import FillGapsOption, MaxDtOption, RateOption, SnapOption

#: Bundled example studies: name -> folder inside the package.
BUNDLED = {"example": "example"}


def resolve_manifest(spec: str) -> Path:
    """A manifest file, or the manifest of a bundled study (``example``)."""
    p = Path(spec)
    if p.is_file() or spec not in BUNDLED:
        return p
    from importlib import resources

    return Path(str(resources.files("expertise_irl.userstudy") / BUNDLED[spec] / "manifest.csv"))


@app.command()
@handles_errors
def study(
    manifest: Annotated[
        str,
        typer.Argument(
            metavar="MANIFEST",
            help="Manifest CSV participant,map,recording (or demos), paths relative to it; "
            "or 'example', the bundled study.",
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", help="Study directory (created, or resumed when it holds this study).")
    ],
    thetas: Annotated[
        str, typer.Option(help="Θ: a preset (paper-real, paper-sim) or component values.")
    ] = "paper-real",
    betas: Annotated[
        str, typer.Option(help="B: a preset (paper-real, paper-sim) or temperatures.")
    ] = "paper-real",
    method: Annotated[
        str,
        typer.Option(
            help="discrete (the hypothesis set; joint posterior over a participant's tasks), map or nuts "
            "(log-likelihoods of their tasks summed)."
        ),
    ] = "discrete",
    rate: RateOption = 1.0,
    max_dt: MaxDtOption = None,
    fill_gaps: FillGapsOption = False,
    snap: SnapOption = False,
    workers: Annotated[
        int | None, typer.Option(min=1, help="Local worker processes (default: one per core).")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address, e.g. tcp://HOST:8786.")
    ] = None,
    model: ModelOption = "maxent",
    models: Annotated[
        str | None,
        typer.Option(
            help="Also compare these observation models (comma-separated, --method discrete only): "
            "each participant's log evidence, Bayes factors and held-out check in DIR/models.csv; "
            "the main results still use --model."
        ),
    ] = None,
) -> None:
    """Run every participant of a study: estimates, Tables V–VI, a figure per participant.

    Writes DIR/study.csv and study.md (one row per participant, the joint posterior over
    their tasks), DIR/tasks.csv (one row per manifest row) and DIR/participants/ID/result.json
    and ID.png; with --models, DIR/models.csv too. Floor plans shared by participants are
    solved once; a second run on the same DIR resumes (docs/user-studies.md).
    """
    from ..userstudy.evidence import parse_models
    from ..userstudy.run import StudyOptions
    from ..userstudy.study import METHODS

    path = resolve_manifest(manifest)
    if method not in METHODS:
        raise InputError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    if models is not None and method != "discrete":
        raise InputError(f"--models needs --method discrete (got --method {method})")
    compared = parse_models(models) if models is not None else ()
    opts = StudyOptions(
        thetas=thetas,
        betas=betas,
        method=method,
        rate=rate,
        max_dt=max_dt,
        fill_gaps=fill_gaps,
        snap=snap,
        model=model,
        models=compared,
    )
    _print_outcome(_run(path, out, opts, workers, scheduler), out)


def _run(path: Path, out: Path, opts, workers: int | None, scheduler: str | None):
    """Run the study, reporting progress; a failed task is printed and exits with 1."""
    from ..userstudy.run import StudyFailed, run_study

    def on_task(phase, total, todo, res) -> None:
        if res is None:
            err.print(f"{phase}: {total} task(s), {total - todo} already done", highlight=False)

    prepare_solver(measure=scheduler is None)  # local workers read this machine's lane width
    try:
        outcome = run_study(path, out, opts, workers=workers, scheduler=scheduler, on_task=on_task)
    except StudyFailed as exc:
        for key, message in exc.failures:
            err.print(f"error: {exc.phase} task {key} failed: {message}", markup=False, highlight=False)
        _say(f"{len(exc.failures)} {exc.phase} task(s) failed; run the same command again to retry them")
        raise typer.Exit(1) from None
    return outcome


def _print_outcome(outcome, out: Path) -> None:
    """One line per participant (and per model comparison), then what was written."""
    names = outcome.feature_names
    for r in outcome.participants:
        theta = ", ".join(f"{r[f'theta_{f}']:.2f}" for f in names)
        _say(
            f"{r['participant']}: β̂ = {r['beta_hat']:.3g}, θ̂ = [{theta}], path length {r['path_length']} "
            f"(optimal {r['optimal_path_length']}), filled gaps {r['filled_gaps']}, "
            f"snapped samples {r['snapped_samples']}"
        )
    for pid, ev in (outcome.evidence or {}).items():
        bfs = ", ".join(f"{f['model']} {f['log_bayes_factor']:.2f}" for f in ev["models"])
        _say(f"{pid}: best model {ev['best'] or 'n/a'} (log Bayes factors vs best: {bfs})")
    wrote = "study.csv, study.md, tasks.csv" + (", models.csv" if outcome.evidence else "")
    _say(
        f"wrote {out}/{wrote} and participants/: {len(outcome.participants)} "
        f"participants; {outcome.tasks_run} engine task(s) run, {outcome.tasks_skipped} already done "
        f"({outcome.wall_time_s:.1f} s)"
    )
