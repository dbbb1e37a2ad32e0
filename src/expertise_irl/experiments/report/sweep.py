"""What a report reads from a sweep directory: manifest, rows, timings and how far the sweep got."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import InputError
from ...results import is_number
from ..store import MANIFEST, SweepDir


@dataclass(frozen=True)
class Sweep:
    """One sweep, read once: everything a report is computed from.

    Attributes:
        root: the sweep directory.
        manifest: ``manifest.json`` (study, version, scale, seed, config, versions, machine).
        rows: the rows of the finished tasks (the study's schema).
        timings: one row per finished task (``wall_time_s``, ``set_solve_time_s``, ...).
        done, failed, total: task counts (failed excludes tasks that later finished).
        runs: the records in ``runs/*.json``, one per invocation of ``experiment run`` (engine,
            scheduler, workers, tasks_to_run, ...), oldest first; unreadable ones are skipped.
    """

    root: Path
    manifest: dict[str, Any]
    rows: Any  # pandas.DataFrame
    timings: Any  # pandas.DataFrame
    done: int
    failed: int
    total: int
    runs: tuple[dict[str, Any], ...] = ()

    @property
    def study(self) -> str:
        return str(self.manifest.get("study"))

    @property
    def config(self) -> dict[str, Any]:
        return dict(self.manifest.get("config") or {})

    @property
    def unfinished(self) -> int:
        return self.total - self.done

    @property
    def working_runs(self) -> list[dict[str, Any]]:
        """The runs that had tasks to run (those that can have written rows)."""
        return [r for r in self.runs if (r.get("tasks_to_run") or 0) > 0]

    def shared_machine(self) -> str | None:
        """Why a task's timings may have shared the machine with other tasks (a clause), or None if
        every run that had tasks to run used one local worker; not None where no run is recorded."""
        runs = self.working_runs
        if not runs:
            return ("the sweep records no run with tasks to run (`runs/*.json`), so whether other tasks "
                    "shared the machine with the timed ones is unknown")
        many = [r for r in runs if r.get("scheduler") or (r.get("workers") or 1) > 1]
        if not many:
            return None
        return (f"tasks ran side by side ({workers_text(many)}), so other tasks' work shared the "
                "machine with the timed ones")

    @property
    def task_time_s(self) -> float:
        """The sum of the finished tasks' wall times (overlapping where tasks ran side by side)."""
        if "wall_time_s" not in getattr(self.timings, "columns", ()):
            return 0.0
        return float(self.timings["wall_time_s"].sum())

    @property
    def run_times_s(self) -> list[float]:
        """The elapsed times of the invocations of ``experiment run`` that record one (``wall_time_s``
        in ``runs/*.json``); records without it, or with no finite non-negative number, are left out."""
        out = []
        for r in self.runs:
            v = r.get("wall_time_s")
            if is_number(v) and v >= 0:
                out.append(float(v))
        return out


#: The protocol of rows and configs written before ``goal_reward_mode`` existed.
DEFAULT_PROTOCOL = "scaled"
#: What each protocol (``goal_reward_mode``) means, for a report's notes.
PROTOCOLS = {"scaled": "the goal bonus is part of the `length` feature, weighted by θ_length (it vanishes "
                       "with θ_length, and only θ/β enters the likelihood)",
             "fixed": "a constant terminal reward for entering the goal, outside θ·φ (people have a reason "
                      "to finish whatever their θ; π depends on θ and β apart)"}


def protocol_of(rows, config: dict | None = None) -> str:
    """The protocol of a sweep: its rows' ``goal_reward_mode`` (one value, or the values joined by "+"),
    else its config's, else :data:`DEFAULT_PROTOCOL` (rows written before the column existed)."""
    if rows is not None and "goal_reward_mode" in getattr(rows, "columns", ()):
        modes = sorted({str(v) for v in rows["goal_reward_mode"].dropna()})
        if modes:
            return "+".join(modes)
    return str((config or {}).get("goal_reward_mode") or DEFAULT_PROTOCOL)


def protocol_note(sweep) -> str:
    """One paragraph: the sweep's protocol and what it means."""
    mode = protocol_of(sweep.rows, sweep.config)
    bonus = sweep.config.get("goal_bonus")
    where = "its rows' `goal_reward_mode`" if "goal_reward_mode" in sweep.rows.columns else (
        "its config" if "goal_reward_mode" in sweep.config else "the default: rows and config written before "
        "the field existed")
    return (f"Protocol (goal reward): `{mode}` (from {where}): {PROTOCOLS.get(mode, 'see the config')}"
            + (f"; goal bonus {bonus:g}." if isinstance(bonus, int | float) else "."))


def workers_text(runs) -> str:
    """``"a run with 2 local workers and 3 tasks to run; a run on the Dask scheduler tcp://..."``"""
    parts = []
    for r in runs:
        tasks = r.get("tasks_to_run")
        todo = f"{tasks} task{'s' if tasks != 1 else ''} to run" if tasks is not None else ""
        if r.get("scheduler"):
            parts.append(f"a run on the Dask scheduler {r['scheduler']}" + (f" with {todo}" if todo else ""))
        else:
            w = r.get("workers")
            parts.append(f"a run with {w if w is not None else 'an unrecorded number of'} local worker"
                         f"{'' if w == 1 else 's'}" + (f" and {todo}" if todo else ""))
    return "; ".join(parts)


def read_sweep(root, sort_by: tuple[str, ...] = ()) -> Sweep:
    """Read the sweep in ``root``; rows sorted by ``sort_by`` (the study's identity columns).

    Args:
        root: the sweep directory.
        sort_by: the columns the rows are sorted by.

    Returns:
        The sweep: its manifest, finished rows and timings, counts and runs.

    Raises:
        InputError: ``root`` is not a directory, holds no manifest, or no finished task.
    """
    import pandas as pd

    root = Path(root)
    check_directory(root)
    src = SweepDir.open(root)
    rows = src.frame("rows", src.done, sort_by)
    if rows is None or not len(rows):
        raise InputError(f"{root / 'rows'}: no rows yet ({len(src.done)} of {len(src.tasks)} tasks done); "
                         "nothing to report")
    timings = src.frame("timings", src.done)
    timings = pd.DataFrame() if timings is None else timings
    return Sweep(root, src.manifest, rows, timings, len(src.done), len(src.failed), len(src.tasks),
                 src.runs())


def check_directory(root: Path) -> None:
    """A one-line InputError unless ``root`` is an existing directory."""
    if not root.exists():
        raise InputError(f"{root}: does not exist (expected a sweep directory with {MANIFEST})")
    if not root.is_dir():
        raise InputError(f"{root}: not a directory (expected a sweep directory with {MANIFEST})")


def require_columns(sweep_or_rows, columns, where: str) -> None:
    """Raise a one-line InputError naming the first column the rows lack."""
    rows = getattr(sweep_or_rows, "rows", sweep_or_rows)
    missing = [c for c in columns if c not in rows.columns]
    if missing:
        raise InputError(f"{where}: rows lack column {missing[0]!r}"
                         + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
