"""OnlineEstimator: equal to the batch discrete posterior after every action; episodes, undo,
save/restore; refuses what the demonstration format refuses."""

from __future__ import annotations

import json

import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import validate
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.online import OnlineEstimator, OnlineSnapshot
from expertise_irl.worlds.zones import load_bundled

# Rounding: both sides sum the same float64 log-probabilities, in a different order
# (sequential here, pairwise in numpy's batch sum); over a few hundred pairs of magnitude
# <= 50 nats the difference stays far below 1e-9.
TOL = 1e-9


@pytest.fixture(scope="module")
def setup():
    mdp = load_bundled("crossroads").to_mdp()
    thetas = theta_grid((0.0, 0.5, 1.0), 5)[::12]  # 20 directions spread over the grid
    hyp = HypothesisSet(thetas, BETA_PRESETS["paper-sim"])
    calls = []
    est = OnlineEstimator.from_mdp(mdp, hyp, progress=lambda d, t: calls.append((d, t)))
    trajs = simulate(mdp, np.array([0.6, 0.2, 0.2, 0.0, 0.0]), 0.5, 4, np.random.default_rng(3),
                     max_steps=60)
    return mdp, hyp, est, trajs, calls


def fresh(setup) -> OnlineEstimator:
    mdp, hyp, est, _, _ = setup
    return OnlineEstimator(mdp, hyp, est.belief().log_policy)


def assert_matches(r, b: DiscreteBelief) -> None:
    _betas, pb = b.marginal_beta()
    np.testing.assert_allclose(r.beta_probabilities, pb, atol=TOL)
    assert r.beta_hat == pytest.approx(b.mean_beta, abs=TOL)
    np.testing.assert_allclose(r.theta_hat, b.mean_theta, atol=TOL)
    assert r.entropy == pytest.approx(b.entropy, abs=TOL)
    for g, p in b.group_probabilities().items():
        assert r.group_probabilities[g] == pytest.approx(p, abs=TOL)
    th, be, pm = b.map_hypothesis()
    np.testing.assert_array_equal(r.map_theta, th)
    assert r.map_beta == be and r.map_probability == pytest.approx(pm, abs=TOL)
    assert r.n_observed == b.n_observed


def test_solve_reports_progress_and_prior_is_uniform(setup):
    _, hyp, _est, _, calls = setup
    assert calls and calls[-1] == (len(hyp), len(hyp))
    r = fresh(setup).estimate
    assert r.entropy == pytest.approx(np.log(len(hyp)))
    np.testing.assert_allclose(r.beta_probabilities, 1 / hyp.n_beta)


def test_equals_batch_posterior_after_every_action(setup):
    mdp, hyp, est, trajs, _ = setup
    on = fresh(setup)
    prior = DiscreteBelief.from_log_policy(hyp, est.belief().log_policy)
    trace = prior.trace(trajs)
    i = 0
    for states, actions in trajs.episodes():
        for s, a in zip(states.tolist(), actions.tolist(), strict=True):
            r = on.observe(s, a)
            i += 1
            batch = prior.update_pairs(trajs.state[:i], trajs.action[:i])  # all pairs so far at once
            assert_matches(r, batch)
            assert r.beta_hat == pytest.approx(trace.mean_beta[i], abs=TOL)
        on.end_episode()
    assert i == len(trajs) > 50
    assert on.estimate.entropy < np.log(len(hyp)) - 1  # the data did move the belief
    t = on.trajectories()
    for k in ("episode", "step", "state", "action"):
        np.testing.assert_array_equal(getattr(t, k), getattr(trajs, k))
    validate(t, mdp)


def test_episodes_end_at_goal_and_continuity_is_checked(setup):
    mdp, _, _, trajs, _ = setup
    on = fresh(setup)
    states, actions = trajs.episodes()[0]
    assert mdp.terminal[mdp.next_state[states[-1], actions[-1]]]  # this episode reached the goal
    on.observe(states[0], actions[0])
    assert on.episode_open and on.current_state == states[1]
    with pytest.raises(InputError, match="does not follow the last action"):
        on.observe(states[0], actions[0])
    for s, a in zip(states[1:], actions[1:], strict=True):
        on.observe(s, a)
    assert not on.episode_open and on.current_state is None
    on.observe(states[0], actions[0])  # a new episode, labelled 1, step 0
    t = on.trajectories()
    assert t.episode[-1] == 1 and t.step[-1] == 0 and t.n_episodes == 2


def test_refuses_bad_pairs_without_changing_anything(setup):
    mdp, _, _, _, _ = setup
    on = fresh(setup)
    before = on.estimate
    wall = np.argwhere(mdp.next_state < 0)[0]
    goal = int(np.flatnonzero(mdp.terminal)[0])
    for s, a, msg in ((-1, 0, "out of range"), (0, 7, "out of range"), (goal, 0, "terminal"),
                      (int(wall[0]), int(wall[1]), "not available")):
        with pytest.raises(InputError, match=msg):
            on.observe(s, a)
    assert on.n_observed == 0 and on.estimate is before


def test_impossible_under_every_hypothesis_is_refused(setup):
    mdp, hyp, est, _, _ = setup
    lp = est.belief().log_policy.copy()
    s = int(np.flatnonzero(~mdp.terminal & ((mdp.next_state >= 0).sum(axis=1) >= 2))[0])
    a, other = np.flatnonzero(mdp.next_state[s] >= 0)[:2]
    lp[:, s, :] = -np.inf
    lp[:, s, other] = 0.0  # every hypothesis takes `other` in s for sure
    on = OnlineEstimator(mdp, hyp, lp)
    with pytest.raises(InputError, match="impossible under every hypothesis"):
        on.observe(s, a)
    assert on.n_observed == 0


def test_undo_round_trips(setup):
    _, _, _, trajs, _ = setup
    on = fresh(setup)
    states, actions = max(trajs.episodes(), key=lambda e: len(e[0]))
    assert len(states) > 10
    history = [on.estimate]
    for s, a in zip(states[:10].tolist(), actions[:10].tolist(), strict=True):
        history.append(on.observe(s, a))
    for k in range(10, 0, -1):
        r = on.undo()
        ref = history[k - 1]
        assert r.n_observed == ref.n_observed == k - 1
        assert r.beta_hat == pytest.approx(ref.beta_hat, abs=TOL)
        assert r.entropy == pytest.approx(ref.entropy, abs=TOL)
        np.testing.assert_allclose(r.theta_hat, ref.theta_hat, atol=TOL)
        # The episode stays open where the removed action began (none is open once it is empty).
        assert on.current_state == (int(states[k - 1]) if k > 1 else None)
    with pytest.raises(InputError, match="nothing to undo"):
        on.undo()
    on.observe(states[0], actions[0])
    assert on.trajectories().episode.tolist() == [0]


def test_snapshot_restore_round_trips_through_json(setup):
    _, _, _, trajs, _ = setup
    on = fresh(setup)
    on.feed(trajs.first(2))
    states, actions = trajs.episodes()[2]
    on.observe(states[0], actions[0])
    on.observe(states[1], actions[1])  # episode 2 is open mid-way
    snap = on.snapshot()
    doc = json.loads(json.dumps(snap.to_dict()))
    expected = on.estimate
    other = fresh(setup)
    r = other.restore(OnlineSnapshot.from_dict(doc))
    assert r.beta_hat == pytest.approx(expected.beta_hat, abs=TOL)
    assert r.entropy == pytest.approx(expected.entropy, abs=TOL)
    np.testing.assert_allclose(other.log_likelihood, on.log_likelihood, atol=TOL)
    assert other.current_state == on.current_state == states[2]
    other.observe(states[2], actions[2])  # continues the open episode
    assert other.trajectories().step[-1] == 2
    # The restored estimator is independent of the one the snapshot came from.
    on.undo()
    assert other.n_observed == on.n_observed + 2


def test_restore_refuses_a_snapshot_of_another_size(setup):
    on = fresh(setup)
    snap = on.snapshot()
    bad = OnlineSnapshot(snap.episode, snap.step, snap.state, snap.action, False,
                         snap.n_hypotheses + 1, snap.n_states, snap.n_actions)
    with pytest.raises(InputError, match="snapshot is of"):
        on.restore(bad)
    with pytest.raises(InputError, match="snapshot must be"):
        OnlineSnapshot.from_dict({"episode": []})


def test_feed_keeps_labels_and_leaves_a_cut_episode_open(setup):
    _mdp, _, _, trajs, _ = setup
    cut = trajs.first(2)
    keep = np.ones(len(cut), dtype=bool)
    keep[-3:] = False  # the second episode loses its last three actions
    from expertise_irl.demos.trajectories import Trajectories

    part = Trajectories(cut.episode[keep] + 5, cut.step[keep], cut.state[keep], cut.action[keep])
    on = fresh(setup)
    on.feed(part)
    assert on.episode_open
    assert on.current_state == int(cut.state[keep.sum()])
    assert on.trajectories().episode.tolist() == part.episode.tolist()


def test_observe_is_fast(setup):
    """Per action: a gather and a log-sum-exp over H = 120 hypotheses (generous bound for CI)."""
    import time

    _, _, _, trajs, _ = setup
    on = fresh(setup)
    states, actions = trajs.episodes()[0]
    t0 = time.perf_counter()
    for s, a in zip(states.tolist(), actions.tolist(), strict=True):
        on.observe(s, a)
    per = (time.perf_counter() - t0) / len(states)
    assert per < 1e-3, f"{per * 1e6:.0f} µs per action"


def test_built_from_mdp_and_set_directly_with_progress(setup, capsys):
    mdp, hyp, est, _, _ = setup
    calls = []
    direct = OnlineEstimator(mdp, hyp, progress=lambda d, t: calls.append(d))
    assert calls[-1] == len(hyp)
    np.testing.assert_allclose(direct.belief().log_policy, est.belief().log_policy)
    OnlineEstimator(mdp, hyp, progress=True)
    assert "hypotheses" in capsys.readouterr().err  # the bar went to stderr
    with pytest.raises(InputError, match="only when log_policy is not given"):
        OnlineEstimator(mdp, hyp, est.belief().log_policy, progress=True)


def test_estimate_speaks_the_belief_names_and_saves_to_a_file(setup, tmp_path):
    trajs = setup[3]
    on = fresh(setup)
    on.feed(trajs.first(1))
    r = on.estimate
    b = on.belief()
    assert r.mean_beta == r.beta_hat and r.mean_theta is r.theta_hat
    assert r.group_probabilities() == r.group_probabilities == pytest.approx(b.group_probabilities())
    assert r.map_hypothesis()[1] == b.map_hypothesis()[1]
    assert r.expertise_group in ("high", "medium", "low")
    json.dumps(r.to_dict(["a", "b", "c", "d", "e"]))
    on.save(tmp_path / "snap.json")
    other = fresh(setup)
    assert other.restore(tmp_path / "snap.json").beta_hat == pytest.approx(r.beta_hat, abs=TOL)
    assert other.restore(on.snapshot().to_dict()).n_observed == on.n_observed
    with pytest.raises(InputError, match="no such snapshot"):
        other.restore(tmp_path / "missing.json")
