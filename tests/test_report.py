"""``experiment report``: its files, one-line errors, verdicts computed from the rows, Pearson tables."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pandas as pd
import pytest
from cli_helpers import assert_input_error, invoke, ok
from report_frames import conditions_like_rows, fullset_rows, optimisation_rows, write_sweep
from scipy import stats

from expertise_irl.experiments.report import build_report, read_sweep
from expertise_irl.experiments.report import claims as C
from expertise_irl.experiments.report import conditions as cond_report
from expertise_irl.experiments.report.output import MARKER
from expertise_irl.experiments.report.tables import CONSTANT, factor_rows, format_rho, pearson_table

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
    assert list(claims["id"]) == ["VI-B", "VI-C-cosine", "VI-C-regret", "VI-D-expertise_distance",
                                  "VI-D-policy_regret", "VI-E-group", "VI-E-regret"]
    assert set(claims["verdict"]) <= {C.REPRODUCED, C.DIFFERS, C.NOT_REPRODUCED}
    # the header comes from the manifest and the timings
    assert "| study | conditions (version" in md and "| tasks | 4 done / 4 total, 0 failed |" in md
    assert "| rows | 168 |" in md and "Warning" not in md
    for rule in ("Ordering claims", "Ratio claims", "Share claims", "Threshold claims"):
        assert rule in md
    assert "## Capped episodes" in md


def test_report_md_claims_match_claims_csv(smoke):
    sweep, _ = smoke
    md = (sweep / "report" / "report.md").read_text()
    for row in pd.read_csv(sweep / "report" / "claims.csv").itertuples():
        assert f"| {row.verdict} | {row.why.replace('|', chr(92) + '|')} |" in md


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
    assert_input_error(invoke("experiment", "report", tmp_path / "absent"), "absent", "not a directory")
    other = write_sweep(tmp_path / "other", "no-such-study", optimisation_rows(instances=1), {})
    assert_input_error(invoke("experiment", "report", other), "no report for study 'no-such-study'")
    none = write_sweep(tmp_path / "none", "optimisation", optimisation_rows(instances=2), {}, tasks=2)
    shutil.rmtree(none / "rows")
    (none / "rows").mkdir()
    assert_input_error(invoke("experiment", "report", none), "no rows yet", "0 of 2 tasks")
    broken = write_sweep(tmp_path / "broken", "optimisation",
                         optimisation_rows(instances=2).drop(columns="wall_time_s"), {})
    assert_input_error(invoke("experiment", "report", broken), "rows lack column 'wall_time_s'")


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
    assert md.splitlines()[2].startswith("> **Warning: unfinished sweep.** 1 of 4 tasks")
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


def test_vi_c_cosine_verdict_flips_with_the_rows(smoke):
    rows = read_sweep(smoke[0]).rows
    lower = _set_fixed(rows, 3, "fixed_beta", "cosine_similarity", -0.1)
    assert _by_id(cond_report.claims(lower, 3))["VI-C-cosine"].verdict == C.REPRODUCED
    higher = _set_fixed(rows, 3, "fixed_beta", "cosine_similarity", 0.1)
    assert _by_id(cond_report.claims(higher, 3))["VI-C-cosine"].verdict == C.NOT_REPRODUCED


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


def test_ratio_verdict_rule():
    for x in (1.5, 2.5, 4.0, 100.0):
        assert C.ratio_verdict(x, x) == C.REPRODUCED
        assert C.ratio_verdict(x * 1.5, x) == C.REPRODUCED
        assert C.ratio_verdict(x * 1.5 * 1.001, x) == C.DIFFERS
        assert C.ratio_verdict(x / 1.5, x) == C.REPRODUCED
    assert C.ratio_verdict(1.66, 2.5) == C.DIFFERS
    assert C.ratio_verdict(0.99, 1.5) == C.NOT_REPRODUCED  # on the wrong side of 1
    assert C.ratio_verdict(1.0, 1.5) == C.REPRODUCED  # 1.5 / 1.5: the band's lower edge
    assert C.ratio_verdict(float("nan"), 3.0) == C.NOT_REPRODUCED
    got = C.ratio_claim("x", "s", "c", "p", [2.0, 4.0], [1.0, 1.0], "a", "b", "q", 3.0)
    assert got.value == 3.0 and got.verdict == C.REPRODUCED and "ratio 3" in got.why


def test_vi_e_share_and_threshold_follow_the_rows(smoke):
    rows = read_sweep(smoke[0]).rows.copy()
    full_in = (rows["truth"] == "in_set") & (rows["condition"] == "full") & (rows["episodes"] == 3)
    got = _by_id(cond_report.claims(rows, 3))
    share = (rows.loc[full_in, "group_hat"] == rows.loc[full_in, "group_true"]).mean()
    assert got["VI-E-group"].value == pytest.approx(share)
    rows.loc[full_in, "group_hat"] = "nobody"
    assert _by_id(cond_report.claims(rows, 3))["VI-E-group"].verdict == C.NOT_REPRODUCED
    rows.loc[full_in, "policy_regret"] = 0.05
    assert _by_id(cond_report.claims(rows, 3))["VI-E-regret"].verdict == C.REPRODUCED
    rows.loc[full_in, "policy_regret"] = 0.04
    rows.loc[full_in & (rows["group_true"] == "high"), "policy_regret"] = 0.06
    got = _by_id(cond_report.claims(rows, 3))["VI-E-regret"]
    assert got.value <= 0.05 and got.verdict == C.DIFFERS  # all at most 0.05, the high group not
    rows.loc[full_in, "policy_regret"] = 0.2
    assert _by_id(cond_report.claims(rows, 3))["VI-E-regret"].verdict == C.NOT_REPRODUCED


def test_ordering_rule_not_significant_is_differs():
    a = np.array([1.0, 2.0, 3.0, 4.0])
    got = C.ordering_claim("x", "s", "c", "p", a - 0.1, a, "A", "B", "q", claimed="below")
    assert got.verdict == C.DIFFERS  # right sign, 4 pairs: Wilcoxon p = 0.125
    assert got.value == pytest.approx(-0.1)


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


def test_table_1_says_when_it_needs_study_version_2(smoke):
    sweep = read_sweep(smoke[0])
    v1 = dataclasses.replace(sweep, rows=sweep.rows.drop(columns=list(cond_report.V2), errors="ignore"))
    report = cond_report.build(v1)
    table1 = next(t for t in report.tables if t.name == "table1")
    assert set(table1.data["cell"]) == {"needs study version 2"}
    for f in report.figures:
        f.fig.clear()


# ---------------------------------------------------------------- other studies, hand-made rows
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
    speed = box["wall_time_s"].mean() / disc["wall_time_s"].mean()
    assert claims.loc["VII-D", "value"] == pytest.approx(speed)
    assert claims.loc["VII-D", "verdict"] == C.ratio_verdict(speed, 4.0)
    at40 = rows[rows["episodes"] == 40]
    ratio = (at40.loc[at40["method"] == "discrete", "expertise_distance"].mean()
             / at40.loc[at40["method"] == "birl_box", "expertise_distance"].mean())
    assert claims.loc["VII-B-beta-birl_box", "value"] == pytest.approx(ratio)
    assert claims.loc["VII-B-beta-birl_box", "verdict"] == C.ratio_verdict(ratio, 1.5)
    for m in ("birl_simplex", "map", "nuts"):
        assert claims.loc[f"VII-B-regret-{m}", "verdict"] == C.NOT_JUDGED
    nuts = at40[at40["method"] == "nuts"].set_index(["environment", "instance"])
    disc40 = at40[at40["method"] == "discrete"].set_index(["environment", "instance"]).loc[nuts.index]
    assert claims.loc["VII-B-beta-nuts", "value"] == pytest.approx(
        disc40["expertise_distance"].mean() / nuts["expertise_distance"].mean())  # over NUTS' instances
    wall = pd.read_csv(out / "tables" / "walltime.csv").set_index("method")
    assert wall.loc["birl_box", "median_s"] == pytest.approx(box["wall_time_s"].median())
    table4 = pd.read_csv(out / "tables" / "table4.csv")
    got = table4[(table4["factor"] == "beta_true") & (table4["metric"] == "policy_regret")].iloc[0]
    assert got["rho"] == pytest.approx(stats.pearsonr(box["beta_true"], box["policy_regret"]).statistic)
    md = (out / "report.md").read_text()
    assert "β ~ N(5.005, 1.5)" in md and "## Capped episodes" in md


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
    assert claims.loc["VI-E-card-in-regret", "verdict"] == (
        C.REPRODUCED if in_regret.statistic > 0 and in_regret.pvalue < 0.05 else C.DIFFERS)


@pytest.mark.parametrize("truth_column", [True, False])
def test_fullset_report_from_contract_rows(tmp_path, truth_column):
    rows = fullset_rows(truth_column=truth_column)
    sweep = write_sweep(tmp_path / "full", "fullset", rows, {"source_scale": "paper"})
    build_report(sweep)
    out = sweep / "report"
    assert (out / "figures" / "fig_fullset.png").is_file()
    cost = pd.read_csv(out / "tables" / "fullset_cost.csv")
    people = rows.drop_duplicates(["source", "environment", "run", "k", "group", "instance",
                                   *(["truth"] if truth_column else [])])
    per_map = cost[cost["environment"] != "all"].set_index("environment")["people_served"]
    assert per_map.to_dict() == {str(e): n for e, n in people.groupby("environment").size().items()}
    md = (out / "report.md").read_text()
    means = pd.read_csv(out / "tables" / "fullset_means.csv")
    if truth_column:
        gap = pd.read_csv(out / "tables" / "fullset_gap.csv").set_index(["source", "metric"])
        row = gap.loc[("conditions", "policy_regret")]
        at = rows[(rows["source"] == "conditions") & (rows["episodes"] == 20)]
        out_k = at.loc[(at["truth"] == "out_of_set") & (at["set"] == "theta_k"), "policy_regret"].mean()
        out_f = at.loc[(at["truth"] == "out_of_set") & (at["set"] == "full"), "policy_regret"].mean()
        in_k = at.loc[(at["truth"] == "in_set") & (at["set"] == "theta_k"), "policy_regret"].mean()
        assert row["share_closed"] == pytest.approx(1 - (out_f - in_k) / (out_k - in_k))
        assert "For the conditions study's out-of-set people, own Ψ_k → full set: " in md
    else:
        assert set(means["truth"]) == {"out_of_set"}  # derived from truth_probability
        assert "No in-set people" in md
