"""Diagnostics: statistics that cannot be computed are None with a reason; each threshold warns."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference import diagnostics as dg
from expertise_irl.inference.belief import DiscreteBelief

NAMES = ("length", "road")


def draws(rng, C, D, shift=0.0):
    """``theta [C, D, 2]``, ``beta [C, D]``: iid normal draws, chain c shifted by ``c * shift``."""
    beta = rng.normal(size=(C, D)) + shift * np.arange(C)[:, None]
    theta = rng.normal(size=(C, D, 2)) + shift * np.arange(C)[:, None, None]
    return theta, beta


def test_chain_statistics_of_iid_chains():
    # 4 chains x 1000 iid draws: R-hat is 1 + O(1/sqrt(4000)) and bulk ESS ≈ 4000 (sd ≈ 4000 * 0.03).
    theta, beta = draws(np.random.default_rng(0), 4, 1000)
    s = dg.chain_statistics(theta, beta)
    assert s["unavailable"] == {}
    assert max(s["r_hat"]["beta"], *s["r_hat"]["theta"]) < dg.R_HAT_MAX
    assert 3000 < s["ess_bulk"]["beta"] < 5000
    assert dg.sampling_warnings(s, chains=4, feature_names=NAMES, more="--samples") == []


def test_chains_that_disagree_warn_on_r_hat():
    theta, beta = draws(np.random.default_rng(1), 2, 200, shift=1.0)
    s = dg.chain_statistics(theta, beta)
    w = dg.sampling_warnings(s, chains=2, feature_names=NAMES, more="--samples")
    assert any(m.startswith("R-hat of ") and "--samples" in m for m in w), w


def test_autocorrelated_chain_warns_on_ess():
    # A random walk: 400 draws with an ESS of a few.
    rng = np.random.default_rng(2)
    beta = np.cumsum(rng.normal(size=(2, 400)), axis=1)
    theta = np.repeat(beta[..., None], 2, axis=2)
    s = dg.chain_statistics(theta, beta)
    w = dg.sampling_warnings(s, chains=2, feature_names=NAMES, more="--samples")
    assert any(m.startswith("bulk ESS of β is 2.7, below 200 (100 per chain × 2 chains): ") for m in w), w
    one = dg.sampling_warnings(dg.chain_statistics(theta[:1], beta[:1]), chains=1, feature_names=NAMES,
                               more="--iterations")
    assert any(m.startswith("bulk ESS of ") and ", below 100: " in m for m in one), one


@pytest.mark.parametrize("C,D,missing", [(1, 50, {"r_hat"}), (2, 3, {"r_hat", "ess_bulk"}),
                                         (1, 1, {"r_hat", "ess_bulk"})])
def test_too_short_runs_give_none_with_a_reason(C, D, missing):
    theta, beta = draws(np.random.default_rng(3), C, D)
    s = dg.chain_statistics(theta, beta)
    assert set(s["unavailable"]) == missing
    for name in missing:
        assert s[name] is None
        assert f"has {C} chain(s) of {D}" in s["unavailable"][name] or f"has {D}" in s["unavailable"][name]
    w = dg.sampling_warnings(s, chains=C, feature_names=NAMES, more="--samples")
    assert sum(m.startswith("convergence not checked") for m in w) == len(missing)


def test_one_chain_split_in_halves():
    rng = np.random.default_rng(4)
    beta = rng.normal(size=600)
    theta = rng.normal(size=(600, 2))
    s = dg.chain_statistics(theta, beta, halves=True)
    assert s["unavailable"] == {} and s["r_hat"]["beta"] < dg.R_HAT_MAX
    assert 450 < s["ess_bulk"]["beta"] < 750  # the whole chain's ESS, not a half's
    drift = np.linspace(0, 5, 600)  # a chain that drifts: its halves disagree
    s = dg.chain_statistics(theta + drift[:, None], beta + drift, halves=True)
    assert s["r_hat"]["beta"] > 1.5
    short = dg.chain_statistics(theta[:5], beta[:5], halves=True)
    assert short["r_hat"] is None and "halves" in short["unavailable"]["r_hat"]
    assert short["ess_bulk"]["beta"] is not None


# ----------------------------------------------------------------------------- chains that did not move
def test_a_constant_chain_has_no_ess_r_hat_or_interval():
    """ArviZ calls a constant series of n draws n effective draws (and its R-hat NaN): here it is ESS 0,
    R-hat None with the reason, a warning that says so first, and no interval."""
    rng = np.random.default_rng(5)
    theta, beta = draws(rng, 1, 800)
    theta, beta = theta[0], beta[0]
    beta[:] = 0.81  # β never moved; θ did
    s = dg.chain_statistics(theta, beta, halves=True, feature_names=NAMES)
    assert s["stuck"] == {0: {0: 0.81}}
    assert s["ess_bulk"]["beta"] == 0.0 and s["r_hat"]["beta"] is None
    assert s["unavailable"] == {
        "r_hat.beta": "the chain did not move in β (always 0.81): no posterior to summarise"}
    assert 600 < min(s["ess_bulk"]["theta"])  # the components that moved keep their statistics (iid: ≈ 800)
    intervals = dg.withhold_intervals({"beta": [0.81, 0.81], "theta": [[0, 1], [0, 1]]}, s["stuck"], 1, NAMES,
                                      s["unavailable"])
    assert intervals == {"beta": None, "theta": [[0, 1], [0, 1]]}
    assert "did not move in β" in s["unavailable"]["credible_intervals.beta"]
    w = dg.birl_warnings({**s, "acceptance_rate": 0.2}, NAMES, s["stuck"])
    assert len(w) == 1, w  # one warning, not one per null statistic
    assert w[0].startswith("the chain did not move in β: every kept draw has β = 0.81, so there is no "
                           "posterior")
    assert "ESS 0; R-hat and 90% interval null" in w[0] and "smaller --beta-step" in w[0]


def test_a_chain_that_froze_everywhere():
    """Every parameter constant (the issue's 10,000-iteration chain): every ESS 0, one warning naming all."""
    theta, beta = np.tile([0.9, 0.1], (500, 1)), np.full(500, 2.5)
    s = dg.chain_statistics(theta, beta, halves=True, feature_names=NAMES)
    assert s["ess_bulk"] == {"beta": 0.0, "theta": [0.0, 0.0]}
    assert s["r_hat"] == {"beta": None, "theta": [None, None]}
    assert set(s["unavailable"]) == {"r_hat.beta", "r_hat.theta[0]", "r_hat.theta[1]"}
    (w,) = dg.birl_warnings({**s, "acceptance_rate": 0.0}, NAMES, s["stuck"])[:1]
    assert w.startswith("the chain did not move in β, θ[length], θ[road]: every kept draw has β = 2.5, "
                        "θ[length] = 0.9, θ[road] = 0.1")


def test_one_stuck_chain_among_several():
    """A chain stuck at the median of three healthy ones: the pooled statistics are finite, but its
    parameter gets ESS 0, no R-hat and a warning naming the chain."""
    theta, beta = draws(np.random.default_rng(6), 4, 500)
    beta[2] = np.median(beta[[0, 1, 3]])
    s = dg.chain_statistics(theta, beta, feature_names=NAMES)
    assert s["stuck"] == {0: {2: pytest.approx(beta[2, 0])}}
    assert s["ess_bulk"]["beta"] == 0.0 and s["r_hat"]["beta"] is None
    assert s["unavailable"]["r_hat.beta"].startswith("chain 2 (of 0–3) did not move in β (always ")
    w = dg.nuts_warnings({**s, "divergences": 0, "chains": 4}, NAMES, s["stuck"])
    assert len(w) == 1 and w[0].startswith("chain 2 (of 0–3) did not move in β: every draw after warm-up "
                                           "has β = ") and "--warmup" in w[0], w
    assert "the estimate pools chains that did not move" in w[0]  # three chains moved: β̂ is not that value


def test_a_short_constant_chain_is_not_judged_stuck():
    """Below 4 draws no statistic is computed: the run says 'convergence not checked', not 'stuck'."""
    s = dg.chain_statistics(np.zeros((3, 2)), np.ones(3), halves=True, feature_names=NAMES)
    assert s["stuck"] == {} and set(s["unavailable"]) == {"r_hat", "ess_bulk"}


def test_a_nan_statistic_gets_a_reason():
    s = {"r_hat": None, "ess_bulk": {"beta": float("nan"), "theta": [1.0, 2.0]}, "unavailable": {}}
    s["ess_bulk"]["beta"] = None
    dg._apply_stuck(s, {}, 2, NAMES)
    assert s["unavailable"] == {"ess_bulk.beta": "bulk ESS of β is not a finite number for this run"}


def test_nuts_warnings():
    diag = {"r_hat": None, "ess_bulk": None, "divergences": 3, "chains": 1,
            "unavailable": {"r_hat": "R-hat needs at least 2 chains"}}
    w = dg.nuts_warnings(diag, NAMES)
    assert any("3 divergent transitions" in m for m in w)
    assert any("--chains 2 or more" in m for m in w)
    diag.update(divergences=0, unavailable={}, chains=2)
    assert dg.nuts_warnings(diag, NAMES) == []


def test_birl_acceptance_warning():
    base = {"r_hat": None, "ess_bulk": None, "unavailable": {}}
    stuck = dg.birl_warnings({**base, "acceptance_rate": 0.01}, NAMES)
    assert any("acceptance rate 0.010" in m for m in stuck)
    assert dg.birl_warnings({**base, "acceptance_rate": 0.2}, NAMES) == []


@pytest.mark.parametrize("optima,warns", [([-10.0, -10.05, -20.0], False), ([-10.0, -12.0, -20.0], True),
                                          ([-10.0], False)])
def test_map_starts_that_disagree(optima, warns):
    w = dg.map_warnings({"optima": optima}, 1.0, (0.01, 10.0))
    assert any("starts reached the best" in m for m in w) == warns
    if warns:
        assert "2–10 nats lower" in w[0]


def test_map_beta_on_the_prior_edge():
    assert any("edge of the prior" in m for m in dg.map_warnings({"optima": [-1.0]}, 0.01, (0.01, 10.0)))
    assert dg.map_warnings({"optima": [-1.0]}, 0.5, (0.01, 10.0)) == []


def belief_with(probabilities, thetas, betas) -> DiscreteBelief:
    """A belief whose posterior is ``probabilities`` (flattened θ-major), from one observed pair."""
    hyp = HypothesisSet(np.asarray(thetas, dtype=float), betas)
    p = np.asarray(probabilities, dtype=float)
    log_policy = np.stack([np.log(p), np.log1p(-p)], axis=-1)[:, None, :]  # [H, 1 state, 2 actions]
    return DiscreteBelief.from_log_policy(hyp, log_policy).update_pairs([0], [0])


@pytest.mark.parametrize("edge_mass,warns", [(0.12, True), (0.08, False)])
def test_discrete_mass_on_the_smallest_beta(edge_mass, warns):
    betas = [0.01, 1.0, 10.0]
    rest = (1 - edge_mass) / 2
    # one θ; posterior ∝ likelihood, so these are the β marginal
    b = belief_with([edge_mass, rest, rest], [[1.0, 0.0]], betas)
    assert b.marginal_beta()[1][0] == pytest.approx(edge_mass)
    w = dg.discrete_warnings(b, NAMES)
    assert any("smallest β" in m and "--betas 0.001,0.00333333,0.01,1,10" in m for m in w) == warns


def test_discrete_mass_on_the_largest_beta():
    b = belief_with([0.05, 0.25, 0.7], [[1.0, 0.0]], [0.01, 1.0, 10.0])
    w = dg.discrete_warnings(b, NAMES)
    assert len(w) == 1 and "largest β" in w[0] and "--betas 0.01,1,10,30,100" in w[0]


def test_discrete_mass_on_the_border_of_the_theta_set():
    # θ_length takes values 0.3..0.7 in this set: 0.7 is an edge of the set, not of the simplex.
    thetas = [[0.7, 0.3], [0.5, 0.5], [0.3, 0.7]]
    b = belief_with([0.6, 0.3, 0.1], thetas, [1.0])
    w = dg.discrete_warnings(b, NAMES)
    assert any("θ_length = 0.7, the largest value in the set" in m for m in w), w
    assert not any("θ_length = 0.3" in m for m in w)
    full = [[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]  # edges of the simplex itself never warn
    assert dg.discrete_warnings(belief_with([0.9, 0.05, 0.05], full, [1.0]), NAMES) == []


def test_a_real_experts_single_demonstration_warns_with_the_default_grid():
    """A person far more expert than the grid's smallest β: the warning says which --betas to add."""
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.worlds.zones import load_bundled

    mdp = load_bundled("crossroads").to_mdp()
    trajs = simulate(mdp, np.array([1.0, 0, 0, 0, 0]), 0.002, 1, np.random.default_rng(0))
    hyp = HypothesisSet(theta_grid(THETA_PRESETS["paper-real"], mdp.n_features), BETA_PRESETS["paper-sim"])
    post = DiscreteBelief.from_mdp(mdp, hyp).update(trajs)
    assert post.marginal_beta()[1][0] >= dg.EDGE_MASS
    w = dg.discrete_warnings(post, mdp.feature_names)
    assert any("smallest β of the grid (0.01)" in m and "--betas 0.001," in m for m in w), w


def test_one_feature_on_the_simplex_is_not_stuck():
    """θ = [1] in every draw is what the simplex allows with one feature, not a frozen chain; β still
    is judged."""
    theta = np.ones((2, 50, 1))
    beta = np.random.default_rng(0).uniform(0.5, 2.0, (2, 50))
    assert dg.stuck_parameters(theta, beta) == {}
    assert set(dg.stuck_parameters(theta, np.ones((2, 50)))) == {0}
