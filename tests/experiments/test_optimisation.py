"""The ``optimisation`` study (Sec. VII): protocol, the paper's prior, and rows equal to direct calls."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from expertise_irl.errors import InputError
from expertise_irl.experiments import load
from expertise_irl.experiments.engine import run
from expertise_irl.experiments.studies import get_study
from expertise_irl.experiments.studies.fixed_vs_joint import FEATURES, environment
from expertise_irl.experiments.studies.optimisation import METHODS, SCALES, OptimisationConfig, instance

STUDY = get_study("optimisation")
SMOKE = SCALES["smoke"]


def test_paper_scale_follows_sec_vii_a():
    p = SCALES["paper"]
    assert (p.environments, p.instances, p.episode_counts, p.k) == (5, 20, (10, 20, 30, 40), 20)
    assert (p.beta_low, p.beta_high, p.birl_iterations, p.prior) == (0.01, 5.0, 1000, "paper")
    # NUTS on a stated subset: the first instance of each map (the docstring gives the whole's cost)
    assert p.methods == METHODS and p.nuts_instances == 1
    assert STUDY.counts(p)["rows"] == 100 * 4 * 4 + 5 * 4
    small = SCALES["small"]
    assert small.prior == "paper" and small.birl_iterations == 1000 and small.nuts_instances >= 1


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("opt") / "sweep"
    summary = run(STUDY, out, scale="smoke", seed=0, workers=1)
    assert summary.failed == 0 and summary.ran == len(STUDY.tasks(SMOKE))
    return out


@pytest.fixture(scope="module")
def smoke(sweep_dir) -> pd.DataFrame:
    return load(sweep_dir)


@pytest.mark.slow
def test_every_method_at_every_count_and_nuts_on_its_subset(smoke):
    assert len(smoke) == STUDY.counts(SMOKE)["rows"]
    for i in range(SMOKE.instances):
        got = smoke[smoke.instance == i].groupby("method")["episodes"].apply(sorted).to_dict()
        want = [m for m in METHODS if m != "nuts" or i < SMOKE.nuts_instances]
        assert sorted(got) == sorted(want)
        assert all(v == list(SMOKE.episode_counts) for v in got.values())
    cont = smoke[smoke.method != "discrete"]
    assert (cont["prior"] == "paper").all() and cont["prior_text"].str.contains("5.005").all()
    assert (smoke[smoke.method == "discrete"]["n_hypotheses"] == SMOKE.k * 6).all()
    assert (cont["n_hypotheses"] == 0).all()
    assert (smoke["wall_time_s"] > 0).all()
    assert smoke.loc[smoke.method.str.startswith("birl"), "acceptance_rate"].between(0, 1).all()
    assert smoke.loc[smoke.method == "nuts", "divergences"].notna().all()
    assert smoke.loc[~smoke.method.isin(["nuts"]), "divergences"].isna().all()


@pytest.mark.slow
def test_truths_are_out_of_the_set_and_beta_in_range(smoke):
    for i in range(SMOKE.instances):
        inst = instance(SMOKE, 0, 0, i)
        assert not np.isclose(inst.thetas, inst.theta, atol=1e-9).all(axis=1).any()
        assert SMOKE.beta_low <= inst.beta <= SMOKE.beta_high
        rows = smoke[smoke.instance == i]
        np.testing.assert_array_equal(rows[[f"theta_true_{f}" for f in FEATURES]].to_numpy()[0], inst.theta)
        assert (rows["beta_set_distance"] > 0).all()
        assert (rows["n_pairs"] == [len(inst.trajectories.first(n)) for n in rows["episodes"]]).all()


def _row(df, i, method, n):
    r = df[(df.instance == i) & (df.method == method) & (df.episodes == n)]
    assert len(r) == 1
    return r.iloc[0]


@pytest.mark.slow
def test_rows_equal_direct_calls_with_the_papers_prior(smoke):
    """Algorithm 1 (box, as printed), MAP and the set, called directly on the same episodes."""
    from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet
    from expertise_irl.inference.belief import DiscreteBelief
    from expertise_irl.inference.birl import extended_birl
    from expertise_irl.inference.gradient import map_estimate

    _, mdp = environment(SMOKE, 0, 0)
    inst = instance(SMOKE, 0, 0, 1)
    n = SMOKE.episode_counts[-1]
    tr = inst.trajectories.first(n)
    box = extended_birl(mdp, tr, n_iter=SMOKE.birl_iterations, variant="box", prior="paper",
                        rng=np.random.default_rng([inst.method_seeds["birl_box"], n]))
    row = _row(smoke, 1, "birl_box", n)
    assert row["beta_hat"] == box.mean_beta
    np.testing.assert_array_equal(row[[f"theta_hat_{f}" for f in FEATURES]].to_numpy(float), box.mean_theta)
    m = map_estimate(mdp, tr, n_starts=SMOKE.map_starts, prior="paper",
                     rng=np.random.default_rng([inst.method_seeds["map"], n]))
    assert _row(smoke, 1, "map", n)["beta_hat"] == pytest.approx(m.beta, rel=1e-9)
    # The prior is what the row says it is: under the default prior the mode moves.
    other = map_estimate(mdp, tr, n_starts=SMOKE.map_starts, prior="log-uniform",
                         rng=np.random.default_rng([inst.method_seeds["map"], n]))
    assert abs(other.beta - m.beta) > 0.1
    b = DiscreteBelief.from_mdp(mdp, HypothesisSet(inst.thetas, BETA_PRESETS["paper-sim"])).update(tr)
    assert _row(smoke, 1, "discrete", n)["beta_hat"] == pytest.approx(b.mean_beta, abs=1e-9)


def test_first_episodes_do_not_depend_on_the_maximum():
    longer = dataclasses.replace(SMOKE, episode_counts=(2, 6))
    a, b = instance(SMOKE, 0, 0, 0), instance(longer, 0, 0, 0)
    assert a.beta == b.beta and np.array_equal(a.thetas, b.thetas)
    t4 = b.trajectories.first(4)
    assert np.array_equal(a.trajectories.state, t4.state) and np.array_equal(a.trajectories.action, t4.action)


def test_bad_configs_are_refused():
    with pytest.raises(InputError, match="methods must be among"):
        OptimisationConfig(methods=("discrete", "gibbs"))
    with pytest.raises(InputError, match="beta_low < beta_high"):
        OptimisationConfig(beta_low=5.0, beta_high=1.0)
    with pytest.raises(InputError, match="prior must be one of"):
        OptimisationConfig(prior="flat")


@pytest.mark.slow
def test_report_builds_from_the_smoke_sweep(sweep_dir, smoke):
    """Figs. 8-9, Table IV, the wall times and the Sec. VII claims come from these rows alone."""
    from expertise_irl.experiments.report import build_report

    md = build_report(sweep_dir).read_text()
    out = sweep_dir / "report"
    for fig in ("fig8", "fig9"):
        assert (out / "figures" / f"{fig}.png").stat().st_size > 1000 and f"](figures/{fig}.png)" in md
    claims = pd.read_csv(out / "claims.csv").set_index("id")
    assert {"VII-B-beta-birl_box", "VII-B-regret-birl_box", "VII-D"} <= set(claims.index)
    # VII-D's number is the ratio of the mean wall times in the rows.
    p = smoke.groupby("method")["wall_time_s"].mean()
    assert claims.loc["VII-D", "value"] == pytest.approx(p["birl_box"] / p["discrete"], rel=1e-9)
    wall = pd.read_csv(out / "tables" / "walltime.csv")
    assert set(wall.iloc[:, 0]) >= {"discrete", "birl_box"}
    assert "5.005" in md  # the prior is stated


@pytest.mark.slow
def test_the_budget_ablation_adds_a_method_per_budget_and_a_verdict_column_each(tmp_path):
    """``birl_budgets``: `birl_box@40` (2 chains × 40 iterations) and `birl_box@rhat` (2 chains in
    blocks of 1,000 until R-hat < 1.01, at most 1,000 here); their rows carry the budget and chains,
    and the report judges Algorithm 1's claims once per budget."""
    from expertise_irl.experiments.report import build_report

    cfg = dataclasses.replace(SMOKE, methods=("discrete",), birl_budgets=("40", "rhat", "40:log"),
                              birl_chains=2, birl_max_iterations=1000)
    out = tmp_path / "ablation"
    summary = run(STUDY, out, scale="smoke", seed=0, workers=1, config=cfg)
    assert summary.failed == 0
    rows = load(out)
    assert len(rows) == STUDY.counts(cfg)["rows"]
    fixed, rhat = rows[rows.method == "birl_box@40"], rows[rows.method == "birl_box@rhat"]
    assert (fixed.birl_iterations == 40).all() and (fixed.birl_chains == 2).all()
    assert (rhat.birl_iterations == 1000).all() or (rhat.max_rhat < 1.01).all()
    assert not rows.loc[rows.method != "discrete", "max_rhat"].isna().any()
    assert (rows.loc[rows.method == "discrete", ["birl_iterations", "birl_chains"]] == 0).all().all()
    md = build_report(out).read_text()
    table = pd.read_csv(out / "report" / "tables" / "budget_ablation.csv").set_index("claim")
    assert {"birl_box@40", "birl_box@rhat", "birl_box@40:log"} <= set(table.columns)
    assert "VII-D" in table.index
    assert (rows[rows.method == "birl_box@40:log"].birl_iterations == 40).all()
    assert "## Algorithm 1's budget" in md


def test_bad_budgets_are_refused():
    with pytest.raises(InputError, match="birl_budgets entries"):
        OptimisationConfig(birl_budgets=("many",))
    with pytest.raises(InputError, match="birl_budgets entries"):
        OptimisationConfig(birl_budgets=("5000:lin",))
    with pytest.raises(InputError, match="birl_beta_ratio must be > 1"):
        OptimisationConfig(birl_budgets=("5000:log",), birl_beta_ratio=1.0)


def test_a_log_budget_runs_the_same_chains_on_the_log_spaced_beta_lattice():
    from expertise_irl.experiments.studies.optimisation import budget_options

    cfg = OptimisationConfig(birl_budgets=("5000", "rhat", "5000:log", "rhat:log"), birl_beta_ratio=1.1)
    assert cfg.budget_methods == ("birl_box@5000", "birl_box@rhat", "birl_box@5000:log", "birl_box@rhat:log")
    assert budget_options(cfg, "5000") == {"n_iter": 5000}
    assert budget_options(cfg, "5000:log") == {"n_iter": 5000, "beta_ratio": 1.1}
    assert budget_options(cfg, "rhat:log") == {**budget_options(cfg, "rhat"), "beta_ratio": 1.1}
    assert "beta_ratio" not in budget_options(cfg, "rhat")
    with pytest.raises(InputError, match=r"birl_chains must be at least 1 \(2 with"):
        OptimisationConfig(birl_budgets=("rhat",), birl_chains=1)


@pytest.mark.slow
def test_the_finishing_protocol_makes_sec_vii_people_finish():
    """docs/reproduction/finishing.toml: with R_goal = 175 outside θ·φ, people across the study's β*
    range reach the goal within max_steps: none capped at β ≤ 2, at most 10% of episodes at β = 5
    (a person at β = 5 wandering forever collects at most 138.6 of entropy, so the margin is thin
    there; measured over 5 maps × 6 people: 1.3%), where with the default R_goal = 10 a person at
    β = 5 never finishes. The episodes still lengthen with β, so Table IV's episode-length rows
    have something to judge."""
    import tomllib
    from pathlib import Path

    from expertise_irl.demos.simulation import capped_episodes, simulate

    path = Path(__file__).resolve().parents[2] / "docs" / "reproduction" / "finishing.toml"
    finishing = dataclasses.replace(SCALES["paper"], **tomllib.loads(path.read_text()))
    default = dataclasses.replace(finishing, goal_bonus=10.0)
    assert finishing.goal_bonus > finishing.beta_high * math.log(4) / 0.05
    rng = np.random.default_rng(3)
    capped, lengths = {}, {}
    for e in range(2):
        theta = rng.dirichlet(np.ones(5))
        for beta in (0.5, 2.0, finishing.beta_high):
            for name, cfg in (("finishing", finishing), ("default", default)):
                _, mdp = environment(cfg, 0, e)
                tr = simulate(mdp, theta, beta, 10, np.random.default_rng([e, int(10 * beta)]),
                              max_steps=cfg.max_steps)
                capped.setdefault((name, beta), []).append(capped_episodes(tr, mdp, cfg.max_steps))
                lengths.setdefault((name, beta), []).append(len(tr) / 10)
    assert sum(capped[("finishing", 0.5)]) == sum(capped[("finishing", 2.0)]) == 0
    assert sum(capped[("finishing", 5.0)]) <= 2  # of 20 episodes
    assert sum(capped[("default", 5.0)]) == 20
    assert np.mean(lengths[("finishing", 5.0)]) > 1.5 * np.mean(lengths[("finishing", 0.5)])
