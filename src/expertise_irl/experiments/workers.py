"""Where tasks run: the worker-side entry point, a local ``spawn`` process pool, Dask.

:func:`execute_task` is what every engine ships to a worker: it rebuilds the study's config
from plain values and runs one task. The local pool (one JAX process per worker, ``spawn``
since JAX is not fork-safe) is rebuilt if a worker dies and the unfinished tasks run again;
on Dask, tasks are submitted with ``retries`` and a dead worker's task is rescheduled by the
scheduler. Both only yield results; the driver (:mod:`.engine`) writes them.
"""

from __future__ import annotations

import os
import signal
import socket
import time
import traceback
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from ..planning.jax_cache import JAX_CACHE_ENV, enable_jax_cache  # noqa: F401  (JAX_CACHE_ENV: public here too)

if TYPE_CHECKING:
    from .spec import TaskSpec

#: Environment variable read by the engine to inject faults (tests only); see :func:`faults`.
FAULTS_ENV = "EXPERTISE_IRL_FAULTS"
#: Attempts the local pool gives a task whose worker process died before it gives up.
LOCAL_ATTEMPTS = 3
#: Dask ``retries`` for every task.
DASK_RETRIES = 2


def cores() -> int:
    """The CPU cores this process may use (its affinity where the system tells it, else all of
    them): the default number of local workers, of experiments and of a study's figures alike."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not on Linux
        return max(1, os.cpu_count() or 1)


def faults() -> list[tuple[str, str]]:
    """Faults to inject, from ``EXPERTISE_IRL_FAULTS`` (comma-separated ``kind:arg``).

    Worker side: ``raise:KEY`` (the task raises), ``die:KEY:MARKER`` (the worker process exits
    abruptly the first time, creating file MARKER). Driver side: ``kill-at-start``,
    ``kill-after:N`` (SIGKILL after N shards were committed), ``kill-in-write:N`` (SIGKILL
    halfway through writing shard N + 1).
    """
    spec = os.environ.get(FAULTS_ENV, "")
    out = []
    for item in filter(None, (s.strip() for s in spec.split(","))):
        kind, _, arg = item.partition(":")
        out.append((kind, arg))
    return out


def kill_self() -> None:
    """End this process at once with SIGKILL (the driver-side faults)."""
    os.kill(os.getpid(), signal.SIGKILL)


@dataclass
class TaskResult:
    key: str
    columns: dict[str, np.ndarray] | None
    stats: dict[str, Any]
    error: dict[str, str] | None = None


def execute_task(study_name: str, config: dict[str, Any], seed: int, key: str,
                 params: dict[str, Any]) -> TaskResult:
    """Run one task in this process (the function the engines ship to workers)."""
    from .spec import config_from_dict
    from .studies import get_study

    for kind, arg in faults():
        if kind == "raise" and arg == key:
            raise RuntimeError(f"injected failure in task {key}")
        if kind == "die":
            target, _, marker = arg.partition(":")
            if target == key and not os.path.exists(marker):
                Path(marker).touch()
                os._exit(17)
    enable_jax_cache()
    study = get_study(study_name)
    cfg = config_from_dict(study, config)
    t0 = time.perf_counter()
    columns, stats = study.run_task(cfg, seed, params)
    stats = {**stats, "wall_time_s": time.perf_counter() - t0, "host": socket.gethostname(),
             "pid": os.getpid()}
    return TaskResult(key, columns, stats)


def _exit_with_parent(parent: int) -> None:
    """Pool initializer: end this worker when the process that started it is gone (e.g. killed)."""
    import threading

    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os._exit(3)

    threading.Thread(target=watch, daemon=True).start()


def error_info(exc: BaseException) -> dict[str, str]:
    """A failure as the ``failures`` table records it: error type, message and traceback."""
    return {"error_type": type(exc).__name__, "message": str(exc),
            "traceback": "".join(traceback.format_exception(exc))}


# ---------------------------------------------------------------------------- engines
def run_local(todo: list[TaskSpec], job: tuple, workers: int) -> Iterator[TaskResult]:
    """Run tasks on a ``spawn`` process pool; rebuild the pool if a worker dies.

    If the caller stops early (an error, Ctrl-C) the queued tasks are cancelled and the
    workers terminated rather than waited for.
    """
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    attempts = dict.fromkeys((t.key for t in todo), 0)
    pending = list(todo)
    ctx = mp.get_context("spawn")
    while pending:
        pool = ProcessPoolExecutor(max_workers=min(workers, len(pending)), mp_context=ctx,
                                   initializer=_exit_with_parent, initargs=(os.getpid(),))
        futures = {}
        try:
            for t in pending:
                attempts[t.key] += 1
                futures[pool.submit(execute_task, *job, t.key, t.params)] = t
            pending = []
            while futures:
                done, _ = wait(futures, return_when=FIRST_COMPLETED)
                for fut in done:
                    t = futures.pop(fut)
                    try:
                        res = fut.result()
                    except BrokenProcessPool as exc:
                        if attempts[t.key] < LOCAL_ATTEMPTS:
                            pending.append(t)
                            continue
                        res = TaskResult(t.key, None, {}, error_info(RuntimeError(
                            f"worker process died {attempts[t.key]} times running this task ({exc})")))
                    except Exception as exc:
                        res = TaskResult(t.key, None, {}, error_info(exc))
                    yield res
        finally:
            if futures:  # stopped early: do not wait for the rest
                pool.shutdown(wait=False, cancel_futures=True)
                procs = getattr(pool, "_processes", None) or {}
                for proc in list(procs.values()):
                    proc.terminate()
            else:
                pool.shutdown(wait=True)


def run_dask(todo: list[TaskSpec], job: tuple, address: str) -> Iterator[TaskResult]:
    """Run tasks on a Dask distributed cluster (``retries`` re-runs failed attempts)."""
    from distributed import Client, as_completed

    try:
        client = Client(address, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"--scheduler {address}: cannot connect to a Dask scheduler ({exc})") from None
    with client:
        token = os.urandom(4).hex()
        futures = {}
        for t in todo:
            fut = client.submit(execute_task, *job, t.key, t.params, key=f"{job[0]}-{t.key}-{token}",
                                pure=False, retries=DASK_RETRIES)
            futures[fut] = t
        for fut in as_completed(futures):
            t = futures[fut]
            try:
                yield fut.result()
            except Exception as exc:
                yield TaskResult(t.key, None, {}, error_info(exc))
            fut.release()
