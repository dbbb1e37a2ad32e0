"""The two goal-reward protocols: ``scaled`` (the bonus is part of ``length``) and ``fixed`` (a
reward outside θ·φ). One reward function serves the solver, the likelihood, the simulator and
the gym; the protocols differ exactly where the issue says they must."""

from __future__ import annotations

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from reference_solver import soft_value_iteration

from expertise_irl.demos.simulation import capped_flags, simulate
from expertise_irl.errors import InputError
from expertise_irl.gym import ZoneEnv
from expertise_irl.hypotheses import THETA_PRESETS, theta_grid
from expertise_irl.inference.task_likelihood import pair_counts
from expertise_irl.mdp import TabularMDP
from expertise_irl.planning.differentiable import make_log_likelihood
from expertise_irl.planning.soft_vi import solve
from expertise_irl.planning.table_likelihood import log_likelihood
from expertise_irl.worlds.maps import load_world
from expertise_irl.worlds.warehouse import parse_floor_plan
from expertise_irl.worlds.zones import bundled_maps, load_bundled, parse_map

THETA = np.array([0.4, 0.2, 0.2, 0.1, 0.1])


def fixed(zone_map):
    return dataclasses.replace(zone_map, goal_reward_mode="fixed")


@pytest.fixture(scope="module")
def crossroads():
    z = load_bundled("crossroads")
    return z.to_mdp(), fixed(z).to_mdp()


# ------------------------------------------------------------------------ the reward itself
def test_fixed_mode_moves_the_bonus_out_of_length(crossroads):
    scaled, fix = crossroads
    enters_goal = (scaled.next_state >= 0) & scaled.terminal[np.maximum(scaled.next_state, 0)]
    assert enters_goal.any()
    assert not scaled.has_offset and fix.has_offset
    # scaled: length = −1 + 10 on entering the goal; fixed: length = −1 everywhere, +10 outside θ·φ
    np.testing.assert_array_equal(scaled.features[..., 0][enters_goal], 9.0)
    np.testing.assert_array_equal(fix.features[..., 0][fix.available], -1.0)
    np.testing.assert_array_equal(fix.reward_offset[enters_goal], 10.0)
    assert np.all(fix.reward_offset[~enters_goal] == 0.0)
    np.testing.assert_array_equal(fix.features[..., 1:], scaled.features[..., 1:])
    # at θ_length = 1 (and nothing else) both protocols pay the same
    one = np.array([1.0, 0, 0, 0, 0])
    np.testing.assert_allclose(np.where(fix.available, fix.reward(one), 0),
                               np.where(scaled.available, scaled.reward(one), 0))


def test_soft_vi_matches_the_reference_solver_under_fixed(crossroads):
    _, fix = crossroads
    for beta in (0.09, 1.0):
        sol = solve(fix, THETA, beta, tol=1e-12)
        ref = soft_value_iteration(fix, THETA, beta)
        np.testing.assert_allclose(sol.value[0], ref.value, rtol=1e-8, atol=1e-8 * beta)
        ok = fix.available
        np.testing.assert_allclose(sol.log_policy[0][ok], ref.log_policy[ok], atol=1e-7)


def test_likelihood_and_simulator_use_the_same_reward(crossroads):
    _, fix = crossroads
    beta = 0.3
    sol = solve(fix, THETA, beta, tol=1e-12)
    # the simulator solving for itself walks exactly as it does from the solver's policy
    a = simulate(fix, THETA, beta, 5, np.random.default_rng(4))
    b = simulate(fix, None, None, 5, np.random.default_rng(4), log_policy=sol.log_policy[0])
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.action, b.action)
    f = make_log_likelihood(fix, pair_counts(fix, a), tol=1e-12)
    ref = log_likelihood(sol.log_policy, a.state, a.action)[0]
    assert float(f(jnp.asarray(THETA), beta)[0]) == pytest.approx(ref, rel=1e-9)


def test_gradient_under_fixed_matches_finite_differences(crossroads):
    _, fix = crossroads
    trajs = simulate(fix, THETA, 0.5, 6, np.random.default_rng(0))
    f = make_log_likelihood(fix, pair_counts(fix, trajs), tol=1e-12)
    theta, beta = np.array([0.3, 0.3, 0.2, 0.1, 0.1]), 0.6
    g_theta, g_beta = jax.grad(lambda t, b: f(t, b)[0], argnums=(0, 1))(jnp.asarray(theta), beta)
    h = 1e-5  # central differences: O(h²) truncation, rounding ≈ eps·|L|/h, as in test_gradient
    for k in (0, 1):
        e = np.zeros_like(theta)
        e[k] = h
        fd = (float(f(theta + e, beta)[0]) - float(f(theta - e, beta)[0])) / (2 * h)
        assert float(g_theta[k]) == pytest.approx(fd, rel=1e-6, abs=1e-5)
    fd_beta = (float(f(theta, beta + h)[0]) - float(f(theta, beta - h)[0])) / (2 * h)
    assert float(g_beta) == pytest.approx(fd_beta, rel=1e-6, abs=1e-5)
    # the fixed reward breaks the θ/β ridge: scaling (θ, β) together now moves L
    assert abs(float(g_theta @ theta + g_beta * beta)) > 1e-3


def test_scaling_theta_and_beta_together_changes_the_policy_only_under_fixed(crossroads):
    scaled, fix = crossroads
    c = 3.0
    for mdp, changes in ((scaled, False), (fix, True)):
        lp = solve(mdp, np.stack([THETA, c * THETA]), [0.4, c * 0.4], tol=1e-12).log_policy
        diff = np.abs(lp[0][mdp.available] - lp[1][mdp.available]).max()
        assert (diff > 1e-3) == changes, (mdp.has_offset, diff)
        if not changes:
            assert diff < 1e-8


def test_gym_pays_the_fixed_reward(crossroads):
    _, fix = crossroads
    env = ZoneEnv(fixed(load_bundled("crossroads")), theta=THETA)
    s, a = np.argwhere(fix.available & fix.terminal[np.maximum(fix.next_state, 0)])[0]
    env.reset(seed=0, options={"start": int(s)})  # next to the goal
    _, reward, terminated, _, _ = env.step(int(a))
    assert terminated
    assert reward == pytest.approx(float(fix.reward(THETA)[s, a]))
    assert reward == pytest.approx(float(THETA @ fix.features[s, a]) + 10.0)


# ------------------------------------------------------------------------ who finishes
def _capped_share(mdp, thetas, beta, seed, episodes) -> float:
    sol = solve(mdp, thetas, np.full(len(thetas), beta))
    rng = np.random.default_rng(seed)
    walks = (simulate(mdp, None, None, episodes, rng, max_steps=500, log_policy=lp) for lp in sol.log_policy)
    flags = [capped_flags(tr, mdp, 500) for tr in walks]
    return float(np.concatenate(flags).mean())


@pytest.mark.slow
@pytest.mark.parametrize("name", bundled_maps())
@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow)])
def test_experts_finish_under_fixed_and_wander_under_scaled(name, seed):
    """High expertise (β ∈ {0.01, 0.09}): under ``fixed`` ≥ 95% of episodes reach the goal within
    500 steps on every bundled zone map, for every θ of the ``paper-sim`` grid with θ_length = 0
    (579 people, 2 episodes each, the hardest case: nothing but the goal reward pulls them there)
    and for as many drawn from the rest; under ``scaled`` the θ_length = 0 people are paid nothing
    to finish and wander to the cap (≥ 95% capped). A few θ_length = 0 people who value roads
    highly circle along one-way roads for their reward on ``zones30`` (≈ 2% of those episodes).
    """
    zone_map = load_bundled(name)
    grid = theta_grid(THETA_PRESETS["paper-sim"], 5)
    rng = np.random.default_rng(seed)
    zero = grid[grid[:, 0] == 0]
    some = grid[grid[:, 0] > 0]
    thetas = np.vstack([zero, some[rng.choice(len(some), len(zero), replace=False)]])
    for beta in (0.01, 0.09):
        assert _capped_share(fixed(zone_map).to_mdp(), thetas, beta, seed, 2) <= 0.05
        assert _capped_share(zone_map.to_mdp(), zero[::10], beta, seed, 2) >= 0.95


# ------------------------------------------------------------------------ files and errors
def test_map_toml_sets_the_mode(tmp_path):
    text = "S.G\n...\n"
    (tmp_path / "m.txt").write_text(text)
    (tmp_path / "m.toml").write_text('goal_reward_mode = "fixed"\ngoal_bonus = 4.0\n')
    m = load_world(tmp_path / "m.txt")
    assert m.goal_reward_mode == "fixed"
    assert m.to_mdp().reward_offset.max() == 4.0
    (tmp_path / "m.toml").write_text('goal_reward_mode = "always"\n')
    with pytest.raises(InputError, match=r"m\.toml: goal_reward_mode must be one of scaled, fixed"):
        load_world(tmp_path / "m.txt")
    with pytest.raises(InputError, match="goal_reward_mode must be one of"):
        parse_map(text, goal_reward_mode="sometimes")


def test_floor_plan_pays_the_fixed_reward_on_both_headings():
    plan = parse_floor_plan("S..G\n", goal_reward_mode="fixed", goal_bonus=5.0)
    mdp = plan.to_mdp()
    enters = np.argwhere(mdp.reward_offset != 0)
    assert len(enters) == 2  # the move right into G from either heading of the cell beside it
    assert set(mdp.state_heading[enters[:, 0]].tolist()) == {0, 1}
    assert np.all(mdp.reward_offset[mdp.reward_offset != 0] == 5.0)
    assert 'goal_reward_mode = "fixed"' in plan.settings_text()


def test_archive_keeps_the_offset(tmp_path, crossroads):
    _, fix = crossroads
    fix.save(tmp_path / "m.npz")
    back = TabularMDP.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(back.reward_offset, fix.reward_offset)
    bad = dict(np.load(tmp_path / "m.npz"))
    bad["reward_offset"] = bad["reward_offset"][:3]
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(InputError, match=r"bad\.npz: reward_offset must have shape \[S, A\]"):
        TabularMDP.load(tmp_path / "bad.npz")


# ------------------------------------------------------------------------ the command line
@pytest.mark.slow
def test_goal_reward_option_reaches_archive_simulation_and_result(tmp_path):
    npz = tmp_path / "fixed.npz"
    ok(invoke("export-mdp", "corridor", "--out", npz, "--goal-reward", "fixed"))
    mdp = TabularMDP.load(npz)
    want = fixed(load_bundled("corridor")).to_mdp()
    np.testing.assert_array_equal(mdp.reward_offset, want.reward_offset)
    demos = tmp_path / "d.csv"
    ok(invoke("simulate", "corridor", "--goal-reward", "fixed", "--theta", "0,1,0,0,0", "--beta", "0.05",
              "--episodes", "3", "--out", demos))
    out = tmp_path / "r.json"
    ok(invoke("infer", "corridor", "--goal-reward", "fixed", "--demos", demos, "--out", out,
              "--thetas", "paper-real", "--betas", "paper-real"))
    doc = json.loads(out.read_text())
    assert doc["settings"]["goal_reward_mode"] == "fixed"
    # the same walks read under the archive that holds the offset give the same posterior
    out2 = tmp_path / "r2.json"
    ok(invoke("infer", "--mdp", npz, "--demos", demos, "--out", out2, "--thetas", "paper-real",
              "--betas", "paper-real"))
    doc2 = json.loads(out2.read_text())
    assert doc2["settings"]["goal_reward_mode"] == "fixed"
    assert doc2["beta_hat"] == pytest.approx(doc["beta_hat"], rel=1e-9)


def test_goal_reward_option_errors(tmp_path):
    corridor_npz = tmp_path / "corridor.npz"
    load_bundled("corridor").to_mdp().save(corridor_npz)
    assert_input_error(invoke("export-mdp", "corridor", "--out", tmp_path / "m.npz", "--goal-reward", "both"),
                       "--goal-reward: goal_reward_mode must be one of scaled, fixed, got 'both'")
    assert_input_error(invoke("simulate", "--mdp", corridor_npz, "--goal-reward", "fixed", "--theta",
                              "1,0,0,0,0", "--beta", "1", "--out", tmp_path / "d.csv"),
                       "--goal-reward applies to a MAP")


@pytest.mark.slow
def test_study_rows_record_the_protocol():
    from expertise_irl.experiments.studies.fixed_vs_joint import SCALES, run_task, tasks

    for mode in ("scaled", "fixed"):
        cfg = dataclasses.replace(SCALES["smoke"], goal_reward_mode=mode)
        cols, _ = run_task(cfg, 0, tasks(cfg)[0].params)
        assert set(cols["goal_reward_mode"]) == {mode}
        regret = cols["random_theta_regret"]
        assert np.all(np.isfinite(regret)) and np.all(regret >= 0)
        # one guess per person: constant over their rows, different between people
        person = [tuple(x) for x in zip(cols["group"], cols["truth"], strict=True)]
        for p in set(person):
            assert len(set(regret[[q == p for q in person]])) == 1
    with pytest.raises(InputError, match="goal_reward_mode must be one of scaled, fixed"):
        dataclasses.replace(SCALES["smoke"], goal_reward_mode="both")


def test_a_user_study_keeps_the_floor_plans_goal_reward():
    """A study's engine rebuilds each map from the study data: the protocol travels too."""
    from expertise_irl.userstudy.study import _plan_mdp, world_entry
    from expertise_irl.worlds.zones import parse_map

    plan = parse_floor_plan("S..G\n.x..\n", name="p", goal_reward_mode="fixed", goal_bonus=3.0)
    zone = parse_map("S..G\n.x..\n", name="z", goal_reward_mode="fixed", goal_bonus=3.0)
    for world in (plan, zone):
        text = json.dumps({"maps": {"k": world_entry(world)}})
        rebuilt, mdp = _plan_mdp(text, "k")
        assert type(rebuilt) is type(world) and rebuilt.goal_reward_mode == "fixed"
        np.testing.assert_array_equal(mdp.reward_offset, world.to_mdp().reward_offset)


def test_demo_names_a_fixed_goal_reward_apart(tmp_path):
    from expertise_irl.experiments.demo import demo_outputs

    scaled = demo_outputs(tmp_path, 0, "crossroads")
    fixed_ = demo_outputs(tmp_path, 0, "crossroads", goal_reward_mode="fixed")
    names = ["demo-crossroads-seed0-fixed.png", "result-crossroads-seed0-fixed.json"]
    assert [p.name for p in fixed_] == names
    assert not set(scaled) & set(fixed_)
