"""Pearson tables in the paper's form (ρ to 2 decimals, † where p < 0.05, and n) and small summaries."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .parts import Table
from .stats import EXTRA_METRICS, METRIC_RANGE, METRICS, clip_ci, fmt, mean_ci

ALPHA = 0.05
CONSTANT = "n/a (constant)"


class PearsonCell(NamedTuple):
    rho: float
    p: float
    n: int
    text: str


def format_rho(rho: float, p: float) -> str:
    """``0.57†`` (p < 0.05) or ``−0.06``: two decimals, a true minus sign, no ``−0.00``."""
    s = f"{rho:.2f}"
    if s in ("-0.00", "0.00"):
        s = "0.00"
    s = s.replace("-", "−")
    return s + ("†" if p < ALPHA else "")


def pearson_cell(x, y) -> PearsonCell:
    """Pearson ρ and p of ``x`` and ``y`` (pairs with a NaN dropped); text "n/a (...)" where undefined."""
    from scipy import stats

    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    n = len(x)
    if n < 3:
        return PearsonCell(np.nan, np.nan, n, f"n/a (n = {n})")
    if np.ptp(x) == 0 or np.ptp(y) == 0:
        return PearsonCell(np.nan, np.nan, n, CONSTANT)
    r = stats.pearsonr(x, y)
    rho, p = float(r.statistic), float(r.pvalue)
    return PearsonCell(rho, p, n, format_rho(rho, p))


@dataclass(frozen=True)
class PearsonRow:
    """One row of a Pearson table: ``factor`` against every metric over ``frame``.

    ``missing`` is the text written in every cell when ``frame`` lacks the factor column.
    """

    label: str
    frame: object  # pandas.DataFrame
    factor: str
    missing: str = "n/a (column missing)"


def pearson_table(name: str, title: str, caption: str, rows: list[PearsonRow],
                  metrics: dict[str, str] = METRICS, first: str = "Factor") -> Table:
    import pandas as pd

    display, data = [], []
    for row in rows:
        shown = {first: row.label}
        ns = set()
        for col, label in metrics.items():
            if row.factor not in row.frame.columns:
                cell = PearsonCell(np.nan, np.nan, 0, row.missing)
            else:
                cell = pearson_cell(row.frame[row.factor], row.frame[col])
            ns.add(cell.n)
            shown[label] = cell.text
            data.append({"row": row.label, "factor": row.factor, "metric": col, "rho": cell.rho,
                         "p": cell.p, "n": cell.n, "significant": bool(cell.p < ALPHA), "cell": cell.text})
        shown["n"] = "/".join(str(n) for n in sorted(ns))
        display.append(shown)
    caption = (caption + " Pearson ρ (scipy.stats.pearsonr) over the rows named, † where p < 0.05; "
               "n = rows used (pairs with a missing value dropped).")
    return Table(name, title, caption, pd.DataFrame(display), pd.DataFrame(data))


def factor_rows(frame, factors: dict[str, str], missing: dict[str, str] | None = None) -> list[PearsonRow]:
    """Rows for the usual case: several factors over one frame."""
    missing = missing or {}
    return [PearsonRow(label, frame, col, missing.get(col, "n/a (column missing)"))
            for col, label in factors.items()]


def means_table(name: str, title: str, caption: str, frame, by: list[str],
                metrics: dict[str, str] | None = None) -> Table:
    """Mean [95% CI] and n of each metric per group of ``by`` (default: :data:`.stats.METRICS`, and
    :data:`.stats.EXTRA_METRICS` where ``frame`` has them)."""
    import pandas as pd

    if metrics is None:
        metrics = {**METRICS, **{c: label for c, label in EXTRA_METRICS.items() if c in frame.columns}}
    display, data = [], []
    for key, g in frame.groupby(by, sort=False, observed=True):  # in the order the frame holds them
        key = key if isinstance(key, tuple) else (key,)
        shown = dict(zip(by, key, strict=True))
        rec = dict(shown)
        for col, label in metrics.items():
            ci = clip_ci(mean_ci(g[col]), METRIC_RANGE.get(col, (-np.inf, np.inf)))
            shown[label] = (f"{fmt(ci.mean)} [{fmt(ci.low)}, {fmt(ci.high)}]" if np.isfinite(ci.half)
                            else f"{fmt(ci.mean)} [n/a: n = {ci.n}]")
            rec.update({f"{col}_mean": ci.mean, f"{col}_ci_low": ci.low, f"{col}_ci_high": ci.high})
        shown["n"] = len(g)
        rec["n"] = len(g)
        display.append(shown)
        data.append(rec)
    return Table(name, title, caption + " Mean [95% CI] (Student t, clipped to the metric's range) per "
                 "group.", pd.DataFrame(display),
                 pd.DataFrame(data))
