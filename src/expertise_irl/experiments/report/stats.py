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


def clip_ci(ci: MeanCI, bounds: tuple[float, float]) -> MeanCI:
    """``ci`` with its interval clipped to ``bounds``, the range the metric can take."""
    lo, hi = bounds
    return MeanCI(ci.mean, max(ci.low, lo) if np.isfinite(ci.low) else ci.low,
                  min(ci.high, hi) if np.isfinite(ci.high) else ci.high, ci.n)


#: Bootstrap of a ratio of means: resamples and the seed of its ``numpy`` Generator (fixed, so a
#: report is the same every time it is built from the same rows).
RESAMPLES, BOOTSTRAP_SEED = 2000, 0


def ratio_ci(num, den, *, paired: bool, level: float = 0.95, resamples: int = RESAMPLES,
             seed: int = BOOTSTRAP_SEED) -> tuple[float, float]:
    """Percentile-bootstrap CI of ``mean(num) / mean(den)``.

    ``paired``: ``num[i]`` and ``den[i]`` belong together (the same person under two conditions)
    and are resampled together; otherwise each side is resampled on its own. (NaN, NaN) where
    a resample's ratio is undefined (0 / 0) or there are no values.
    """
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    if paired and len(num) != len(den):
        raise ValueError("paired ratio: num and den must have the same length")
    if len(num) == 0 or len(den) == 0:
        return (np.nan, np.nan)
    rng = np.random.default_rng(seed)
    chunk = max(1, 2_000_000 // max(len(num), len(den)))  # resamples drawn at once (memory)
    ratios = []
    for start in range(0, resamples, chunk):
        m = min(chunk, resamples - start)
        i = rng.integers(0, len(num), size=(m, len(num)))
        j = i if paired else rng.integers(0, len(den), size=(m, len(den)))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios.append(num[i].mean(axis=1) / den[j].mean(axis=1))
    r = np.concatenate(ratios)
    if np.isnan(r).any():
        return (np.nan, np.nan)
    lo, hi = np.quantile(r, [(1 - level) / 2, (1 + level) / 2], method="inverted_cdf")
    return float(lo), float(hi)


def wilcoxon_p(differences) -> float:
    """Two-sided p of the Wilcoxon signed-rank test of paired differences (NaN if all are zero)."""
    from scipy import stats

    d = np.asarray(differences, dtype=np.float64)
    d = d[np.isfinite(d)]
    if len(d) == 0 or not np.any(d != 0):
        return float("nan")
    return float(stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided").pvalue)


MINUS = "−"


def fmt(x: float, digits: int = 3) -> str:
    """A number for a sentence: 3 significant digits, scientific below 1e-3, a true minus sign "−"
    (never "−0")."""
    if x is None or not np.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    if abs(x) < 1e-3 or abs(x) >= 1e5:
        return f"{x:.{max(digits - 1, 0)}e}".replace("-", MINUS)
    s = f"{x:.{digits}g}"
    return "0" if float(s) == 0 else s.replace("-", MINUS)


def fmt_p(p: float) -> str:
    if p is None or not np.isfinite(p):
        return "n/a"
    return f"{p:.2g}" if p >= 1e-3 else f"{p:.1e}".replace("-", MINUS)


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
