"""``expertise-irl experiment run | status | list | report``: sweeps on a laptop or a Dask cluster, and
the report of a sweep (figures, tables and the paper's claims)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import QuietProgress, _say, app, err, handles_errors, prepare_solver

experiment_app = typer.Typer(
    help="Run a study's sweep (resumable, Parquet results), check on it, list the studies.",
    no_args_is_help=True,
)
app.add_typer(experiment_app, name="experiment")

#: Seconds to start the worker processes (Python, NumPy and JAX imports).
STARTUP_S = 5.0


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "unknown"
    if seconds < 90:
        return f"{seconds:.1f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


@experiment_app.command("run")
@handles_errors
def run_cmd(
    study: Annotated[str, typer.Argument(
        metavar="STUDY", help="Study name (see `expertise-irl experiment list`).")],
    out: Annotated[Path, typer.Option("--out", help="Sweep directory (created, or resumed if it holds "
                                      "the same study, scale and seed).")],
    scale: Annotated[str, typer.Option(help="smoke | small | paper.")] = "smoke",
    seed: Annotated[int, typer.Option(min=0, help="The sweep's seed (every instance's seed derives "
                                      "from it and the instance's identity).")] = 0,
    workers: Annotated[int | None, typer.Option(min=1, help="Local worker processes (default: one per "
                                                "core).")] = None,
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address, e.g. tcp://HOST:8786; "
                                                  "tasks then run on its workers.")] = None,
    retry_failed: Annotated[bool, typer.Option("--retry-failed", help="Run again the tasks that "
                                               "failed before.")] = False,
    config: Annotated[Path | None, typer.Option("--config", help="TOML file of config fields that "
                                                "replace the scale's (e.g. model = \"maxent-relative\"; "
                                                "a sweep's DIR/config.toml is one). The sweep's scale is "
                                                "then recorded as `custom`.")] = None,
) -> None:
    """Run a sweep, or resume it: finished tasks are skipped, each task's rows land in one shard."""
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeRemainingColumn

    from ..experiments.engine import run
    from ..experiments.spec import config_from_toml
    from ..experiments.studies import get_study
    from ..experiments.workers import cores

    st = get_study(study)
    cfg = st.config(scale)  # a bad scale (or config file) is reported before any directory is made
    cfg = config_from_toml(st, config, cfg) if config is not None else None
    bar = QuietProgress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                        TextColumn("tasks, {task.fields[rows]} rows"), TimeRemainingColumn(), console=err,
                        transient=False)
    state = {"task": None, "rows": 0}

    def on_start(total: int, todo: int) -> None:
        state["task"] = bar.add_task(f"{study} ({scale})", total=total, completed=total - todo, rows=0)

    def on_result(res, rows: int) -> None:
        state["rows"] += rows
        bar.update(state["task"], advance=1, rows=state["rows"])

    where = f"Dask scheduler {scheduler}" if scheduler else f"{workers or cores()} local worker(s)"
    if scheduler is None:  # local workers read this machine's lane width instead of each measuring it
        prepare_solver()
    with bar:
        summary = run(st, out, scale=scale, seed=seed, config=cfg, workers=workers, scheduler=scheduler,
                      retry_failed=retry_failed, on_start=on_start, on_result=on_result)
    shown = f"{scale} with {config}" if config is not None else scale
    _say(f"{study} ({shown}, seed {seed}) on {where}: {summary.ran} task(s) run, {summary.skipped} already "
         f"done or skipped, {summary.failed} failed, {summary.rows} rows written to {out} in "
         f"{_duration(summary.wall_time_s)}")
    if summary.failed or summary.failed_before:
        parts = [f"{summary.failed} task(s) failed"] if summary.failed else []
        if summary.failed_before:
            parts.append(f"{summary.failed_before} task(s) that failed before were not retried")
        _say(f"{', and '.join(parts)}: see `expertise-irl experiment status {out}`; "
             "re-run them with --retry-failed")
        raise typer.Exit(1)


@experiment_app.command("status")
@handles_errors
def status_cmd(
    out: Annotated[Path, typer.Argument(metavar="DIR", help="Sweep directory.")],
) -> None:
    """Tasks done / total / failed, rows, time spent and an estimate of the time left."""
    from ..experiments.engine import status
    from ..experiments.workers import cores

    s = status(out)
    n = cores()
    _say(f"{s.study} (scale {s.scale}, seed {s.seed}) in {out}")
    _say(f"tasks: {s.done} done / {s.total} total, {s.failed} failed, {s.remaining} to do")
    _say(f"rows: {s.rows}")
    mean = f" (mean {_duration(s.mean_task_s)} per task)" if s.mean_task_s is not None else ""
    _say(f"time spent: {_duration(s.time_spent_s)} of task time{mean}")
    if s.remaining:
        _say(f"estimated time left: {_duration(s.eta_s(1))} with 1 worker, "
             f"{_duration(s.eta_s(n))} with {n}")
    for key, message in s.failures:
        _say(f"failed: {key}: {message}")


def estimate_s(tasks, workers: int) -> float:
    """Estimated seconds of a run of ``tasks`` on ``workers`` local workers (their cost models'
    seconds spread evenly over the workers, plus starting them)."""
    return STARTUP_S + sum(t.estimate_s for t in tasks) / min(workers, len(tasks))


@experiment_app.command("list")
@handles_errors
def list_cmd(
    workers: Annotated[int | None, typer.Option(min=1, help="Local workers to estimate for (default: one "
                                                "per core, as `run` uses).")] = None,
) -> None:
    """Studies and their scales: tasks, instances, rows, solves, and an estimated time.

    The estimate comes from each study's cost model (timed on a 2-core laptop) spread over the
    local workers; it is not measured here. The models are fitted to measured runs: `conditions`'
    to a first run (JAX's compilation cache empty), the others' to runs with the kernels already
    compiled, which a first run exceeds by up to ≈ 30 s per map (docs/experiments.md).
    """
    from rich.table import Table

    from ..experiments.studies import studies
    from ..experiments.workers import cores

    n = workers or cores()
    table = Table(title=f"studies (estimated time with {n} local worker(s), from timings on a 2-core "
                        "laptop; a first run also compiles, up to ≈ 30 s per map)")
    for name in ("study", "scale", "tasks", "instances", "rows", "set solves (grouped / ungrouped)",
                 "estimated time"):
        table.add_column(name, justify="left" if name in ("study", "scale") else "right",
                         no_wrap=name in ("study", "scale"))
    for st in studies().values():
        for scale, cfg in st.scales.items():
            c = st.counts(cfg)
            tasks = st.tasks(cfg)
            table.add_row(st.name, scale, str(len(tasks)), str(c.get("instances", "")),
                          str(c.get("rows", "")),
                          f"{c.get('set_solves_grouped', '')} / {c.get('set_solves_ungrouped', '')}",
                          _duration(estimate_s(tasks, n)))
        _say(f"{st.name}: {st.description}")
    from ._app import out as console

    console.print(table)


@experiment_app.command("report")
@handles_errors
def report_cmd(
    out_dir: Annotated[Path, typer.Argument(metavar="DIR", help="Sweep directory.")],
    out: Annotated[Path | None, typer.Option("--out", help="Report folder (default DIR/report); a "
                                             "previous report there is replaced, any other non-empty "
                                             "folder is refused.")] = None,
) -> None:
    """Figures, Pearson tables and the paper's claims with computed verdicts, from the sweep's Parquet."""
    from ..experiments.report import build_report

    path = build_report(out_dir, out, on_warning=lambda w: err.print(f"warning: {w}", markup=False,
                                                                      highlight=False, soft_wrap=True))
    _say(f"report written to {path} (figures, tables and claims.csv beside it)")
