"""The experiment engine: a study is data, a task is a pure function, engines only place tasks.

A :class:`Study` names a config type (a frozen dataclass of plain values), its scales
(``smoke``, ``small``, ``paper``), how a config expands into tasks, and the function that
runs one task. Each task is a pure function of ``(config, seed, task key)`` that returns
the rows of its instances; the randomness of an instance comes from
``np.random.SeedSequence(entropy=seed, spawn_key=identity)`` (:func:`seed_sequence`), so the
rows never depend on the order of tasks, the number of workers, the grouping or the engine.

Engines (:mod:`.workers`): a local process pool (``spawn`` start method: JAX is not
fork-safe; a pool whose worker dies is rebuilt and the unfinished tasks re-run) or a Dask
``distributed`` cluster when a scheduler address is given (tasks are submitted with
``retries``). Workers return rows; this process writes them (:mod:`.store`), so workers need
no access to DIR.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .store import LAYOUT_VERSION, Store, config_hash, machine, to_toml, versions, write_atomic
from .workers import (  # noqa: F401  (FAULTS_ENV, JAX_CACHE_ENV, execute_task: public here too)
    FAULTS_ENV,
    JAX_CACHE_ENV,
    TaskResult,
    _dask_results,
    _error_info,
    _faults,
    _kill_self,
    _local_results,
    execute_task,
)

SCALES = ("smoke", "small", "paper")


def cores() -> int:
    """CPU cores this process may use (the default number of local workers)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def seed_sequence(seed: int, identity) -> np.random.SeedSequence:
    """The seed of the thing named by ``identity`` (a tuple of non-negative ints) in sweep ``seed``."""
    return np.random.SeedSequence(entropy=int(seed), spawn_key=tuple(int(i) for i in identity))


@dataclass(frozen=True)
class Column:
    """One documented column: name, Arrow type (as pyarrow names it) and meaning."""

    name: str
    type: str
    doc: str


@dataclass(frozen=True)
class TaskSpec:
    """A task: its key (file name of its shard), its parameters and a cost estimate (seconds)."""

    key: str
    params: dict[str, Any]
    estimate_s: float = 1.0


@dataclass(frozen=True)
class Study:
    """A named, versioned sweep definition.

    Attributes:
        name: the CLI name.
        version: bump when a change alters the rows for the same config and seed.
        description: one line for ``experiment list``.
        config_type: a frozen dataclass; its fields are the study's factors.
        scales: scale name -> config.
        tasks: config -> task specs (each task's key unique within the study), in the order
            they should be handed out (e.g. long ones first, maps interleaved so that workers
            compile different maps' kernels at the start).
        run_task: (config, seed, params) -> (columns dict of 1-D arrays, stats dict).
        columns: the documented schema of the rows.
        sort_by: columns that order the rows of :func:`load`.
        counts: config -> dict of totals (instances, rows, solves grouped and not) for ``list``.
    """

    name: str
    version: int
    description: str
    config_type: type
    scales: dict[str, Any]
    tasks: Callable[[Any], list[TaskSpec]]
    run_task: Callable[[Any, int, dict[str, Any]], tuple[dict[str, np.ndarray], dict[str, Any]]]
    columns: tuple[Column, ...]
    sort_by: tuple[str, ...]
    counts: Callable[[Any], dict[str, int]] = field(default=lambda cfg: {})

    def config(self, scale: str):
        if scale not in self.scales:
            raise InputError(f"study {self.name!r} has no scale {scale!r} (scales: {', '.join(self.scales)})")
        return self.scales[scale]

    def arrow_schema(self):
        import pyarrow as pa

        return pa.schema([(c.name, _arrow_type(c.type)) for c in self.columns])


def _arrow_type(name: str):
    import pyarrow as pa

    types = {"int32": pa.int32(), "int64": pa.int64(), "float64": pa.float64(), "string": pa.string(),
             "bool": pa.bool_()}
    return types[name]


def config_dict(config) -> dict[str, Any]:
    """A config as plain JSON/TOML values (tuples become lists)."""
    return json.loads(json.dumps(dataclasses.asdict(config)))


def config_from_dict(study: Study, values: dict[str, Any]):
    kwargs = {}
    for f in dataclasses.fields(study.config_type):
        if f.name in values:
            v = values[f.name]
            kwargs[f.name] = tuple(v) if isinstance(v, list) else v
    return study.config_type(**kwargs)


def config_from_toml(study: Study, path, base):
    """``base`` (a scale's config) with the fields set in the TOML file ``path`` replaced.

    The file holds the fields either at the top level or in a table named after the study
    (the form ``DIR/config.toml`` is written in, so a sweep's config can be edited and reused).
    Every key must be a field of the study's config with a value of the field's type; the
    config then checks its own values. Errors are one line naming the file and the field.
    """
    import tomllib

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {'is a directory' if path.is_dir() else 'no such file'} (--config)")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a TOML file: {exc}") from None
    if set(data) == {study.name} and isinstance(data[study.name], dict):
        data = data[study.name]
    elif len(data) == 1 and isinstance(next(iter(data.values())), dict):
        raise InputError(f"{path}: holds a [{next(iter(data))}] table, but the study is {study.name!r} "
                         f"(write its fields at the top level or in a [{study.name}] table)")
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    changes = {}
    for key, value in data.items():
        if key not in fields:
            raise InputError(f"{path}: {key!r} is not a field of study {study.name!r} "
                             f"(fields: {', '.join(fields)})")
        changes[key] = _typed(path, key, value, fields[key])
    try:
        return dataclasses.replace(base, **changes)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def _typed(path, key: str, value, default):
    """``value`` as the type of ``default`` (lists become tuples), or a one-line InputError."""
    def kind(x) -> str:
        return "a boolean" if isinstance(x, bool) else "a whole number" if isinstance(x, int) else \
            "a number" if isinstance(x, float) else "a string" if isinstance(x, str) else "a list"

    if isinstance(default, tuple):
        if not isinstance(value, list) or not value:
            raise InputError(f"{path}: {key} must be a non-empty list, got {value!r}")
        like = default[0] if default else value[0]
        return tuple(_typed(path, f"{key}[{i}]", v, like) for i, v in enumerate(value))
    ok = (isinstance(value, bool) if isinstance(default, bool)
          else isinstance(value, int) and not isinstance(value, bool) if isinstance(default, int)
          else isinstance(value, int | float) and not isinstance(value, bool) if isinstance(default, float)
          else isinstance(value, str))
    if not ok:
        raise InputError(f"{path}: {key} must be {kind(default)}, got {value!r}")
    return float(value) if isinstance(default, float) else value


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
    write_atomic(path, (json.dumps(record, indent=2) + "\n").encode(), store.tmp)
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
    faults = _faults()
    if ("kill-at-start", "") in faults:
        _kill_self()
    done, failed = store.keys("rows"), store.keys("failures")
    for key in done & failed:  # a retried task finished but its old failure was not removed yet
        store.remove("failures", key)
    failed -= done
    todo = [t for t in tasks if t.key not in done and (retry_failed or t.key not in failed)]
    record = {"started": _now(), "engine": "dask" if scheduler else "local",
              "scheduler": scheduler, "workers": None if scheduler else workers,
              "retry_failed": retry_failed, "tasks_to_run": len(todo), "versions": versions(),
              "machine": machine()}
    record_path = _record_run(store, record)
    if on_start is not None:
        on_start(len(tasks), len(todo))
    kill_after = next((int(a) for k, a in faults if k == "kill-after"), None)
    kill_in_write = next((int(a) for k, a in faults if k == "kill-in-write"), None)
    by_key = {t.key: t for t in tasks}
    job = (study.name, manifest["config"], int(seed))
    results = _dask_results(todo, job, scheduler) if scheduler else _local_results(todo, job, workers)
    ran = n_failed = rows = committed = 0
    for res in results:
        if res.error is None:
            try:
                table = _columns_table(study, res.columns)
            except Exception as exc:  # a study that breaks its own schema: that task fails
                res = TaskResult(res.key, None, res.stats, _error_info(exc))
        if res.error is not None:
            store.write_table("failures", res.key, _failure_table(res.key, by_key[res.key].params, res.error))
            n_failed += 1
            if on_result is not None:
                on_result(res, 0)
            continue
        store.write_table("timings", res.key, _stats_table(res.key, res.stats))
        hook = _kill_self if kill_in_write is not None and committed == kill_in_write else None
        store.write_table("rows", res.key, table, before_rename=hook)
        store.remove("failures", res.key)
        committed += 1
        ran += 1
        rows += table.num_rows
        if on_result is not None:
            on_result(res, table.num_rows)
        if kill_after is not None and committed >= kill_after:
            _kill_self()
    wall = time.perf_counter() - t_start
    _record_run(store, {**record, "finished": _now(), "wall_time_s": round(wall, 3), "tasks_run": ran,
                        "tasks_failed": n_failed}, record_path)
    still_failed = 0 if retry_failed else len({t.key for t in tasks} & failed)
    return RunSummary(len(tasks), len(tasks) - len(todo), ran, n_failed, rows, wall, still_failed)


# ----------------------------------------------------------------------------- reading
def load(out, table: str = "rows"):
    """The sweep's ``rows`` (or ``timings`` / ``failures``) as one pandas DataFrame.

    Rows are sorted by the study's identity columns, so two runs of the same sweep give equal
    frames whatever the order their tasks finished in.
    """
    import pandas as pd

    from .store import TABLES
    from .studies import get_study

    if table not in TABLES:
        raise InputError(f"table must be one of {', '.join(TABLES)}, got {table!r}")
    store = Store(Path(out))
    manifest = store.read_manifest()
    keys = set(manifest["task_keys"])
    if table == "failures":
        keys -= store.keys("rows")
    arrow = store.read(table, keys)
    if arrow is None:
        if table == "rows":
            return get_study(manifest["study"]).arrow_schema().empty_table().to_pandas()
        return pd.DataFrame()
    df = arrow.to_pandas()
    if table == "rows":
        study = get_study(manifest["study"])
        df = df.sort_values(list(study.sort_by), kind="stable").reset_index(drop=True)
    else:
        df = df.sort_values("task", kind="stable").reset_index(drop=True)
    return df


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
    store = Store(Path(out))
    manifest = store.read_manifest()
    keys = set(manifest["task_keys"])
    done = store.keys("rows") & keys
    failed = (store.keys("failures") & keys) - done
    spent, mean = 0.0, None
    timings = store.read("timings", done)
    if timings is not None and "wall_time_s" in timings.column_names:
        wall = timings.column("wall_time_s").to_pylist()
        spent = float(sum(wall))
        mean = spent / len(wall) if wall else None
    fails = []
    if failed:
        ft = store.read("failures", failed)
        fails = list(zip(ft.column("task").to_pylist(), ft.column("message").to_pylist(), strict=True))
    return Status(manifest["study"], manifest["scale"], int(manifest["seed"]), len(keys), len(done),
                  len(failed), store.n_rows(done), spent, mean, fails)
