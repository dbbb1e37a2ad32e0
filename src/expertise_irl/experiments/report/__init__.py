"""Reports of sweeps: figures, Pearson tables and the paper's claims with computed verdicts.

``build_report(DIR, out)`` reads one sweep directory alone (``manifest.json``, the Parquet rows and
timings, ``runs/*.json``), hands it to the report builder its study declares (``Study.report``:
:mod:`.fixed_vs_joint`, :mod:`.cardinality`, :mod:`.optimisation`, :mod:`.fullset`), with the rows
in the study's ``sort_by`` order, and writes, into ``out`` (default ``DIR/report``): ``report.md``,
``figures/figN.png`` and ``.pdf``, ``tables/*.csv`` and ``claims.csv``.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import import_module
from pathlib import Path

from ...errors import InputError
from .sweep import Sweep, check_directory, read_sweep

__all__ = ["Sweep", "build_report", "read_sweep"]


def _study_of(root: Path):
    """The study of the sweep in ``root``, if it has a report; else a one-line InputError."""
    from ..store import Store
    from ..studies import studies

    check_directory(root)
    manifest = Store(root).read_manifest()
    name = manifest.get("study") if isinstance(manifest, dict) else None
    reports = [s.name for s in studies().values() if s.report]
    if name not in reports:
        raise InputError(f"{root / 'manifest.json'}: no report for study {name!r} "
                         f"(reports: {', '.join(reports)})")
    return studies()[name]


def _builder(study) -> Callable:
    module, _, function = study.report.partition(":")
    return getattr(import_module(module), function)


def build_report(root, out=None, *, on_warning: Callable[[str], None] | None = None) -> Path:
    """Build the report of the sweep in ``root`` into ``out`` (default ``root/report``).

    Args:
        root: the sweep directory.
        out: the report's directory.
        on_warning: called with one line per problem that does not stop the report (a sweep at
            scale ``smoke``, whose verdicts mean nothing; tasks still unfinished).

    Returns:
        The path of ``report.md``.

    Raises:
        InputError: ``root`` holds no sweep, its study has no report, or no task has finished.
    """
    from .markdown import smoke_warning, unfinished_warning
    from .output import write

    root = Path(root)
    out = Path(out) if out is not None else root / "report"
    study = _study_of(root)
    sweep = read_sweep(root, study.sort_by)
    report = _builder(study)(sweep)
    path = write(report, sweep, out)
    for warn in (smoke_warning(report, sweep), unfinished_warning(sweep)):
        if warn and on_warning is not None:
            on_warning(warn)
    return path
