"""The ``fullset`` study: the source studies' people, scored with their Ψ_k and with all of Θ × B."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from expertise_irl.experiments import load
from expertise_irl.experiments.engine import run
from expertise_irl.experiments.studies import fixed_vs_joint as cond
from expertise_irl.experiments.studies import get_study
from expertise_irl.experiments.studies import optimisation as opt
from expertise_irl.experiments.studies.fullset import SCALES

STUDY = get_study("fullset")
SMOKE = SCALES["smoke"]
KEY = ["environment", "run", "k", "group", "truth", "episodes"]


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("full") / "sweep"
    summary = run(STUDY, out, scale="smoke", seed=0, workers=1)
    assert summary.failed == 0
    return out


@pytest.fixture(scope="module")
def smoke(sweep_dir) -> pd.DataFrame:
    return load(sweep_dir)


@pytest.mark.slow
def test_counts_and_sets(smoke):
    assert len(smoke) == STUDY.counts(SMOKE)["rows"]
    full = smoke[smoke.set == "full"]
    assert (full["n_hypotheses"] == 3031 * 6).all()
    own = smoke[smoke.set == "theta_k"]
    assert (own["n_hypotheses"] == own["k"] * 6).all()
    # One solve per map: the same time on every row of an environment.
    assert (smoke.groupby("environment")["set_solve_time_s"].nunique() == 1).all()
    # In-set truths are in both sets; out-of-set β* is never one of B's six values.
    ins = smoke[smoke.truth == "in_set"]
    assert ins["truth_probability"].notna().all()
    assert smoke[smoke.truth == "out_of_set"]["truth_probability"].isna().all()


@pytest.mark.slow
def test_own_set_rows_equal_the_source_studies(smoke):
    c = cond.SCALES["smoke"]
    theirs = pd.concat([pd.DataFrame(cond.run_task(c, 0, t.params)[0]) for t in cond.tasks(c)])
    theirs = theirs[theirs.condition == "full"].sort_values(KEY).reset_index(drop=True)
    ours = smoke[(smoke.source == "conditions") & (smoke.set == "theta_k")].sort_values(KEY)
    ours = ours.reset_index(drop=True)
    assert len(ours) == len(theirs)
    np.testing.assert_array_equal(ours["n_pairs"], theirs["n_pairs"])
    for col in ("beta_hat", "cosine_similarity", "policy_regret"):
        np.testing.assert_allclose(ours[col], theirs[col], atol=1e-9, err_msg=col)
    o = opt.SCALES["smoke"]
    cols, _ = opt.run_task(o, 0, {"environment": 0, "instance": 1})
    d = pd.DataFrame(cols)
    d = d[d.method == "discrete"].set_index("episodes")
    mine = smoke[(smoke.source == "optimisation") & (smoke.instance == 1) & (smoke.set == "theta_k")]
    mine = mine.set_index("episodes").loc[d.index]
    np.testing.assert_allclose(mine["beta_hat"], d["beta_hat"], atol=1e-9)
    np.testing.assert_allclose(mine["policy_regret"], d["policy_regret"], atol=1e-9)


@pytest.mark.slow
def test_full_set_posterior_differs_and_contains_the_own_set(smoke):
    """The full set is another posterior (more hypotheses), on exactly the same episodes."""
    a = smoke[smoke.set == "theta_k"].sort_values(["source", *KEY, "instance"]).reset_index(drop=True)
    b = smoke[smoke.set == "full"].sort_values(["source", *KEY, "instance"]).reset_index(drop=True)
    np.testing.assert_array_equal(a["n_pairs"], b["n_pairs"])
    assert not np.allclose(a["beta_hat"], b["beta_hat"])


@pytest.mark.slow
def test_report_builds_from_the_smoke_sweep(sweep_dir):
    from expertise_irl.experiments.report import build_report

    md = build_report(sweep_dir).read_text()
    out = sweep_dir / "report"
    assert (out / "figures" / "fig_fullset.png").stat().st_size > 1000
    gap = pd.read_csv(out / "tables" / "fullset_gap.csv")
    assert set(gap["source"]) == {"conditions", "optimisation"}
    assert "](figures/fig_fullset.png)" in md and "18,186" in md
