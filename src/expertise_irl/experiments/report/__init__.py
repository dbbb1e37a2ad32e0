"""Reports of sweeps: figures, Pearson tables and the paper's claims with computed verdicts.

``build_report(DIR, out)`` reads one sweep directory alone (``manifest.json``, the Parquet rows and
timings, ``runs/*.json``), dispatches on the manifest's study to that study's report (:mod:`.conditions`,
:mod:`.cardinality`, :mod:`.optimisation`, :mod:`.fullset`) and writes, into ``out``
(default ``DIR/report``): ``report.md``, ``figures/figN.png`` and ``.pdf``, ``tables/*.csv`` and
``claims.csv``.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import import_module
from pathlib import Path

from ...errors import InputError
from .sweep import Sweep, check_directory, read_sweep

#: study name -> (module of its report, the identity columns its rows are sorted by)
REPORTS = {
    "conditions": ("fixed_vs_joint", ("environment", "run", "k", "group", "truth", "condition", "method",
                                  "episodes")),
    "cardinality": ("cardinality", ("environment", "run", "k", "group", "truth", "condition", "method",
                                    "episodes")),
    "optimisation": ("optimisation", ("environment", "instance", "method", "episodes")),
    "fullset": ("fullset", ("source", "environment", "run", "k", "group", "instance", "set", "episodes")),
}

__all__ = ["REPORTS", "Sweep", "build_report", "read_sweep"]


def _study_of(root: Path) -> str:
    from ..store import Store

    check_directory(root)
    manifest = Store(root).read_manifest()
    study = manifest.get("study") if isinstance(manifest, dict) else None
    if study not in REPORTS:
        raise InputError(f"{root / 'manifest.json'}: no report for study {study!r} "
                         f"(reports: {', '.join(REPORTS)})")
    return study


def build_report(root, out=None, *, on_warning: Callable[[str], None] | None = None) -> Path:
    """Build the report of the sweep in ``root`` into ``out`` (default ``root/report``).

    Returns the path of ``report.md``. ``on_warning`` is called with one line per problem that
    does not stop the report (a sweep at scale ``smoke``, whose verdicts mean nothing; tasks still
    unfinished).
    """
    from .markdown import smoke_warning, unfinished_warning
    from .output import write

    root = Path(root)
    out = Path(out) if out is not None else root / "report"
    study = _study_of(root)
    module, sort_by = REPORTS[study]
    sweep = read_sweep(root, sort_by)
    report = import_module(f"{__name__}.{module}").build(sweep)
    path = write(report, sweep, out)
    for warn in (smoke_warning(report, sweep), unfinished_warning(sweep)):
        if warn and on_warning is not None:
            on_warning(warn)
    return path
