"""study.md's "Do people improve?": a sign test over the participants whose β falls or rises."""

import math

import pytest

from expertise_irl.userstudy.report import changing_markdown, sign_test


def _rows(p_falls, p_rises):
    pairs = enumerate(zip(p_falls, p_rises, strict=True))
    return [{"participant": f"P{i}", "changing_log_bf": -1.0, "p_changing": 0.2, "trend_p_falls": f,
             "trend_p_rises": r, "trend_log_ratio": 0.0} for i, (f, r) in pairs]


def test_nobody_changed_is_no_change_not_a_small_p():
    # Six participants, none more likely than not to fall or to rise: no sign test, no p.
    md = changing_markdown(_rows([0.3] * 6, [0.3] * 6))
    assert "**Do people improve?** 0 of 6 participants" in md
    assert "no change" in md
    assert "p = " not in md
    assert sign_test(0, 0) is None


def test_the_sign_test_leaves_ties_out():
    # Two fall, none rise, four keep: the test is over the 2 who changed, p = 2·(1/2)² = 0.5
    # (counting the four ties as "did not fall" would give binom(2; 6) p = 0.6875).
    md = changing_markdown(_rows([0.9, 0.8, 0.3, 0.3, 0.3, 0.3], [0.05, 0.1, 0.3, 0.3, 0.3, 0.3]))
    assert "**Do people improve?** 2 of 6 participants" in md
    assert "over the 2 who changed gives p = 0.5" in md
    assert "4 most likely keep their expertise" in md
    assert sign_test(2, 0) == pytest.approx(0.5, rel=1e-12)
    # Seven fall, one rises: two-sided p = 2·(1 + 8)/2⁸ = 0.0703125.
    assert sign_test(7, 1) == pytest.approx(18 / 256, rel=1e-12)
    assert sign_test(1, 7) == sign_test(7, 1)


def test_map_point_estimates_count_slopes_of_zero_as_ties():
    rows = [{"participant": f"P{i}", "changing_log_bf": math.nan, "p_changing": math.nan,
             "trend_p_falls": math.nan, "trend_p_rises": math.nan, "trend_log_ratio": v}
            for i, v in enumerate([-0.5, -0.2, 0.0, 0.0])]
    md = changing_markdown(rows)
    assert "**Do people improve?** 2 of 4 participants are estimated" in md
    assert "over the 2 who changed gives p = 0.5" in md
