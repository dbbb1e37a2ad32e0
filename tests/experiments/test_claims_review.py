"""The review of the claim rules: float ties, inconclusive against excluded, signs on noise, one-sided
rank tests that agree with the mean, groups without rows, small n, 0 / 0 and the matrix's small runs.
Each test's rows gave the wrong verdict before its fix."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from expertise_irl.experiments.report import claim_kinds as K
from expertise_irl.experiments.report import claims as C
from expertise_irl.experiments.report.ratios import ratio_extras
from expertise_irl.experiments.report.stats import fisher_ci, paired_differences, wilcoxon_p


# ------------------------------------------------------------------ 1. floating-point ties
def test_ties_within_the_tolerance_are_zero_differences():
    a = np.array([1e-16, 1.0, 1.0 + 1e-12, 2.0, 5e-13, 0.0])
    b = np.array([0.0, 1.0, 1.0, 1.0, 0.0, 0.0])
    assert list(paired_differences(a, b)) == [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]
    assert np.isnan(wilcoxon_p(np.full(5, 1e-16), np.zeros(5)))  # every pair a tie


def test_float_noise_ties_do_not_decide_an_ordering():
    # 34 pairs where one side is 1e-16 and the other exactly 0, 10 pairs clearly below
    a = np.r_[np.full(34, 1e-16), np.arange(1.0, 11.0)]
    b = np.r_[np.zeros(34), np.arange(2.0, 12.0)]
    assert stats.wilcoxon(a - b, zero_method="wilcox").pvalue > 0.05  # the noise ranked as differences
    got = C.ordering_claim("x", "s", "c", "p", a, b, "A", "B", "q", claimed="below")
    assert got.verdict == C.REPRODUCED and got.p == pytest.approx(1 / 2 ** 10)
    assert "34 ties dropped" in got.why


def test_all_noise_is_no_difference_for_ordering_and_no_effect():
    a, b = np.full(10, 1e-16), np.zeros(10)  # a "above" b by 1e-16 in every pair
    above = C.ordering_claim("x", "s", "c", "p", a, b, "A", "B", "q", claimed="above")
    assert above.verdict == C.NOT_REPRODUCED and above.value == 0.0
    assert "every pair is a tie" in above.why
    not_above = K.no_effect_claim("x", "s", "c", "p", a, b, "A", "B", "q", ruled_out="above")
    assert not_above.verdict == C.REPRODUCED


# ------------------------------------------------ 2. inconclusive only where the CI allows both
def test_fisher_ci():
    lo, hi = fisher_ci(-0.01, 300)
    z = np.arctanh(-0.01)
    half = 1.959964 / np.sqrt(297)
    assert (lo, hi) == pytest.approx((np.tanh(z - half), np.tanh(z + half)))
    assert lo == pytest.approx(-0.123, abs=1e-3) and hi == pytest.approx(0.103, abs=1e-3)
    assert np.isnan(fisher_ci(0.5, 3)[0]) and np.isnan(fisher_ci(np.nan, 30)[0])


def _cell(rho: float, n: int, paper: str) -> C.ClaimResult:
    p = float(2 * stats.t.sf(abs(rho) * np.sqrt((n - 2) / (1 - rho ** 2)), n - 2))  # Pearson's p
    return K.cell_claim("T", "VI-D", "Table I", "row", "col", paper, {"rho": rho, "p": p, "n": n,
                                                                       "cell": f"{rho:.2f}"}, "rows")


def test_a_non_significant_rho_that_excludes_the_papers_is_not_inconclusive():
    got = _cell(-0.01, 300, "−0.45†")  # CI [−0.12, 0.10]: includes 0, excludes −0.45
    assert got.verdict == C.DIFFERS and got.why.startswith(C.EXCLUDED)
    assert "which excludes the paper's −0.45" in got.why
    assert got.ci_low == pytest.approx(-0.123, abs=1e-3)
    small = _cell(-0.01, 12, "−0.45†")  # CI [−0.58, 0.56]: both 0 and −0.45
    assert small.verdict == C.DIFFERS and small.why.startswith(C.INCONCLUSIVE)
    assert K.cell_judgement(-0.45, True, -0.3, 0.01, 80)[:2] == (C.REPRODUCED, C.PLAIN)


def test_a_ratio_whose_ci_includes_1_but_misses_the_band_excludes_the_papers_value():
    assert C.ratio_judgement(1.07, 6.0, (0.47, 2.54)) == (C.DIFFERS, C.RULED_OUT)  # band [4, 9]
    assert C.ratio_judgement(1.07, 6.0, (0.47, 4.5)) == (C.DIFFERS, C.UNSURE)  # overlaps the band
    assert C.ratio_judgement(1.07, 6.0, (np.nan, np.nan)) == (C.DIFFERS, C.UNSURE)  # no CI
    assert C.ratio_judgement(0.5, 0.1, (0.05, 1.3)) == (C.DIFFERS, C.UNSURE)  # band [0.067, 0.15]
    assert C.ratio_judgement(0.9, 0.1, (0.5, 1.3)) == (C.DIFFERS, C.RULED_OUT)
    rng = np.random.default_rng(0)
    num, den = rng.exponential(1.0, 60), rng.exponential(1.0, 60)
    got = C.ratio_claim("x", "s", "c", "p", num, den, "out", "in", "regret", 6.0, paired=False, who="people")
    assert got.ci_low < 1 < got.ci_high < 4
    assert got.verdict == C.DIFFERS and got.why.startswith(C.EXCLUDED)
    assert "lies wholly outside the band: the rows rule out the paper's size" in got.why


# --------------------------------------------------------------- 3. signs that flip on noise
@pytest.mark.parametrize("n, kind", [(300, C.RULED_OUT), (8, C.UNSURE)])
def test_a_wrong_sign_that_is_noise_is_not_not_reproduced(n, kind):
    verdict, got_kind, _ = K.cell_judgement(0.57, True, -0.0045, 0.94, n)
    assert (verdict, got_kind) == (C.DIFFERS, kind)
    assert K.cell_verdict(0.57, True, -0.3, 0.01, n) == C.NOT_REPRODUCED  # significant the other way


def test_a_wrong_sign_ordering_is_not_reproduced_only_when_significant():
    a = np.arange(1.0, 5.0)
    noise = C.ordering_claim("x", "s", "c", "p", a + 0.1, a, "A", "B", "q", claimed="below")
    assert noise.verdict == C.DIFFERS and noise.why.startswith(C.INCONCLUSIVE)  # 4 pairs: p = 1/16
    b = np.arange(1.0, 11.0)
    assert C.ordering_claim("x", "s", "c", "p", b + 0.1, b, "A", "B", "q").verdict == C.NOT_REPRODUCED


def test_correlation_claim_against_the_papers_rho():
    rng = np.random.default_rng(1)
    x = rng.normal(size=400)
    y = rng.normal(size=400)
    got = C.correlation_claim("x", "s", "c", "ρ = 0.57†", x, y, "f", "m", paper_rho=0.57)
    assert got.p >= 0.05 and got.verdict == C.DIFFERS and got.why.startswith(C.EXCLUDED)
    x8, y8 = np.arange(8.0), np.array([1.0, 3.0, 0.0, 2.0, 3.0, 0.0, 2.0, 1.0])  # ρ = −0.10, p = 0.82
    wrong = C.correlation_claim("x", "s", "c", "p", x8, y8, "f", "m", claimed="positive", paper_rho=0.57)
    assert wrong.value < 0 and wrong.verdict == C.DIFFERS and wrong.why.startswith(C.INCONCLUSIVE)


# ------------------------------------------------- 4. the mean and the rank test must agree
def test_mean_and_one_sided_rank_test_disagree():
    a, b = np.r_[np.zeros(20), 100.0], np.ones(21)  # mean above (+3.8), 20 of 21 pairs below
    got = C.ordering_claim("x", "s", "c", "p", a, b, "A", "B", "q", claimed="above")
    assert got.value > 0 and got.verdict == C.DIFFERS and got.why.startswith(C.INCONCLUSIVE)
    assert "the mean and the rank test point different ways" in got.why
    assert got.p > 0.5  # the one-sided p in the claimed direction
    ruled = K.no_effect_claim("x", "s", "c", "p", a, b, "A", "B", "q", ruled_out="below")
    assert ruled.verdict == C.DIFFERS and ruled.why.startswith(C.INCONCLUSIVE)
    assert ruled.p < 0.05  # the rank test says below, what the claim rules out


def test_one_sided_tests_and_their_p():
    b = np.arange(1.0, 21.0)
    a = b - np.r_[0.1, -0.05].repeat(10)  # 10 pairs 0.1 below, 10 pairs 0.05 above
    p_less = stats.wilcoxon(a - b, alternative="less").pvalue
    got = C.ordering_claim("x", "s", "c", "p", a, b, "A", "B", "q", claimed="below")
    assert got.p == pytest.approx(p_less) and p_less < 0.05 < 2 * p_less
    assert got.verdict == C.REPRODUCED  # one-sided in the claimed direction


# --------------------------------------------------------------- 5. a group without rows
def test_margin_claim_with_a_group_short_of_rows_is_no_data():
    at15 = [1.0, 1.01, 1.02, 1.03]
    recs = [{"group_true": "high", "episodes": e, "m": v}
            for e, vs in ((15, at15), (20, [1.02] * 4)) for v in vs]
    recs += [{"group_true": "low", "episodes": 15, "m": 1.0}, {"group_true": "low", "episodes": 20, "m": 1.0}]
    got = K.margin_claim("x", "s", "c", "p", pd.DataFrame(recs), "m", (15, 20), ["high", "low"], "m")
    assert got.verdict == C.NO_DATA and "low (1 at 15, 1 at 20)" in got.why
    recs = [r for r in recs if not (r["group_true"] == "low" and r["episodes"] == 20)]
    recs += [{"group_true": "low", "episodes": 15, "m": 1.0}]  # 2 at 15, none at 20
    got = K.margin_claim("x", "s", "c", "p", pd.DataFrame(recs), "m", (15, 20), ["high", "low"], "m")
    assert got.verdict == C.NO_DATA and "low (2 at 15, 0 at 20)" in got.why


# ------------------------------------------------------------------ 6. unpaired, small n
def test_difference_claim_needs_the_rows_for_a_ci():
    few = K.difference_claim("x", "s", "c", "p", [1.0, 1.0, 1.0], np.full(10, 2.0), "A", "B", "q")
    assert few.verdict == C.DIFFERS and few.why.startswith(C.INCONCLUSIVE)
    assert np.isnan(few.ci_low) and "no CI from fewer than 6 people on a side" in few.why
    rng = np.random.default_rng(2)
    b = rng.normal(1.0, 0.5, 40)
    noise = K.difference_claim("x", "s", "c", "p", b[::-1] + 0.01, b, "A", "B", "q")  # wrong sign, CI over 0
    assert noise.verdict == C.DIFFERS and noise.ci_low < 0 < noise.ci_high


# ------------------------------------------------------------------ 7. 0 / 0 and n/a counts
def test_a_ratio_of_zero_means_is_no_data():
    got = C.ratio_claim("x", "s", "c", "p", np.zeros(8), np.zeros(8), "a", "b", "q", 3.0, paired=True,
                        who="people")
    assert got.verdict == C.NO_DATA and "the ratio is undefined (0 / 0)" in got.why
    assert C.ratio_verdict(float("nan"), 3.0, (1.2, 9.0)) == C.NO_DATA


def test_every_count_ranks_the_judged_counts_above_a_missing_one():
    ok = C.ordering_claim("", "s", "", "", np.zeros(10), np.arange(1.0, 11.0), "A", "B", "q")
    unsure = C.ordering_claim("", "s", "", "", np.zeros(3), np.ones(3), "A", "B", "q")
    none = C.ordering_claim("", "s", "", "", [], [], "A", "B", "q")
    assert (ok.verdict, unsure.verdict, none.verdict) == (C.REPRODUCED, C.DIFFERS, C.NO_DATA)
    got = K.every_count_claim("x", "s", "c", "p", [(20, ok), (25, none), (30, unsure)])
    assert got.verdict == C.DIFFERS and got.why.startswith(C.INCONCLUSIVE)
    assert "n/a at 25 episodes, not counted" in got.why
    assert K.every_count_claim("x", "s", "c", "p", [(20, ok), (25, none)]).verdict == C.REPRODUCED
    assert K.every_count_claim("x", "s", "c", "p", [(20, none), (25, none)]).verdict == C.NO_DATA


# --------------------------------------------------------------- 9. the numbers beside a ratio
def test_group_ratios_carry_their_n_and_small_groups_withhold_the_adjusted_ratio():
    num = np.r_[np.full(1, 9.0), np.full(10, 2.0)]
    den = np.r_[np.full(25, 1e-3), np.full(10, 1.0)]
    gn = np.array(["high"] + ["low"] * 10)
    gd = np.array(["high"] * 25 + ["low"] * 10)
    ex = ratio_extras(num, den, gn, gd, paired=False)
    assert ex.group_text() == "high 9e+03× (n = 1/25), low 2× (n = 10/10)"
    assert np.isnan(ex.adjusted) and "fewer than 6 units on a side in high (1/25)" in ex.adjusted_text()
    assert "mix-adjusted n/a" in ex.ours_text()
    many = ratio_extras(np.r_[np.full(6, 9.0), np.full(10, 2.0)], den,
                        np.array(["high"] * 6 + ["low"] * 10), gd, paired=False)
    assert np.isfinite(many.adjusted)


def test_a_median_at_zero_gives_no_ratio_of_medians():
    ex = ratio_extras(np.ones(7), np.r_[np.zeros(4), np.ones(3)], paired=True)
    assert np.isnan(ex.medians) and "ratio of medians n/a (median at 0)" in ex.ours_text()
    tiny = ratio_extras(np.ones(7), np.r_[np.full(4, 1e-12), np.ones(3)], paired=True)
    assert np.isnan(tiny.medians)  # 1e12× of floating-point noise
    assert ratio_extras(np.ones(3), np.full(3, 0.5), paired=True).medians == 2.0
