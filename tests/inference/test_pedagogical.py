"""The teaching model's core (inference.pedagogical) against brute-force Bayes on the crossroads map."""

import math

import numpy as np
import pytest
from teaching_task import crossroads_task

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import HypothesisSet
from expertise_irl.inference import pedagogical as P
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.planning.soft_vi import solve


@pytest.fixture(scope="module")
def task():
    return crossroads_task(tol=1e-10)


def _brute_informativeness(hyp, lp, prior):
    """log P_lit(θ | s, a) − log P(θ) by Bayes' rule, one (s, a) at a time, in plain probabilities."""
    nt, nb = hyp.n_theta, hyp.n_beta
    S, A = lp.shape[1:]
    out = np.zeros((nt, S, A))
    p_theta = prior.reshape(nt, nb).sum(axis=1)
    for s in range(S):
        for a in range(A):
            like = np.exp(lp[:, s, a])
            if like.sum() == 0:
                continue
            post = (prior * like).reshape(nt, nb).sum(axis=1)
            post /= post.sum()
            with np.errstate(divide="ignore"):
                out[:, s, a] = np.log(post) - np.log(p_theta)
    return out


def test_informativeness_is_the_literal_observers_bayes_update(task):
    mdp, hyp, lp = task
    rng = np.random.default_rng(3)
    prior = rng.uniform(0.5, 2.0, len(hyp))
    prior /= prior.sum()
    obs = P.observer(hyp, lp, np.log(prior))
    got = obs.informativeness()
    want = _brute_informativeness(hyp, lp, prior)
    avail = np.broadcast_to(mdp.available, got.shape)
    np.testing.assert_allclose(got[avail], want[avail], atol=1e-10)
    assert np.all(got[~avail] == 0)


def test_teaching_policy_is_normalised_and_lambda_zero_is_maxent(task):
    mdp, hyp, lp = task
    info = P.observer(hyp, lp).informativeness()
    h = 7  # θ index 7 // 3 = 2, β = 0.5
    pol = P.teaching_log_policy(lp[h], info[h // hyp.n_beta], 0.3 / hyp.beta[h])
    live = mdp.available.any(axis=1)
    np.testing.assert_allclose(np.exp(pol[live]).sum(axis=1), 1.0, atol=1e-12)
    assert np.all(np.isneginf(pol[~mdp.available]))
    np.testing.assert_allclose(P.teaching_log_policy(lp[h], info[h // hyp.n_beta], 0.0), lp[h], atol=1e-12)
    # the bonus moves mass towards the actions that tell the observer most about this θ
    s = int(np.argmax(np.ptp(np.where(mdp.available, info[h // hyp.n_beta], 0), axis=1)))
    best = int(np.argmax(np.where(mdp.available[s], info[h // hyp.n_beta, s], -np.inf)))
    assert pol[s, best] > lp[h, s, best]


def test_teacher_in_the_set_matches_the_observers_informativeness(task):
    """θ of the set: the simulator's route (its own solves at the set's βs) gives the inference's policy."""
    mdp, hyp, lp = task
    obs = P.observer(hyp, lp)
    t, j = 5, 1
    got = P.teacher_log_policy(mdp, hyp.thetas[t], hyp.betas[j], 0.2, obs, tol=1e-10)
    want = P.teaching_log_policy(lp[t * hyp.n_beta + j], obs.informativeness()[t], 0.2 / hyp.betas[j])
    np.testing.assert_allclose(np.where(np.isfinite(want), got, 0), np.where(np.isfinite(want), want, 0),
                               atol=1e-7)


def _episodes(mdp, hyp, lp, lam, seed, n=20, beta=0.1):
    rng = np.random.default_rng(seed)
    theta = rng.dirichlet(np.ones(mdp.n_features))
    obs = P.observer(hyp, lp)
    pol = P.teacher_log_policy(mdp, theta, beta, lam, obs)
    return simulate(mdp, None, None, n, rng, log_policy=pol, max_steps=100)


def test_lambda_zero_row_is_the_maxent_likelihood_and_the_bayes_factor_is_its_definition(task):
    mdp, hyp, lp = task
    trajs = _episodes(mdp, hyp, lp, 0.1, seed=11, n=5)
    tp = P.teaching_posterior(lp, hyp, trajs)
    doer = DiscreteBelief.from_log_policy(hyp, lp).update(trajs)
    np.testing.assert_allclose(tp.log_likelihood[0], doer.log_likelihood, atol=1e-9)
    z = [math.log(np.mean(np.exp(row - row.max()))) + row.max() for row in tp.log_likelihood]
    want = math.log(np.mean(np.exp(np.array(z[1:]) - max(z[1:])))) + max(z[1:]) - z[0]
    assert tp.log_bayes_factor == pytest.approx(want, abs=1e-9)
    # posterior odds of teaching = the Bayes factor (prior odds 1)
    p = tp.lambda_probabilities
    assert math.log(p[1:].sum() / p[0]) == pytest.approx(tp.log_bayes_factor, abs=1e-9)
    # the λ-marginal belief's evidence is the joint's normaliser
    joint = tp.log_likelihood + tp.log_prior[None, :] + tp.log_prior_lambda[:, None]
    assert tp.belief(lp).log_evidence == pytest.approx(float(np.logaddexp.reduce(joint.ravel())), abs=1e-9)
    assert tp.belief(lp, doer=True).mean_beta == pytest.approx(doer.mean_beta, abs=1e-12)


def test_strong_teachers_read_as_teaching_and_doers_do_not(task):
    """Five people (θ ~ Dirichlet(1), β = 0.1), each simulated as a doer and as a teacher at λ = 1.0 (a
    logit shift of 10·I per choice, I's median |I| ≈ 0.2 nats on this map). A teacher whose shortest
    path is already the most telling one (one of the five here, 244 pairs) has little to show, so four
    of five are asked to read as teaching (2 log BF ≥ 6); a doer's Bayes factor is positive only
    through the set's misfit to an off-grid θ (at most 3.9 in 2 log BF at these seeds), so none may."""
    mdp, hyp, lp = task
    teachers = [P.teaching_posterior(lp, hyp, _episodes(mdp, hyp, lp, 1.0, seed=s)) for s in range(5)]
    doers = [P.teaching_posterior(lp, hyp, _episodes(mdp, hyp, lp, 0.0, seed=s)) for s in range(5)]
    assert sum(t.verdict == "teaching" for t in teachers) >= 4
    assert not any(d.verdict == "teaching" for d in doers)
    best = max(teachers, key=lambda t: t.log_bayes_factor)
    lo, hi = best.lambda_interval()
    assert lo > 0 and hi <= 1.0
    rec = best.record(lp)
    assert rec["verdict"] == "teaching" and rec["reading"].startswith("demonstrations read as teaching")
    assert rec["p_teaching"] > 0.999 and rec["lambda_interval"] == [lo, hi]


@pytest.mark.parametrize("spec, why", [("0.1,0.3", "must hold 0"), ("0", "must hold 0"),
                                       ("0,-1", "from 0 to"), ("0,x", "comma-separated numbers"),
                                       ("0,inf", "from 0 to"), ("0,1e308", "from 0 to 1000")])
def test_bad_lambda_grids_are_refused(spec, why):
    with pytest.raises(InputError, match=why):
        P.parse_lambdas(spec)


def test_parse_lambdas_sorts_and_deduplicates():
    np.testing.assert_array_equal(P.parse_lambdas("0.3, 0, 0.1,0.3"), [0.0, 0.1, 0.3])
    assert P.lambda_log_prior(np.array([0.0, 0.1, 0.3])) == pytest.approx(np.log([0.5, 0.25, 0.25]))


def test_teacher_refuses_a_negative_lambda_and_a_foreign_observer(task):
    mdp, hyp, lp = task
    obs = P.observer(hyp, lp)
    for lam in (-0.1, 1e308):
        with pytest.raises(InputError, match="lambda must be a number from 0 to 1000"):
            P.teacher_log_policy(mdp, hyp.thetas[0], 0.1, lam, obs)
    small = P.observer(hyp, lp[:, :10])
    with pytest.raises(InputError, match="observer covers 10 states"):
        P.teacher_log_policy(mdp, hyp.thetas[0], 0.1, 0.1, small)


def test_a_coarse_beta_grid_warns_unless_the_verdict_is_doing(task):
    mdp, hyp, lp = task  # βs 0.1, 0.5, 2: 5× apart
    teacher = P.teaching_posterior(lp, hyp, _episodes(mdp, hyp, lp, 1.0, seed=1))
    assert teacher.verdict == "teaching"
    (w,) = teacher.warnings()
    assert "up to 5× apart" in w and "--betas" in w
    one = HypothesisSet(hyp.thetas, np.array([0.1]))
    lp_one = lp[::hyp.n_beta]  # the β = 0.1 column of the θ-major set
    assert P.teaching_posterior(lp_one, one, _episodes(mdp, hyp, lp, 1.0, seed=1)).warnings() == []
    fine = HypothesisSet(hyp.thetas, np.array([0.1, 0.15, 0.2]))
    lp_fine = np.asarray(solve(mdp, fine.theta, fine.beta, tol=1e-10).log_policy)
    assert P.teaching_posterior(lp_fine, fine, _episodes(mdp, hyp, lp, 1.0, seed=1)).warnings() == []
