"""Running the command line in-process and checking its outcome (shared by the CLI tests)."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from expertise_irl.cli import app


def invoke(*args):
    """Run the CLI in-process; every argument is passed as a string."""
    return CliRunner().invoke(app, [str(a) for a in args])


def ok(result) -> None:
    """The command succeeded and nothing went wrong on the way."""
    assert result.exit_code == 0, f"exit {result.exit_code}\n{result.output}\n{result.exception!r}"
    assert result.exception is None
    assert "Traceback" not in result.output


def assert_input_error(result, *fragments: str) -> str:
    """Exit code 2, exactly one non-empty line ``error: ...`` on stderr naming ``fragments``."""
    assert result.exit_code == 2, f"exit {result.exit_code}\n{result.output}\n{result.exception!r}"
    # A handled error ends in SystemExit(2); an escaped exception would be stored here instead.
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected a one-line error, got {lines}"
    line = lines[0]
    assert line.startswith("error: "), line
    assert line in result.stderr, "the error must go to stderr"
    assert result.stdout.strip() == ""
    for fragment in fragments:
        assert fragment in line, f"{fragment!r} not in {line!r}"
    return line


def load(path: Path) -> dict:
    """A JSON file's content."""
    return json.loads(Path(path).read_text(encoding="utf-8"))


def snapshot(path: Path) -> tuple[bytes, int]:
    """A file's bytes and mtime, to tell that it was left alone."""
    return path.read_bytes(), path.stat().st_mtime_ns
