"""``expertise-irl study --population``: what it writes, and that it fits the study's own data."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok

from expertise_irl.demos.csv_io import read_demos_csv, write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.worlds.maps import load_bundled_world

M = np.array([0.4, 0.3, 0.2, 0.05, 0.05])
FEATURES = ("length", "road", "avoid", "slow", "traffic")


@pytest.fixture(scope="module")
def manifest(tmp_path_factory):
    """Ten people on crossroads, two episodes each, in two groups whose β differ fourfold
    (log β ~ N(log 0.15, 0.4²) and N(log 0.6, 0.4²)), θ ~ Dirichlet(20·m)."""
    d = tmp_path_factory.mktemp("population")
    mdp = load_bundled_world("crossroads").to_mdp()
    rng = np.random.default_rng(1)
    lines = ["participant,map,demos,group"]
    for i in range(10):
        g = "A" if i % 2 == 0 else "B"
        beta = float(np.exp(rng.normal(np.log(0.15 if g == "A" else 0.6), 0.4)))
        tr = simulate(mdp, rng.dirichlet(20 * M), beta, 2, rng)
        write_demos_csv(d / f"p{i}.csv", tr, mdp)
        lines.append(f"p{i},crossroads,p{i}.csv,{g}")
    (d / "m.csv").write_text("\n".join(lines) + "\n")
    return d, mdp


@pytest.fixture(scope="module")
def study(manifest):
    """The study of :func:`manifest` with ``--population``."""
    d, mdp = manifest
    res = invoke("study", d / "m.csv", "--out", d / "out", "--workers", "1", "--population", "--group-by",
                 "group", "--figures", "none")
    ok(res)
    return d, mdp, res


@pytest.mark.slow
def test_population_outputs(study):
    d, _, res = study
    out = d / "out"
    doc = json.loads((out / "population.json").read_text())
    assert doc["participants"] == 10 and doc["groups"] == ["A", "B"] and doc["group_by"] == "group"
    names = {"mu[A]", "mu[B]", "sigma[A]", "sigma[B]", "alpha"} | {f"m[{c}]" for c in range(5)}
    assert set(doc["hyperparameters"]) == names
    for h in doc["hyperparameters"].values():
        assert h["q05"] <= h["median"] <= h["q95"] and h["r_hat"] is not None and h["ess_bulk"] > 0
    held = doc["heldout_nats_per_action"]
    assert {"population", "independent", "pooled", "split"} <= set(held) and held["split"] == "episode"
    assert all(v < 0 for k, v in held.items() if k in ("population", "independent", "pooled"))
    (cmp,) = doc["comparisons"]
    assert cmp["a"] == "A" and cmp["b"] == "B" and 0 <= cmp["p_mu_a_lt_mu_b"] <= 1
    assert cmp["mu_diff"]["q05"] <= cmp["mu_diff"]["mean"] <= cmp["mu_diff"]["q95"]
    rows = list(csv.DictReader(open(out / "study.csv", encoding="utf-8")))
    for r in rows:
        for c in ("beta_hat_pooled", "heldout_population", "heldout_pooled", *(f"theta_{f}_pooled" for f in
                                                                                 FEATURES)):
            assert r[c] != ""
        assert sum(float(r[f"theta_{f}_pooled"]) for f in FEATURES) == pytest.approx(1.0, abs=1e-9)
        assert float(r["beta_q05_pooled"]) <= float(r["beta_q95_pooled"])
        # The independent held-out value is the study's own held-out check, computed apart.
        assert float(r["heldout_independent"]) == pytest.approx(float(r["heldout_log_likelihood_per_action"]),
                                                                abs=1e-9)
        one = json.loads((out / "participants" / r["participant"] / "result.json").read_text())
        assert one["population"]["beta_hat_pooled"] == pytest.approx(float(r["beta_hat_pooled"]), rel=1e-12)
    # The totals are the per-participant values weighted by their held-out actions.
    per = doc["heldout_per_participant"]
    for k in ("population", "independent", "pooled"):
        tot = sum(p[k] * p["actions"] for p in per) / sum(p["actions"] for p in per)
        assert held[k] == pytest.approx(tot, rel=1e-12)
    md = (out / "study.md").read_text()
    assert "## Population (--population)" in md and "P(μ_A < μ_B)" in md
    assert (out / "population.png").read_bytes()[:4] == b"\x89PNG"
    assert "population: A: median β" in res.stdout and "population.json, population.png" in res.stdout


@pytest.mark.slow
def test_population_is_fitted_to_the_participants_own_likelihoods(study):
    """type-II ML in population.json equals the library's on the participants' grid likelihoods,
    computed here from their files with a solve of our own."""
    from expertise_irl.inference.methods import DiscreteOptions
    from expertise_irl.inference.population import population_data, type2_ml
    from expertise_irl.planning.soft_vi import solve
    from expertise_irl.planning.table_likelihood import log_likelihood

    d, mdp, _ = study
    out = d / "out"
    doc = json.loads((out / "population.json").read_text())
    grid = doc["model"]["beta_grid"]
    hyp = DiscreteOptions(thetas="paper-real", betas=",".join(repr(b) for b in grid)).hypotheses(5)
    assert hyp.betas.tolist() == pytest.approx(grid, rel=1e-12)
    lp = solve(mdp, hyp.theta, hyp.beta).log_policy
    lls = [sum(log_likelihood(lp, s, a) for s, a in read_demos_csv(d / f"p{i}.csv", mdp).episodes())
           for i in range(10)]
    data = population_data(lls, hyp, groups=["A" if i % 2 == 0 else "B" for i in range(10)])
    fit = type2_ml(data, n_starts=4, rng=0)
    assert doc["type2_ml"]["log_marginal"] == pytest.approx(fit.log_marginal, abs=1e-6)


def test_population_is_refused_where_it_does_not_apply(manifest):
    d, _ = manifest
    base = ("study", d / "m.csv", "--out", d / "x", "--population")
    assert_input_error(invoke(*base, "--method", "map"), "--population needs --method discrete")
    assert_input_error(invoke(*base, "--share", "beta"), "--population needs --share both")
    assert not (d / "x").exists()
