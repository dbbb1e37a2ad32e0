"""Simulation-based calibration (SBC; Talts et al. 2018, "Validating Bayesian inference
algorithms with simulation-based calibration").

Draw a truth from the prior, simulate data from it, and draw from the sampler's posterior
given those data. If the sampler is exact, the truth is one more draw from that posterior,
so its **rank** among ``L`` independent posterior draws (how many draws are smaller) is
uniform on ``{0, 1, …, L}``, for every scalar quantity. Over many simulated truths:

- :func:`rank_histogram` counts the ranks in ``B`` bins and :func:`uniformity_test` tests
  the counts against uniformity with Pearson's χ² (``scipy.stats.chisquare``). A sampler
  that is too confident piles ranks at both ends (a U), one that is too vague piles them
  in the middle, and a biased one piles them on one side.
- :func:`coverage` is the fraction of truths inside the equal-tailed central interval of
  the posterior (:func:`central_intervals`), with its binomial standard error and the
  Clopper–Pearson interval; :func:`coverage_by_bins` does the same within bins of a
  covariate (e.g. the true β).

**Thinning.** Ranks are uniform only for draws that are independent of one another.
:func:`thin` keeps ``L`` draws evenly spaced over all the draws of a run (chains
concatenated), about ``N / L`` apart for ``N`` draws. When the run's bulk effective sample
size is at least ``L``, that spacing is at least the integrated autocorrelation time
``N / ESS``, so the kept draws are roughly independent; :func:`thinned_enough` checks
it. ``L`` is fixed for all truths, so all ranks share the support ``{0, …, L}``.

Everything here takes plain arrays (truths ``[n]``, draws ``[n, L]`` per quantity) and
knows nothing of the sampler.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import InputError


def _check_truths_draws(truths, draws) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(truths, dtype=np.float64)
    d = np.asarray(draws, dtype=np.float64)
    if t.ndim != 1 or d.ndim != 2 or d.shape[0] != t.shape[0] or d.shape[1] < 1:
        raise InputError(f"truths must be [n] and draws [n, L] with L >= 1, got {t.shape} and {d.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(d))):
        raise InputError("truths and draws must be finite")
    return t, d


def ranks(truths, draws, rng: np.random.Generator | int = 0) -> np.ndarray:
    """Rank of each truth among its draws: ``#{draws < truth}``, an int in ``[0, L]``.

    ``truths [n]``, ``draws [n, L]``. Draws equal to the truth (ties, e.g. a sampler stuck
    on one value) are split at random: the rank is ``#{<} + U`` with ``U`` uniform on
    ``{0, …, #{=}}``, drawn from ``rng``, which keeps the ranks of an exact sampler uniform;
    without ties ``rng`` is not used.
    """
    t, d = _check_truths_draws(truths, draws)
    below = np.sum(d < t[:, None], axis=1)
    equal = np.sum(d == t[:, None], axis=1)
    if equal.any():
        gen = np.random.default_rng(rng)
        below = below + gen.integers(0, equal + 1)
    return below.astype(np.int64)


def rank_histogram(rank: np.ndarray, n_draws: int, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """``(counts [B], expected [B])`` of ranks in ``[0, n_draws]`` over ``bins`` bins.

    Rank ``r`` falls in bin ``floor(r · B / (L + 1))``. When ``B`` divides ``L + 1`` every bin
    holds the same number of rank values; otherwise the expected counts under uniformity
    follow the number of values each bin holds.
    """
    r = np.asarray(rank)
    L = int(n_draws)
    if not 1 <= bins <= L + 1:
        raise InputError(f"bins must be in [1, L + 1] = [1, {L + 1}], got {bins}")
    if r.ndim != 1 or not np.issubdtype(r.dtype, np.integer) or np.any((r < 0) | (r > L)):
        raise InputError(f"ranks must be a 1-D array of integers in [0, {L}]")
    which = r * bins // (L + 1)
    counts = np.bincount(which, minlength=bins)
    per_bin = np.bincount(np.arange(L + 1) * bins // (L + 1), minlength=bins)
    expected = r.size * per_bin / (L + 1)
    return counts, expected


@dataclass(frozen=True)
class UniformityTest:
    """Pearson's χ² test of a rank histogram against uniformity (``bins − 1`` degrees of freedom)."""

    statistic: float
    p_value: float
    dof: int
    counts: list[int]
    expected: list[float]

    def to_dict(self) -> dict:
        return asdict(self)


def uniformity_test(rank: np.ndarray, n_draws: int, bins: int) -> UniformityTest:
    """χ² test that ``rank`` (ints in ``[0, n_draws]``) is uniform, on a ``bins``-bin histogram.

    The χ² approximation wants about 5 or more expected per bin; choose ``bins`` ≲ n / 5.
    """
    from scipy.stats import chisquare

    counts, expected = rank_histogram(rank, n_draws, bins)
    res = chisquare(counts, expected)
    return UniformityTest(float(res.statistic), float(res.pvalue), bins - 1,
                          counts.tolist(), expected.tolist())


def thin(draws, n_keep: int) -> np.ndarray:
    """``n_keep`` draws evenly spaced over ``draws [C, D, ...]`` (chains concatenated).

    Returns ``[n_keep, ...]``: draws ``round(linspace(0, C·D − 1, n_keep))`` of the
    concatenated chains, so the same draws of a run serve every quantity (pass θ and β
    stacked on the last axes, or thin each with the same ``C, D``).
    """
    d = np.asarray(draws)
    if d.ndim < 2:
        raise InputError(f"draws must be [chains, draws, ...], got shape {d.shape}")
    flat = d.reshape(d.shape[0] * d.shape[1], *d.shape[2:])
    if not 1 <= n_keep <= flat.shape[0]:
        raise InputError(f"n_keep must be in [1, {flat.shape[0]}] (the run's draws), got {n_keep}")
    return flat[np.round(np.linspace(0, flat.shape[0] - 1, n_keep)).astype(np.int64)]


def thinned_enough(ess: float | None, n_keep: int) -> bool:
    """Whether ``n_keep`` evenly spaced draws of a run with bulk ESS ``ess`` are about
    independent (``ess ≥ n_keep``; see the module's note on thinning). ``None`` (ESS not
    computable) is ``False``."""
    return ess is not None and bool(np.isfinite(ess)) and ess >= n_keep


def central_intervals(draws, prob: float = 0.9) -> tuple[np.ndarray, np.ndarray]:
    """``(low [n], high [n])``: the equal-tailed ``prob`` interval of each row of ``draws [n, M]``
    (the ``(1 − prob)/2`` and ``(1 + prob)/2`` quantiles, NumPy's linear interpolation)."""
    d = np.asarray(draws, dtype=np.float64)
    if d.ndim != 2 or not 0 < prob < 1:
        raise InputError(f"draws must be [n, M] and 0 < prob < 1, got {d.shape} and {prob}")
    lo, hi = np.quantile(d, [(1 - prob) / 2, (1 + prob) / 2], axis=1)
    return lo, hi


@dataclass(frozen=True)
class Coverage:
    """How many of ``n`` truths lie inside their intervals.

    ``rate = covered / n``; ``se`` its binomial standard error ``sqrt(rate (1 − rate) / n)``;
    ``ci_low``, ``ci_high`` the 95% Clopper–Pearson interval of the true coverage. With
    ``n = 0`` the rate and its intervals are NaN.
    """

    covered: int
    n: int
    rate: float
    se: float
    ci_low: float
    ci_high: float

    def to_dict(self) -> dict:
        return asdict(self)


def coverage(truths, low, high, confidence: float = 0.95) -> Coverage:
    """Fraction of ``truths [n]`` with ``low ≤ truth ≤ high`` (``low``, ``high`` ``[n]``)."""
    from scipy.stats import binomtest

    t, lo, hi = (np.asarray(a, dtype=np.float64) for a in (truths, low, high))
    if not (t.ndim == 1 and t.shape == lo.shape == hi.shape):
        raise InputError(f"truths, low and high must be [n] alike, got {t.shape}, {lo.shape}, {hi.shape}")
    n = int(t.size)
    k = int(np.sum((lo <= t) & (t <= hi)))
    if n == 0:
        nan = float("nan")
        return Coverage(0, 0, nan, nan, nan, nan)
    rate = k / n
    ci = binomtest(k, n).proportion_ci(confidence_level=confidence, method="exact")
    return Coverage(k, n, rate, float(np.sqrt(rate * (1 - rate) / n)), float(ci.low), float(ci.high))


def coverage_by_bins(truths, low, high, covariate, edges) -> list[tuple[float, float, Coverage]]:
    """:func:`coverage` within bins of ``covariate [n]``: ``[(lo, hi, Coverage), ...]``.

    Bin ``i`` holds ``edges[i] ≤ covariate < edges[i + 1]``; the last bin includes its upper
    edge. Values outside ``[edges[0], edges[-1]]`` are in no bin.
    """
    t, lo, hi, c = (np.asarray(a, dtype=np.float64) for a in (truths, low, high, covariate))
    e = np.asarray(edges, dtype=np.float64)
    if e.ndim != 1 or e.size < 2 or np.any(np.diff(e) <= 0):
        raise InputError(f"edges must be increasing with at least 2 values, got {list(edges)}")
    if c.shape != t.shape:
        raise InputError(f"covariate must be [n] like truths, got {c.shape} and {t.shape}")
    out = []
    for i in range(e.size - 1):
        last = i == e.size - 2
        inside = (c >= e[i]) & ((c <= e[i + 1]) if last else (c < e[i + 1]))
        out.append((float(e[i]), float(e[i + 1]), coverage(t[inside], lo[inside], hi[inside])))
    return out
