"""Low expertise or missing features: predictive checks, the per-state competitor, identifiability, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from detour_map import MAP, REDUCED
from scipy.stats import kstest

from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import HypothesisSet, resolve_thetas
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.identifiability import feature_identifiability
from expertise_irl.inference.misspecification import (
    EXPLAINED,
    UNEXPLAINED,
    UNKNOWN,
    VERDICTS,
    misspecification,
    verdict,
)
from expertise_irl.inference.predictive_checks import holm_rejections, p_value, simulate_from_starts
from expertise_irl.inference.tabular_reward import augmented_mdp, support_states
from expertise_irl.mdp import TabularMDP
from expertise_irl.worlds.zones import parse_map


@pytest.fixture(scope="module")
def world():
    full = parse_map(MAP.strip("\n"), name="detour").to_mdp()
    reduced = TabularMDP(full.next_state, full.features[..., REDUCED], full.terminal, gamma=full.gamma,
                         feature_names=tuple(full.feature_names[i] for i in REDUCED),
                         start_states=full.start_states, state_xy=full.state_xy)
    hyp = HypothesisSet(resolve_thetas("paper-real", 4), np.round(np.logspace(-2.5, 1, 8), 5))
    return full, reduced, DiscreteBelief.from_mdp(reduced, hyp)


def _person(world, hidden: bool, seed: int, check: str):
    full, reduced, prior = world
    th = np.array([0.3, 0.05, 0.6 if hidden else 0.0, 0.025, 0.025])
    trajs = simulate(full, th / th.sum(), 0.05, 20, np.random.default_rng(seed))
    post = prior.update(trajs)
    hyp = post.hypotheses
    return misspecification([(reduced, trajs)], check=check, theta=hyp.theta, beta=hyp.beta,
                            weights=post.probabilities, tables=[post.log_policy], theta_hat=post.mean_theta,
                            beta_hat=post.mean_beta, model="maxent", seed=seed)


# ------------------------------------------------------------------------------ p-values
@pytest.mark.parametrize("discrete", [False, True])
def test_p_values_are_uniform_when_observed_and_replicated_are_exchangeable(discrete):
    # 3,000 trials of one observed value among 99 replicates from the same law. The randomised
    # PIT is exactly uniform then, ties included (a Poisson(1) law ties often). KS at n = 3,000 has
    # a critical distance of ~0.03 at level 0.001, so a mid-p that piles tied values at one p
    # (distance ≥ 0.15 here) fails while the exact version passes with probability 0.999.
    rng = np.random.default_rng(5)
    draw = (lambda n: rng.poisson(1.0, n).astype(float)) if discrete else (lambda n: rng.normal(size=n))
    for one_sided in (False, True):
        ps = [p_value(float(draw(1)[0]), draw(99), one_sided=one_sided, v=float(rng.random()))
              for _ in range(3000)]
        assert kstest(ps, "uniform").pvalue > 1e-3


def test_p_value_of_an_outlier_and_of_missing_values():
    x = np.arange(100.0)
    assert p_value(1e3, x, one_sided=True, v=0.5) == pytest.approx(0.5 / 101)
    assert p_value(-1e3, x, one_sided=False, v=0.5) == pytest.approx(2 * 0.5 / 101)
    assert p_value(float("nan"), x, one_sided=False) is None
    assert p_value(1.0, np.array([np.nan]), one_sided=False) is None


def test_holm_steps_down():
    # m = 3: 0.01 <= 0.05/3, 0.02 <= 0.05/2, 0.04 <= 0.05/1 -> all three; 0.03 after 0.02 fails 0.025
    assert holm_rejections({"a": 0.01, "b": 0.02, "c": 0.04}) == {"a": True, "b": True, "c": True}
    assert holm_rejections({"a": 0.01, "b": 0.03, "c": 0.04}) == {"a": True, "b": False, "c": False}
    assert holm_rejections({"a": 0.02, "b": None}) == {"a": True, "b": False}


def test_replicates_start_where_the_episodes_started_and_follow_a_deterministic_policy(world):
    _, reduced, _ = world
    lp = np.where(reduced.available, 0.0, -np.inf)
    lp = np.where(np.arange(reduced.n_actions)[None] == np.argmax(reduced.available, axis=1)[:, None], 0.0,
                  -np.inf)
    starts = reduced.initial_states()[:2]
    r, e, s, a, capped = simulate_from_starts(reduced, lp[None], np.zeros(3, dtype=int), starts,
                                              np.random.default_rng(0), 50)
    for rep in range(3):
        for ep in range(2):
            m = (r == rep) & (e == ep)
            assert s[m][0] == starts[ep]
            assert np.all(a[m] == np.argmax(reduced.available, axis=1)[s[m]])  # the only action it allows
    assert capped.shape == (3, 2)


# ------------------------------------------------------------------------------ verdicts
def test_verdict_rules():
    checks = {"failed": []}
    assert verdict(20, 200, checks, None)[0] == EXPLAINED
    assert verdict(20, 200, {"failed": ["path_length"]}, None)[0] == UNEXPLAINED
    assert verdict(3, 200, checks, None)[0] == UNKNOWN
    assert verdict(20, 30, checks, None)[0] == UNKNOWN
    comp = {"gain": 0.1, "gain_se": 0.02, "beta_ratio": 0.5}
    assert verdict(20, 200, checks, comp)[0] == UNEXPLAINED
    assert verdict(20, 200, checks, {**comp, "gain_se": 0.08})[0] == UNKNOWN  # short of 2 SE
    assert verdict(20, 200, checks, {**comp, "beta_ratio": 0.95})[0] == UNKNOWN  # no smaller β
    assert verdict(20, 200, checks, {**comp, "gain": -0.1})[0] == EXPLAINED


def test_fast_checks_tell_a_hidden_preference_from_a_well_specified_person(world):
    # A careful person who avoids the zone (its feature removed) detours on every episode; the
    # features read the detours as noise (β̂ ≈ 4× the truth), so replicates at β̂ wander over the map
    # and the observed visits lie far outside them (measured: p ≈ 0.001 against a Holm threshold of
    # 0.05/8). The well-specified person's checks pass. Fixed seeds.
    a = _person(world, True, 1, "fast")
    c = _person(world, False, 1, "fast")
    assert a["verdict"] == UNEXPLAINED and a["predictive"]["failed"]
    assert c["verdict"] == EXPLAINED and not c["predictive"]["failed"]
    assert a["competitor"] is None and "--check full" in a["unavailable"]["competitor"]
    assert a["beta_upper_bound"] > 0 and "beta_upper_bound" not in c


def test_the_competitors_per_state_rewards_are_features_for_entering_the_support(world):
    full, reduced, _ = world
    trajs = simulate(full, np.array([0.3, 0.05, 0.6, 0.025, 0.025]), 0.05, 2, np.random.default_rng(0))
    support = support_states(reduced, trajs)
    assert set(trajs.state.tolist()) <= set(support.tolist()) and len(support) < reduced.n_states
    k = reduced.n_features
    rich = augmented_mdp(reduced, support)
    assert rich.feature_names == (*reduced.feature_names, *(f"r{s}" for s in support))
    np.testing.assert_array_equal(rich.features[..., :k], reduced.features)
    s, a = np.nonzero(reduced.next_state >= 0)
    column = {int(state): j for j, state in enumerate(support)}
    expected = np.zeros((len(s), len(support)))
    for row, state in enumerate(reduced.next_state[s, a]):
        if int(state) in column:
            expected[row, column[int(state)]] = 1.0
    np.testing.assert_array_equal(rich.features[s, a, k:], expected)


@pytest.mark.slow
def test_full_check_the_per_state_reward_explains_the_hidden_preference(world):
    # Measured: A gains ~0.25 nats/action (SE ~0.015) with a β 0.6–0.7 times the features'; C loses
    # ~0.03 (the penalised per-state reward only adds variance). The margins are many SEs wide.
    a = _person(world, True, 2, "full")
    c = _person(world, False, 2, "full")
    ca, cc = a["competitor"], c["competitor"]
    assert ca["gain"] > 0.1 and ca["gain"] > 4 * ca["gain_se"] and ca["beta_ratio"] < 0.9
    assert cc["gain"] < 0.02
    assert a["verdict"] == UNEXPLAINED and c["verdict"] == EXPLAINED
    # the departure is most negative in the zone (columns 4-7, rows 2-4) or on the ring of cells
    # around it, where the detours turn; the starts are at x = 0 and the goal at x = 11
    worst = min(ca["top_states"], key=lambda e: e["departure"])
    assert 3 <= worst["x"] <= 8 and 1 <= worst["y"] <= 5 and worst["departure"] < 0


# ------------------------------------------------------------------------------ identifiability
def test_a_zero_feature_and_collinear_features_are_named(world):
    full, _, _ = world
    ident = feature_identifiability(full)
    assert ident["not_identified"] == [] and ident["warnings"] == []
    # no slow zone reachable: a map where the slow cells are walled off from the start
    walled = parse_map("S.#s\n..#.\n.G..\n", name="walled").to_mdp()
    starts = np.array([0])
    ident = feature_identifiability(walled, starts)
    assert "slow" in ident["not_identified"]
    assert any("feature slow is 0 on every move reachable" in w for w in ident["warnings"])
    # a copy of length, scaled: collinear with it
    f = np.concatenate([full.features, 2 * full.features[..., :1]], axis=2)
    dup = TabularMDP(full.next_state, f, full.terminal, gamma=full.gamma,
                     feature_names=(*full.feature_names, "twice_length"), start_states=full.start_states)
    ident = feature_identifiability(dup)
    assert {"features": ["length", "twice_length"], "ratio": pytest.approx(0.5)} in ident["collinear"]
    assert set(ident["not_identified"]) == {"length", "twice_length"}


# ------------------------------------------------------------------------------ command line
@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    d = tmp_path_factory.mktemp("mis")
    ok(invoke("simulate", "corridor", "--theta", "0.5,0.2,0.2,0.05,0.05", "--beta", "0.5", "--episodes", 12,
              "--seed", 3, "--out", d / "d.csv"))
    return d


@pytest.mark.slow
def test_infer_writes_the_verdict_and_plot_check_draws_it(demos):
    out = demos / "r.json"
    ok(invoke("infer", "corridor", "--demos", demos / "d.csv", "--out", out, "--betas", "0.1,0.5,2"))
    doc = json.loads(out.read_text())
    mis = doc["diagnostics"]["misspecification"]
    assert doc["settings"]["check"] == "fast" and mis["check"] == "fast"
    assert mis["verdict"] in VERDICTS and mis["predictive"]["replicates"] == 400
    want = {"path_length", "steps_to_goal", "visit_discrepancy", "agreement",
            *(f"feature_{n}" for n in doc["feature_names"])}
    assert set(mis["predictive"]["statistics"]) == want
    assert "identifiability" in doc["diagnostics"]
    png = demos / "check.png"
    ok(invoke("plot", out, "--check", "--out", png))
    assert png.stat().st_size > 10_000


def test_check_off_and_bad_values(demos):
    out = demos / "off.json"
    ok(invoke("infer", "corridor", "--demos", demos / "d.csv", "--out", out, "--betas", "0.5",
              "--check", "off"))
    doc = json.loads(out.read_text())
    assert "misspecification" not in doc["diagnostics"]
    assert_input_error(invoke("infer", "corridor", "--demos", demos / "d.csv", "--out", demos / "x.json",
                              "--check", "fastest"), "--check", "fastest")
    assert_input_error(invoke("plot", out, "--check", "--out", demos / "x.png"), "misspecification",
                       "--check fast")


def test_checks_policies_are_solved_once_per_map_and_equal_a_direct_solve(monkeypatch):
    """A study's participants share maps and hypotheses: draw_policies solves each (map, θ, β)
    once, in fixed batches of SOLVE_BATCH, and what it returns is the solver's policy for exactly
    the hypotheses asked (compared with a direct solve of each to 1e-12: the solver's answer for
    one hypothesis does not depend on its batch-mates)."""
    import expertise_irl.inference.misspecification as mis
    from expertise_irl.planning import soft_vi
    from expertise_irl.worlds.maps import resolve_world

    mdp = resolve_world("crossroads").to_mdp()
    K = mdp.n_features
    rng = np.random.default_rng(5)
    theta = rng.dirichlet(np.ones(K), size=20)
    beta = np.exp(rng.uniform(np.log(0.05), np.log(2.0), size=20))
    monkeypatch.setattr(mis, "_POLICIES", mis._PolicyCache(mis.POLICY_CACHE_BYTES))
    calls = []
    real = soft_vi.solve

    def counting(m, th, b, **kw):
        calls.append(len(b))
        return real(m, th, b, **kw)

    monkeypatch.setattr(soft_vi, "solve", counting)
    w = np.ones(20)
    def draw():
        return mis.draw_policies([mdp], theta, beta, w, np.random.default_rng(0), "maxent", replicates=60)

    pols, which, n = draw()
    assert set(calls) == {mis.SOLVE_BATCH} and n == len(np.unique(which))
    first = len(calls)
    pols2, _, _ = draw()
    assert len(calls) == first  # every hypothesis was already solved
    np.testing.assert_array_equal(pols2[0], pols[0])
    used = np.unique(np.random.default_rng(0).choice(20, size=60, p=w / w.sum()))
    for d, h in enumerate(used):
        direct = real(mdp, theta[h:h + 1], beta[h:h + 1], model="maxent").log_policy[0]
        np.testing.assert_allclose(pols[0][d], direct, rtol=0, atol=1e-12)


def test_cut_off_episodes_are_compared_with_replicates_cut_the_same_way():
    """Episodes that stop before a goal (a recording's end, simulate's step limit) are cut off, not
    the person's choice: their replicates stop at the same number of moves. Data simulated from the
    model itself and cut at 12 moves (β = 3 on crossroads, where the goal takes longer than that by
    chance) must then keep path_length inside the predictive distribution: every replicate of a
    cut episode has at most 12 moves. Without the rule the replicates ran on to a goal or to
    100 moves."""
    from expertise_irl.worlds.maps import resolve_world

    mdp = resolve_world("crossroads").to_mdp()
    theta, beta = np.full(mdp.n_features, 1 / mdp.n_features), 3.0
    trajs = simulate(mdp, theta, beta, 6, np.random.default_rng(3), max_steps=12)
    cut = sum(not mdp.terminal[mdp.next_state[s[-1], a[-1]]] for s, a in trajs.episodes())
    assert cut >= 4  # the premise: most episodes were cut off
    doc = misspecification([(mdp, trajs)], check="fast", theta=theta[None], beta=np.array([beta]),
                           weights=None,
                           theta_hat=theta, beta_hat=beta, model="maxent", seed=0)
    pred = doc["predictive"]
    assert pred["cut_episodes"] == cut
    lengths = np.array(pred["replicated"]["path_length"], dtype=float)
    assert lengths.max() <= 12
    assert not pred["statistics"]["path_length"]["rejected"]
