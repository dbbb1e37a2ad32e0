"""compare-models with the teaching model (``pedagogical``): its evidence is a teacher's, so that its
difference to maxent's is the Bayes factor of teaching; its held-out check and its ``teaching`` entry."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from scipy.special import logsumexp
from teaching_task import BETAS, THETAS, crossroads_task

from expertise_irl.demos.csv_io import write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.inference import pedagogical as P
from expertise_irl.inference.evidence import compare_models, split_episodes, teaching_pair_log_likelihoods


@pytest.fixture(scope="module")
def task():
    return crossroads_task()


def episodes(task, lam: float, seed: int = 1, n: int = 10):
    """``n`` episodes of the set's θ = (1, 0, 0, 0, 0) (path length only) at β = 0.1, teaching at ``lam``.

    Measured at seeds 0-11 (10 episodes, ≈ 100 pairs): the teacher at λ = 1 scored 2 log BF 22 to 81
    (always past the verdict's 6), the doer (λ = 0) −2.2 to 5.4 (never 6); seed 1 gives 44.3 and −2.2.
    """
    mdp, hyp, lp = task
    pol = P.teacher_log_policy(mdp, hyp.thetas[15], 0.1, lam, P.observer(hyp, lp))
    return simulate(mdp, None, None, n, np.random.default_rng(seed), log_policy=pol, max_steps=100)


def test_the_teachers_evidence_against_maxent_is_the_bayes_factor(task):
    mdp, hyp, lp = task
    trajs = episodes(task, 1.0)
    cmp = compare_models(mdp, trajs, hyp, ["maxent", "pedagogical"])
    maxent, taught = cmp.fits
    tp = P.teaching_posterior(lp, hyp, trajs)
    z = tp.log_evidence_by_lambda
    # maxent's row is the λ = 0 evidence of the same set and prior (one solve, to the same 1e-8)
    assert maxent.log_evidence == pytest.approx(z[0], abs=1e-9)
    assert taught.log_evidence == pytest.approx(float(logsumexp(z[1:]) - math.log(len(z) - 1)), abs=1e-9)
    assert taught.log_evidence - maxent.log_evidence == pytest.approx(tp.log_bayes_factor, abs=1e-9)
    assert cmp.best.model == "pedagogical" and maxent.log_bayes_factor < -10
    t = taught.teaching
    assert t["verdict"] == "teaching" and t["two_log_bayes_factor"] == pytest.approx(2 * tp.log_bayes_factor)
    assert t["log_evidence_by_lambda"] == pytest.approx(z.tolist(), abs=1e-12)
    lo, hi = t["lambda_interval"]
    assert 0 < lo <= hi <= 1.0 and t["lambda_hat"] > 0.3  # the truth, 1.0, is the top of the grid
    # β̂ is the posterior's over Ψ × Λ; under maxent the teacher's detours read as noise
    assert taught.beta_hat == pytest.approx(tp.belief(lp).mean_beta, abs=1e-12)
    assert t["beta_hat_maxent"] == pytest.approx(maxent.beta_hat, abs=1e-9)


def test_a_doer_does_not_read_as_teaching(task):
    mdp, hyp, _ = task
    cmp = compare_models(mdp, episodes(task, 0.0), hyp, ["pedagogical", "maxent"])
    taught, maxent = cmp.fits
    assert cmp.best.model == "maxent" and taught.log_evidence < maxent.log_evidence
    assert taught.teaching["verdict"] != "teaching"
    assert taught.beta_hat == pytest.approx(maxent.beta_hat, rel=0.1)


def test_the_heldout_check_is_the_fit_posterior_over_psi_and_lambda_predicting_the_test(task):
    """The test pairs' teaching likelihoods need no other solve: the observer is per state, so they are
    the whole data's minus the fitted part's, which is how this check computes them."""
    mdp, hyp, lp = task
    trajs = episodes(task, 1.0)
    (taught,) = compare_models(mdp, trajs, hyp, ["pedagogical"], holdout=0.4).fits
    fit, test = split_episodes(trajs, 0.4)
    whole, part = P.teaching_posterior(lp, hyp, trajs), P.teaching_posterior(lp, hyp, fit)
    joint = part.log_likelihood + part.log_prior[None, :] + part.log_prior_lambda[:, None]
    ll_test = whole.log_likelihood - part.log_likelihood
    np.testing.assert_allclose(teaching_pair_log_likelihoods(lp, hyp, test, P.LAMBDAS), ll_test, atol=1e-9)
    want = float(logsumexp(joint - logsumexp(joint) + ll_test)) / len(test)
    assert taught.heldout_per_action == pytest.approx(want, abs=1e-10)


def test_pedagogical_alone_solves_the_set_once_under_maxent(task, monkeypatch):
    from expertise_irl.inference import belief

    mdp, hyp, _ = task
    models = []
    real = belief.solve

    def counted(*args, **kwargs):
        models.append(kwargs.get("model", "maxent"))
        return real(*args, **kwargs)

    monkeypatch.setattr(belief, "solve", counted)
    compare_models(mdp, episodes(task, 1.0), hyp, ["maxent", "pedagogical"])
    compare_models(mdp, episodes(task, 1.0), hyp, ["pedagogical"])
    assert models == ["maxent", "maxent"]


def write_episodes(task, path, lam: float):
    mdp = task[0]
    write_demos_csv(path, episodes(task, lam), mdp)
    return path


@pytest.mark.parametrize("lam, best", [(1.0, "pedagogical"), (0.0, "maxent")])
def test_compare_models_command_with_pedagogical(task, tmp_path, lam, best):
    demos, out = write_episodes(task, tmp_path / "d.csv", lam), tmp_path / "cmp.json"
    res = invoke("compare-models", "crossroads", "--demos", demos, "--models", "maxent,pedagogical",
                 "--thetas", THETAS, "--betas", BETAS, "--out", out)
    ok(res)
    doc = json.loads(out.read_text(encoding="utf-8"))
    maxent, taught = doc["models"]
    assert doc["best"] == best and doc["settings"]["lambdas"] == list(P.LAMBDAS)
    assert "teaching" not in maxent and set(maxent) <= set(taught)  # the old keys, and teaching added
    t = taught["teaching"]
    assert maxent["log_evidence"] == pytest.approx(t["log_evidence_by_lambda"][0], abs=1e-9)
    assert taught["log_evidence"] - maxent["log_evidence"] == pytest.approx(t["log_bayes_factor"], abs=1e-9)
    assert (t["verdict"] == "teaching") == (lam > 0)
    lo, hi = t["lambda_interval"]
    line = (f"pedagogical: {t['reading']}; λ̂ = {t['lambda_hat']:.3g}, "
            f"90% credible interval [{lo:.3g}, {hi:.3g}]")
    assert line in " ".join(res.stdout.split())
    assert f"2 log BF = {round(t['two_log_bayes_factor'], 1) + 0.0:.1f}" in t["reading"]


def test_compare_models_takes_a_lambda_grid(task, tmp_path):
    demos, out = write_episodes(task, tmp_path / "d.csv", 1.0), tmp_path / "cmp.json"
    ok(invoke("compare-models", "crossroads", "--demos", demos, "--models", "pedagogical", "--thetas", THETAS,
              "--betas", BETAS, "--lambdas", "0,0.5,1", "--holdout", "0.3", "--out", out))
    doc = json.loads(out.read_text(encoding="utf-8"))
    t = doc["models"][0]["teaching"]
    assert t["lambdas"] == [0.0, 0.5, 1.0] and len(t["log_evidence_by_lambda"]) == 3
    assert doc["models"][0]["log_evidence"] == pytest.approx(
        float(logsumexp(t["log_evidence_by_lambda"][1:]) - math.log(2)), abs=1e-9)


@pytest.mark.parametrize("options, fragment", [
    (["--models", "pedagogical", "--lambdas", "0.1,0.3"], "--lambdas must hold 0"),
    (["--models", "maxent", "--lambdas", "0,0.1"], "--lambdas is the pedagogical model's"),
    (["--models", "pedagogical,pedagogical"], "names a model twice"),
])
def test_compare_models_refuses_bad_teaching_options(task, tmp_path, options, fragment):
    demos = write_episodes(task, tmp_path / "d.csv", 0.0)
    assert_input_error(invoke("compare-models", "crossroads", "--demos", demos, *options), fragment)
