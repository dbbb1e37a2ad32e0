"""Small statistics shared by figures, tables and claims: means with 95% CIs, paired tests."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Metric columns and how the paper names them (Sec. V-E), in the paper's table order.
METRICS = {
    "cosine_similarity": "Preferences similarity",
    "expertise_distance": "Expertise distance",
    "policy_regret": "Regret",
}
#: Axis labels of the metrics.
METRIC_AXES = {
    "cosine_similarity": "cosine similarity (θ*, θ̂)",
    "expertise_distance": "|β* − β̂|",
    "policy_regret": "policy regret (Eq. 17)",
}
#: The range each metric can take (θ ≥ 0, so the cosine is in [0, 1]); CIs are clipped to it.
METRIC_RANGE = {"cosine_similarity": (0.0, 1.0), "expertise_distance": (0.0, np.inf),
                "policy_regret": (0.0, np.inf)}
#: True where a larger value of the metric is better.
HIGHER_IS_BETTER = {"cosine_similarity": True, "expertise_distance": False, "policy_regret": False}
GROUPS = ("high", "medium", "low")


class MeanCI(NamedTuple):
    """Mean of ``n`` values and its 95% confidence interval (Student t; NaN half-width if n < 2)."""

    mean: float
    low: float
    high: float
    n: int

    @property
    def half(self) -> float:
        return (self.high - self.low) / 2


def mean_ci(values, level: float = 0.95) -> MeanCI:
    from scipy import stats

    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    n = len(x)
    if n == 0:
        return MeanCI(np.nan, np.nan, np.nan, 0)
    m = float(x.mean())
    if n < 2:
        return MeanCI(m, np.nan, np.nan, 1)
    half = float(stats.t.ppf(0.5 + level / 2, n - 1) * x.std(ddof=1) / np.sqrt(n))
    return MeanCI(m, m - half, m + half, n)


def wilcoxon_p(differences) -> float:
    """Two-sided p of the Wilcoxon signed-rank test of paired differences (NaN if all are zero)."""
    from scipy import stats

    d = np.asarray(differences, dtype=np.float64)
    d = d[np.isfinite(d)]
    if len(d) == 0 or not np.any(d != 0):
        return float("nan")
    return float(stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided").pvalue)


def fmt(x: float, digits: int = 3) -> str:
    """A number for a sentence: 3 significant digits, scientific below 1e-3 (never "-0")."""
    if x is None or not np.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    if abs(x) < 1e-3 or abs(x) >= 1e5:
        return f"{x:.{max(digits - 1, 0)}e}"
    s = f"{x:.{digits}g}"
    return "0" if float(s) == 0 else s


def fmt_p(p: float) -> str:
    if p is None or not np.isfinite(p):
        return "n/a"
    return f"{p:.2g}" if p >= 1e-3 else f"{p:.1e}"


def paired(frame, index: list[str], column: str, values: str, a: str, b: str):
    """Rows of ``frame`` with ``column`` == a and == b matched on ``index``: DataFrame with columns a, b.

    Only keys present in both are kept (a person scored under both conditions).
    """
    sub = frame[frame[column].isin([a, b])]
    wide = sub.pivot_table(index=index, columns=column, values=values, aggfunc="first", observed=True)
    if a not in wide.columns or b not in wide.columns:
        import pandas as pd

        return pd.DataFrame(columns=[a, b])
    return wide[[a, b]].dropna()
