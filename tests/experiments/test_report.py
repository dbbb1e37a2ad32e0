"""``experiment report``: its files, one-line errors, verdicts computed from the rows, Pearson tables."""

from __future__ import annotations

import dataclasses
import json
import re
import shutil

import numpy as np
import pandas as pd
import pytest
from cli_helpers import assert_input_error, invoke, ok
from report_frames import (
    BOX_L1,
    conditions_like_rows,
    fullset_rows,
    optimisation_rows,
    run_record,
    write_sweep,
)
from scipy import stats

from expertise_irl.experiments.report import build_report, read_sweep
from expertise_irl.experiments.report import claims as C
from expertise_irl.experiments.report import fixed_vs_joint as cond_report
from expertise_irl.experiments.report.output import MARKER
from expertise_irl.experiments.report.stats import METRICS, fmt, fmt_p, ratio_ci
from expertise_irl.experiments.report.tables import (
    CONSTANT,
    factor_rows,
    format_rho,
    means_table,
    pearson_table,
)

FIGURES = ["fig2", "fig3", "fig4", "fig5", "fig6", "fig7"]


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """A conditions smoke sweep run through the engine, and its report."""
    sweep = tmp_path_factory.mktemp("report") / "sweep"
    ok(invoke("experiment", "run", "conditions", "--out", sweep, "--scale", "smoke", "--workers", "1"))
    result = invoke("experiment", "report", sweep)
    ok(result)
    return sweep, result


def _by_id(claims):
    return {c.id: c for c in claims}


# ----------------------------------------------------------------------------- the command
@pytest.mark.slow
def test_report_from_the_smoke_sweep_has_every_file(smoke):
    sweep, result = smoke
    out = sweep / "report"
    assert str(out / "report.md") in result.output
    md = (out / "report.md").read_text()
    for name in FIGURES:
        assert (out / "figures" / f"{name}.png").stat().st_size > 1000
        assert (out / "figures" / f"{name}.pdf").read_bytes().startswith(b"%PDF")
        assert f"](figures/{name}.png)" in md
    for name in ("table1", "table2", "capped", "conditions_means"):
        assert len(pd.read_csv(out / "tables" / f"{name}.csv")) > 0
    claims = pd.read_csv(out / "claims.csv")
    first = ["VI-B", "VI-C-cosine", "VI-C-regret", "VI-D-expertise_distance", "VI-D-policy_regret",
             "VI-E-group", "VI-E-regret"]  # the ids the report judged first, kept
    cells = [f"T{t}-{f}-{m}" for t, fs in ((1, ("theta_k_truth_similarity", "theta_k_diversity",
                                                  "beta_set_distance")),
                                           (2, ("episodes", "n_hypotheses", "n_states")))
             for f in fs for m in ("cosine", "beta", "regret")]
    assert list(claims["id"]) == [
        "VI-B", "VI-B-high", "VI-B-medium", "VI-B-low-group-full", "VI-B-low-group-fixed_theta",
        "VI-B-fig3-full", "VI-B-fig3-fixed_theta", "VI-C-cosine", "VI-C-regret", "VI-C-cosine-high",
        "VI-C-cosine-medium", "VI-C-cosine-low", "VI-C-cosine-low-lower", "VI-C-regret-high",
        "VI-C-regret-medium", "VI-C-regret-low", "VI-C-regret-low-near-0", "VI-D-expertise_distance",
        "VI-D-policy_regret", "VI-D-cosine_similarity", "VI-E-group", "VI-E-regret", "VI-E-cosine-15", *cells]
    assert set(first) <= set(claims["id"]) and claims["id"].is_unique
    assert set(claims["verdict"]) <= {C.REPRODUCED, C.DIFFERS, C.NOT_REPRODUCED, C.NO_DATA}
    # a table cell claim names its table, row and column
    cell = claims.set_index("id").loc["T1-beta_set_distance-beta"]
    assert cell["claim"] == "Table I, row “Min. distance between β*_out and B”, column “Expertise distance”"
    assert cell["paper"] == "0.58†" and cell["rule"] == "table-cell"
    # the header comes from the manifest and the timings
    assert "| study | conditions (version" in md and "| tasks | 4 done / 4 total, 0 failed |" in md
    assert "| rows | 168 |" in md and "Warning" not in md
    # smoke says at the top, in bold, that its verdicts mean nothing, and warns the same
    people = read_sweep(sweep).rows.drop_duplicates(cond_report.PERSON).shape[0]
    line = (f"**Scale `smoke` is a test of the machinery: its verdicts rest on a handful of people "
            f"(n = {people}) and mean nothing.**")
    assert md.splitlines()[2] == line
    assert (f"warning: Scale smoke is a test of the machinery: its verdicts rest on a handful of people "
            f"(n = {people}) and mean nothing.") in result.stderr
    assert "the sum of the wall times of the 4 finished tasks" in md
    assert "not the sweep's elapsed time" in md
    for rule in ("Ordering claims", "Ratio claims", "Share claims", "Threshold claims"):
        assert rule in md
    assert "## Capped episodes" in md and "DESIGN" not in md
    # Fig. 2: what its y scale says of a group
    assert ("The largest distance between two β values of the same group is 0.08 for high (0.01, 0.09), "
            "0.5 for medium (0.5, 1) and 5 for low (5, 10): a |β* − β̂| above it means β̂ left β*'s "
            "group") in md and "only within a group" not in md


@pytest.mark.slow
def test_report_md_claims_match_claims_csv(smoke):
    sweep, _ = smoke
    md = (sweep / "report" / "report.md").read_text()
    for row in pd.read_csv(sweep / "report" / "claims.csv").itertuples():
        assert f"| {row.verdict} | {row.why.replace('|', chr(92) + '|')} |" in md


@pytest.mark.slow
def test_a_previous_report_is_replaced_and_user_files_kept(smoke, tmp_path):
    sweep, _ = smoke
    out = tmp_path / "rep"
    ok(invoke("experiment", "report", sweep, "--out", out))
    (out / "figures" / "fig2.png").write_bytes(b"stale")
    (out / "notes.txt").write_text("mine")
    ok(invoke("experiment", "report", sweep, "--out", out))
    assert (out / "figures" / "fig2.png").read_bytes().startswith(b"\x89PNG")
    assert (out / "notes.txt").read_text() == "mine"
    assert "notes.txt" not in (out / MARKER).read_text()


@pytest.mark.slow
def test_rebuilding_a_report_leaves_its_files_as_they_were(smoke, tmp_path):
    """The marker holds no time: a report rebuilt from the same rows is byte for byte the same."""
    sweep, _ = smoke
    out = tmp_path / "rep"
    ok(invoke("experiment", "report", sweep, "--out", out))
    first = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    marker = json.loads((out / MARKER).read_text())
    assert set(marker) == {"written_by", "study", "files"} and marker["study"] == "conditions"
    ok(invoke("experiment", "report", sweep, "--out", out))
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == first


@pytest.mark.slow
def test_foreign_non_empty_out_is_refused(smoke, tmp_path):
    sweep, _ = smoke
    out = tmp_path / "mine"
    out.mkdir()
    (out / "report.md").write_text("my own notes")
    assert_input_error(invoke("experiment", "report", sweep, "--out", out), str(out), "holds no report")
    assert (out / "report.md").read_text() == "my own notes"
    assert sorted(p.name for p in out.iterdir()) == ["report.md"]


def test_not_a_sweep_unknown_study_and_no_rows_are_one_line_errors(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert_input_error(invoke("experiment", "report", empty), str(empty), "manifest.json")
    assert_input_error(invoke("experiment", "report", tmp_path / "absent"), "absent", "does not exist")
    afile = tmp_path / "a-file"
    afile.write_text("x")
    assert_input_error(invoke("experiment", "report", afile), "a-file", "not a directory")
    other = write_sweep(tmp_path / "other", "no-such-study", optimisation_rows(instances=1), {})
    assert_input_error(invoke("experiment", "report", other), "no report for study 'no-such-study'")
    none = write_sweep(tmp_path / "none", "optimisation", optimisation_rows(instances=2), {}, tasks=2)
    shutil.rmtree(none / "rows")
    (none / "rows").mkdir()
    assert_input_error(invoke("experiment", "report", none), "no rows yet", "0 of 2 tasks")
    broken = write_sweep(tmp_path / "broken", "optimisation",
                         optimisation_rows(instances=2).drop(columns="wall_time_s"), {})
    assert_input_error(invoke("experiment", "report", broken), "rows lack column 'wall_time_s'")


@pytest.mark.slow
def test_unfinished_sweep_reports_with_a_warning(smoke, tmp_path):
    sweep, _ = smoke
    part = tmp_path / "part"
    shutil.copytree(sweep, part, ignore=shutil.ignore_patterns("report"))
    first = sorted((part / "rows").iterdir())[0]
    first.unlink()
    result = invoke("experiment", "report", part)
    ok(result)
    assert "warning: 1 of 4 tasks are not finished" in result.stderr
    md = (part / "report" / "report.md").read_text()
    assert md.splitlines()[2].startswith("**Scale `smoke` is a test of the machinery")
    assert md.splitlines()[4].startswith("> **Warning: unfinished sweep.** 1 of 4 tasks")
    assert "| tasks | 3 done / 4 total, 0 failed |" in md


# ------------------------------------------------------------------------------- verdicts
def _set_fixed(rows, n, condition, metric, delta):
    """Rows where ``condition``'s ``metric`` is each in-set person's Full value + ``delta`` at n episodes."""
    rows = rows.copy()
    key = cond_report.PERSON
    at = (rows["episodes"] == n) & (rows["truth"] == "in_set")
    full = rows[at & (rows["condition"] == "full")].set_index(key)[metric]
    target = at & (rows["condition"] == condition)
    idx = pd.MultiIndex.from_frame(rows.loc[target, key])
    rows.loc[target, metric] = full.reindex(idx).to_numpy() + delta
    return rows


@pytest.mark.slow
def test_vi_b_verdict_follows_the_rows(smoke):
    rows = read_sweep(smoke[0]).rows
    n = 3
    worse = _by_id(cond_report.claims(_set_fixed(rows, n, "fixed_theta", "expertise_distance", 1.0), n))
    assert worse["VI-B"].verdict == C.REPRODUCED  # 12 pairs, all one way: Wilcoxon p = 2 / 2**12
    better = _by_id(cond_report.claims(_set_fixed(rows, n, "fixed_theta", "expertise_distance", -0.5), n))
    assert better["VI-B"].verdict == C.NOT_REPRODUCED
    assert better["VI-B"].value == pytest.approx(0.5)
    mixed = _set_fixed(rows, n, "fixed_theta", "expertise_distance", 0.0)
    assert _by_id(cond_report.claims(mixed, n))["VI-B"].verdict == C.NOT_REPRODUCED  # all ties


@pytest.mark.slow
def test_vi_c_cosine_verdict_flips_with_the_rows(smoke):
    rows = read_sweep(smoke[0]).rows
    lower = _set_fixed(rows, 3, "fixed_beta", "cosine_similarity", -0.1)
    assert _by_id(cond_report.claims(lower, 3))["VI-C-cosine"].verdict == C.REPRODUCED
    higher = _set_fixed(rows, 3, "fixed_beta", "cosine_similarity", 0.1)
    assert _by_id(cond_report.claims(higher, 3))["VI-C-cosine"].verdict == C.NOT_REPRODUCED


@pytest.mark.slow
def test_vi_d_ratio_verdict_at_the_band_edges(smoke):
    rows = read_sweep(smoke[0]).rows.copy()
    at = (rows["k"] == rows["k"].max()) & (rows["episodes"] == 3) & (rows["condition"] == "full")
    rows.loc[at & (rows["truth"] == "in_set"), "policy_regret"] = 0.25  # binary fractions: exact ratios
    for value, verdict in ((1.5, C.REPRODUCED), (2.25, C.REPRODUCED), (2.2501, C.DIFFERS),
                           (1.0, C.REPRODUCED), (0.9999, C.DIFFERS), (0.2, C.NOT_REPRODUCED)):
        rows.loc[at & (rows["truth"] == "out_of_set"), "policy_regret"] = value
        got = _by_id(cond_report.claims(rows, 3))["VI-D-policy_regret"]
        assert got.verdict == verdict, (value, got)
        assert got.value == pytest.approx(value / 0.25)
    # 6× on average, but out-of-set people spread from 0 to 3 (regret ratio 0 to 12): inconclusive
    out = at & (rows["truth"] == "out_of_set")
    rows.loc[out, "policy_regret"] = np.resize([0.0, 0.0, 0.0, 0.0, 3.0, 6.0], out.sum())
    got = _by_id(cond_report.claims(rows, 3))["VI-D-policy_regret"]
    assert got.value == pytest.approx(6.0) and got.verdict == C.DIFFERS
    assert got.why.startswith("inconclusive: ")
    assert "the CI includes 1 and overlaps the band. Beside the pooled ratio" in got.why


def test_ratio_verdict_rule():
    clear, includes, below = (1.2, 9.0), (0.8, 9.0), (0.5, 0.9)  # CIs: above 1, across 1, below 1
    for x in (1.5, 2.5, 4.0, 100.0):
        assert C.ratio_verdict(x, x, clear) == C.REPRODUCED
        assert C.ratio_verdict(x * 1.5, x, clear) == C.REPRODUCED
        assert C.ratio_verdict(x * 1.5 * 1.001, x, clear) == C.DIFFERS
        assert C.ratio_verdict(x / 1.5, x, clear) == C.REPRODUCED
        assert C.ratio_verdict(x, x, includes) == C.DIFFERS  # in the band, but inconclusive
        assert C.ratio_verdict(x, x, (np.nan, np.nan)) == C.DIFFERS  # no CI: inconclusive
    assert C.ratio_verdict(1.66, 2.5, clear) == C.DIFFERS
    # 1.0 is the lower edge of 1.5×'s band, but a ratio of 1 is no effect: never reproduced
    assert C.ratio_verdict(1.0, 1.5, (1.0, 1.0)) == C.NOT_REPRODUCED
    assert C.ratio_verdict(1.0, 1.5, includes) == C.DIFFERS
    assert C.ratio_verdict(0.99, 1.5, includes) == C.DIFFERS
    assert C.ratio_verdict(0.7, 1.5, below) == C.NOT_REPRODUCED  # the whole CI on the wrong side
    assert C.ratio_verdict(float("nan"), 3.0, clear) == C.NO_DATA  # 0 / 0: undefined
    # the log band of "2 orders of magnitude": 10**1.5 to 10**2.5
    band = C.ratio_band(100.0, orders=2)
    assert band == pytest.approx((31.6227766, 316.227766))
    assert C.ratio_verdict(50.0, 100.0, clear, band) == C.REPRODUCED
    assert C.ratio_verdict(50.0, 100.0, clear) == C.DIFFERS  # the linear band [66.7, 150]
    assert C.ratio_verdict(31.0, 100.0, clear, band) == C.DIFFERS


def test_ratio_ci_is_the_seeded_bootstrap_of_the_ratio_of_means():
    # two pairs: resamples are (0, 0), (1, 1) or mixed, with ratios 2, 4 and 3
    assert ratio_ci([2.0, 4.0], [1.0, 1.0], paired=True) == (2.0, 4.0)
    assert ratio_ci([3.0] * 7, [1.5] * 9, paired=False) == (2.0, 2.0)
    rng = np.random.default_rng(5)
    num, den = rng.exponential(size=40), rng.exponential(size=40)
    assert ratio_ci(num, den, paired=True) == ratio_ci(num, den, paired=True)  # seeded: the same
    lo, hi = ratio_ci(num, den, paired=True)
    assert lo < num.mean() / den.mean() < hi


def _ratio(num, den, target=1.5, paired=True):
    return C.ratio_claim("x", "s", "c", "p", num, den, "a", "b", "q", target, paired=paired, who="people")


def test_ratio_claims_near_1_and_in_the_band():
    ones = np.ones(8)
    same = _ratio(ones, ones)  # no effect at all: ratio 1, CI [1, 1]
    assert same.value == 1.0 and same.verdict == C.NOT_REPRODUCED
    noisy = _ratio([1.5, 0.5, 1.6, 0.6, 1.4, 0.7, 1.2, 0.66], ones)  # ratio 1.02, CI across 1
    assert noisy.value == pytest.approx(1.02)
    assert noisy.verdict == C.DIFFERS and noisy.why.startswith("inconclusive: ")
    assert noisy.ci_low < 1 < noisy.ci_high
    tight = _ratio([1.49, 1.51] * 4, ones)  # 1.5× with every pair at 1.49 or 1.51
    assert tight.verdict == C.REPRODUCED and 1.49 <= tight.ci_low <= tight.ci_high <= 1.51
    assert "1.5× [1.49, 1.51]" in tight.ours
    few = _ratio([1.5] * 5, np.ones(5))  # 5 pairs: too few for a CI
    assert few.verdict == C.DIFFERS and "n/a: n < 6" in few.ours and few.why.startswith("inconclusive: ")
    wrong_size = _ratio([3.0] * 8, ones)  # 3× against a claimed 1.5×, CI [3, 3]: not inconclusive
    assert wrong_size.verdict == C.DIFFERS and not wrong_size.why.startswith("inconclusive")
    ours = C.ratio_claim("x", "s", "c", "p", [1.5, 0.5, 1.6, 0.6, 1.4, 0.7, 1.2, 0.66], ones, "a", "b", "q",
                         1.5, paired=True, who="people", judged=False)
    assert ours.verdict == C.NOT_JUDGED
    assert "the CI includes 1 and overlaps the band: inconclusive. Beside" in ours.why
    worse = _ratio(0.8 * ones, ones)
    assert worse.verdict == C.NOT_REPRODUCED and "against the claim" in worse.why
    got = _ratio([2.0, 4.0] * 3, np.ones(6), target=3.0)
    assert got.value == 3.0 and got.verdict == C.REPRODUCED and "ratio 3" in got.why


def test_pairing_matters_where_people_differ_a_lot():
    den = np.array([0.1] * 7 + [10.0])
    num = 1.5 * den  # each person 1.5× worse: paired, the ratio is 1.5 in every resample
    assert _ratio(num, den, paired=True).verdict == C.REPRODUCED
    unpaired = _ratio(num, den, paired=False)  # as two independent samples the CI spans 1
    assert unpaired.verdict == C.DIFFERS and unpaired.ci_low < 1 < unpaired.ci_high


@pytest.mark.slow
def test_vi_c_regret_uses_the_log_band(smoke):
    rows = read_sweep(smoke[0]).rows.copy()
    at = (rows["truth"] == "in_set") & (rows["episodes"] == 3)
    rows.loc[at & (rows["condition"] == "full"), "policy_regret"] = 0.01
    for fixed, verdict in ((0.5, C.REPRODUCED), (0.25, C.DIFFERS), (3.0, C.REPRODUCED), (3.2, C.DIFFERS)):
        rows.loc[at & (rows["condition"] == "fixed_beta"), "policy_regret"] = fixed  # 50×, 25×, 300×, 320×
        got = _by_id(cond_report.claims(rows, 3))["VI-C-regret"]
        assert got.value == pytest.approx(fixed / 0.01) and got.verdict == verdict, (fixed, got)
        assert got.rule == "magnitude"


@pytest.mark.slow
def test_vi_e_share_and_threshold_follow_the_rows(smoke):
    rows = read_sweep(smoke[0]).rows.copy()
    full_in = (rows["truth"] == "in_set") & (rows["condition"] == "full") & (rows["episodes"] == 3)
    got = _by_id(cond_report.claims(rows, 3))
    share = (rows.loc[full_in, "group_hat"] == rows.loc[full_in, "group_true"]).mean()
    assert got["VI-E-group"].value == pytest.approx(share)
    mass = (rows.loc[full_in, "p_group_true"] > 0.5).mean()
    assert f"(p_group_true > 0.5): {mass:.0%}" in got["VI-E-group"].why
    rows.loc[full_in, "p_group_true"] = 0.4
    assert "(p_group_true > 0.5): 0%" in _by_id(cond_report.claims(rows, 3))["VI-E-group"].why
    rows.loc[full_in, "group_hat"] = "nobody"
    assert _by_id(cond_report.claims(rows, 3))["VI-E-group"].verdict == C.NOT_REPRODUCED
    rows.loc[full_in, "policy_regret"] = 0.05
    assert _by_id(cond_report.claims(rows, 3))["VI-E-regret"].verdict == C.REPRODUCED
    rows.loc[full_in, "policy_regret"] = 0.04
    rows.loc[full_in & (rows["group_true"] == "high"), "policy_regret"] = 0.06
    got = _by_id(cond_report.claims(rows, 3))["VI-E-regret"]
    assert got.value <= 0.05 and got.verdict == C.DIFFERS  # all at most 0.05, the high group not
    assert not got.why.startswith("inconclusive")  # a group above the threshold: not a matter of n
    rows.loc[full_in, "policy_regret"] = 0.2
    assert _by_id(cond_report.claims(rows, 3))["VI-E-regret"].verdict == C.NOT_REPRODUCED


def test_ordering_rule_not_significant_is_differs():
    a = np.array([1.0, 2.0, 3.0, 4.0])
    got = C.ordering_claim("x", "s", "c", "p", a - 0.1, a, "A", "B", "q", claimed="below")
    assert got.verdict == C.DIFFERS  # right sign, 4 pairs: one-sided Wilcoxon p = 1/16
    assert got.value == pytest.approx(-0.1) and got.why.startswith("inconclusive: ")
    assert got.p == pytest.approx(1 / 16)
    b = np.arange(1.0, 11.0)  # the wrong sign, significant: not reproduced, not inconclusive
    wrong = C.ordering_claim("x", "s", "c", "p", b + 0.1, b, "A", "B", "q")
    assert wrong.verdict == C.NOT_REPRODUCED and not wrong.why.startswith("inconclusive")
    share = C.share_claim("x", "s", "c", "p", [True, True, False], "people")  # 2 of 3, p = 0.5
    assert share.verdict == C.DIFFERS and share.why.startswith("inconclusive: ")
    assert not C.share_claim("x", "s", "c", "p", [True] * 10, "people").why.startswith("inconclusive")


# ------------------------------------------------------------------------------- Pearson
def test_pearson_table_matches_scipy_and_daggers_exactly_where_p_below_005():
    rng = np.random.default_rng(3)
    n = 40
    x = rng.normal(size=n)
    frame = pd.DataFrame({
        "strong": x, "weak": rng.normal(size=n), "edge": x + rng.normal(scale=4.5, size=n),
        "constant": np.ones(n),
        "cosine_similarity": x + rng.normal(scale=0.5, size=n),
        "expertise_distance": rng.normal(size=n),
        "policy_regret": np.r_[x[:-2] * 0.1 + rng.normal(scale=0.3, size=n - 2), np.nan, np.nan]})
    factors = {"strong": "Strong", "weak": "Weak", "edge": "Edge", "constant": "Constant", "v2": "Later"}
    table = pearson_table("t", "T", "cap.", factor_rows(frame, factors, {"v2": "needs study version 2"}))
    data = table.data
    seen_dagger = seen_plain = False
    for row in data.itertuples():
        cell = table.display.loc[table.display["Factor"] == factors[row.factor]].iloc[0]
        label = {"cosine_similarity": "Preferences similarity", "expertise_distance": "Expertise distance",
                 "policy_regret": "Regret"}[row.metric]
        assert cell[label] == row.cell
        if row.factor == "constant":
            assert row.cell == CONSTANT
            continue
        if row.factor == "v2":
            assert row.cell == "needs study version 2"
            continue
        keep = frame[[row.factor, row.metric]].dropna()
        ref = stats.pearsonr(keep[row.factor], keep[row.metric])
        assert row.rho == pytest.approx(ref.statistic, abs=1e-12)
        assert row.p == pytest.approx(ref.pvalue, rel=1e-9)
        assert row.n == len(keep)
        assert row.cell.endswith("†") == (ref.pvalue < 0.05)
        assert row.cell.rstrip("†").replace("−", "-") == f"{ref.statistic:.2f}".replace("-0.00", "0.00")
        seen_dagger |= ref.pvalue < 0.05
        seen_plain |= ref.pvalue >= 0.05
    assert seen_dagger and seen_plain
    assert set(data.loc[data["metric"] == "policy_regret", "n"]) >= {n - 2}


def test_format_rho():
    assert format_rho(-0.123, 0.01) == "−0.12†"
    assert format_rho(0.57, 0.05) == "0.57"
    assert format_rho(-0.004, 0.5) == "0.00"


@pytest.mark.slow
def test_table_1_says_when_it_needs_study_version_2(smoke):
    sweep = read_sweep(smoke[0])
    v1 = dataclasses.replace(sweep, rows=sweep.rows.drop(columns=list(cond_report.V2), errors="ignore"))
    report = cond_report.build(v1)
    table1 = next(t for t in report.tables if t.name == "table1")
    assert set(table1.data["cell"]) == {"needs study version 2"}
    for f in report.figures:
        f.fig.clear()


# ---------------------------------------------------------------- other studies, hand-made rows
def _pairs(rows, a: str, b: str, column: str):
    """``column`` of methods a and b on the same (environment, instance, episodes), a and b aligned."""
    key = ["environment", "instance", "episodes"]
    x = rows[rows["method"] == a].set_index(key)[column]
    y = rows[rows["method"] == b].set_index(key)[column]
    common = x.index.intersection(y.index)
    return x.loc[common], y.loc[common]


@pytest.mark.slow
def test_optimisation_report_from_contract_rows(tmp_path):
    rows = optimisation_rows()
    sweep = write_sweep(tmp_path / "opt", "optimisation", rows, {"episode_counts": [10, 20, 30, 40],
                                                                  "max_steps": 500}, tasks=3)
    build_report(sweep)
    out = sweep / "report"
    for name in ("fig8", "fig9"):
        assert (out / "figures" / f"{name}.png").is_file() and (out / "figures" / f"{name}.pdf").is_file()
    claims = pd.read_csv(out / "claims.csv").set_index("id")
    box, disc = rows[rows["method"] == "birl_box"], rows[rows["method"] == "discrete"]
    # VII-D: about 4× in every pair (the rows' 4.0 n / 10 · (1 + 0.1 U) against 1.0 n / 10 · ...), so
    # the CI lies inside the band [2.67, 6]
    b, d = _pairs(rows, "birl_box", "discrete", "wall_time_s")
    assert ((b / d) > 3.3).all() and ((b / d) < 4.5).all()
    speed = box["wall_time_s"].mean() / disc["wall_time_s"].mean()
    assert claims.loc["VII-D", "value"] == pytest.approx(speed)
    assert claims.loc["VII-D", "verdict"] == C.REPRODUCED
    at40 = rows[rows["episodes"] == 40]
    # β distance: every pair above 1, the ratio of means 2.54, above the band [1, 2.25]
    d, b = _pairs(at40, "discrete", "birl_box", "expertise_distance")
    ratio = d.mean() / b.mean()
    assert ((d / b) > 1).all() and ratio == pytest.approx(2.543, abs=1e-3)
    assert claims.loc["VII-B-beta-birl_box", "value"] == pytest.approx(ratio)
    assert claims.loc["VII-B-beta-birl_box", "verdict"] == C.DIFFERS
    assert claims.loc["VII-B-beta-birl_box", "ci_low"] > 1
    # regret: every pair above 1, the ratio 1.87, inside [1.67, 3.75]
    d, b = _pairs(at40, "discrete", "birl_box", "policy_regret")
    assert ((d / b) > 1).all() and d.mean() / b.mean() == pytest.approx(1.871, abs=1e-3)
    assert claims.loc["VII-B-regret-birl_box", "verdict"] == C.REPRODUCED
    for m in ("birl_simplex", "map", "nuts"):
        assert claims.loc[f"VII-B-regret-{m}", "verdict"] == C.NOT_JUDGED
    nuts = at40[at40["method"] == "nuts"].set_index(["environment", "instance"])
    disc40 = at40[at40["method"] == "discrete"].set_index(["environment", "instance"]).loc[nuts.index]
    assert claims.loc["VII-B-beta-nuts", "value"] == pytest.approx(
        disc40["expertise_distance"].mean() / nuts["expertise_distance"].mean())  # over NUTS' instances
    # birl_box rescaled: |β* − β̂ / ‖θ̂‖₁| with ‖θ̂‖₁ = 0.8 on every birl_box row; not judged
    box40 = at40[at40["method"] == "birl_box"]
    rescaled = (box40["beta_true"] - box40["beta_hat"] / BOX_L1).abs()
    got = claims.loc["VII-B-beta-birl_box_rescaled"]
    discrete40 = at40.loc[at40["method"] == "discrete", "expertise_distance"]
    assert got["value"] == pytest.approx(discrete40.mean() / rescaled.mean())
    assert got["verdict"] == C.NOT_JUDGED
    wall = pd.read_csv(out / "tables" / "walltime.csv").set_index("method")
    assert wall.loc["birl_box", "median_s"] == pytest.approx(box["wall_time_s"].median())
    table4 = pd.read_csv(out / "tables" / "table4.csv")
    got = table4[(table4["factor"] == "beta_true") & (table4["metric"] == "policy_regret")].iloc[0]
    assert got["rho"] == pytest.approx(stats.pearsonr(box["beta_true"], box["policy_regret"]).statistic)
    md = (out / "report.md").read_text()
    assert "## Capped episodes" in md
    # the prior once, with the methods that use it
    assert md.count("θ ~ U[0,1]^5, β ~ N(5.005, 1.5)") == 1
    assert "`birl_box`, `birl_simplex`, `map`, `nuts`: paper (θ ~ U[0,1]^5" in md
    assert f"mean ‖θ̂‖₁ is {fmt(BOX_L1)}" in md and "not the chain's mean of β/‖θ‖₁" in md
    assert "| runs | 1 recorded in `runs/`: a run with 1 local worker and 3 tasks to run |" in md
    assert "one worker" not in md
    assert "| elapsed time | not recorded (no `wall_time_s` in `runs/*.json`) |" in md
    assert "Scale `smoke`" not in md  # scale custom


@pytest.mark.parametrize("walls, expect", [
    ([12.5, 200.0], "212.5 s (3.5 min): the sum of the elapsed times of the 2 invocations of "
                    "`experiment run`"),
    pytest.param([12.5, None, "x"], "12.5 s: the sum of the elapsed times of the 1 of 3 invocations of "
                 "`experiment run` that record it (2 without `wall_time_s`)", marks=pytest.mark.slow),
    pytest.param([7200.0], "7200.0 s (2.0 h): the sum of the elapsed times of the 1 invocation of "
                 "`experiment run`", marks=pytest.mark.slow)])
def test_header_gives_the_runs_elapsed_time_where_recorded(tmp_path, walls, expect):
    runs = [run_record(**({"wall_time_s": w} if w is not None else {})) for w in walls]
    sweep = write_sweep(tmp_path / "opt", "optimisation", optimisation_rows(instances=2), {"max_steps": 500},
                        runs=runs, timings=[3.0, 4.0])
    md = build_report(sweep).read_text()
    assert f"| elapsed time | {expect} (`wall_time_s` in `runs/*.json`) |" in md
    assert ("| task wall time | 7.0 s: the sum of the wall times of the 2 finished tasks (`wall_time_s` in "
            "`timings/`); tasks on parallel workers overlap, so this is not the sweep's elapsed time |") in md


@pytest.mark.slow
@pytest.mark.parametrize("run, shared", [
    (run_record(workers=2), "2 local workers"),
    (run_record(workers=None, engine="dask", scheduler="tcp://10.0.0.1:8786"), "tcp://10.0.0.1:8786"),
    (None, "records no run")])
def test_vii_d_is_not_judged_when_tasks_shared_the_machine(tmp_path, run, shared):
    rows = optimisation_rows(instances=3)
    runs = [run_record(workers=1, tasks_to_run=0), run] if run is not None else []
    sweep = write_sweep(tmp_path / "opt", "optimisation", rows, {"max_steps": 500}, runs=runs)
    build_report(sweep)
    claims = pd.read_csv(sweep / "report" / "claims.csv").set_index("id")
    got = claims.loc["VII-D"]
    assert got["verdict"] == C.WITHHELD and shared in got["why"] and "Not judged" in got["why"]
    assert got["value"] == pytest.approx(4.0, rel=0.15)  # the number is still given
    assert claims.loc["VII-B-regret-birl_box", "verdict"] != C.WITHHELD  # only the timing claim
    md = (sweep / "report" / "report.md").read_text()
    assert C.VERDICT_NOTES[C.WITHHELD] in md
    if run is not None:
        assert shared in md.split("| runs |")[1].splitlines()[0]  # the header names the workers


def test_cardinality_report_from_contract_rows(tmp_path):
    rows = conditions_like_rows()
    sweep = write_sweep(tmp_path / "card", "cardinality", rows, {"episodes": 20, "max_steps": 500})
    build_report(sweep)
    out = sweep / "report"
    assert (out / "figures" / "fig_cardinality.png").is_file()
    table3 = pd.read_csv(out / "tables" / "table3.csv")
    at = rows[rows["episodes"] == 20]
    for truth, label in (("in_set", "In set"), ("out_of_set", "Out of set")):
        sub = at[at["truth"] == truth]
        got = table3[table3["row"].str.startswith(label) & (table3["metric"] == "policy_regret")].iloc[0]
        ref = stats.pearsonr(sub["n_hypotheses"], sub["policy_regret"])
        assert got["rho"] == pytest.approx(ref.statistic) and got["n"] == len(sub)
    claims = pd.read_csv(out / "claims.csv").set_index("id")
    in_regret = stats.pearsonr(at.loc[at["truth"] == "in_set", "n_hypotheses"],
                               at.loc[at["truth"] == "in_set", "policy_regret"])
    assert in_regret.statistic > 0  # the fixture's in-set regret grows with k
    assert claims.loc["VI-E-card-in-regret", "verdict"] == (
        C.REPRODUCED if in_regret.pvalue < 0.05 else C.DIFFERS)


@pytest.mark.parametrize("truth_column", [pytest.param(True, marks=pytest.mark.slow), False])
def test_fullset_report_from_contract_rows(tmp_path, truth_column):
    rows = fullset_rows(truth_column=truth_column)
    timings = [{"set_solve_time_s": 12.0, "set_solves": 1, "people": 0}, {"set_solve_time_s": 13.0,
                                                                           "set_solves": 1, "people": 0}]
    sweep = write_sweep(tmp_path / "full", "fullset", rows, {"source_scale": "paper"}, keys=["e000", "e001"],
                        timings=[30.0, 50.0], timing_columns=timings)
    build_report(sweep)
    out = sweep / "report"
    assert (out / "figures" / "fig_fullset.png").is_file()
    cost = pd.read_csv(out / "tables" / "fullset_cost.csv")
    people = rows.drop_duplicates(["source", "environment", "run", "k", "group", "instance",
                                   *(["truth"] if truth_column else [])])
    per_map = cost[cost["environment"] != "all"].set_index("environment")
    counts = {str(e): n for e, n in people.groupby("environment").size().items()}
    assert per_map["people_served"].to_dict() == counts
    # each map's whole task from the timings table, beside its solve, and per person
    assert per_map["task_wall_time_s"].to_dict() == {"0": 30.0, "1": 50.0}
    assert per_map.loc["1", "task_s_per_person"] == pytest.approx(50.0 / counts["1"])
    assert per_map.loc["1", "set_solve_time_s"] == 13.0
    md = (out / "report.md").read_text()
    assert "compilation of that shape on its first use" in md
    # the source studies' max_steps at the paper scale, said once
    assert "hits the cap (500 actions)" in md and "(the step cap)" not in md
    capped = md.split("## Capped episodes")[1].split("\n\n")[1]
    pops = ["the conditions study's out-of-set people", "the optimisation study's out-of-set people"]
    if truth_column:
        pops.insert(0, "the conditions study's in-set people")
    for who in pops:  # one sentence on the shares, one on the β distances
        assert capped.count(f"For {who}, most episodes are capped") == 1
        assert capped.count(f"For {who}: ") == 1
    means = pd.read_csv(out / "tables" / "fullset_means.csv")
    if truth_column:
        gap = pd.read_csv(out / "tables" / "fullset_gap.csv").set_index(["source", "metric"])
        row = gap.loc[("conditions", "policy_regret")]
        at = rows[(rows["source"] == "conditions") & (rows["episodes"] == 20)]
        out_k = at.loc[(at["truth"] == "out_of_set") & (at["set"] == "theta_k"), "policy_regret"].mean()
        out_f = at.loc[(at["truth"] == "out_of_set") & (at["set"] == "full"), "policy_regret"].mean()
        in_k = at.loc[(at["truth"] == "in_set") & (at["set"] == "theta_k"), "policy_regret"].mean()
        in_f = at.loc[(at["truth"] == "in_set") & (at["set"] == "full"), "policy_regret"].mean()
        assert row["share_closed"] == pytest.approx(1 - (out_f - in_k) / (out_k - in_k))
        assert row["in_set_full"] == pytest.approx(in_f)
        assert gap.loc[("optimisation", "policy_regret"), "reference"] == "conditions"
        # the reference's episodes and β*; the optimisation people are judged against another protocol
        assert "For the conditions study's out-of-set people (18 people, 20 episodes, β* from " in md
        assert "reference: its in-set people (18 people, 20 episodes, β* ∈ {0.01 ×" in md
        assert ("For the optimisation study's out-of-set people (10 people, 40 episodes, β* from "
                in md) and "reference, from another protocol: the conditions study's in-set people" in md
        # in-set people as good under the full set as under Ψ_k: no worse; worse once their full-set
        # regret is raised
        same = rows.copy()
        inset, key = same["truth"] == "in_set", ["source", "environment", "run", "k", "group", "episodes"]
        own = same[inset & (same["set"] == "theta_k")].set_index(key)[list(METRICS)]
        full = inset & (same["set"] == "full")
        same.loc[full, list(METRICS)] = own.loc[pd.MultiIndex.from_frame(same.loc[full, key])].to_numpy()
        paper = {"source_scale": "paper"}
        md = build_report(write_sweep(tmp_path / "same", "fullset", same, paper)).read_text()
        assert ("The conditions study's in-set people, own Ψ_k → full set: the full set leaves them no "
                "worse") in md
        same.loc[full, "policy_regret"] += 0.5
        md = build_report(write_sweep(tmp_path / "worse", "fullset", same, paper)).read_text()
        assert "the full set makes them worse on regret" in md
    else:
        assert set(means["truth"]) == {"out_of_set"}  # derived from truth_probability
        assert "No in-set people" in md


def test_means_tables_clip_their_cis_to_the_metric_range():
    frame = pd.DataFrame({"g": ["a"] * 4, "cosine_similarity": [1.0, 1.0, 0.9, 1.0],
                          "expertise_distance": [0.0, 0.0, 0.0, 4.0], "policy_regret": [0.1, 0.2, 0.1, 0.2]})
    t = means_table("m", "M", "cap.", frame, ["g"])
    rec = t.data.iloc[0]
    ref = stats.t.interval(0.95, 3, loc=0.975, scale=frame["cosine_similarity"].std() / 2)
    assert ref[1] > 1 and rec["cosine_similarity_ci_high"] == 1.0
    assert rec["cosine_similarity_ci_low"] == pytest.approx(ref[0])
    assert rec["expertise_distance_ci_low"] == 0.0  # the Student t bound is below 0
    assert t.display.iloc[0]["Preferences similarity"].endswith(", 1]")
    assert "clipped to the metric's range" in t.caption


@pytest.mark.slow
def test_capped_shares_and_the_effect_text_speak_of_the_same_people(smoke):
    sweep = read_sweep(smoke[0])
    rows = sweep.rows
    report = cond_report.build(sweep)
    for f in report.figures:
        f.fig.clear()
    text = report.sections[0].text
    last = rows[rows["condition"] == "full"].sort_values("episodes").groupby(cond_report.PERSON).tail(1)
    inset = last[last["truth"] == "in_set"].groupby("group_true")[["n_capped", "episodes"]].sum()
    shares = {g: inset.loc[g, "n_capped"] / inset.loc[g, "episodes"] for g in inset.index}
    assert set(rows["goal_reward_mode"]) == {"scaled"}  # the protocol: the shares are stated under it
    sentence = text.split("For in-set people under the `scaled` protocol, ")[1].split(". ")[0]
    for g, v in shares.items():
        assert f"{g} ({v:.0%})" in sentence or f"{g} {v:.0%}" in sentence
        assert f"× ({v:.0%} of episodes capped)" in text.split("per expertise group of the in-set")[1]
    assert "hits the cap (60 actions)" in text  # conditions smoke's max_steps
    assert "see the README, 'A property of the model worth knowing'" in text and "DESIGN" not in text


def _capped_text(shares: dict[str, dict[str, float]]) -> str:
    from expertise_irl.experiments.report.capped import capped_section

    last = pd.DataFrame([{"truth": t, "group_true": g, "episodes": 100, "n_capped": round(100 * v)}
                         for t, per in shares.items() for g, v in per.items()])
    return capped_section(last, "", by=["truth"], max_steps=500).text


def test_capped_text_says_one_sentence_per_population():
    text = _capped_text({"in_set": {"high": 0.3, "medium": 0.99, "low": 1.0},
                         "out_of_set": {"high": 0.55, "medium": 0.97, "low": 1.0}})
    assert ("For in-set people, most episodes are capped at medium (99%) and low (100%) expertise, at "
            "most half at high (30%).") in text
    assert ("For out-of-set people, most episodes are capped at every expertise level (high 55%, "
            "medium 97%, low 100%).") in text
    assert "An episode that hits the cap (500 actions) ends without reaching the goal" in text
    few = _capped_text({"in_set": {"high": 0.1, "medium": 0.5}, "out_of_set": {"medium": 0.8, "low": 1.0}})
    assert ("For in-set people, no expertise group has most of its episodes capped (high 10%, "
            "medium 50%).") in few
    assert "For out-of-set people, most episodes are capped at medium (80%) and low (100%) expertise." in few


def test_why_sentences_use_a_true_minus_sign():
    x = np.arange(10.0)
    got = C.correlation_claim("x", "s", "c", "p", x, -x + np.sin(x), "f", "m", claimed="negative")
    assert "is −0.9" in got.why and "-0." not in got.why
    assert fmt(-0.5) == "−0.5" and fmt(-2e-5) == "−2.00e−05" and fmt(0.25) == "0.25"
    assert fmt_p(1.3e-14) == "1.3e−14" and fmt_p(0.031) == "0.031"
    tiny = C.ordering_claim("x", "s", "c", "p", np.zeros(30), np.arange(1.0, 31.0), "A", "B", "q")
    assert "e−" in tiny.why and not re.search(r"\de-\d", tiny.why)  # Wilcoxon p = 9.3e−10
