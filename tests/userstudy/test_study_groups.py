"""userstudy.groups (``study --group-by``) and userstudy.summaries (the β summaries it reads)."""

from __future__ import annotations

import math

import pytest

from expertise_irl.errors import InputError
from expertise_irl.userstudy import groups as gr
from expertise_irl.userstudy import summaries as sm

COLUMNS = ["participant", "map", "recording", "condition"]


def rows(**groups):
    """study.csv-like rows (strings, as csv gives them back): ``name=[β̂, ...]`` per group."""
    out = []
    for name, betas in groups.items():
        for i, b in enumerate(betas):
            out.append({"participant": f"{name}{i}", "condition": name, "beta_hat": f"{b:g}",
                        "beta_geomean": f"{b / 2:g}", "beta_median": f"{b:g}"})
    return out


# ---------------------------------------------------------------- summaries
def test_beta_summary_grid_by_hand():
    s = sm.beta_summary_grid([0.1, 1.0, 10.0], [0.2, 0.3, 0.5])
    assert s["mean"] == pytest.approx(0.02 + 0.3 + 5.0)
    assert s["geomean"] == pytest.approx(10 ** 0.3)  # exp(0.2 ln 0.1 + 0.5 ln 10)
    # cdf 0.2, 0.5, 1.0: the median is the smallest value whose cdf is ≥ 0.5 (here exactly 0.5).
    assert (s["q05"], s["median"], s["q95"]) == (0.1, 1.0, 10.0)
    # The grid's order does not matter.
    assert sm.beta_summary_grid([10.0, 0.1, 1.0], [0.5, 0.2, 0.3]) == s


def test_grid_quantiles_are_grid_values_and_survive_rounding_in_the_sums():
    s = sm.beta_summary_grid(list(range(1, 11)), [0.1] * 10)
    # cdf reaches 0.5 at 5 (a cumulative sum of 0.1's, so only up to rounding), 0.95 at 10.
    assert (s["q05"], s["median"], s["q95"]) == (1.0, 5.0, 10.0)
    s = sm.beta_summary_grid([0.5, 2.0], [0.49, 0.51])
    assert s["median"] == 2.0 and s["q05"] == 0.5 and s["q95"] == 2.0


def test_beta_summary_grid_rejects_bad_input():
    for values, p in (([0.1, 1.0], [0.5, 0.6]), ([0.0, 1.0], [0.5, 0.5]), ([0.1, 1.0], [1.0]),
                      ([0.1, 1.0], [-0.1, 1.1])):
        with pytest.raises(InputError):
            sm.beta_summary_grid(values, p)


def test_beta_summary_draws_by_hand():
    s = sm.beta_summary_draws([4.0, 1.0, 3.0, 2.0])
    assert s["mean"] == 2.5 and s["median"] == 2.5
    assert s["geomean"] == pytest.approx(24 ** 0.25)
    # Linear interpolation between order statistics: positions 0.05·3 and 0.95·3.
    assert s["q05"] == pytest.approx(1.15) and s["q95"] == pytest.approx(3.85)
    with pytest.raises(InputError):
        sm.beta_summary_draws([1.0, math.nan])
    with pytest.raises(InputError):
        sm.beta_summary_draws([])


def test_beta_summary_point():
    assert sm.beta_summary_point(0.3) == {"mean": 0.3, "median": 0.3, "geomean": 0.3,
                                          "q05": None, "q95": None}
    with pytest.raises(InputError):
        sm.beta_summary_point(-1.0)
    assert set(sm.beta_summary_point(1.0)) == set(sm.KEYS)


# ---------------------------------------------------------------- groups
def test_group_summaries_by_hand():
    r = rows(b=[1.0, 2.0, 3.0, 4.0], a=[0.5, 8.0])
    r.append({"participant": "x", "condition": "  ", "beta_hat": "2", "beta_geomean": "1",
              "beta_median": "2"})
    r.append({"participant": "y", "beta_hat": "", "beta_geomean": "", "beta_median": ""})  # no column, no β
    s = gr.group_summaries(r, "condition", COLUMNS)
    assert [g["group"] for g in s] == ["(empty)", "a", "b"]
    empty, a, b = s
    assert (empty["n"], empty["n_missing"]) == (1, 1)
    assert (b["n"], b["n_missing"]) == (4, 0)
    assert b["beta_hat_median"] == 2.5
    # numpy's linear quantiles of 1, 2, 3, 4: q25 = 1.75, q75 = 3.25.
    assert (b["beta_hat_q25"], b["beta_hat_q75"], b["beta_hat_iqr"]) == (1.75, 3.25, 1.5)
    # geomean of the participants' beta_geomean 0.5, 1, 1.5, 2: (1.5)^(1/4).
    assert b["beta_geomean_geomean"] == pytest.approx(1.5 ** 0.25)
    assert a["beta_geomean_geomean"] == pytest.approx(math.sqrt(0.25 * 4.0))
    assert b["beta_median_median"] == 2.5


def test_unknown_column_names_the_columns():
    with pytest.raises(InputError) as e:
        gr.group_summaries(rows(a=[1.0]), "cond", COLUMNS)
    assert str(e.value) == ("--group-by cond: no such manifest column "
                            "(columns: participant, map, recording, condition)")
    for fn in (gr.group_tests, gr.group_markdown):
        with pytest.raises(InputError, match="--group-by cond: no such manifest column"):
            fn(rows(a=[1.0]), "cond", COLUMNS)


def test_two_groups_mann_whitney_by_hand():
    # a: 0.1 0.5 0.9 2.0; b: 0.3 1.0 3.0. U_a counts pairs with a's β̂ larger: 0.5 > 0.3, 0.9 > 0.3,
    # 2.0 > 0.3 and 1.0: U_a = 4 of 12. No ties and small samples: the exact distribution of U for
    # sizes (4, 3) over C(7, 3) = 35 rankings has P(U ≤ 4) = (1 + 1 + 2 + 3 + 4)/35, so the
    # two-sided p = 22/35. Rank-biserial r = 2·4/12 − 1 = −1/3: b's β̂ tend to be larger.
    (t,) = gr.group_tests(rows(a=[0.1, 0.5, 0.9, 2.0], b=[0.3, 1.0, 3.0]), "condition", COLUMNS)
    assert t["groups"] == ("a", "b") and t["n"] == (4, 3)
    assert t["U"] == 4.0
    assert t["p"] == pytest.approx(22 / 35, rel=1e-12)
    assert t["p_holm"] == t["p"] and t["adjustment"] == "none"
    assert t["effect"] == pytest.approx(-1 / 3)
    assert t["larger"] == "b" and t["note"] is None


def test_effect_sign_follows_the_group_with_larger_beta():
    # Complete separation, sizes (3, 3): U = 0 or 9, exact two-sided p = 2/C(6, 3) = 0.1.
    (t,) = gr.group_tests(rows(novice=[4.0, 5.0, 6.0], expert=[1.0, 2.0, 3.0]), "condition", COLUMNS)
    assert t["groups"] == ("expert", "novice")
    assert (t["U"], t["effect"], t["larger"]) == (0.0, -1.0, "novice")
    assert t["p"] == pytest.approx(0.1)
    (t,) = gr.group_tests(rows(novice=[0.1, 0.2, 0.3], expert=[1.0, 2.0, 3.0]), "condition", COLUMNS)
    assert (t["U"], t["effect"], t["larger"]) == (9.0, 1.0, "expert")
    md = gr.group_markdown(rows(novice=[0.1, 0.2, 0.3], expert=[1.0, 2.0, 3.0]), "condition", COLUMNS)
    assert "expert's β̂ tend to be larger (less expert) than novice's" in md
    assert "p = 0.1" in md and "r = +1.00" in md


def test_holm_by_hand():
    # sorted 0.01, 0.03, 0.04, 0.5 → × 4, 3, 2, 1 = 0.04, 0.09, 0.08, 0.5 → running max.
    assert gr.holm_adjusted([0.01, 0.04, 0.03, 0.5]) == pytest.approx([0.04, 0.09, 0.09, 0.5])
    assert gr.holm_adjusted([0.6, 0.9]) == pytest.approx([1.0, 1.0])
    assert gr.holm_adjusted([]) == []


def test_more_groups_test_every_pair_with_holm():
    r = rows(a=[1.0, 2.0, 3.0], b=[4.0, 5.0, 6.0], c=[7.0, 8.0, 9.0, 10.0], d=[0.5])
    tests = gr.group_tests(r, "condition", COLUMNS)
    assert [t["groups"] for t in tests] == [("a", "b"), ("a", "c"), ("a", "d"), ("b", "c"), ("b", "d"),
                                            ("c", "d")]
    by = {t["groups"]: t for t in tests}
    # Exact p's: (3, 3) separated 2/20; (3, 4) separated 2/35. Holm over the 3 pairs tested:
    # 3·2/35 for the two smallest, max(6/35, 0.1) for (a, b).
    assert by["a", "b"]["p"] == pytest.approx(0.1)
    assert by["a", "c"]["p"] == pytest.approx(2 / 35) and by["b", "c"]["p"] == pytest.approx(2 / 35)
    for k in (("a", "b"), ("a", "c"), ("b", "c")):
        assert by[k]["p_holm"] == pytest.approx(6 / 35)
        assert by[k]["adjustment"] == "holm" and by[k]["larger"] == k[1]
    for k in (("a", "d"), ("b", "d"), ("c", "d")):
        t = by[k]
        assert t["U"] is None and t["p"] is None and t["effect"] is None
        assert "needs at least 2 participants per group (d has 1)" in t["note"]
    md = gr.group_markdown(r, "condition", COLUMNS)
    assert "Holm-adjusted over the 3 pairs tested" in md
    assert md.count("\n- ") == 6


def test_group_markdown_table():
    r = rows(a=[1.0, 2.0, 3.0, 4.0], b=[0.1, 0.2])
    md = gr.group_markdown(r, "condition", COLUMNS)
    lines = md.splitlines()
    assert lines[0] == "## β by condition"
    assert "| a | 4 | 2.5 | 1.75–3.25 | " in md
    assert any(line.startswith("| b | 2 | 0.15 |") for line in lines)
    assert "a's β̂ tend to be larger (less expert) than b's" in md
    one = gr.group_markdown(rows(a=[1.0, 2.0]), "condition", COLUMNS)
    assert "Only one group of condition: nothing to compare." in one
    assert gr.group_tests(rows(a=[1.0, 2.0]), "condition", COLUMNS) == []


def test_tied_small_samples_get_the_exact_permutation_p():
    # Every β̂ of a is 0.5 and every one of b is 1.0: U_a = 0. Of the C(6, 3) = 20 ways to split the
    # six pooled values into groups of three, only the two complete separations are as extreme,
    # so the two-sided p = 2/20 = 0.1 (the normal approximation with tie correction says 0.047).
    (t,) = gr.group_tests(rows(a=[0.5, 0.5, 0.5], b=[1.0, 1.0, 1.0]), "condition", COLUMNS)
    assert t["U"] == 0.0 and t["effect"] == -1.0
    assert t["p"] == pytest.approx(0.1, rel=1e-12)
    assert t["method"] == "exact permutation (ties)"
    # A tie across the groups, sizes (3, 3): a = 0.5 0.5 1, b = 1 1 2. U_a = ½ + ½ (a's 1 against
    # b's two 1s) = 1. Of the 20 splits of the pooled values, U is 1 in three and 8 in three (the
    # mirror), and every other split lies nearer the centre 4.5: p = 6/20.
    (t,) = gr.group_tests(rows(a=[0.5, 0.5, 1.0], b=[1.0, 1.0, 2.0]), "condition", COLUMNS)
    assert t["U"] == 1.0 and t["p"] == pytest.approx(6 / 20, rel=1e-12)
    md = gr.group_markdown(rows(a=[0.5, 0.5, 0.5], b=[1.0, 1.0, 1.0]), "condition", COLUMNS)
    assert "p = 0.1, exact permutation (ties)" in md


def test_every_beta_the_same_gives_p_one():
    (t,) = gr.group_tests(rows(a=[1.0, 1.0], b=[1.0, 1.0, 1.0]), "condition", COLUMNS)
    assert (t["U"], t["p"], t["effect"], t["larger"]) == (3.0, 1.0, 0.0, None)
