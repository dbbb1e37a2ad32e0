"""Simulation-based calibration: ranks, histograms, the χ² test, thinning and coverage.

The calibration checks are run on a conjugate Gaussian model whose posterior is known
exactly: μ ~ N(0, 1), one observation y | μ ~ N(μ, 1), so μ | y ~ N(y/2, 1/2). An exact
sampler must pass; samplers that are overconfident, too vague or biased must fail.
"""

import math

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.inference.sbc import (
    central_intervals,
    coverage,
    coverage_by_bins,
    rank_histogram,
    ranks,
    thin,
    thinned_enough,
    uniformity_test,
)

N_TRUTHS = 1000
L = 99  # draws per rank: ranks in {0, ..., 99}
BINS = 20  # 100 rank values / 20 bins = 5 values per bin; 50 truths expected per bin
ALPHA = 1e-3
POST_SD = math.sqrt(0.5)


def gaussian_sbc(seed: int, n_draws: int, sd_scale: float = 1.0, shift_sd: float = 0.0):
    """Truths μ* from the prior, y from μ*, and ``n_draws`` draws per truth from a sampler
    that returns N(y/2 + shift_sd·sd, (sd_scale·sd)²) with sd the exact posterior sd."""
    rng = np.random.default_rng(seed)
    mu = rng.normal(0.0, 1.0, N_TRUTHS)
    y = mu + rng.normal(0.0, 1.0, N_TRUTHS)
    mean = y / 2 + shift_sd * POST_SD
    draws = mean[:, None] + sd_scale * POST_SD * rng.normal(size=(N_TRUTHS, n_draws))
    return mu, draws


# --------------------------------------------------------------- the check passes and fails
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_posterior_draws_pass_the_uniformity_test(seed):
    # Exact, independent draws make each rank exactly uniform on {0..L} and the ranks of
    # different truths independent, so the χ² statistic is (asymptotically, 50 expected
    # per bin) χ²(19) and p < ALPHA has probability ALPHA = 0.1% per seed: the three seeds
    # together raise a false alarm with probability at most 0.3%.
    mu, draws = gaussian_sbc(seed, L)
    test = uniformity_test(ranks(mu, draws), L, BINS)
    assert test.dof == BINS - 1
    assert sum(test.counts) == N_TRUTHS
    assert test.p_value > ALPHA


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("sd_scale", "shift_sd", "shape"), [
    (0.5, 0.0, "U"),         # overconfident: the truth falls in the tails of the draws
    (2.0, 0.0, "hump"),      # too vague: the truth sits in the middle of the draws
    (1.0, 0.5, "one side"),  # biased by half a posterior sd: the draws lie above the truth
])
def test_a_miscalibrated_sampler_is_rejected(seed, sd_scale, shift_sd, shape):
    # Power: the rank fractions follow Φ(Φ⁻¹(u)/2), Φ(2Φ⁻¹(u)) and Φ(Φ⁻¹(u) + 0.5) instead of
    # u; over 20 bins and 1000 truths the χ² noncentrality is about 1100, over 1000 and
    # about 270 against a critical value of 43.8 (χ²(19) at 1e-3), so a miss has
    # probability below 1e-12 for each. The p-value is far below ALPHA, not just below it.
    mu, draws = gaussian_sbc(seed, L, sd_scale, shift_sd)
    r = ranks(mu, draws)
    test = uniformity_test(r, L, BINS)
    assert test.p_value < 1e-10
    counts = np.asarray(test.counts)
    ends, middle = counts[[0, -1]].sum(), counts[BINS // 2 - 1:BINS // 2 + 1].sum()
    if shape == "U":
        assert ends > 3 * middle
    elif shape == "hump":
        assert middle > 3 * ends
    else:  # draws too large: small ranks
        assert np.mean(r) < 0.4 * L


@pytest.mark.parametrize("seed", [0, 1])
def test_coverage_of_the_90_percent_interval_moves_the_expected_way(seed):
    # 999 draws per truth for the intervals. Exact: the interval between the 5% and 95%
    # sample quantiles of 999 draws covers 0.898 on average; the binomial standard error
    # over 1000 truths is 0.0095, so ±0.04 is over 4 standard errors (false alarm < 1e-4).
    # Overconfident (sd / 2): covers P(|Z| < 1.645 / 2) = 0.589. Too vague (sd × 2): covers
    # P(|Z| < 3.29) = 0.999. Both are over 30 standard errors from 0.9.
    m = 999
    exact = coverage(*_with_intervals(*gaussian_sbc(seed, m)))
    narrow = coverage(*_with_intervals(*gaussian_sbc(seed, m, sd_scale=0.5)))
    wide = coverage(*_with_intervals(*gaussian_sbc(seed, m, sd_scale=2.0)))
    assert exact.n == N_TRUTHS
    assert abs(exact.rate - 0.9) < 0.04
    assert exact.ci_low < 0.9 < exact.ci_high
    assert abs(narrow.rate - 0.589) < 0.05 and narrow.ci_high < 0.8
    assert wide.rate > 0.98 and wide.ci_low > 0.95


def _with_intervals(mu, draws):
    lo, hi = central_intervals(draws, 0.9)
    return mu, lo, hi


# -------------------------------------------------------------------------------- ranks
def test_rank_counts_draws_below_the_truth_at_the_edges_and_inside():
    draws = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [3.0, 1.0, 2.0]])
    truths = np.array([0.5, 3.5, 2.5, 1.5])
    assert ranks(truths, draws).tolist() == [0, 3, 2, 1]


def test_ties_are_split_at_random_between_the_possible_ranks():
    # truth 1 with draws [0, 1, 1, 2]: one draw below, two equal, so the rank is 1, 2 or 3,
    # each with probability 1/3. Over 30000 rows each count is 10000 ± 82 (binomial sd);
    # ±600 is over 7 sd.
    n = 30000
    r = ranks(np.ones(n), np.tile([0.0, 1.0, 1.0, 2.0], (n, 1)), rng=1)
    values, counts = np.unique(r, return_counts=True)
    assert values.tolist() == [1, 2, 3]
    assert np.all(np.abs(counts - n / 3) < 600)


def test_a_stuck_sampler_gets_uniform_ranks_not_all_zero():
    # Every draw equals the truth: without splitting ties every rank would be 0 (or L).
    # Split at random they are uniform on {0..4}: 4000 ± 57 each over 20000 rows.
    n, ell = 20000, 4
    r = ranks(np.full(n, 2.0), np.full((n, ell), 2.0), rng=0)
    counts = np.bincount(r, minlength=ell + 1)
    assert counts.size == ell + 1 and np.all(np.abs(counts - n / (ell + 1)) < 400)


def test_ranks_are_reproducible_and_reject_bad_input():
    t, d = np.zeros(50), np.random.default_rng(0).integers(-1, 2, (50, 7)).astype(float)
    assert np.array_equal(ranks(t, d, rng=3), ranks(t, d, rng=3))
    with pytest.raises(InputError, match="finite"):
        ranks([0.0], [[np.nan, 1.0]])
    with pytest.raises(InputError, match=r"\[n, L\]"):
        ranks([0.0, 1.0], [[1.0, 2.0]])


# ----------------------------------------------------------------------------- histogram
def test_rank_histogram_bins_and_expected_counts():
    # L = 9: ranks 0..9. Three bins take floor(r · 3 / 10): {0..3}, {4..6}, {7..9}.
    r = np.array([0, 3, 4, 6, 7, 9, 9])
    counts, expected = rank_histogram(r, 9, 3)
    assert counts.tolist() == [2, 2, 3]
    assert np.allclose(expected, 7 * np.array([4, 3, 3]) / 10)
    counts, expected = rank_histogram(r, 9, 10)  # one bin per rank value
    assert counts.tolist() == [1, 0, 0, 1, 1, 0, 1, 1, 0, 2]
    assert np.allclose(expected, 0.7)


def test_uniformity_test_of_a_perfectly_flat_histogram_and_bad_input():
    test = uniformity_test(np.repeat(np.arange(10), 8), 9, 5)
    assert test.statistic == 0.0 and test.p_value == pytest.approx(1.0)
    with pytest.raises(InputError, match="integers"):
        rank_histogram(np.array([0, 10]), 9, 5)
    with pytest.raises(InputError, match="bins"):
        rank_histogram(np.array([0, 1]), 9, 11)


# ------------------------------------------------------------------------------ thinning
def test_thin_keeps_evenly_spaced_draws_across_chains():
    draws = np.arange(2 * 5 * 2).reshape(2, 5, 2)  # 2 chains × 5 draws × 2 quantities
    kept = thin(draws, 3)
    assert kept.shape == (3, 2)
    assert kept[:, 0].tolist() == [0, 8, 18]  # concatenated draws 0, 4, 9 (quantity 0)
    assert thin(draws, 10).shape == (10, 2)
    with pytest.raises(InputError, match="n_keep"):
        thin(draws, 11)
    assert thinned_enough(120.0, 99) and not thinned_enough(80.0, 99) and not thinned_enough(None, 99)


# ------------------------------------------------------------------------------ coverage
def test_coverage_counts_closed_intervals_with_an_exact_binomial_interval():
    cov = coverage([0.0, 1.0, 2.0, 5.0], [0.0, 0.0, 2.5, 0.0], [1.0, 0.5, 3.0, 4.0])
    assert (cov.covered, cov.n, cov.rate) == (1, 4, 0.25)
    assert cov.se == pytest.approx(math.sqrt(0.25 * 0.75 / 4))
    # Clopper–Pearson for 1 of 4: lower = Beta(0.025; 1, 4), upper = Beta(0.975; 2, 3).
    assert cov.ci_low == pytest.approx(1 - 0.975 ** 0.25, rel=1e-6)
    assert 0.8 < cov.ci_high < 0.82
    empty = coverage([], [], [])
    assert empty.n == 0 and math.isnan(empty.rate)


def test_coverage_by_bins_uses_half_open_bins_with_a_closed_last_one():
    truths = np.zeros(5)
    low = np.array([-1.0, 1.0, -1.0, -1.0, -1.0])  # truth 1 is outside its interval
    high = np.ones(5)
    beta = np.array([0.01, 0.05, 0.5, 100.0, 200.0])  # 200 lies beyond the last edge
    rows = coverage_by_bins(truths, low, high, beta, [1e-3, 0.05, 1.0, 100.0])
    assert [(lo, hi) for lo, hi, _ in rows] == [(1e-3, 0.05), (0.05, 1.0), (1.0, 100.0)]
    assert [(c.covered, c.n) for _, _, c in rows] == [(1, 1), (1, 2), (1, 1)]
    with pytest.raises(InputError, match="increasing"):
        coverage_by_bins(truths, low, high, beta, [1.0, 0.5])
