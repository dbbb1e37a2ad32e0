"""On-disk layout of a sweep: a manifest, one Parquet shard per finished task, failures, timings.

```
DIR/manifest.json       study, version, scale, seed, config, task keys, versions, machine
DIR/config.toml         the same config, for people
DIR/rows/<task>.parquet     the task's rows (deterministic; the study's documented schema)
DIR/timings/<task>.parquet  wall times, worker and host of the task (differ run to run)
DIR/failures/<task>.parquet one row: the task's key, parameters, error type, message, traceback
DIR/runs/<time>-<pid>.json  one record per invocation: engine, workers, versions, machine
DIR/tmp/                    files being written; renamed into place when complete
DIR/lock                    flock held by the run that is writing
```

A row shard is the commit point of its task: it is written to ``DIR/tmp``, flushed to
disk, then renamed into ``DIR/rows`` (an atomic step) and the directory is synced. Nothing
is recorded anywhere else about a finished task, so a run killed at any moment leaves every
task either finished (its shard is there, complete) or not started; the next run redoes
the latter. The timing file is written before the shard, so a finished task always has one.

Reading: :class:`SweepDir` opens a sweep once (manifest, which tasks are done and which failed,
counted by :func:`progress` alone) and serves ``engine.status``, ``engine.load`` and the reports.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import socket
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from ..atomic import atomic_open, fsync_dir, write_atomic
from ..errors import InputError

MANIFEST = "manifest.json"
LAYOUT_VERSION = 1
TABLES = ("rows", "timings", "failures")
_VERSIONED = ("expertise-irl", "numpy", "scipy", "jax", "jaxlib", "pandas", "pyarrow", "dask", "distributed")


def config_hash(identity: dict[str, Any]) -> str:
    """SHA-256 of the canonical JSON of what defines a sweep (study, version, scale, seed, config)."""
    text = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


_IDENTITY = (("study_version", "study version"), ("scale", "scale"), ("seed", "seed"))


def _config_fields(old: dict[str, Any], new: dict[str, Any]) -> str:
    """``another config (k = a there, b here; …)``, three fields named; the config hashes when the
    fields cannot be compared; "" when the configs are the same."""
    cfg, here = old.get("config"), new["config"]
    if not isinstance(cfg, dict):
        return f"another config ({str(old.get('config_hash'))[:12]} there, {new['config_hash'][:12]} here)"
    fields = [k for k in sorted(set(cfg) | set(here)) if cfg.get(k) != here.get(k)]
    if not fields:
        return ""
    named = "; ".join(f"{k} = {cfg.get(k)!r} there, {here.get(k)!r} here" for k in fields[:3])
    return f"another config ({named}" + (f"; {len(fields) - 3} more" if len(fields) > 3 else "") + ")"


def _difference(old: dict[str, Any], new: dict[str, Any]) -> str:
    """What makes the sweep in a directory (manifest ``old``) another than ``new``: the study, its
    version, scale or seed, and the config fields where a scale is custom or the same."""
    if old.get("study") != new["study"]:
        return f"study {old.get('study')!r}, not {new['study']!r}"
    changed = [(f"{label} {old.get(k)}", f"{label} {new[k]}")
               for k, label in _IDENTITY if old.get(k) != new[k]]
    config = _config_fields(old, new) if old.get("scale") == new["scale"] or "custom" in (
        old.get("scale"), new["scale"]) else ""
    if not changed:
        return f"study {new['study']!r} with {config or 'another config'}"
    there, here = (", ".join(x) for x in zip(*changed, strict=True))
    also = f" and {config}" if config else ""
    return f"study {new['study']!r} run with {there}; this command has {here}{also}"


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in _VERSIONED:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def machine() -> dict[str, Any]:
    return {"host": socket.gethostname(), "platform": platform.platform(),
            "processor": platform.machine(), "cpus": os.cpu_count()}


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def to_toml(table: dict[str, Any], header: str | None = None) -> str:
    """A flat TOML table (scalars and lists), readable back with :mod:`tomllib`."""
    lines = [f"[{header}]"] if header else []
    lines += [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Store:
    """One sweep directory."""

    root: Path

    def table_dir(self, table: str) -> Path:
        return self.root / table

    @property
    def tmp(self) -> Path:
        return self.root / "tmp"

    def shard(self, table: str, key: str) -> Path:
        return self.table_dir(table) / f"{key}.parquet"

    # ------------------------------------------------------------------ manifest
    def read_manifest(self) -> dict[str, Any]:
        path = self.root / MANIFEST
        if not self.root.exists():
            raise InputError(f"{self.root}: does not exist (expected an experiment directory)")
        if not path.is_file():
            raise InputError(f"{self.root}: not an experiment directory (no {MANIFEST})")
        try:
            return json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise InputError(f"{path}: not a valid manifest (unreadable JSON)") from None

    def open(self, manifest: dict[str, Any], config_toml: str) -> dict[str, Any]:
        """Create the directory for this sweep, or check that it already holds the same sweep.

        Raises InputError if DIR is a file, a non-empty directory of something else, or a
        sweep with another study, version, scale, seed or config.
        """
        root = self.root
        if root.exists() and not root.is_dir():
            raise InputError(f"{root}: exists and is not a directory")
        if (root / MANIFEST).exists():
            old = self.read_manifest()
            if old.get("config_hash") != manifest["config_hash"]:
                raise InputError(f"{root}: holds {_difference(old, manifest)}; refusing to mix results, use "
                                 f"another --out, or delete {root} to start again")
            self._make_dirs()
            return old
        if root.exists() and any(root.iterdir()):
            raise InputError(f"{root}: directory is not empty and holds no experiment; use another --out")
        self._make_dirs()
        write_atomic(root / "config.toml", config_toml, tmp_dir=self.tmp)
        write_atomic(root / MANIFEST, json.dumps(manifest, indent=2) + "\n", tmp_dir=self.tmp)
        return manifest

    @contextlib.contextmanager
    def lock(self):
        """Hold ``DIR/lock`` while writing: a second run on the same DIR is refused, not interleaved.

        The lock is an ``flock`` on the file, so the system releases it when the process ends,
        however it ends; a stale lock file left by a killed run does not block the next one.
        """
        try:
            import fcntl
        except ImportError:  # no flock on this platform: run unlocked
            yield
            return
        fd = os.open(self.root / "lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise InputError(f"{self.root}: another `experiment run` is writing to this directory "
                                 "right now; wait for it or use another --out") from None
            yield
        finally:
            os.close(fd)

    def _make_dirs(self) -> None:
        for d in (*TABLES, "tmp"):
            (self.root / d).mkdir(parents=True, exist_ok=True)

    def clean_tmp(self) -> None:
        """Remove files left in ``tmp/`` by a run that was killed while writing."""
        for p in self.tmp.glob("*.part"):
            with contextlib.suppress(OSError):
                p.unlink()

    # -------------------------------------------------------------------- tables
    def keys(self, table: str) -> set[str]:
        d = self.table_dir(table)
        return {p.stem for p in d.glob("*.parquet")} if d.is_dir() else set()

    def write_table(self, table: str, key: str, arrow_table, *, before_rename=None) -> None:
        """Write one shard atomically (``before_rename`` is a hook used to test interruptions)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        sink = pa.BufferOutputStream()
        pq.write_table(arrow_table, sink, compression="zstd")
        data = sink.getvalue().to_pybytes()
        with atomic_open(self.shard(table, key), "wb", tmp_dir=self.tmp) as fh:
            if before_rename is not None:
                fh.write(data[: len(data) // 2])
                fh.flush()
                before_rename()
            fh.write(data[len(data) // 2:] if before_rename is not None else data)

    def remove(self, table: str, key: str) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.shard(table, key).unlink()
            fsync_dir(self.table_dir(table))

    def read(self, table: str, keys: Iterable[str] | None = None):
        """Concatenate the shards of ``table`` (all, or those of ``keys``) into one Arrow table."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        names = sorted(self.keys(table) if keys is None else set(keys) & self.keys(table))
        tables = [pq.read_table(self.shard(table, k)) for k in names]
        if not tables:
            return None
        return pa.concat_tables(tables, promote_options="default")

    def n_rows(self, keys: Iterable[str]) -> int:
        import pyarrow.parquet as pq

        return sum(pq.read_metadata(self.shard("rows", k)).num_rows for k in keys)


# ------------------------------------------------------------------------ reading
def progress(store: Store, keys: Iterable[str]) -> tuple[set[str], set[str]]:
    """``(done, failed)`` among the task ``keys``: done has a row shard; failed has a failure shard
    and no row shard (a retried task that finished may keep its old failure until the next run)."""
    keys = set(keys)
    done = store.keys("rows") & keys
    return done, (store.keys("failures") & keys) - done


@dataclass(frozen=True)
class SweepDir:
    """A sweep directory opened for reading: its manifest and which of its tasks are done or failed.

    Attributes:
        store: the directory.
        manifest: ``manifest.json``.
        tasks, done, failed: task keys: all of the manifest's, those finished, those failed (and
            not finished since).
    """

    store: Store
    manifest: dict[str, Any]
    tasks: frozenset[str]
    done: frozenset[str]
    failed: frozenset[str]

    @classmethod
    def open(cls, root) -> SweepDir:
        """Read ``root``'s manifest and progress; a one-line InputError if it holds no sweep."""
        store = Store(Path(root))
        manifest = store.read_manifest()
        if not isinstance(manifest, dict) or "study" not in manifest or "task_keys" not in manifest:
            raise InputError(f"{store.root / MANIFEST}: not a sweep manifest (no study or task_keys)")
        keys = set(manifest["task_keys"])
        done, failed = progress(store, keys)
        return cls(store, manifest, frozenset(keys), frozenset(done), frozenset(failed))

    @property
    def root(self) -> Path:
        return self.store.root

    def frame(self, table: str, keys: Iterable[str], sort_by: Iterable[str] = ("task",)):
        """The shards of ``table`` among ``keys`` as one pandas DataFrame, stably sorted by the
        ``sort_by`` columns it has (the shards' order where it has none); None where no shard is."""
        arrow = self.store.read(table, keys)
        if arrow is None:
            return None
        df = arrow.to_pandas()
        by = [c for c in sort_by if c in df.columns]
        return df.sort_values(by, kind="stable").reset_index(drop=True) if by else df

    def n_rows(self) -> int:
        """Rows of the finished tasks (from the shards' metadata)."""
        return self.store.n_rows(self.done)

    def runs(self) -> tuple[dict[str, Any], ...]:
        """The records in ``runs/*.json``, oldest first; unreadable ones are skipped."""
        out = []
        for path in sorted((self.root / "runs").glob("*.json")):
            try:
                record = json.loads(path.read_text())
            except (OSError, UnicodeDecodeError, json.JSONDecodeError):
                continue
            if isinstance(record, dict):
                out.append(record)
        return tuple(sorted(out, key=lambda r: str(r.get("started", ""))))
