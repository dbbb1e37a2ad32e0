"""userstudy.diagnostics: constant features, the θ_i = 0 mask, and the default β grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.inference.methods import DiscreteOptions
from expertise_irl.mdp import TabularMDP
from expertise_irl.userstudy import diagnostics as dx

LEFT, RIGHT = 0, 1


def corridor(n: int, *, gamma: float = 0.9, goals=("right",), extra=None) -> TabularMDP:
    """States 0..n-1 on a line, actions left/right; feature 0 = −1 per move, feature 1 = ``extra``
    (default 0 everywhere). ``goals``: terminal states at the right end (state n-1) and/or the left
    end (state 0)."""
    ns = np.full((n, 2), -1)
    for s in range(n):
        if s > 0:
            ns[s, LEFT] = s - 1
        if s < n - 1:
            ns[s, RIGHT] = s + 1
    term = np.zeros(n, dtype=bool)
    if "right" in goals:
        term[n - 1] = True
    if "left" in goals:
        term[0] = True
    feats = np.zeros((n, 2, 2))
    feats[..., 0] = -1.0
    if extra is not None:
        feats[..., 1] = extra
    return TabularMDP(ns, feats, term, gamma=gamma, feature_names=("step", "other"))


# ---------------------------------------------------------------- constant features
def test_constant_features_lists_features_that_never_vary_with_their_value():
    m = corridor(5)  # step −1 everywhere, other 0 everywhere
    assert dx.constant_features([m]) == [(0, -1.0), (1, 0.0)]
    assert dx.constant_features(m) == [(0, -1.0), (1, 0.0)]


def test_terminal_states_do_not_count_but_moves_into_them_do():
    # Feature "other" is 5 on the terminal state's (absorbing, never-taken) rows only: still constant.
    extra = np.zeros((5, 2))
    extra[4] = 5.0
    assert dx.constant_features([corridor(5, extra=extra)]) == [(0, -1.0), (1, 0.0)]
    # ... but 5 on the move *into* the terminal state (state 3, right) makes it vary.
    extra = np.zeros((5, 2))
    extra[3, RIGHT] = 5.0
    assert dx.constant_features([corridor(5, extra=extra)]) == [(0, -1.0)]


def test_unavailable_actions_do_not_count():
    extra = np.zeros((5, 2))
    extra[0, LEFT] = 7.0  # state 0 cannot move left
    assert dx.constant_features([corridor(5, extra=extra)]) == [(0, -1.0), (1, 0.0)]


def test_constant_on_every_task_with_different_values_gives_none():
    a = corridor(5)
    b = corridor(6, extra=np.full((6, 2), -1.0))
    c = corridor(4, extra=np.where(np.arange(4)[:, None] == 1, 1.0, 0.0) * np.ones((4, 2)))
    assert dx.constant_features([a, b]) == [(0, -1.0), (1, None)]
    assert dx.constant_features([a, c]) == [(0, -1.0)]  # varies on c: not listed


def test_constant_features_on_the_example_floor_plans():
    from importlib import resources

    from expertise_irl.worlds.warehouse import load_floor_plan

    folder = resources.files("expertise_irl.userstudy") / "example"
    mdps = [load_floor_plan(folder / f"spec-{s}.txt").to_mdp() for s in "abc"]
    # length (−1/−2 and the goal bonus) and road vary on every plan.
    for m in mdps:
        assert 0 not in dict(dx.constant_features([m]))
        assert 2 not in dict(dx.constant_features([m]))


def test_a_fixed_goal_reward_leaves_length_a_constant_step_cost():
    from expertise_irl.worlds.zones import parse_map

    text = "S...\n.x.G\n"
    scaled = parse_map(text).to_mdp()
    fixed = parse_map(text, goal_reward_mode="fixed").to_mdp()
    # length: −1 per move (+ the bonus on entering the goal unless it is paid outside θ·φ);
    # slow and traffic: no such zones, 0. road: none either, 0 (off-road is 0 on zone maps).
    assert dx.constant_features([scaled]) == [(1, 0.0), (3, 0.0), (4, 0.0)]
    assert dx.constant_features([fixed]) == [(0, -1.0), (1, 0.0), (3, 0.0), (4, 0.0)]
    assert dx.constant_features([scaled, fixed]) == [(1, 0.0), (3, 0.0), (4, 0.0)]


def test_constant_features_reject_mixed_feature_counts():
    m3 = TabularMDP(np.array([[1], [-1]]), np.zeros((2, 1, 3)), np.array([False, True]))
    with pytest.raises(InputError, match="same features"):
        dx.constant_features([corridor(4), m3])
    with pytest.raises(InputError, match="at least one"):
        dx.constant_features([])


def test_constant_feature_warnings():
    w0 = dx.constant_feature_warning("restricted", 0.0)
    assert w0 == ("feature restricted is 0 on every task of this participant: its θ is not identified "
                  "and would only rescale β (β_eff = β/(1 − θ_restricted)); the study keeps "
                  "θ_restricted = 0")
    w1 = dx.constant_feature_warning("road", -1.0)
    assert "\n" not in w1 and w1.startswith("feature road is -1 on every move")
    assert "per-step reward" in w1 and "kept in θ" in w1 and "keeps θ_road = 0" not in w1
    wn = dx.constant_feature_warning("road", None)
    assert "not the same on all" in wn and "per-step reward" in wn


def test_zero_feature_mask():
    th = np.array([[1.0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0, 1.0]])
    assert dx.zero_feature_mask(th, [1]).tolist() == [True, False, True, True]
    assert dx.zero_feature_mask(th, [1, 2]).tolist() == [True, False, False, False]
    assert dx.zero_feature_mask(th, []).all()
    with pytest.raises(InputError, match="no θ of the set"):
        dx.zero_feature_mask(th[1:2], [0])
    with pytest.raises(InputError, match="outside"):
        dx.zero_feature_mask(th, [3])


def test_zero_feature_mask_on_the_paper_real_set():
    th = DiscreteOptions(thetas="paper-real", betas="paper-real").hypotheses(3).thetas
    mask = dx.zero_feature_mask(th, [1])
    # θ_1 = 0 leaves (θ_0, θ_2) in (0, .5, 1)^2 less zero: 8 vectors, 5 directions after unit l1
    # and deduplication ((1,0), (0,1), (½,½), (⅓,⅔), (⅔,⅓)).
    assert len(th) == 19 and mask.sum() == 5
    assert np.all(th[mask, 1] == 0) and np.all(th[~mask, 1] > 0)


# ---------------------------------------------------------------- the β grid
def test_q_gaps_of_a_corridor_by_hand():
    # Goal at state 4; with step cost c, V*(d) = −c(1 − γ^d)/(1 − γ) at distance d, and the gap
    # between moving toward the goal and away is γ(V*(d−1) − V*(d+1)) = c γ^d (1 + γ).
    # States 1..3 (d = 3..1) offer both moves; state 0 only one. A θ on the zero feature has no
    # reward: every action ties, no gap.
    g = 0.9
    m = corridor(5, gamma=g)
    th = np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])
    gaps = np.sort(dx.q_gaps(m, th))
    expect = np.sort([c * g**d * (1 + g) for c in (1.0, 0.5) for d in (1, 2, 3)])
    np.testing.assert_allclose(gaps, expect, rtol=1e-9)
    betas, info = dx.auto_beta_grid([m], th)
    # Six gaps: the median is the mean of the 3rd and 4th, 0.5·γ(1+γ) and γ³(1+γ).
    gmed = (0.5 * g * (1 + g) + g**3 * (1 + g)) / 2
    assert info["q_gap_median"] == pytest.approx(gmed, rel=1e-9)
    assert info["n_gaps"] == 6
    assert (info["low"], info["high"], info["per_decade"]) == (1e-3, 100.0, 3)
    assert "median" in info["rule"] and "\n" not in info["rule"]
    # 5 decades at 3 per decade: 16 values, both ends included, 3 significant figures.
    raw = np.logspace(math.log10(1e-3 * gmed), math.log10(100 * gmed), 16)
    np.testing.assert_array_equal(betas, [float(f"{b:.3g}") for b in raw])
    assert betas[0] == float(f"{1e-3 * gmed:.3g}") and betas[-1] == float(f"{100 * gmed:.3g}")


def test_exact_ties_are_left_out():
    # Goals at both ends of 0..4: state 2 is 2 moves from either (an exact tie); states 1 and 3
    # have the gap γ(1 + γ)·c between the near goal and the far one's path.
    g = 0.9
    m = corridor(5, gamma=g, goals=("left", "right"))
    gaps = dx.q_gaps(m, np.array([[1.0, 0.0]]))
    np.testing.assert_allclose(gaps, [g * (1 + g)] * 2, rtol=1e-9)


def test_grid_options_and_errors():
    m = corridor(5)
    th = np.array([[1.0, 0.0]])
    betas, info = dx.auto_beta_grid(m, th, low=0.01, high=1.0, per_decade=2)
    assert len(betas) == 5 and info["per_decade"] == 2
    assert betas[0] == pytest.approx(0.01 * info["q_gap_median"], rel=5e-3)
    # 1.5 decades at 2 per decade: ceil(3) = 3 intervals.
    assert len(dx.auto_beta_grid(m, th, low=0.1, high=10**0.5, per_decade=2)[0]) == 4
    for bad in ({"low": 0.0}, {"low": 2.0, "high": 1.0}, {"per_decade": 0}, {"per_decade": 1.5},
                {"model": "nope"}):
        with pytest.raises(InputError):
            dx.auto_beta_grid(m, th, **bad)
    with pytest.raises(InputError, match="no Q gap"):
        dx.auto_beta_grid(m, np.array([[0.0, 1.0]]))  # no reward at all


def _hard_q(mdp: TabularMDP, theta: np.ndarray) -> np.ndarray:
    """Plain numpy hard value iteration for one θ to convergence: Q* [S, A], −inf where unavailable."""
    r = mdp.reward(theta)
    avail = mdp.available
    nxt = np.where(mdp.next_state >= 0, mdp.next_state, 0)
    v = np.zeros(mdp.n_states)
    for _ in range(100_000):
        q = np.where(avail, r + mdp.gamma * v[nxt], -np.inf)
        new = np.where(mdp.terminal, 0.0, q.max(axis=1))
        if np.max(np.abs(new - v)) < 1e-13:
            break
        v = new
    return np.where(avail, r + mdp.gamma * v[nxt], -np.inf)


def test_gap_median_on_the_bundled_corridor_matches_a_plain_solver():
    from expertise_irl.worlds.zones import load_bundled

    m = load_bundled("corridor").to_mdp()
    th = DiscreteOptions(thetas="paper-real", betas="paper-real").hypotheses(m.n_features).thetas
    th = th[::7]  # a spread of the 211 directions keeps the plain solver quick
    ref = []
    multi = m.available.sum(axis=1) >= 2
    for t in th:
        q = np.sort(_hard_q(m, t)[multi], axis=1)
        gap = q[:, -1] - q[:, -2]
        ref.append(gap[gap > 1e-9])
    ref = np.concatenate(ref)
    betas, info = dx.auto_beta_grid([m], th)
    assert info["n_gaps"] == ref.size
    assert info["q_gap_median"] == pytest.approx(float(np.median(ref)), rel=1e-8)
    assert betas[0] < 1e-3 and betas[-1] > 1.0


def test_default_grid_on_the_bundled_corridor_with_the_paper_real_set():
    from expertise_irl.worlds.zones import load_bundled

    m = load_bundled("corridor").to_mdp()
    th = DiscreteOptions(thetas="paper-real", betas="paper-real").hypotheses(m.n_features).thetas
    betas, info = dx.auto_beta_grid([m], th)
    # Measured (and the plain solver above agrees on its subset): g ≈ 0.326 over 7,893 gaps.
    assert info["q_gap_median"] == pytest.approx(0.3257, rel=1e-3)
    assert info["n_gaps"] == 7893
    assert len(betas) == 16 and np.all(np.diff(betas) > 0)
    # The paper's low-expertise group (β = 5, 10) lies inside the default grid on this zone map.
    assert betas[-1] > 10


@pytest.mark.slow  # a 4,604-state plan at γ = 0.99: ~9 s with the solver's compilation
def test_default_grid_on_a_warehouse_plan_reaches_expert_temperatures():
    from importlib import resources

    from expertise_irl.worlds.warehouse import load_floor_plan

    plan = resources.files("expertise_irl.userstudy") / "example" / "spec-a.txt"
    m = load_floor_plan(plan).to_mdp()
    th = DiscreteOptions(thetas="paper-real", betas="paper-real").hypotheses(m.n_features).thetas
    betas, info = dx.auto_beta_grid([m], th)
    assert info["q_gap_median"] == pytest.approx(0.627, rel=1e-2)
    assert (betas < 0.1).sum() >= 6 and betas[0] < 1e-3
