"""Writing a report into its folder, never over a user's files.

A report folder holds :data:`MARKER`, listing the files the report wrote (its content depends on the
report alone, never on when it was written). A folder that exists, is not empty and has no marker
is refused; a previous report is replaced (its listed files are removed first; anything else in the
folder is left alone).
"""

from __future__ import annotations

import json
from pathlib import Path

from ...atomic import write_atomic
from ...errors import InputError
from .claims import claims_frame
from .figures import save
from .markdown import render
from .parts import Report

MARKER = ".expertise-irl-report.json"

#: Numbers in the CSV files, to 10 significant digits: a rebuild on another machine (another
#: summation order, another SIMD width) writes the same text, not a different last digit.
FLOAT_FORMAT = "%.10g"


def prepare(out: Path) -> None:
    """Make ``out`` ready for a report: create it, or clear the previous report in it."""
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory; use another --out")
    if out.is_dir() and any(out.iterdir()):
        marker = out / MARKER
        if not marker.is_file():
            raise InputError(f"{out}: directory is not empty and holds no report (no {MARKER}); "
                             "refusing to overwrite, use another --out")
        try:
            listed = json.loads(marker.read_text()).get("files", [])
        except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
            raise InputError(f"{marker}: unreadable report marker; remove the folder or use another "
                             "--out") from None
        root = out.resolve()
        for rel in listed:
            p = (out / rel).resolve()
            if root in p.parents and p.is_file():
                p.unlink()
        for d in ("figures", "tables"):
            sub = out / d
            if sub.is_dir() and not any(sub.iterdir()):
                sub.rmdir()
    out.mkdir(parents=True, exist_ok=True)


def _marker(out: Path, study: str, files: list[str]) -> None:
    """The marker: what wrote the folder, the study and the files; no time, so that rebuilding a
    report from the same rows leaves the folder byte for byte as it was."""
    record = {"written_by": "expertise-irl experiment report", "study": study, "files": sorted(files)}
    write_atomic(out / MARKER, json.dumps(record, indent=2) + "\n")


def write(report: Report, sweep, out: Path) -> Path:
    """Write report.md, figures/, tables/ and claims.csv into ``out``; the path of report.md."""
    out = Path(out)
    prepare(out)
    files: list[str] = []
    _marker(out, report.study, files)
    for f in report.figures:
        files += [str(p.relative_to(out)) for p in save(f.fig, out / "figures", f.name)]
        f.fig.clear()
    tables = [*report.tables, *(s.table for s in report.sections if s.table is not None)]
    if tables:
        (out / "tables").mkdir(exist_ok=True)
    for t in tables:
        path = out / "tables" / f"{t.name}.csv"
        write_atomic(path, t.data.to_csv(index=False, float_format=FLOAT_FORMAT))
        files.append(str(path.relative_to(out)))
    claims = claims_frame(report.claims).to_csv(index=False, float_format=FLOAT_FORMAT)
    write_atomic(out / "claims.csv", claims)
    files.append("claims.csv")
    path = out / "report.md"
    write_atomic(path, render(report, sweep))
    files.append("report.md")
    _marker(out, report.study, files)
    return path
