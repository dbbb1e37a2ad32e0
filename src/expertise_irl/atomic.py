"""Every output file is written atomically: to a temporary file in the same folder, flushed to
disk (fsync), then renamed onto its path (``os.replace``, atomic on one file system), and the
folder synced. A reader sees the old file or the whole new one, never half; a run stopped on the
way (an error, Ctrl-C, SIGTERM) removes its temporary file and leaves nothing at the path.

Temporary files are hidden (``.NAME.XXXX.tmp``) beside the output, or, with ``tmp_dir``, in that
folder (``NAME.XXXX.part``; it must be on the same file system).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any


def fsync_dir(path: str | Path) -> None:
    """Flush a folder's entries (a rename in it) to disk, where the file system allows it."""
    with contextlib.suppress(OSError):  # not every file system lets a directory be opened
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _umask() -> int:
    """The process umask, read once (reading it means setting it; doing that per write would race
    with threads that create files meanwhile)."""
    global _UMASK
    if _UMASK is None:
        _UMASK = os.umask(0o022)
        os.umask(_UMASK)
    return _UMASK


_UMASK: int | None = None


@contextlib.contextmanager
def atomic_path(path: str | Path, *, tmp_dir: str | Path | None = None) -> Iterator[Path]:
    """A temporary path to write ``path``'s content to; when the block ends normally the file is
    fsynced and renamed onto ``path``; when it raises (KeyboardInterrupt included) it is removed.
    The file gets the mode a plain ``open`` would give it."""
    path = Path(path)
    if tmp_dir is None:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    else:
        fd, name = tempfile.mkstemp(dir=tmp_dir, prefix=f"{path.name}.", suffix=".part")
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_dir(path.parent)


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", *, tmp_dir: str | Path | None = None,
                **open_args: Any) -> Iterator[IO]:
    """``open(path, mode, **open_args)`` through :func:`atomic_path` (``mode``: ``"w"`` or ``"wb"``)."""
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open writes a new file: mode 'w' or 'wb', not {mode!r}")
    with atomic_path(path, tmp_dir=tmp_dir) as tmp, open(tmp, mode, **open_args) as fh:
        yield fh


def write_atomic(path: str | Path, data: bytes | str, *, tmp_dir: str | Path | None = None) -> Path:
    """Write ``data`` (text as UTF-8) to ``path`` atomically; returns ``path``."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with atomic_open(path, "wb", tmp_dir=tmp_dir) as fh:
        fh.write(raw)
    return Path(path)


def save_figure_atomic(fig, path: str | Path, **savefig_args: Any) -> Path:
    """``fig.savefig(path, ...)`` atomically, in the format the suffix of ``path`` names (PNG when
    it has none)."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, **savefig_args)
    return path
