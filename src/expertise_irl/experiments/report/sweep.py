"""What a report reads from a sweep directory: manifest, rows, timings and how far the sweep got."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import InputError
from ..store import MANIFEST, Store


@dataclass(frozen=True)
class Sweep:
    """One sweep, read once: everything a report is computed from.

    Attributes:
        root: the sweep directory.
        manifest: ``manifest.json`` (study, version, scale, seed, config, versions, machine).
        rows: the rows of the finished tasks (the study's schema).
        timings: one row per finished task (``wall_time_s``, ``set_solve_time_s``, ...).
        done, failed, total: task counts (failed excludes tasks that later finished).
    """

    root: Path
    manifest: dict[str, Any]
    rows: Any  # pandas.DataFrame
    timings: Any  # pandas.DataFrame
    done: int
    failed: int
    total: int

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
    def task_time_s(self) -> float:
        if "wall_time_s" not in getattr(self.timings, "columns", ()):
            return 0.0
        return float(self.timings["wall_time_s"].sum())


def _table(store: Store, table: str, keys: set[str], sort_by: list[str]):
    import pandas as pd

    arrow = store.read(table, keys)
    if arrow is None:
        return pd.DataFrame()
    df = arrow.to_pandas()
    by = [c for c in sort_by if c in df.columns]
    return df.sort_values(by, kind="stable").reset_index(drop=True) if by else df


def read_sweep(root, sort_by: tuple[str, ...] = ()) -> Sweep:
    """Read the sweep in ``root``; rows sorted by ``sort_by`` (the study's identity columns).

    Raises InputError if ``root`` holds no manifest or no finished task.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: not a directory (expected a sweep directory with {MANIFEST})")
    store = Store(root)
    manifest = store.read_manifest()
    if not isinstance(manifest, dict) or "study" not in manifest or "task_keys" not in manifest:
        raise InputError(f"{root / MANIFEST}: not a sweep manifest (no study or task_keys)")
    keys = set(manifest["task_keys"])
    done = store.keys("rows") & keys
    failed = (store.keys("failures") & keys) - done
    rows = _table(store, "rows", done, list(sort_by))
    if not len(rows):
        raise InputError(f"{root / 'rows'}: no rows yet ({len(done)} of {len(keys)} tasks done); "
                         "nothing to report")
    timings = _table(store, "timings", done, ["task"])
    return Sweep(root, manifest, rows, timings, len(done), len(failed), len(keys))


def require_columns(sweep_or_rows, columns, where: str) -> None:
    """Raise a one-line InputError naming the first column the rows lack."""
    rows = getattr(sweep_or_rows, "rows", sweep_or_rows)
    missing = [c for c in columns if c not in rows.columns]
    if missing:
        raise InputError(f"{where}: rows lack column {missing[0]!r}"
                         + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
