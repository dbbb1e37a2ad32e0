"""The ``cardinality`` study: conditions' machinery with k = 20..100, the Full set only."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from expertise_irl.errors import InputError
from expertise_irl.experiments import load
from expertise_irl.experiments.engine import run
from expertise_irl.experiments.studies import get_study
from expertise_irl.experiments.studies.cardinality import SCALES
from expertise_irl.experiments.studies.fixed_vs_joint import ConditionsConfig, run_task

STUDY = get_study("cardinality")


def test_scales_follow_the_paper():
    paper = SCALES["paper"]
    assert paper.ks == (20, 40, 60, 80, 100) and paper.environments == 1
    assert paper.conditions == ("full",) and paper.episodes == paper.low_episodes == 20


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("card") / "sweep"
    summary = run(STUDY, out, scale="smoke", seed=0, workers=1)
    assert summary.failed == 0 and summary.ran == len(STUDY.tasks(SCALES["smoke"]))
    return out


@pytest.fixture(scope="module")
def smoke(sweep_dir) -> pd.DataFrame:
    return load(sweep_dir)


@pytest.mark.slow
def test_rows_hold_the_full_set_only_for_every_k_and_truth(smoke):
    cfg = SCALES["smoke"]
    assert set(smoke["condition"]) == {"full"}
    assert sorted(smoke["k"].unique()) == list(cfg.ks)
    assert (smoke["n_hypotheses"] == 6 * smoke["k"]).all()
    assert set(smoke["truth"]) == {"in_set", "out_of_set"}
    assert len(smoke) == STUDY.counts(cfg)["rows"] == len(cfg.ks) * 3 * 2 * cfg.episodes


def test_a_person_has_the_same_rows_as_in_conditions(smoke):
    """Same identity, same person: the cardinality rows are conditions' Full-set rows."""
    cfg = SCALES["smoke"]
    full_conditions = dataclasses.replace(cfg, conditions=("full", "fixed_theta", "fixed_beta"))
    cols, _ = run_task(full_conditions, 0, {"environment": 0, "run": 0, "k": 8})
    theirs = pd.DataFrame(cols)
    theirs = theirs[theirs.condition == "full"].reset_index(drop=True)
    ours = smoke[smoke.k == 8].sort_values(["group", "truth", "episodes"]).reset_index(drop=True)
    theirs = theirs.sort_values(["group", "truth", "episodes"]).reset_index(drop=True)
    for c in ("beta_hat", "policy_regret", "cosine_similarity", "beta_true", "n_pairs"):
        np.testing.assert_array_equal(ours[c].to_numpy(), theirs[c].to_numpy(), err_msg=c)


def test_conditions_must_include_the_full_set():
    with pytest.raises(InputError, match="must include 'full'"):
        ConditionsConfig(conditions=("fixed_beta",))
    with pytest.raises(InputError, match="among"):
        ConditionsConfig(conditions=("full", "fixed_gamma"))


def test_report_builds_from_the_smoke_sweep(sweep_dir, smoke):
    """Table III and the cardinality figure come from these rows alone."""
    from expertise_irl.experiments.report import build_report

    md = build_report(sweep_dir).read_text()
    out = sweep_dir / "report"
    table3 = pd.read_csv(out / "tables" / "table3.csv")
    assert len(table3) == 2 * 3  # (in-set, out-of-set) × three metrics
    assert (out / "figures" / "fig_cardinality.png").stat().st_size > 1000
    assert "Table III" in md and "](figures/fig_cardinality.png)" in md
    claims = pd.read_csv(out / "claims.csv")
    assert {"VI-E-card-in-regret", "VI-E-card-out-cosine", "VI-E-card-out-regret"} <= set(claims["id"])
    # Table III's cells are Pearson's ρ over these rows (in-set, the largest episode count).
    from scipy.stats import pearsonr

    at = smoke[(smoke.truth == "in_set") & (smoke.episodes == smoke.episodes.max())]
    rho = pearsonr(at["n_hypotheses"], at["policy_regret"]).statistic
    cell = table3[table3.row.str.startswith("In set") & (table3.metric == "policy_regret")]
    # the table's CSV holds 10 significant digits (report.output.FLOAT_FORMAT)
    assert cell["rho"].item() == pytest.approx(rho, rel=1e-9) and cell["n"].item() == len(at)
