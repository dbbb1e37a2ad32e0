"""``infer(model="pedagogical")``: the discrete method's teaching model end to end (inference.methods,
the pipeline and the typed result) on the bundled crossroads map."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl import HypothesisSet, infer, simulate, simulate_teacher
from expertise_irl.hypotheses import resolve_betas, resolve_thetas
from expertise_irl.inference import pedagogical as P
from expertise_irl.inference.methods import (
    BIRLOptions,
    DiscreteOptions,
    MAPOptions,
    NUTSOptions,
    get_method,
    teaching_draws,
)
from expertise_irl.numerics import enable_float64
from expertise_irl.options import OptionError
from expertise_irl.pipeline import prepare
from expertise_irl.planning.soft_vi import solve
from expertise_irl.result import Result, Teaching
from expertise_irl.results import read_result, write_result
from expertise_irl.worlds.maps import resolve_world

#: A small named set: 15 θ (the unit-l1 grid of 0, 0.5, 1 over 5 features) × 3 β.
THETAS, BETAS = "0,0.5,1", "0.1,0.5,2"


@pytest.fixture(scope="module")
def mdp():
    enable_float64()
    return resolve_world("crossroads").to_mdp()


@pytest.fixture(scope="module")
def demos(mdp):
    """A doer (maxent) off the set: θ from a Dirichlet, β = 0.3."""
    theta = np.random.default_rng(1).dirichlet(np.ones(mdp.n_features))
    return simulate(mdp, theta, 0.3, 8, np.random.default_rng(2), max_steps=100)


@pytest.fixture(scope="module")
def result(mdp, demos):
    return infer(mdp, demos, model="pedagogical", thetas=THETAS, betas=BETAS, seed=3)


def test_the_posterior_is_the_teaching_posterior_of_one_maxent_solve(mdp, demos, result):
    """β̂, θ̂, every hypothesis' probability and the teaching record are those of
    :func:`teaching_posterior` on the set solved once under maxent to 1e-8 (the same solve: equal to
    rounding, 1e-12)."""
    hyp = HypothesisSet(resolve_thetas(THETAS, mdp.n_features), resolve_betas(BETAS))
    lp = np.asarray(solve(mdp, hyp.theta, hyp.beta, tol=1e-8).log_policy)
    tp = P.teaching_posterior(lp, hyp, demos)
    belief = tp.belief(lp)
    assert result.beta_hat == pytest.approx(belief.mean_beta, abs=1e-12)
    np.testing.assert_allclose(result.theta_hat, belief.mean_theta, atol=1e-12)
    np.testing.assert_allclose(result.posterior.hypotheses.probability, belief.probabilities, atol=1e-12)
    assert result.posterior.log_evidence == pytest.approx(belief.log_evidence, abs=1e-9)
    want = tp.record(lp)
    got = result.teaching.to_json()
    assert got.keys() == want.keys() and got["verdict"] == want["verdict"]
    np.testing.assert_allclose(got["lambda_probabilities"], want["lambda_probabilities"], atol=1e-12)
    s = result.settings
    assert s.model == "pedagogical" and tuple(s["lambdas"]) == P.LAMBDAS and s["tol"] == 1e-8
    assert s["hypotheses"] == "fixed" and s.n_hypotheses == len(hyp)


def test_the_lambda_zero_reading_is_the_maxent_fit_on_the_same_set(mdp, demos, result):
    """``beta_hat_maxent`` and ``theta_hat_maxent`` are ``infer(model="maxent")``'s on the same named set
    and tolerance. Both solve to 1e-8 nats; the maxent run's certified path leaves only hypotheses whose
    mass is below 1e-12 in all at its screening tolerance, so the estimates (β ≤ 2) agree to far below
    1e-9."""
    maxent = infer(mdp, demos, model="maxent", thetas=THETAS, betas=BETAS, tol=1e-8, check="off")
    assert result.teaching.beta_hat_maxent == pytest.approx(maxent.beta_hat, abs=1e-9)
    np.testing.assert_allclose(result.teaching.theta_hat_maxent, maxent.theta_hat, atol=1e-9)


def test_the_teaching_record_round_trips_through_the_result(result, tmp_path):
    assert isinstance(result.teaching, Teaching)
    doc = result.to_json()
    assert doc["teaching"]["verdict"] in ("teaching", "doing", "undecided")
    assert "teaching" not in result.extra
    assert Result.from_json(doc) == result and Result.from_json(doc).to_json() == doc
    write_result(tmp_path / "r.json", result)
    again = read_result(tmp_path / "r.json")
    assert again.teaching == result.teaching and again.to_json() == doc
    # an entry the package does not interpret is kept, in place
    doc["teaching"]["note"] = "kept"
    assert Result.from_json(doc).to_json()["teaching"] == doc["teaching"]


def test_the_default_set_is_fixed_and_never_refined(mdp):
    opts = DiscreteOptions(model="pedagogical")
    assert not opts.refines
    hyp = get_method("discrete").setup(mdp, opts, 0)
    assert hyp.n_theta == len(resolve_thetas("paper-real", mdp.n_features))
    np.testing.assert_array_equal(hyp.betas, resolve_betas("paper-sim"))


def test_the_predictive_checks_judge_the_teaching_model(mdp, demos, result):
    """The checks' draws are (θ, β, λ) of the joint posterior with the teacher's policy: every table
    is the teaching policy of its draw's hypothesis at one λ of the grid (to rounding, 1e-10), and the
    share of draws at λ > 0 is P(teaching) within 4 binomial standard deviations."""
    mis = result.misspecification
    assert mis is not None and "teacher policy" in mis.details["predictive"]["draws_note"]
    opts = DiscreteOptions(model="pedagogical", thetas=THETAS, betas=BETAS, lambdas="0,0.01,0.03")
    fit = get_method("discrete").run(mdp, demos, opts, 0).result
    hyp, lp = fit.teaching.hypotheses, np.asarray(fit.posterior.log_policy)
    draws = teaching_draws(fit, 40, np.random.default_rng(0))
    info = P.observer(hyp, lp).informativeness()
    taught = 0
    for theta, beta, table in zip(draws["theta"], draws["beta"], draws["tables"][0], strict=True):
        h = int(np.flatnonzero((hyp.theta == theta).all(axis=1) & (hyp.beta == beta))[0])
        close = [lam for lam in fit.teaching.lambdas
                 if np.allclose(table, P.teaching_log_policy(lp[h], info[h // hyp.n_beta], lam / beta),
                                atol=1e-10)]
        assert close, (h, beta)
        taught += 0.0 not in close
    p = float(fit.teaching.lambda_probabilities[1:].sum())
    assert 0.05 < p < 0.95  # both kinds of draw are expected
    assert abs(taught - 40 * p) <= 4 * np.sqrt(40 * p * (1 - p)) and draws["weights"] is None


@pytest.mark.parametrize(("opts", "fields"), [
    ({"per_action": True}, ("per_action", "model")),
    ({"expertise": "changing"}, ("expertise", "model")),
    ({"refine": True}, ("refine", "model")),
    ({"lambdas": "0.1,0.3"}, ("lambdas",)),
    ({"lambdas": "0,x"}, ("lambdas",)),
])
def test_what_the_teaching_model_refuses(opts, fields):
    with pytest.raises(OptionError) as e:
        DiscreteOptions(model="pedagogical", **opts)
    assert e.value.fields == fields
    assert str(e.value).startswith(fields[0])


def test_lambdas_belong_to_the_teaching_model_and_the_continuous_methods_refuse_it(mdp, demos):
    with pytest.raises(OptionError, match=r"^lambdas is the teaching weight's grid") as e:
        DiscreteOptions(lambdas="0,0.1")
    assert e.value.fields == ("lambdas", "model")
    for cls in (BIRLOptions, MAPOptions, NUTSOptions):
        with pytest.raises(OptionError, match=r"^model pedagogical needs a discrete observer set") as e:
            cls(model="pedagogical")
        assert e.value.fields == ("model", "method")
    with pytest.raises(OptionError, match=r"^check full") as e:
        prepare(mdp, demos, model="pedagogical", check="full")
    assert e.value.fields == ("check", "model")


def test_a_strong_teacher_reads_as_teaching_and_a_doer_does_not(mdp):
    """20 episodes of up to 200 steps at β = 0.1 before the default observer (paper-real Θ × paper-sim B),
    θ a Dirichlet draw off the set: a teacher at λ = 0.3 reads as teaching with 2 log BF far above 6 and
    λ's interval away from 0; the doer (λ = 0, the same θ, β and seed) does not. Off the set, the
    teaching weight can also take up the set's coarseness: across episode seeds a doer's 2 log BF stays
    mostly within ±3 but has crossed 6, so the seed is fixed."""
    hyp = HypothesisSet(resolve_thetas("paper-real", mdp.n_features), resolve_betas("paper-sim"))
    obs = P.solved_observer(mdp, hyp)
    theta = np.random.default_rng(2).dirichlet(np.ones(mdp.n_features))
    reads = {}
    for lam in (0.3, 0.0):
        trajs = simulate_teacher(mdp, theta, 0.1, lam, 20, np.random.default_rng([1, 7]), observer=obs,
                                 max_steps=200)
        reads[lam] = infer(mdp, trajs, model="pedagogical", check="off").teaching
    teacher, doer = reads[0.3], reads[0.0]
    assert teacher.verdict == "teaching" and 2 * teacher.log_bayes_factor > 30
    assert teacher.p_teaching > 0.999 and teacher.lambda_interval[0] > 0
    assert doer.verdict != "teaching" and 2 * doer.log_bayes_factor < 6
    assert teacher.reading.startswith("demonstrations read as teaching")
