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
#: Metrics shown beside :data:`METRICS` where the rows have them (rows written before they existed do not).
EXTRA_METRICS = {"return_regret": "Return regret"}
#: Axis labels of the metrics.
METRIC_AXES = {
    "cosine_similarity": "cosine similarity (θ*, θ̂)",
    "expertise_distance": "|β* − β̂|",
    "policy_regret": "policy regret (Eq. 17)",
    "return_regret": "return regret (θ̂'s optimal policy under θ*)",
}
#: The range each metric can take (θ ≥ 0, so the cosine is in [0, 1]); CIs are clipped to it.
METRIC_RANGE = {"cosine_similarity": (0.0, 1.0), "expertise_distance": (0.0, np.inf),
                "policy_regret": (0.0, np.inf), "return_regret": (0.0, np.inf)}
#: True where a larger value of the metric is better.
HIGHER_IS_BETTER = {"cosine_similarity": True, "expertise_distance": False, "policy_regret": False,
                    "return_regret": False}


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


def _unit_totals(values, clusters, units):
    """Per (cluster, unit): the sum of ``values`` and the row count; with each unit's cluster."""
    import pandas as pd

    frame = pd.DataFrame({"v": np.asarray(values, dtype=np.float64), "c": np.asarray(clusters, dtype=object),
                          "u": np.arange(len(values)) if units is None else np.asarray(units, dtype=object)})
    agg = frame.groupby(["c", "u"], sort=True, observed=True)["v"].agg(["sum", "count"]).reset_index()
    return agg["c"].to_numpy(), agg["sum"].to_numpy(np.float64), agg["count"].to_numpy(np.float64)


def _draw_units(rng, k, sums, counts):
    """Each resample's units of one map: the map drawn ``k[b]`` times, each time its units drawn with
    replacement as many as it holds; returns (B,) sums of values and of rows."""
    m = len(sums)
    if m == 0:
        return np.zeros(len(k)), np.zeros(len(k))
    w = rng.multinomial(k * m, np.full(m, 1.0 / m))  # (B, m): how often each unit is drawn
    return w @ sums, w @ counts


def cluster_bootstrap_means(num, den, clusters, *, paired: bool, units=None, resamples: int = RESAMPLES,
                            seed: int = BOOTSTRAP_SEED):
    """Two-stage cluster bootstrap: ``resamples`` replicates of (mean(num), mean(den)).

    Stage 1 draws as many maps (``clusters``, e.g. ``environment``) as there are, with replacement;
    stage 2 draws, within each drawn map, as many units as it holds, with replacement (a map drawn
    twice contributes two independent draws of its units). ``units`` labels the units within a map
    (default: each row is one; a unit's rows move together, e.g. one instance at several episode
    counts). ``paired``: ``num[i]`` and ``den[i]`` are one row and ``clusters``/``units`` are arrays
    for both; otherwise they are pairs ``(for num, for den)`` and the two sides are drawn apart
    within the same drawn maps (maps are shared, the people on each side are not).
    """
    rng = np.random.default_rng(seed)
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    if paired:
        clusters, units = (clusters, clusters), (units, units)
    elif units is None:
        units = (None, None)
    cn, sn, nn = _unit_totals(num, clusters[0], units[0])
    cd, sd, nd = _unit_totals(den, clusters[1], units[1])
    labels = sorted(set(cn) | set(cd), key=str)
    g = len(labels)
    k_all = rng.multinomial(g, np.full(g, 1.0 / g), size=resamples)  # (B, G): times each map is drawn
    tot = np.zeros((4, resamples))
    for j, label in enumerate(labels):
        k = k_all[:, j]
        a, b = cn == label, cd == label
        if paired:  # one unit holds both sides: one draw
            m = int(a.sum())
            w = rng.multinomial(k * m, np.full(m, 1.0 / m))
            tot += np.stack([w @ sn[a], w @ nn[a], w @ sd[b], w @ nd[b]])
        else:
            tot += np.stack([*_draw_units(rng, k, sn[a], nn[a]), *_draw_units(rng, k, sd[b], nd[b])])
    with np.errstate(divide="ignore", invalid="ignore"):
        return tot[0] / tot[1], tot[2] / tot[3]


def percentile_ci(replicates, level: float = 0.95) -> tuple[float, float]:
    """The percentile interval of bootstrap ``replicates``; (NaN, NaN) if any is undefined."""
    r = np.asarray(replicates, dtype=np.float64)
    if len(r) == 0 or np.isnan(r).any():
        return (np.nan, np.nan)
    lo, hi = np.quantile(r, [(1 - level) / 2, (1 + level) / 2], method="inverted_cdf")
    return float(lo), float(hi)


def cluster_ratio_ci(num, den, clusters, *, paired: bool, units=None, level: float = 0.95,
                     resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED) -> tuple[float, float]:
    """Percentile CI of ``mean(num) / mean(den)`` by the two-stage cluster bootstrap
    (:func:`cluster_bootstrap_means`)."""
    if len(num) == 0 or len(den) == 0:
        return (np.nan, np.nan)
    a, b = cluster_bootstrap_means(num, den, clusters, paired=paired, units=units, resamples=resamples,
                                   seed=seed)
    with np.errstate(divide="ignore", invalid="ignore"):
        return percentile_ci(a / b, level)


def cluster_difference_ci(num, den, clusters, *, paired: bool, units=None, level: float = 0.95,
                          resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED) -> tuple[float, float]:
    """Percentile CI of ``mean(num) − mean(den)`` by the two-stage cluster bootstrap."""
    if len(num) == 0 or len(den) == 0:
        return (np.nan, np.nan)
    a, b = cluster_bootstrap_means(num, den, clusters, paired=paired, units=units, resamples=resamples,
                                   seed=seed)
    return percentile_ci(a - b, level)


#: Paired values this close are a tie, a zero difference (before the Wilcoxon test and before the sign
#: of a mean difference is taken): |a − b| ≤ TIE_ATOL + TIE_RTOL·max(|a|, |b|). Rows that differ only
#: in floating-point noise (1e-16 against an exact 0) must not decide a verdict.
TIE_RTOL, TIE_ATOL = 1e-9, 1e-12
#: The fewest rows per side a bootstrap CI (ratio, difference) or a mix-adjusted ratio's group is
#: computed from: the fewest pairs with which a two-sided Wilcoxon test can reach p < 0.05 (2 / 2**6).
MIN_BOOTSTRAP_N = 6


def paired_differences(a, b, rtol: float = TIE_RTOL, atol: float = TIE_ATOL) -> np.ndarray:
    """``a − b`` with every tie (:data:`TIE_RTOL`, :data:`TIE_ATOL`) set to exactly 0."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    d = a - b
    with np.errstate(invalid="ignore"):
        tie = np.abs(d) <= atol + rtol * np.maximum(np.abs(a), np.abs(b))
    return np.where(tie, 0.0, d)


def wilcoxon_p(a, b, alternative: str = "two-sided") -> float:
    """p of the Wilcoxon signed-rank test of the pairs (``a[i]``, ``b[i]``) (scipy.stats.wilcoxon;
    ``alternative`` "less": a below b, "greater": a above b). Ties (:func:`paired_differences`) are
    dropped before the test; NaN if every pair is a tie (or there are none)."""
    from scipy import stats

    d = paired_differences(a, b)
    d = d[np.isfinite(d)]
    d = d[d != 0]
    if len(d) == 0:
        return float("nan")
    return float(stats.wilcoxon(d, zero_method="wilcox", alternative=alternative).pvalue)


def fisher_ci(rho: float, n: int, level: float = 0.95) -> tuple[float, float]:
    """The Fisher-z CI of a Pearson ρ over ``n`` pairs: tanh(atanh ρ ± z/√(n − 3)); (NaN, NaN) if
    n < 4 or ρ is undefined."""
    from scipy import stats

    if not np.isfinite(rho) or n < 4:
        return (np.nan, np.nan)
    with np.errstate(divide="ignore"):
        z = float(np.arctanh(np.clip(rho, -1.0, 1.0)))
    half = float(stats.norm.ppf(0.5 + level / 2)) / np.sqrt(n - 3)
    return float(np.tanh(z - half)), float(np.tanh(z + half))


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


def paired(frame, index: list[str], column: str, values: str, a: str, b: str, keep=()):
    """Rows of ``frame`` with ``column`` == a and == b matched on ``index``: DataFrame with columns a, b
    (and the columns ``keep``, each key's first value, e.g. ``group_true``), indexed by ``index``.

    Only keys present in both are kept (a person scored under both conditions).
    """
    import pandas as pd

    if a == b:
        return pd.DataFrame(columns=[a, *keep])
    sub = frame[frame[column].isin([a, b])]
    wide = sub.pivot_table(index=index, columns=column, values=values, aggfunc="first", observed=True)
    if a not in wide.columns or b not in wide.columns:
        return pd.DataFrame(columns=[a, b, *keep])
    out = wide[[a, b]].dropna()
    out.columns = list(out.columns)
    if keep:
        extra = sub.groupby(index, observed=True)[list(keep)].first()
        out = out.join(extra)
    return out


def level(frame, name: str):
    """The values of ``name`` for each row of ``frame``: an index level or a column."""
    if name in getattr(frame.index, "names", ()):
        return frame.index.get_level_values(name).to_numpy()
    return frame[name].to_numpy()
