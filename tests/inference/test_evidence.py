"""Model evidence, Bayes factors and the held-out check; the compare-models command."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from reference_solver import reference
from scipy.special import logsumexp

from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.evidence import compare_models, split_episodes
from expertise_irl.models import BACKUP_MODELS
from expertise_irl.worlds.zones import load_bundled, parse_map

SMALL = "S...\n.#..\n...G\n"


@pytest.fixture(scope="module")
def small():
    return parse_map(SMALL, name="small").to_mdp()


@pytest.fixture(scope="module")
def hyp(small):
    return HypothesisSet(theta_grid([0, 0.5, 1], small.n_features)[:6], [0.1, 1.0, 5.0])


@pytest.mark.parametrize("model", BACKUP_MODELS)
def test_log_evidence_equals_a_brute_force_sum(model, small, hyp):
    trajs = simulate(small, np.array([0.6, 0.1, 0.1, 0.1, 0.1]), 0.5, 6, np.random.default_rng(0),
                     model=model, max_steps=40)
    post = DiscreteBelief.from_mdp(small, hyp, model=model, tol=1e-11).update(trajs)
    terms = []
    for theta, beta in zip(hyp.theta, hyp.beta, strict=True):
        ref = reference(small, theta, float(beta), model)
        terms.append(ref.log_policy[trajs.state, trajs.action].sum() + np.log(1 / len(hyp)))
    assert post.log_evidence == pytest.approx(float(logsumexp(terms)), abs=1e-7)


def test_split_keeps_file_order(small):
    trajs = simulate(small, np.ones(5) / 5, 1.0, 5, np.random.default_rng(1), max_steps=30)
    fit, test = split_episodes(trajs, 0.4)
    assert fit.episode_ids.tolist() == [0, 1, 2] and test.episode_ids.tolist() == [3, 4]
    assert len(fit) + len(test) == len(trajs)
    assert split_episodes(trajs.first(1), 0.5) is None


def test_heldout_is_the_posterior_predictive_per_action(small, hyp):
    trajs = simulate(small, np.array([0.6, 0.1, 0.1, 0.1, 0.1]), 0.5, 6, np.random.default_rng(2),
                     max_steps=40)
    cmp = compare_models(small, trajs, hyp, ["maxent"], holdout=0.5)
    fit, test = split_episodes(trajs, 0.5)
    start = DiscreteBelief.from_mdp(small, hyp)
    lp_fit = start.update(fit).log_posterior
    ll_test = start.update(test).log_likelihood
    expected = float(logsumexp(lp_fit + ll_test)) / len(test)
    assert cmp.fits[0].heldout_per_action == pytest.approx(expected, rel=1e-12)
    assert cmp.n_test_actions == len(test) and cmp.fits[0].log_bayes_factor == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("truth_model", ["maxent", "maxent-relative"])
def test_the_generating_model_has_the_most_evidence(truth_model):
    """40 episodes on crossroads from a truth inside the set: the generating model wins by a wide
    margin. Measured over simulation seeds 0-4: the runner-up's log BF was -9.8 to -28
    (boltzmann) for maxent-relative data and below -114 for maxent data; -5 (2|log BF| = 10,
    'very strong') leaves room for the spread."""
    mdp = load_bundled("crossroads").to_mdp()
    thetas = theta_grid([0, 0.5, 1], mdp.n_features)
    hyp = HypothesisSet(thetas, BETA_PRESETS["paper-sim"])
    truth = thetas[7]
    trajs = simulate(mdp, truth, 1.0, 40, np.random.default_rng(3), model=truth_model, max_steps=150)
    cmp = compare_models(mdp, trajs, hyp, list(BACKUP_MODELS))
    assert cmp.best.model == truth_model
    others = [f for f in cmp.fits if f.model != truth_model]
    assert all(f.log_bayes_factor < -5 for f in others), [(f.model, f.log_bayes_factor) for f in others]


@pytest.mark.slow
def test_compare_models_command(tmp_path):
    demos, out = tmp_path / "d.csv", tmp_path / "cmp.json"
    ok(invoke("simulate", "corridor", "--theta", "0.5,0.5,0,0,0", "--beta", "0.5", "--episodes", 6,
              "--model", "maxent-relative", "--out", demos))
    result = invoke("compare-models", "corridor", "--demos", demos, "--thetas", "0,1", "--out", out)
    ok(result)
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert [m["model"] for m in doc["models"]] == list(BACKUP_MODELS)
    best = max(doc["models"], key=lambda m: m["log_evidence"])
    assert doc["best"] == best["model"] and best["log_bayes_factor"] == 0.0
    for m in doc["models"]:
        assert m["log_bayes_factor"] == pytest.approx(m["log_evidence"] - best["log_evidence"])
        assert m["model"] in result.stdout
        assert m["heldout_log_likelihood_per_action"] < 0
    assert doc["heldout"]["test_episodes"] == 3 and doc["heldout"]["fit_episodes"] == 3
    assert f"best: {doc['best']}" in result.stdout


def test_compare_models_with_one_episode_says_why_there_is_no_heldout(tmp_path):
    demos, out = tmp_path / "d.csv", tmp_path / "cmp.json"
    ok(invoke("simulate", "corridor", "--theta", "1,0,0,0,0", "--beta", "0.5", "--episodes", 1,
              "--out", demos))
    result = invoke("compare-models", "corridor", "--demos", demos, "--models", "maxent,boltzmann",
                    "--thetas", "0,1", "--out", out)
    ok(result)
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert all(m["heldout_log_likelihood_per_action"] is None for m in doc["models"])
    assert "at least 2 episodes" in doc["unavailable"]["heldout_per_action"]
    assert "at least 2 episodes" in result.stderr


@pytest.mark.parametrize("options,fragment", [
    (["--models", "maxent,softmax"], "--models must be one of"),
    (["--models", "maxent,maxent"], "names a model twice"),
    (["--holdout", "1.5"], "--holdout must be a fraction"),
])
def test_compare_models_bad_options(options, fragment, tmp_path):
    demos = tmp_path / "d.csv"
    ok(invoke("simulate", "corridor", "--theta", "1,0,0,0,0", "--beta", "0.5", "--episodes", 2,
              "--out", demos))
    assert_input_error(invoke("compare-models", "corridor", "--demos", demos, *options), fragment)
