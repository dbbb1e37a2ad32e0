"""The participants' figures of ``expertise-irl study``, drawn in parallel.

:func:`draw_figures` takes one job per figure, ``(png_path, participant, panels, doc)`` (the
arguments of :func:`~expertise_irl.plots.userstudy.render_participant_png`), and draws them:

- ``workers=1`` (or a single job): in this process, one after another;
- ``workers=N``: on a local pool of N ``spawn`` processes (JAX, which is not fork-safe, may
  be loaded here), set up like the experiment engine's (:mod:`expertise_irl.experiments.workers`:
  a worker ends when this process is gone);
- ``scheduler="tcp://host:8786"``: on a Dask cluster (``distributed.Client``).

Workers only draw: each returns the PNG's bytes and this process writes every file, atomically
(a temporary file renamed onto the path), so workers need not share the disk and a reader never
sees half a PNG. A figure is the same bytes whichever worker drew it, or how many there were
(see :mod:`expertise_irl.plots.userstudy`). :func:`select_figures` reads ``--figures``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from ..atomic import write_atomic
from ..errors import InputError
from ..experiments.workers import cores
from ..plots.userstudy import light_panel, participant_png_bytes

#: One figure to draw: where its PNG goes, the participant, their task panels, their result document.
Job = tuple[str | Path, str, Sequence[dict[str, Any]], dict[str, Any]]
#: Default local pool: one process per core, but at least this many figures per process
#: (starting a process costs about as much as drawing a few figures).
FIGURES_PER_WORKER = 4
#: Dask ``retries`` of a figure whose worker died.
DASK_RETRIES = 2


def select_figures(participants: Iterable[str], spec: str | int) -> list[str]:
    """The participants whose figure ``--figures SPEC`` asks for, in manifest order.

    ``all``: every one; ``none``: none; a positive number N: the first N. Anything else raises
    :class:`~expertise_irl.errors.InputError`.
    """
    ids = [str(p) for p in participants]
    text = str(spec).strip()
    if text.lower() == "all":
        return ids
    if text.lower() == "none":
        return []
    if text.isascii() and text.isdigit() and int(text) > 0:
        return ids[: int(text)]
    raise InputError(f"--figures must be all, none or a positive number, got {str(spec)!r}")


def draw_figures(jobs: Iterable[Job], *, workers: int | None = None, scheduler: str | None = None,
                 on_progress: Callable[[int, int], None] | None = None) -> list[Path]:
    """Draw every job's figure and write its PNG; return the paths, in the jobs' order.

    Parameters
    ----------
    jobs
        ``(png_path, participant, panels, doc)`` per figure; the folders must exist.
    workers
        Local processes (``spawn``); default one per core, but no more than one per
        :data:`FIGURES_PER_WORKER` figures; 1 draws in this process, with no pool.
    scheduler
        Address of a Dask scheduler: draw there instead (``workers`` is then ignored).
    on_progress
        Called as ``on_progress(done, total)`` after each figure is written.

    A figure that fails to draw raises here (the figures not yet drawn are cancelled).
    """
    jobs = [(Path(p), str(pid), [light_panel(x) for x in panels], doc) for p, pid, panels, doc in jobs]
    total = len(jobs)
    done = 0

    def finish(i: int, data: bytes) -> None:
        nonlocal done
        write_atomic(jobs[i][0], data)
        done += 1
        if on_progress is not None:
            on_progress(done, total)

    if not jobs:
        return []
    if scheduler:
        _draw_dask(jobs, scheduler, finish)
    else:
        if workers is None:
            n = min(cores(), max(total // FIGURES_PER_WORKER, 1))
        else:
            if int(workers) < 1:
                raise InputError(f"figure workers must be a positive number, got {workers}")
            n = min(int(workers), total)
        if n == 1:
            for i, (_, pid, panels, doc) in enumerate(jobs):
                finish(i, participant_png_bytes(pid, panels, doc))
        else:
            _draw_local(jobs, n, finish)
    return [j[0] for j in jobs]


def _draw_local(jobs: list[Job], workers: int, finish: Callable[[int, bytes], None]) -> None:
    """On a ``spawn`` pool of ``workers`` processes; figures whose worker died are drawn here."""
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    from ..experiments.workers import _exit_with_parent

    pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                               initializer=_exit_with_parent, initargs=(os.getpid(),))
    futures = {pool.submit(participant_png_bytes, pid, panels, doc): i
               for i, (_, pid, panels, doc) in enumerate(jobs)}
    orphans: list[int] = []
    try:
        while futures:
            finished, _ = wait(futures, return_when=FIRST_COMPLETED)
            for fut in finished:
                i = futures.pop(fut)
                try:
                    data = fut.result()
                except BrokenProcessPool:  # a worker died (killed, out of memory): draw it here
                    orphans.append(i)
                    continue
                finish(i, data)
    finally:
        if futures:  # stopped early (an error, Ctrl-C): do not wait for the rest
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
        else:
            pool.shutdown(wait=True)
    for i in sorted(orphans):
        _, pid, panels, doc = jobs[i]
        finish(i, participant_png_bytes(pid, panels, doc))


def _draw_dask(jobs: list[Job], scheduler: str, finish: Callable[[int, bytes], None]) -> None:
    """On the Dask cluster at ``scheduler``: workers return the bytes, this process writes them."""
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--scheduler needs the 'distributed' package (pip install distributed)") from None
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler ({exc})") from None
    with client:
        token = os.urandom(4).hex()
        futures = {client.submit(participant_png_bytes, pid, panels, doc, key=f"figure-{i}-{token}",
                                 pure=False, retries=DASK_RETRIES): i
                   for i, (_, pid, panels, doc) in enumerate(jobs)}
        try:
            for fut in as_completed(futures):
                finish(futures[fut], fut.result())
                fut.release()
        finally:
            client.cancel([f for f in futures if not f.done()])
