"""The claim kinds of issue 28 (claim_kinds) and the numbers beside a ratio (ratios): each rule flips."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from expertise_irl.experiments.report import claim_kinds as K
from expertise_irl.experiments.report import claims as C
from expertise_irl.experiments.report.markdown import render
from expertise_irl.experiments.report.parts import Report
from expertise_irl.experiments.report.ratios import ratio_extras
from expertise_irl.experiments.report.tables import factor_rows, pearson_table


@pytest.mark.parametrize("paper, rho, p, verdict", [
    ("0.57†", 0.4, 0.001, C.REPRODUCED),  # the paper's sign, significant as the paper's
    ("0.57†", 0.1, 0.3, C.DIFFERS),  # the paper's sign, not significant: inconclusive
    ("0.57†", -0.1, 0.3, C.DIFFERS),  # the other sign, not significant: noise, not a finding
    ("0.57†", -0.3, 0.01, C.NOT_REPRODUCED),  # the other sign, significant
    ("−0.45†", -0.3, 0.01, C.REPRODUCED),
    ("−0.45†", 0.3, 0.01, C.NOT_REPRODUCED),
    ("0.05", -0.04, 0.6, C.REPRODUCED),  # not significant, like the paper's: either sign
    ("0.05", 0.04, 0.6, C.REPRODUCED),
    ("0.05", 0.3, 0.001, C.DIFFERS),  # significant where the paper's is not, in its direction
    ("0.05", -0.3, 0.001, C.NOT_REPRODUCED),  # significant the other way
    ("0.0001", float("nan"), float("nan"), C.NO_DATA)])
def test_table_cell_rule(paper, rho, p, verdict):
    assert K.cell_verdict(*K.parse_cell(paper), rho, p) == verdict


def test_parse_cell():
    assert K.parse_cell("−0.45†") == (-0.45, True) and K.parse_cell("0.0001") == (0.0001, False)


def test_table_claims_follow_the_table_and_name_its_cell():
    rng = np.random.default_rng(0)
    x = rng.normal(size=60)
    frame = pd.DataFrame({"f": x, "cosine_similarity": x + rng.normal(scale=0.5, size=60),
                          "expertise_distance": rng.normal(size=60), "policy_regret": -x})
    table = pearson_table("t", "T", "c", factor_rows(frame, {"f": "Factor f"}))
    cols = {"cosine_similarity": ("cosine", "Preferences similarity"),
            "expertise_distance": ("beta", "Expertise distance"), "policy_regret": ("regret", "Regret")}
    paper = {("Factor f", "cosine_similarity"): "0.5†", ("Factor f", "expertise_distance"): "0.1",
             ("Factor f", "policy_regret"): "0.3†"}
    got = {c.id: c for c in K.table_claims(table, paper, {"Factor f": "TX-f"}, "S", "Table X",
                                           {"Factor f": "all rows"}, cols)}
    assert got["TX-f-cosine"].verdict == C.REPRODUCED
    rho = stats.pearsonr(frame["f"], frame["cosine_similarity"]).statistic
    assert got["TX-f-cosine"].value == pytest.approx(rho)
    assert got["TX-f-beta"].verdict == (C.REPRODUCED if got["TX-f-beta"].p >= 0.05 else C.DIFFERS)
    assert got["TX-f-regret"].verdict == C.NOT_REPRODUCED  # ρ = −1 against 0.3†
    assert got["TX-f-regret"].claim == "Table X, row “Factor f”, column “Regret”"
    assert "n = 60" in got["TX-f-regret"].ours


def test_no_effect_rule():
    a = np.arange(1.0, 21.0)
    same = K.no_effect_claim("x", "s", "c", "p", a + 0.5, a, "late", "early", "q", ruled_out="below")
    assert same.verdict == C.REPRODUCED  # above: not what the claim rules out
    b = np.arange(1.0, 11.0)  # 5 pairs 0.1 below, 5 pairs 0.08 above: one-sided p = 0.12
    slight = K.no_effect_claim("x", "s", "c", "p", b - np.r_[0.1, -0.08].repeat(5), b, "late", "early", "q",
                               ruled_out="below")
    assert slight.verdict == C.DIFFERS and slight.why.startswith("inconclusive: ")
    assert 0.05 < slight.p < 0.2
    lower = K.no_effect_claim("x", "s", "c", "p", a - 1, a, "late", "early", "q", ruled_out="below")
    assert lower.verdict == C.NOT_REPRODUCED and lower.p < 0.05


def test_mcnemar_is_the_exact_binomial_tail_of_the_changes():
    before = np.array([False] * 10 + [True] * 10)
    after = np.array([True] * 8 + [False] * 2 + [True] * 9 + [False])
    gains, losses, p = K.mcnemar_greater(before, after)
    assert (gains, losses) == (8, 1)
    assert p == pytest.approx(stats.binomtest(8, 9, 0.5, alternative="greater").pvalue)
    assert np.isnan(K.mcnemar_greater(before, before)[2])


def test_share_gain_rule_can_fail():
    n = 40
    wrong_then_right = (np.arange(n) < 20, np.ones(n, bool))  # 50% → 100%
    assert K.share_gain_claim("x", "s", "c", "p", *wrong_then_right, "people", (1, 5)).verdict == C.REPRODUCED
    high_from_the_start = (np.ones(n, bool), np.ones(n, bool))  # 100% → 100%: nothing learnt
    got = K.share_gain_claim("x", "s", "c", "p", *high_from_the_start, "people", (1, 5))
    assert got.verdict == C.NOT_REPRODUCED and got.value == 1.0
    small_gain = (np.arange(n) < 35, np.arange(n) < 37)  # 88% → 92%: McNemar p = 0.25
    got = K.share_gain_claim("x", "s", "c", "p", *small_gain, "people", (1, 5))
    assert got.verdict == C.DIFFERS and got.p == pytest.approx(0.25)
    few = (np.zeros(n, bool), np.arange(n) < 20)  # 0% → 50%: not above one half
    assert K.share_gain_claim("x", "s", "c", "p", *few, "people", (1, 5)).verdict == C.NOT_REPRODUCED


def test_difference_rule():
    rng = np.random.default_rng(1)
    b = rng.normal(1.0, 0.1, 50)
    env = np.arange(50) % 5
    below = K.difference_claim("x", "s", "c", "p", b - 0.2, b, "A", "B", "q", clusters=(env, env))
    assert below.verdict == C.REPRODUCED and below.ci_high < 0
    tiny = K.difference_claim("x", "s", "c", "p", b[::-1] - 0.001, b, "A", "B", "q", clusters=(env, env))
    assert tiny.verdict == C.DIFFERS and tiny.ci_low < 0 < tiny.ci_high  # the claimed side, CI across 0
    assert tiny.why.startswith("inconclusive: ")
    above = K.difference_claim("x", "s", "c", "p", b + 0.2, b, "A", "B", "q")
    assert above.verdict == C.NOT_REPRODUCED


def test_every_count_takes_the_worst_and_lists_both_rules():
    ok = C.ordering_claim("", "s", "", "", np.zeros(10), np.arange(1.0, 11.0), "A", "B", "q")
    bad = C.ordering_claim("", "s", "", "", np.arange(1.0, 11.0), np.zeros(10), "A", "B", "q")
    assert ok.verdict == C.REPRODUCED and bad.verdict == C.NOT_REPRODUCED
    got = K.every_count_claim("x", "s", "c", "p", [(20, ok), (30, bad), (40, ok)])
    assert got.verdict == C.NOT_REPRODUCED and got.rule == "every-count:ordering"
    assert "worst at 30 episodes" in got.why and got.n == 30
    assert K.every_count_claim("x", "s", "c", "p", [(20, ok), (40, ok)]).verdict == C.REPRODUCED
    md = render(Report("s", "T", claims=[got]), _sweep())
    assert C.RULES["every-count"] in md and C.RULES["ordering"] in md


def _sweep():  # what render reads of a sweep
    from types import SimpleNamespace

    return SimpleNamespace(manifest={"study": "s", "scale": "custom"}, rows=pd.DataFrame(), done=1, total=1,
                           failed=0, unfinished=0, task_time_s=0.0, timings=[], runs=(), run_times_s=[],
                           root="r")


def test_margin_rule():
    at15 = [1.0, 1.01, 1.02, 1.03]  # mean 1.015, 95% half-width 0.021
    frame = pd.DataFrame([{"group_true": g, "episodes": e, "m": v} for g in ("high", "low")
                          for e, vs in ((15, at15), (20, [1.02] * 4)) for v in vs])
    got = K.margin_claim("x", "s", "c", "p", frame, "m", (15, 20), ["high", "low"], "m")
    assert got.verdict == C.REPRODUCED
    moved = frame.copy()
    moved.loc[(moved["episodes"] == 20) & (moved["group_true"] == "high"), "m"] += 1.0
    got = K.margin_claim("x", "s", "c", "p", moved, "m", (15, 20), ["high", "low"], "m")
    assert got.verdict == C.NOT_REPRODUCED and "outside: high" in got.why


def test_ratio_extras_by_hand():
    # out of set: mostly low people (large values); in set: as many of each group (6 units each: fewer
    # withhold the mix-adjusted ratio)
    num = np.array([1.0, 10.0, 10.0, 10.0, 10.0]).repeat(6)
    den = np.array([0.5, 5.0, 8.0]).repeat(6)
    gn = np.array(["high", "low", "low", "low", "low"]).repeat(6)
    gd = np.array(["high", "low", "medium"]).repeat(6)
    ex = ratio_extras(num, den, gn, gd, paired=False)
    assert ex.group_text() == "high 2× (n = 6/6), medium n/a (n = 0/6), low 2× (n = 24/6)"
    assert ex.by_group["high"][0] == pytest.approx(2.0) and ex.by_group["low"][0] == pytest.approx(2.0)
    assert np.isnan(ex.by_group["medium"][0])
    # no out-of-set medium person: no mix to reweight the medium group to
    assert np.isnan(ex.adjusted)
    assert ex.adjusted_text() == "n/a (fewer than 6 units on a side in medium (0/6))"
    assert num.mean() / den.mean() == pytest.approx(8.2 / 4.5)
    assert ex.medians == pytest.approx(10.0 / 5.0)
    assert ex.top_share == pytest.approx(10.0 / 246.0)
    two = ratio_extras(num, den[:12], gn, gd[:12], paired=False)  # in set: high and low only
    # reweighted to the in-set mix (high 1/2, low 1/2): (1 + 10) / (0.5 + 5)
    assert two.adjusted == pytest.approx(11.0 / 5.5)
    assert num.mean() / den[:12].mean() == pytest.approx(8.2 / 2.75)  # the pooled ratio differs
    assert "high 50%, low 50%" in two.adjusted_text()
    paired = ratio_extras(np.array([2.0, 2.0, 30.0]).repeat(6), np.array([1.0, 1.0, 1.0]).repeat(6),
                          np.array(["high", "high", "low"]).repeat(6), None, paired=True)
    assert paired.adjusted == pytest.approx((2.0 + 30.0) / 2.0)  # each group weighted equally


def test_ratio_claim_columns_in_claims_csv(tmp_path):
    got = C.ratio_claim("x", "s", "c", "p", [2.0, 4.0, 2.0, 4.0, 6.0, 6.0], np.ones(6), "a", "b", "q", 3.0,
                        paired=True, who="people", groups=np.array(["low"] * 3 + ["high"] * 3),
                        clusters=np.array([0, 0, 1, 1, 2, 2]))
    frame = C.claims_frame([got])
    assert list(frame.columns[:12]) == ["id", "section", "claim", "paper", "ours", "verdict", "why", "rule",
                                        "n", "value", "ci_low", "ci_high"]  # the old columns, first
    assert {"median_ratio", "adjusted_ratio", "group_ratios", "number", "p"} <= set(frame.columns)
    assert got.group_ratios == "high 5.33× (n = 3), low 2.67× (n = 3)" and got.number.startswith("4× [")
    assert np.isnan(got.adjusted_ratio) and "mix-adjusted n/a" in got.ours  # 3 people a group
    assert "two-stage cluster bootstrap: the 3 maps" in got.why


def test_inner_rule_names_are_all_documented():
    for kind in ("table-cell", "no-effect", "share-gain", "difference", "every-count", "margin"):
        assert kind in C.RULES
    assert list(itertools.chain(C.rule_kinds("every-count:no-effect"))) == ["every-count", "no-effect"]
