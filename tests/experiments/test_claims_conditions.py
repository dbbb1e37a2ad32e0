"""The Sec. VI claims added for issue 28: each flips its verdict with hand-made rows."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from report_frames import conditions_rows, write_sweep

from expertise_irl.experiments.report import build_report
from expertise_irl.experiments.report import claims as C
from expertise_irl.experiments.report import conditions_claims as CC
from expertise_irl.experiments.report.regret_scale import random_theta_section


@pytest.fixture(scope="module")
def rows():
    return conditions_rows()


def _by_id(rows, n=20, n_low=40):
    return {c.id: c for c in CC.claims(rows, n, n_low)}


def test_ids_are_unique_and_the_first_ones_kept(rows):
    got = [c.id for c in CC.claims(rows, 20, 40)]
    assert len(got) == len(set(got))
    for old in ("VI-B", "VI-C-cosine", "VI-C-regret", "VI-D-expertise_distance", "VI-D-policy_regret",
                "VI-E-group", "VI-E-regret"):
        assert old in got


def test_vi_e_group_must_beat_one_episode(rows):
    """The share at 5 episodes is judged against the share at 1, paired per person (McNemar)."""
    got = _by_id(rows)["VI-E-group"]
    assert got.verdict == C.REPRODUCED and got.rule == "share-gain"  # half wrong at 1, all right at 5
    assert "McNemar" in got.why and got.p < 0.05
    right_at_1 = rows.copy()
    full_in = (right_at_1["truth"] == "in_set") & (right_at_1["condition"] == "full")
    right_at_1.loc[full_in, "group_hat"] = right_at_1.loc[full_in, "group_true"]  # right from 1 episode on
    got = _by_id(right_at_1)["VI-E-group"]
    assert got.value == 1.0 and got.verdict == C.NOT_REPRODUCED  # 100% but nothing learnt from episodes
    # a gain of one person of 36: above 1/2 and above the share at 1, but not significantly above it
    one = right_at_1.copy()
    person = one[full_in & (one["episodes"] == 1)].index[0]
    one.loc[person, "group_hat"] = "nobody"
    got = _by_id(one)["VI-E-group"]
    assert got.verdict == C.DIFFERS and got.why.startswith("inconclusive: ") and got.p == pytest.approx(0.5)


@pytest.mark.slow
def test_fig3_full_improves_and_fixed_theta_does_not(rows):
    got = _by_id(rows)
    assert got["VI-B-fig3-full"].verdict == C.REPRODUCED
    assert got["VI-B-fig3-fixed_theta"].verdict == C.REPRODUCED  # constant in episodes
    improving = rows.copy()
    low = (improving["condition"] == "fixed_theta") & (improving["group_true"] == "low")
    improving.loc[low, "expertise_distance"] = 3.0 / improving.loc[low, "episodes"]
    got = _by_id(improving)
    assert got["VI-B-fig3-fixed_theta"].verdict == C.NOT_REPRODUCED
    assert got["VI-B-fig3-fixed_theta"].rule == "no-effect"
    flat = rows.copy()
    full_low = (flat["condition"] == "full") & (flat["group_true"] == "low") & (flat["truth"] == "in_set")
    flat.loc[full_low, "expertise_distance"] = 1.0
    assert _by_id(flat)["VI-B-fig3-full"].verdict == C.NOT_REPRODUCED  # all ties: no improvement


def test_vi_d_cosine_is_a_clustered_difference(rows):
    got = _by_id(rows)["VI-D-cosine_similarity"]
    assert got.verdict == C.REPRODUCED and got.rule == "difference" and got.ci_high < 0
    assert "two-stage cluster bootstrap over 3 maps" in got.why
    better = rows.copy()
    out = better["truth"] == "out_of_set"
    better.loc[out, "cosine_similarity"] = 1.0
    assert _by_id(better)["VI-D-cosine_similarity"].verdict == C.NOT_REPRODUCED


def test_per_group_orderings_flip_in_their_group_only(rows):
    worse = rows.copy()
    high = (worse["condition"] == "fixed_beta") & (worse["group_true"] == "high")
    worse.loc[high, "policy_regret"] = 0.0  # Fixed β's regret below Full's in the high group only
    got = _by_id(worse)
    assert got["VI-C-regret-high"].verdict == C.NOT_REPRODUCED
    assert got["VI-C-regret-medium"].verdict == C.REPRODUCED
    near = rows.copy()
    low = (near["condition"] == "full") & (near["group_true"] == "low")
    near.loc[low, "policy_regret"] = 0.2
    assert _by_id(near)["VI-C-regret-low-near-0"].verdict == C.NOT_REPRODUCED


def test_vi_d_ratios_report_groups_mix_and_medians(rows):
    got = _by_id(rows)["VI-D-expertise_distance"]
    kmax = rows["k"].max()
    at = rows[(rows["condition"] == "full") & (rows["k"] == kmax) & (rows["episodes"] == 20)]
    out, inn = at[at["truth"] == "out_of_set"], at[at["truth"] == "in_set"]
    d = "expertise_distance"
    assert got.median_ratio == pytest.approx(out[d].median() / inn[d].median())
    per = {g: out.loc[out["group_true"] == g, d].mean() / inn.loc[inn["group_true"] == g, d].mean()
           for g in ("high", "medium", "low") if (out["group_true"] == g).any()}
    for g, r in per.items():
        n_out, n_in = (out["group_true"] == g).sum(), (inn["group_true"] == g).sum()
        assert f"{g} {C.fmt(r)}× (n = {n_out}/{n_in})" in got.group_ratios
    # 18 out-of-set people with β* uniform in [0.01, 10]: some group has fewer than 6, no mix-adjusted ratio
    assert min((out["group_true"] == g).sum() for g in ("high", "medium", "low")) < C.MIN_BOOTSTRAP_N
    assert np.isnan(got.adjusted_ratio) and "mix-adjusted n/a" in got.ours
    assert "mix-adjusted n/a (fewer than 6 units on a side in " in got.why
    assert "ratio of medians" in got.ours
    assert "two-stage cluster bootstrap: the 3 maps" in got.why


def test_table_cells_flip_with_the_sign_of_their_factor(rows):
    got = _by_id(rows)
    cell = got["T2-episodes-beta"]  # paper −0.26†; ours falls with episodes
    assert cell.verdict == C.REPRODUCED and cell.rule == "table-cell" and cell.paper == "−0.26†"
    assert cell.claim == "Table II, row “No. episodes”, column “Expertise distance”"
    flipped = rows.copy()
    flipped["expertise_distance"] = flipped["episodes"] * 0.01 + 0.001 * np.sin(np.arange(len(flipped)))
    assert _by_id(flipped)["T2-episodes-beta"].verdict == C.NOT_REPRODUCED


def test_margin_claim_flips(rows):
    assert _by_id(rows)["VI-E-cosine-15"].verdict == C.REPRODUCED
    jump = rows.copy()
    at20 = (jump["condition"] == "full") & (jump["episodes"] == 20) & (jump["truth"] == "in_set")
    jump.loc[at20, "cosine_similarity"] -= 0.3
    assert _by_id(jump)["VI-E-cosine-15"].verdict == C.NOT_REPRODUCED


def test_random_theta_section_puts_the_full_sets_regret_beside_a_random_thetas():
    rows = conditions_rows(environments=2, runs=1, ks=(5,))
    n = 20  # the report reads the rows at the study's episodes
    assert random_theta_section(rows, n) is None  # rows without the column
    rows = rows.assign(random_theta_regret=rows["beta_true"].map(lambda b: 0.5 if b < 0.5 else 0.01))
    section = random_theta_section(rows, n)
    data = section.table.data.set_index(["truth", "group_true"])
    assert data.loc[("in_set", "high"), "random_theta_regret_mean"] == pytest.approx(0.5)
    assert data.loc[("in_set", "low"), "random_theta_regret_mean"] == pytest.approx(0.01)
    full = rows[(rows["condition"] == "full") & (rows["episodes"] == n) & (rows["truth"] == "in_set")
                & (rows["group_true"] == "high")]["policy_regret"].mean()
    assert data.loc[("in_set", "high"), "full_over_random"] == pytest.approx(full / 0.5)
    assert "in-set people a mean regret of" in section.text


@pytest.mark.slow
def test_random_theta_regret_section_only_where_the_rows_carry_it(tmp_path):
    rows = conditions_rows(environments=2, runs=1, ks=(5,))
    cfg = {"episodes": 20, "low_episodes": 40, "max_steps": 500}
    md = build_report(write_sweep(tmp_path / "without", "conditions", rows, cfg)).read_text()
    assert "Regret of a random θ" not in md
    rows = rows.assign(random_theta_regret=rows["beta_true"].map(lambda b: 0.5 if b < 0.5 else 0.01))
    sweep = write_sweep(tmp_path / "with", "conditions", rows, cfg)
    md = build_report(sweep).read_text()
    assert "## Regret of a random θ" in md
    table = pd.read_csv(sweep / "report" / "tables" / "random_theta_regret.csv")
    inset = table[table["truth"] == "in_set"].set_index("group_true")
    assert inset.loc["high", "random_theta_regret_mean"] == pytest.approx(0.5)
    assert inset.loc["low", "random_theta_regret_mean"] == pytest.approx(0.01)
    assert "Protocol (goal reward): `scaled`" in md  # rows without the column, config without the field
