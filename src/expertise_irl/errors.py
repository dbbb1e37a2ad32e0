"""Exceptions raised on bad user input.

Every problem with something the user gave us (a map, a demonstration file, a
parameter) is raised as :class:`InputError` with a one-line message that names
the file and the line or step at fault. The command-line interface turns these
into a message on stderr and exit code 2, with no traceback.
"""

from __future__ import annotations

from pathlib import Path


class InputError(ValueError):
    """A user-supplied input is invalid; the message says where and why."""


class ConvergenceError(RuntimeError):
    """Soft value iteration did not reach its tolerance within ``max_iter`` backups."""


def where(source: str | Path | None, line: int | None = None, col: int | None = None) -> str:
    """Format a location prefix such as ``maps/a.txt:3:7: `` (empty if unknown)."""
    if source is None:
        return ""
    loc = str(source)
    if line is not None:
        loc += f":{line}"
        if col is not None:
            loc += f":{col}"
    return loc + ": "


def read_text(path: str | Path, problem: str = "not a text file (UTF-8)", *, encoding: str = "utf-8") -> str:
    """The text of a user's file; one that is not ``encoding`` raises :class:`InputError`
    ``path: problem``."""
    try:
        return Path(path).read_text(encoding=encoding)
    except UnicodeDecodeError:
        raise InputError(f"{path}: {problem}") from None


def plural(n: int, noun: str) -> str:
    """``"1 episode"``, ``"2 episodes"``: a count and its noun in agreement (regular plurals)."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def os_reason(exc: OSError) -> str:
    """The system's reason in the words of the package's own messages ("no such file", lower case)."""
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    text = exc.strerror or str(exc)
    return text[:1].lower() + text[1:]
