"""The package's exceptions, under one base, and the helpers of their messages.

Every exception the package raises on purpose derives from :class:`ExpertiseIRLError`, so
``except ExpertiseIRLError`` catches them all:

- :class:`InputError` (a :class:`ValueError`): something the user gave (a map, a demonstration
  file, a parameter's value) is invalid; the one-line message names the file and the line or
  step at fault. The command line shows it on stderr with exit code 2 and no traceback.
- :class:`ConvergenceError` (a :class:`RuntimeError`): soft value iteration did not reach its
  tolerance; the command line shows it with exit code 1.
- :class:`ArgumentError` (a :class:`ValueError`): code called a function of the package with an
  array of the wrong shape (a table, counts, start values the package builds itself). It is a
  programming error, not the user's: the command line lets it through as a bug, with its
  traceback.
"""

from __future__ import annotations

from pathlib import Path


class ExpertiseIRLError(Exception):
    """The base of every exception the package raises on purpose."""


class InputError(ExpertiseIRLError, ValueError):
    """A user-supplied input is invalid; the message says where and why."""


class ConvergenceError(ExpertiseIRLError, RuntimeError):
    """Soft value iteration did not reach its tolerance within ``max_iter`` backups."""


class ArgumentError(ExpertiseIRLError, ValueError):
    """A function of the package was called with an array of the wrong shape.

    A programming error (the caller built it wrong), not the user's data.
    """


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
