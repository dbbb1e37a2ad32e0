"""Changing expertise (inference/changing.py): the forward–backward pass against brute-force
enumeration of every β sequence, the stationary limit, a simulated learner on crossroads, and
stationary people (the Bayes factor's false positives)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.special import expit, logsumexp
from scipy.stats import spearmanr

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import ArgumentError, InputError
from expertise_irl.hypotheses import HypothesisSet
from expertise_irl.inference.changing import (
    EPSILONS,
    changing_posterior,
    changing_summary,
    episode_log_likelihoods,
    expertise_by_episode,
    first_last_joint,
    log_epsilon_prior,
    transition_matrix,
    trend_summary,
)
from expertise_irl.inference.methods import DiscreteOptions
from expertise_irl.inference.posterior import beta_quantile
from expertise_irl.planning.soft_vi import solve
from expertise_irl.planning.table_likelihood import log_likelihood
from expertise_irl.worlds.maps import load_bundled_world

# Exactness: both sides work in float64 log space on log-likelihoods of magnitude <= ~10 (or a
# known scale); each forward/backward step is one log-sum-exp (relative error ~1e-16), four
# episodes and a few terms give errors ~1e-15 (measured: <= 2e-15), so 1e-12 leaves three
# orders of margin yet catches any wrong transition probability, prior weight or edge rule
# (those change the answers in the second or third decimal).
EXACT = 1e-12


# ----------------------------------------------------------------------------- brute force
def brute(ll, hyp, eps_grid, trend, log_prior_theta=None):
    """Every β sequence enumerated, in log space: log Z(ε), P(β_e | Ξ, ε), P(β_1, β_E | Ξ, ε) and the
    filtered P(β_e | ξ_1..ξ_e) (ε mixed with the posterior of those episodes)."""
    E = ll.shape[0]
    n_t, J = hyp.n_theta, hyp.n_beta
    L = ll.reshape(E, n_t, J)
    lpt = np.zeros(n_t) if log_prior_theta is None else np.asarray(log_prior_theta)
    lpt = lpt - logsumexp(lpt)
    n_pos = sum(e > 0 for e in eps_grid)
    lpe = [np.log(0.5) if e == 0 else np.log(0.5 / n_pos) for e in eps_grid] if n_pos else [0.0]
    out = []
    for eps in eps_grid:
        with np.errstate(divide="ignore"):
            lT = np.log(transition_matrix(J, eps, trend))
        seqs = list(itertools.product(range(J), repeat=E))
        terms = np.array([[lpt[i] - np.log(J) + sum(lT[s[e], s[e + 1]] for e in range(E - 1))
                           + sum(L[e, i, s[e]] for e in range(E)) for s in seqs] for i in range(n_t)])
        log_z = logsumexp(terms)
        marg = np.zeros((E, J))
        joint = np.zeros((J, J))
        for k, s in enumerate(seqs):
            p = np.exp(logsumexp(terms[:, k]) - log_z)
            for e in range(E):
                marg[e, s[e]] += p
            joint[s[0], s[-1]] += p
        # prefixes: log P(ξ_1..ξ_e, β_e = j | ε)
        pref = np.full((E, J), -np.inf)
        for e in range(E):
            for s in itertools.product(range(J), repeat=e + 1):
                t = [lpt[i] - np.log(J) + sum(lT[s[d], s[d + 1]] for d in range(e))
                     + sum(L[d, i, s[d]] for d in range(e + 1)) for i in range(n_t)]
                pref[e, s[-1]] = np.logaddexp(pref[e, s[-1]], logsumexp(t))
        out.append((log_z, marg, joint, pref))
    log_z = np.array([o[0] for o in out])
    w = np.exp(lpe + log_z - logsumexp(lpe + log_z))
    lj = np.array([o[3] for o in out]) + np.array(lpe)[:, None, None]  # [n_eps, E, J]
    filtered = np.exp(lj - logsumexp(lj, axis=(0, 2), keepdims=True)).sum(axis=0)
    marg = np.einsum("k,kej->ej", w, np.array([o[1] for o in out]))
    joint = np.einsum("k,kab->ab", w, np.array([o[2] for o in out]))
    return log_z, w, marg, joint, filtered, [o[1] for o in out]


@pytest.fixture
def tiny():
    """2 θ × 3 β, 4 episodes of random log-likelihoods, one of them impossible (−inf)."""
    hyp = HypothesisSet(np.array([[1.0, 0.0], [0.3, 0.7]]), [0.1, 1.0, 10.0])
    ll = np.random.default_rng(7).normal(-4.0, 2.0, size=(4, len(hyp)))
    ll[1, 2] = -np.inf  # θ_0, β = 10 cannot have produced episode 1
    ll[3, 3] = -np.inf  # θ_1, β = 0.1 cannot have produced episode 3
    return hyp, ll


def stationary_reference(ll, hyp):
    logw = ll.sum(axis=0) - np.log(len(hyp))
    p = np.exp(logw - logsumexp(logw)).reshape(hyp.n_theta, hyp.n_beta)
    return logsumexp(logw), p.sum(axis=1), p.sum(axis=0)


# ----------------------------------------------------------------------------- 1. stationary limit
def test_epsilon_zero_is_the_stationary_posterior(tiny):
    hyp, ll = tiny
    log_z, pt, pb = stationary_reference(ll, hyp)
    for trend in (None, "falling", "rising"):
        p = changing_posterior(ll, hyp, epsilons=(0.0,), trend=trend)
        assert p.log_evidence_by_epsilon[0] == pytest.approx(log_z, abs=EXACT)
        assert p.log_evidence == pytest.approx(log_z, abs=EXACT)
        np.testing.assert_allclose(p.theta_probabilities, pt, rtol=0, atol=EXACT)
        for e in range(ll.shape[0]):  # the same β in every episode, each with the stationary marginal
            np.testing.assert_allclose(p.beta_smoothed[e], pb, rtol=0, atol=EXACT)
        np.testing.assert_allclose(p.stationary.theta_marginal, pt, rtol=0, atol=EXACT)
        np.testing.assert_allclose(p.stationary.beta_marginal, pb, rtol=0, atol=EXACT)
        # no changing model in the grid: its prior mass is 0
        assert p.p_changing == 0.0 and np.isnan(p.log_bayes_factor) and np.isnan(p.epsilon_mean)
        np.testing.assert_allclose(first_last_joint(p), np.diag(pb), rtol=0, atol=EXACT)


def test_stationary_field_is_the_usual_posterior_with_a_theta_prior(tiny):
    hyp, ll = tiny
    lpt = np.log([0.2, 0.8])
    p = changing_posterior(ll, hyp, log_prior_theta=lpt)
    logw = (lpt[:, None] - np.log(3) + ll.sum(axis=0).reshape(2, 3)).ravel()
    np.testing.assert_allclose(p.stationary.probabilities, np.exp(logw - logsumexp(logw)), rtol=0, atol=EXACT)
    assert p.log_evidence_by_epsilon[0] == pytest.approx(logsumexp(logw), abs=EXACT)


# ----------------------------------------------------------------------------- 2. brute force
@pytest.mark.parametrize("trend", [None, "falling", "rising"])
def test_forward_backward_equals_enumeration(tiny, trend):
    hyp, ll = tiny
    grid = (0.0, 0.1, 0.35)
    p = changing_posterior(ll, hyp, epsilons=grid, trend=trend)
    log_z, w, marg, joint, filtered, by_eps = brute(ll, hyp, grid, trend)
    np.testing.assert_allclose(p.log_evidence_by_epsilon, log_z, rtol=0, atol=EXACT)
    np.testing.assert_allclose(p.epsilon_posterior, w, rtol=0, atol=EXACT)
    np.testing.assert_allclose(p.beta_smoothed, marg, rtol=0, atol=EXACT)
    np.testing.assert_allclose(p.beta_filtered, filtered, rtol=0, atol=EXACT)
    for k in range(len(grid)):
        np.testing.assert_allclose(p.beta_smoothed_by_epsilon[k], by_eps[k], rtol=0, atol=EXACT)
    np.testing.assert_allclose(first_last_joint(p), joint, rtol=0, atol=EXACT)
    ts = trend_summary(p)
    lb = np.log(hyp.betas)
    assert ts["p_falls"] == pytest.approx(np.tril(joint, -1).sum(), abs=EXACT)
    assert ts["log_ratio_mean"] == pytest.approx(np.sum(joint * (lb[None] - lb[:, None])), abs=EXACT)
    if trend == "falling":
        assert ts["p_rises"] == 0.0 and ts["p_falls"] > 0.05  # the chain cannot rise
    # the Bayes factor and P(changing) as stated: log mean_{ε>0} Z(ε) − log Z(0), sigmoid of it
    bf = logsumexp(log_z[1:]) - np.log(2) - log_z[0]
    assert p.log_bayes_factor == pytest.approx(bf, abs=EXACT)
    assert p.p_changing == pytest.approx(expit(bf), abs=EXACT)
    assert p.p_changing == pytest.approx(w[1:].sum(), abs=EXACT)
    assert p.epsilon_mean == pytest.approx(w[1:] @ np.array(grid[1:]) / w[1:].sum(), abs=EXACT)


def test_enumeration_with_theta_prior_and_extreme_log_likelihoods():
    """Log-likelihoods hundreds of nats apart (exp() of them under- or overflows) and episodes that
    favour different β by 800 nats: a scaled (common-shift) pass would lose the second β; log space
    keeps every sequence."""
    hyp = HypothesisSet(np.array([[1.0, 0.0], [0.0, 1.0]]), [0.5, 2.0])
    ll = np.random.default_rng(3).normal(-300.0, 200.0, size=(3, 4))
    ll[0, [0, 2]] += 800.0  # episode 0 favours β = 0.5 by 800 nats ...
    ll[1, [1, 3]] += 800.0  # ... episode 1 favours β = 2
    lpt = np.log([0.9, 0.1])
    grid = (0.0, 0.05)
    p = changing_posterior(ll, hyp, epsilons=grid, log_prior_theta=lpt)
    log_z, _, marg, joint, filtered, _ = brute(ll, hyp, grid, None, lpt)
    np.testing.assert_allclose(p.log_evidence_by_epsilon, log_z, rtol=1e-14, atol=0)
    np.testing.assert_allclose(p.beta_smoothed, marg, rtol=0, atol=EXACT)
    np.testing.assert_allclose(p.beta_filtered, filtered, rtol=0, atol=EXACT)
    np.testing.assert_allclose(first_last_joint(p), joint, rtol=0, atol=EXACT)
    assert np.isfinite(p.log_evidence_by_epsilon).all()


def test_impossible_for_one_beta_is_possible_when_beta_changes():
    """Episode 0 is impossible at β = 2 and episode 1 at β = 0.5: the stationary model cannot
    produce them (Z(0) = 0, no stationary posterior), the changing model can (log BF = +inf)."""
    hyp = HypothesisSet(np.array([[1.0]]), [0.5, 2.0])
    ll = np.array([[-1.0, -np.inf], [-np.inf, -1.0]])
    with np.errstate(all="raise"):
        p = changing_posterior(ll, hyp)
    assert p.log_evidence_by_epsilon[0] == -np.inf and p.stationary is None
    assert p.log_bayes_factor == np.inf and p.p_changing == 1.0
    np.testing.assert_allclose(p.beta_smoothed, [[1, 0], [0, 1]], atol=EXACT)
    np.testing.assert_allclose(p.beta_filtered, [[1, 0], [0, 1]], atol=EXACT)
    assert trend_summary(p)["p_rises"] == pytest.approx(1.0, abs=EXACT)
    assert np.all(np.isfinite(p.theta_probabilities))


def test_chain_and_prior_as_stated():
    # ends: the move that would leave the grid stays (1 − ε/2 both ways; 1 for a one-way chain)
    T = transition_matrix(4, 0.2)
    np.testing.assert_allclose(T, [[0.9, 0.1, 0, 0], [0.1, 0.8, 0.1, 0], [0, 0.1, 0.8, 0.1],
                                   [0, 0, 0.1, 0.9]])
    np.testing.assert_allclose(transition_matrix(3, 0.2, "falling"),
                               [[1, 0, 0], [0.2, 0.8, 0], [0, 0.2, 0.8]])
    np.testing.assert_allclose(transition_matrix(3, 0.2, "rising"),
                               [[0.8, 0.2, 0], [0, 0.8, 0.2], [0, 0, 1]])
    np.testing.assert_allclose(transition_matrix(1, 0.2), [[1.0]])
    np.testing.assert_allclose(np.exp(log_epsilon_prior(EPSILONS)), [0.5, 0.125, 0.125, 0.125, 0.125])


def test_summaries(tiny):
    hyp, ll = tiny
    p = changing_posterior(ll, hyp)
    rows = expertise_by_episode(p, ["a", "b", "c", "d"])
    assert [r["episode"] for r in rows] == ["a", "b", "c", "d"]
    for r, pe in zip(rows, p.beta_smoothed, strict=True):
        assert r["mean"] == pytest.approx(pe @ hyp.betas, abs=EXACT)
        cdf = np.cumsum(pe)
        for key, q in (("q05", 0.05), ("median", 0.5), ("q95", 0.95)):
            assert r[key] == hyp.betas[np.flatnonzero(cdf >= q - 1e-12)[0]]
    s = changing_summary(p)
    assert set(s) == {"log_bayes_factor", "p_changing", "epsilon_mean", "epsilons", "epsilon_posterior"}
    assert s["epsilons"] == list(EPSILONS) and sum(s["epsilon_posterior"]) == pytest.approx(1.0)
    assert p.theta_probabilities.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(p.beta_filtered.sum(axis=1), 1.0, atol=EXACT)
    # the model average is the changing and the stationary model mixed by their posterior
    mix = p.p_changing * p.theta_probabilities_changing + (1 - p.p_changing) * p.stationary.theta_marginal
    np.testing.assert_allclose(p.theta_probabilities, mix, rtol=0, atol=EXACT)
    assert p.expertise_by_episode() == expertise_by_episode(p, range(4))


def test_one_episode():
    hyp = HypothesisSet(np.array([[1.0, 0.0], [0.0, 1.0]]), [0.5, 2.0])
    ll = np.array([[-1.0, -2.0, -3.0, -0.5]])
    p = changing_posterior(ll, hyp)
    _, _, pb = stationary_reference(ll, hyp)
    np.testing.assert_allclose(p.beta_smoothed[0], pb, atol=EXACT)  # one episode: ε has no say
    assert p.log_bayes_factor == pytest.approx(0.0, abs=EXACT)
    assert trend_summary(p) == {"p_falls": 0.0, "p_rises": 0.0, "log_ratio_mean": 0.0}


@pytest.mark.parametrize("kwargs, match", [
    ({"ll": np.zeros((0, 6))}, "no episodes"),
    ({"ll": np.full((2, 6), np.nan)}, "no NaN"),
    ({"epsilons": (0.0, 1.0)}, r"in \[0, 1\), got 1"),
    ({"epsilons": (0.0, -0.1)}, r"in \[0, 1\), got -0.1"),
    ({"epsilons": (0.1, 0.2)}, "must include 0"),
    ({"epsilons": ()}, "empty"),
    ({"trend": "up"}, "trend must be one of none, falling, rising, got 'up'"),
    ({"ll": np.full((2, 6), -np.inf)}, "no hypothesis and no sequence of β"),
])
def test_input_errors(kwargs, match):
    hyp = HypothesisSet(np.array([[1.0, 0.0], [0.0, 1.0]]), [0.1, 1.0, 10.0])
    ll = kwargs.pop("ll", np.zeros((2, 6)))
    with pytest.raises(InputError, match=match) as err:
        changing_posterior(ll, hyp, **kwargs)
    assert "\n" not in str(err.value)


def test_arrays_of_the_wrong_shape_are_programming_errors():
    hyp = HypothesisSet(np.array([[1.0, 0.0], [0.0, 1.0]]), [0.1, 1.0, 10.0])
    with pytest.raises(ArgumentError, match=r"log_prior_theta must have shape \[n_theta=2\]"):
        changing_posterior(np.zeros((2, 6)), hyp, log_prior_theta=np.zeros(3))
    with pytest.raises(ArgumentError, match=r"episode_ll must have shape \[episodes, H=6\]"):
        changing_posterior(np.zeros((2, 5)), hyp)


def test_labels_must_match_episodes(tiny):
    hyp, ll = tiny
    with pytest.raises(InputError, match="3 labels for 4 episodes"):
        expertise_by_episode(changing_posterior(ll, hyp), [1, 2, 3])


# ----------------------------------------------------------------------------- 3–4. simulated people
# Model: maxent-relative for simulation and inference. Under the paper's maxent the entropy
# bonus pays a noisy person to keep moving: on crossroads with θ* below a person at β = 2 or
# β = 1 walks the whole 500-step cap in 40 of 40 episodes and never reaches the goal, so the
# early part of the learning curve would be 500-step wanderings no learner produces.
# maxent-relative (random moves earn nothing) reaches the goal at every β here (mean 49 steps
# at β = 2, 11 at β = 0.05).
MODEL = "maxent-relative"
THETA_STAR = np.array([1.0, 0.5, 0.5, 0.0, 0.0]) / 2.0  # length, road, avoid: in the paper-real set


@pytest.fixture(scope="module")
def crossroads():
    mdp = load_bundled_world("crossroads").to_mdp()  # 185 cells, 4 moves, K = 5 features
    # paper-real Θ over K = 5 (211 directions) × paper-sim B (0.01 … 10: 6 values): 1,266 hypotheses.
    # The paper-sim grid suffices: a learner from β = 2 to 0.05 crosses 1, 0.5 and 0.09 on it,
    # so the smoothed curve can fall in four steps (a denser 10-value grid gave the same ranks).
    hyp = DiscreteOptions(thetas="paper-real", betas="paper-sim").hypotheses(mdp.n_features)
    log_policy = solve(mdp, hyp.theta, hyp.beta, model=MODEL).log_policy
    return mdp, hyp, log_policy


def cosine(a, b):
    return float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))


def test_simulated_learner_is_tracked(crossroads):
    """Six learners, β falling log-linearly from 2 to 0.05 over 20 episodes.

    Measured (seeds 0–5): Spearman 0.93–0.997, log BF 15–47, P(β_20 < β_1) ≥ 0.98. Thresholds:
    each learner's Spearman ≥ 0.8 and log BF > 0 as asked, P(β_20 < β_1) > 0.9. The θ check is
    on the mean cosine of the six: per person the changing model's θ̂ is closer to θ* for four of
    the six (0.777/0.773, 0.992/0.950, 0.988/0.905, 0.892/0.930, 0.998/0.931, 0.893/0.831; the
    stationary model explains the change of β by a different θ, which by chance lands nearer θ*
    for some people); on average 0.923 against 0.887.
    """
    mdp, hyp, log_policy = crossroads
    E = 20
    true_beta = 2.0 * (0.05 / 2.0) ** (np.arange(E) / (E - 1))
    cos_changing, cos_stationary = [], []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        ll = []
        for b in true_beta:
            tr = simulate(mdp, THETA_STAR, b, 1, rng, model=MODEL)
            ll.append(log_likelihood(log_policy, tr.state, tr.action))
        p = changing_posterior(np.array(ll), hyp)
        rows = expertise_by_episode(p)
        rho = spearmanr(true_beta, [r["mean"] for r in rows]).statistic
        assert rho >= 0.8, (seed, rho)
        assert p.log_bayes_factor > 0, (seed, p.log_bayes_factor)
        assert trend_summary(p)["p_falls"] > 0.9
        cos_changing.append(cosine(p.mean_theta, THETA_STAR))
        cos_stationary.append(cosine(p.stationary.mean_theta, THETA_STAR))
    assert np.mean(cos_changing) >= np.mean(cos_stationary), (cos_changing, cos_stationary)


def test_stationary_people_rarely_favour_change(crossroads):
    """20 people with one β each (log-uniform in [0.05, 2], off the grid) and θ from the set (with
    a positive length weight, so that episodes end), 15 episodes each.

    Measured over 400 such people (15 episodes): log BF > 1 for 2.5% (10 episodes 3.3%, 20
    episodes 3.8%); here 2 of the 20 (log BF 1.09 and 1.35). The test allows at most 3 of 20: at a
    true rate of 3% four or more happen with probability 0.003, at the benchmark's 5% target 0.016,
    and the seed is fixed. A Bayes factor that took the best ε instead of the prior mean over ε > 0
    (1.4 nats too high) is above 1 for 28% of these people (~6 of 20); one that let β change at
    no cost, for almost all. Each episode's smoothed median β lies in the stationary 90% interval
    for 99% of episodes over the 400 people (96% of these 20: the two change-favouring people
    have half their episodes outside); the test asks for 90%. Medians, since the interval's ends
    are grid values and a mean is off the grid (even the stationary mean lies in its own grid
    interval for only 44% of people).
    """
    mdp, hyp, log_policy = crossroads
    rng = np.random.default_rng(11)
    cand = np.flatnonzero(hyp.thetas[:, 0] > 0)
    bfs, in_band = [], []
    for _ in range(20):
        theta = hyp.thetas[rng.choice(cand)]
        beta = float(np.exp(rng.uniform(np.log(0.05), np.log(2.0))))
        tr = simulate(mdp, theta, beta, 15, rng, model=MODEL)
        p = changing_posterior(episode_log_likelihoods(log_policy, tr), hyp)
        bfs.append(p.log_bayes_factor)
        st = p.stationary.beta_marginal
        lo, hi = beta_quantile(hyp.betas, st, 0.05), beta_quantile(hyp.betas, st, 0.95)
        med = np.array([r["median"] for r in expertise_by_episode(p)])
        in_band.append(np.mean((med >= lo) & (med <= hi)))
    assert np.sum(np.array(bfs) > 1) <= 3, bfs
    assert np.mean(in_band) >= 0.9, in_band
