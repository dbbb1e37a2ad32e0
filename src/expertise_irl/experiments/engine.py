"""The experiment engine: a study is data, a task is a pure function, engines only place tasks.

A :class:`Study` (:mod:`.spec`) names a config type (a frozen dataclass of plain values), its scales
(``smoke``, ``small``, ``paper``), how a config expands into tasks, and the function that
runs one task. Each task is a pure function of ``(config, seed, task key)`` that returns
the rows of its instances; the randomness of an instance comes from
``np.random.SeedSequence(entropy=seed, spawn_key=identity)`` (:func:`seed_sequence`), so the
rows never depend on the order of tasks, the number of workers, the grouping or the engine.

Engines (:mod:`.workers`): a local process pool (``spawn`` start method: JAX is not
fork-safe; a pool whose worker dies is rebuilt and the unfinished tasks re-run) or a Dask
``distributed`` cluster when a scheduler address is given (tasks are submitted with
``retries``). Workers return rows; this process writes them (:mod:`.store`), so workers need
no access to DIR. :func:`status` and :func:`load` read DIR through :class:`.store.SweepDir`.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_atomic
from ..errors import InputError
from .spec import (  # noqa: F401  (the study's spec, public here too)
    Column,
    Study,
    TaskSpec,
    config_dict,
    config_from_dict,
    config_from_toml,
    seed_sequence,
)
from .store import (
    LAYOUT_VERSION,
    Store,
    SweepDir,
    config_hash,
    machine,
    progress,
    to_toml,
    versions,
)
from .workers import (  # noqa: F401  (FAULTS_ENV, JAX_CACHE_ENV, cores, execute_task: public here too)
    FAULTS_ENV,
    JAX_CACHE_ENV,
    TaskResult,
    cores,
    error_info,
    execute_task,
    faults,
    kill_self,
    run_dask,
    run_local,
)

SCALES = ("smoke", "small", "paper")


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


# ----------------------------------------------------------------------------- driver
@dataclass
class RunSummary:
    total: int
    skipped: int
    ran: int
    failed: int
    rows: int
    wall_time_s: float
    failed_before: int = 0  # tasks that failed in an earlier run and were not retried


def _manifest(study: Study, scale: str, seed: int, config, tasks: list[TaskSpec]) -> dict[str, Any]:
    cfg = config_dict(config)
    identity = {"study": study.name, "study_version": study.version, "scale": scale, "seed": int(seed),
                "config": cfg}
    return {**identity, "layout_version": LAYOUT_VERSION, "config_hash": config_hash(identity),
            "task_keys": [t.key for t in tasks], "created": _now(),
            "versions": versions(), "machine": machine()}


def _record_run(store: Store, record: dict[str, Any], path: Path | None = None) -> Path:
    """One JSON file per invocation in ``DIR/runs/`` (who ran what, where, with which versions);
    written when the run starts and again, with ``finished`` and ``wall_time_s``, when it ends."""
    runs = store.root / "runs"
    runs.mkdir(exist_ok=True)
    path = path or runs / f"{record['started'].replace(':', '')}-{os.getpid()}.json"
    write_atomic(path, json.dumps(record, indent=2) + "\n", tmp_dir=store.tmp)
    return path


def _columns_table(study: Study, columns: dict[str, np.ndarray]):
    import pyarrow as pa

    schema = study.arrow_schema()
    missing = [n for n in schema.names if n not in columns]
    extra = [n for n in columns if n not in schema.names]
    if missing or extra:
        raise RuntimeError(f"study {study.name} returned columns that break its schema: "
                           f"missing {missing}, undocumented {extra}")
    return pa.table({n: pa.array(np.asarray(columns[n]), type=schema.field(n).type) for n in schema.names},
                    schema=schema)


def _stats_table(key: str, stats: dict[str, Any]):
    import pyarrow as pa

    row = {"task": key, **stats}
    return pa.table({k: [v] for k, v in row.items()})


def _failure_table(key: str, params: dict[str, Any], error: dict[str, str]):
    import pyarrow as pa

    row = {"task": key, "params": json.dumps(params, sort_keys=True), **error,
           "failed_at": _now()}
    return pa.table({k: [v] for k, v in row.items()})


def run(
    study: Study,
    out: Path,
    *,
    scale: str = "smoke",
    seed: int = 0,
    config=None,
    workers: int | None = None,
    scheduler: str | None = None,
    retry_failed: bool = False,
    on_start: Callable[[int, int], None] | None = None,
    on_result: Callable[[TaskResult, int], None] | None = None,
) -> RunSummary:
    """Run (or resume) a sweep into ``out``.

    ``config`` overrides the scale's config (the manifest then names the scale ``custom``).
    ``on_start(total, todo)`` is called once the work is known, ``on_result(result, rows)`` after
    each task is stored.
    """
    t_start = time.perf_counter()
    if config is None:
        config = study.config(scale)
    else:
        scale = "custom"
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    if int(seed) < 0:
        raise InputError(f"--seed must be >= 0, got {seed}")
    workers = workers or cores()
    tasks = study.tasks(config)
    store = Store(Path(out))
    manifest = _manifest(study, scale, seed, config, tasks)
    store.open(manifest, to_toml(manifest["config"], header=study.name))
    with store.lock():
        store.clean_tmp()
        return _run_locked(study, store, manifest, tasks, seed, workers, scheduler, retry_failed,
                           on_start, on_result, t_start)


def _run_locked(study, store, manifest, tasks, seed, workers, scheduler, retry_failed, on_start, on_result,
                t_start) -> RunSummary:
    injected = faults()
    if ("kill-at-start", "") in injected:
        kill_self()
    for key in store.keys("failures") & store.keys("rows"):  # a retried task finished, its failure stayed
        store.remove("failures", key)
    done, failed = progress(store, {t.key for t in tasks})
    todo = [t for t in tasks if t.key not in done and (retry_failed or t.key not in failed)]
    record = {"started": _now(), "engine": "dask" if scheduler else "local",
              "scheduler": scheduler, "workers": None if scheduler else workers,
              "retry_failed": retry_failed, "tasks_to_run": len(todo), "versions": versions(),
              "machine": machine()}
    record_path = _record_run(store, record)
    if on_start is not None:
        on_start(len(tasks), len(todo))
    kill_after = next((int(a) for k, a in injected if k == "kill-after"), None)
    kill_in_write = next((int(a) for k, a in injected if k == "kill-in-write"), None)
    by_key = {t.key: t for t in tasks}
    job = (study.name, manifest["config"], int(seed))
    results = run_dask(todo, job, scheduler) if scheduler else run_local(todo, job, workers)
    ran = n_failed = rows = committed = 0
    for res in results:
        if res.error is None:
            try:
                table = _columns_table(study, res.columns)
            except Exception as exc:  # a study that breaks its own schema: that task fails
                res = TaskResult(res.key, None, res.stats, error_info(exc))
        if res.error is not None:
            store.write_table("failures", res.key, _failure_table(res.key, by_key[res.key].params, res.error))
            n_failed += 1
            if on_result is not None:
                on_result(res, 0)
            continue
        store.write_table("timings", res.key, _stats_table(res.key, res.stats))
        hook = kill_self if kill_in_write is not None and committed == kill_in_write else None
        store.write_table("rows", res.key, table, before_rename=hook)
        store.remove("failures", res.key)
        committed += 1
        ran += 1
        rows += table.num_rows
        if on_result is not None:
            on_result(res, table.num_rows)
        if kill_after is not None and committed >= kill_after:
            kill_self()
    wall = time.perf_counter() - t_start
    _record_run(store, {**record, "finished": _now(), "wall_time_s": round(wall, 3), "tasks_run": ran,
                        "tasks_failed": n_failed}, record_path)
    still_failed = 0 if retry_failed else len(failed)
    return RunSummary(len(tasks), len(tasks) - len(todo), ran, n_failed, rows, wall, still_failed)


# ----------------------------------------------------------------------------- reading
def load(out, table: str = "rows"):
    """The sweep's ``rows`` (or ``timings`` / ``failures``) as one pandas DataFrame.

    Rows are sorted by the study's identity columns (its ``sort_by``), so two runs of the same
    sweep give equal frames whatever the order their tasks finished in.
    """
    import pandas as pd

    from .store import TABLES
    from .studies import get_study

    if table not in TABLES:
        raise InputError(f"table must be one of {', '.join(TABLES)}, got {table!r}")
    sweep = SweepDir.open(out)
    if table == "rows":
        study = get_study(sweep.manifest["study"])
        df = sweep.frame("rows", sweep.tasks, study.sort_by)
        return study.arrow_schema().empty_table().to_pandas() if df is None else df
    df = sweep.frame(table, sweep.failed if table == "failures" else sweep.tasks)
    return pd.DataFrame() if df is None else df


@dataclass(frozen=True)
class Status:
    study: str
    scale: str
    seed: int
    total: int
    done: int
    failed: int
    rows: int
    time_spent_s: float
    mean_task_s: float | None
    failures: list[tuple[str, str]]

    @property
    def remaining(self) -> int:
        return self.total - self.done - self.failed

    def eta_s(self, workers: int = 1) -> float | None:
        """Estimated wall time left with ``workers`` workers, from the mean time of finished tasks."""
        if self.mean_task_s is None:
            return None
        return self.remaining * self.mean_task_s / max(1, min(workers, max(self.remaining, 1)))


def status(out) -> Status:
    """Progress of the sweep in ``out``: tasks done / failed / total, rows, time spent."""
    sweep = SweepDir.open(out)
    spent, mean = 0.0, None
    timings = sweep.store.read("timings", sweep.done)
    if timings is not None and "wall_time_s" in timings.column_names:
        wall = timings.column("wall_time_s").to_pylist()
        spent = float(sum(wall))
        mean = spent / len(wall) if wall else None
    fails = []
    if sweep.failed:
        ft = sweep.store.read("failures", sweep.failed)
        fails = list(zip(ft.column("task").to_pylist(), ft.column("message").to_pylist(), strict=True))
    m = sweep.manifest
    return Status(m["study"], m["scale"], int(m["seed"]), len(sweep.tasks), len(sweep.done),
                  len(sweep.failed), sweep.n_rows(), spent, mean, fails)
