"""Tests for inference/belief.py: the discrete-set posterior of Eq. 13 and its read-outs."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from reference_solver import soft_value_iteration

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import ArgumentError, InputError
from expertise_irl.hypotheses import (
    BETA_PRESETS,
    EXPERTISE_GROUPS,
    THETA_PRESETS,
    HypothesisSet,
    expertise_group,
    sample_thetas,
    theta_grid,
)
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.hypothesis_sets import sample_in_set_truth
from expertise_irl.planning.table_likelihood import pair_log_likelihoods
from expertise_irl.worlds.zones import load_bundled

EPS = float(np.finfo(np.float64).eps)

# Three preference directions x three temperatures (H = 9) on the 48-state corridor map.
THETAS = np.array([
    [0.4, 0.1, 0.3, 0.1, 0.1],
    [0.2, 0.2, 0.2, 0.2, 0.2],
    [0.7, 0.0, 0.3, 0.0, 0.0],
])
BETAS = [0.09, 0.5, 2.0]
TRUTH = (0, 1)  # (theta row, beta position) that generates the corridor data: h = 0 * 3 + 1


@pytest.fixture(scope="module")
def corridor():
    return load_bundled("corridor").to_mdp()


@pytest.fixture(scope="module")
def hyp():
    return HypothesisSet(THETAS, BETAS)


@pytest.fixture(scope="module")
def ref_log_policy(corridor, hyp):
    """[H, S, A] log-policies from the slow reference solver, indexed by the documented
    θ-major flattening h = i * n_beta + j (not by hyp.theta / hyp.beta)."""
    out = np.empty((len(hyp), corridor.n_states, corridor.n_actions))
    for i, theta in enumerate(THETAS):
        for j, beta in enumerate(BETAS):
            out[i * len(BETAS) + j] = soft_value_iteration(corridor, theta, beta).log_policy
    return out


@pytest.fixture(scope="module")
def trajs(corridor, ref_log_policy):
    """4 episodes of 12 actions (all truncated by max_steps) from the truth hypothesis."""
    h = TRUTH[0] * len(BETAS) + TRUTH[1]
    t = simulate(corridor, None, None, 4, np.random.default_rng(11), max_steps=12,
                 log_policy=ref_log_policy[h])
    assert t.n_episodes == 4 and len(t) == 48
    return t


@pytest.fixture(scope="module")
def prior(corridor, hyp):
    # tol far below the default so the solver's error (~1e-11 nats per pair) is negligible
    # next to the 1e-10 tolerance of the brute-force comparison.
    return DiscreteBelief.from_mdp(corridor, hyp, tol=1e-13)


def brute_force_posterior(log_policy, prior_w, trajs):
    """Eq. 13 literally: P(h | Ξ) ∝ P(h) Π_n π_h(a_n | s_n), in probability space."""
    w = np.array(prior_w, dtype=float)
    for h in range(w.size):
        for s, a in zip(trajs.state.tolist(), trajs.action.tolist(), strict=True):
            w[h] *= math.exp(log_policy[h, s, a])
    return w / w.sum()


def summation_tol(belief, trajs):
    """Bound on the difference between two float64 sums of the same pair log-likelihoods
    taken in a different order: |error| ≤ (N − 1)·eps·Σ|terms| per hypothesis (recursive
    summation bound). Per-action and per-trajectory updates differ only in summation order."""
    ll = pair_log_likelihoods(belief.log_policy, trajs.state, trajs.action)
    return len(trajs) * EPS * np.abs(ll).sum(axis=1)


def episodes_from(t: Trajectories, first: int) -> Trajectories:
    keep = t.episode >= first
    return Trajectories(t.episode[keep], t.step[keep], t.state[keep], t.action[keep])


def reorder_episodes(t: Trajectories, order) -> Trajectories:
    ids = t.episode_ids
    rows = np.concatenate([np.flatnonzero(t.episode == ids[i]) for i in order])
    return Trajectories(t.episode[rows], t.step[rows], t.state[rows], t.action[rows])


# ------------------------------------------------------------------------- Eq. 13
def test_posterior_matches_brute_force_eq13_uniform_prior(prior, ref_log_policy, trajs):
    post = prior.update(trajs)
    expected = brute_force_posterior(ref_log_policy, np.ones(9), trajs)
    assert post.n_observed == len(trajs)
    np.testing.assert_allclose(post.probabilities, expected, rtol=0, atol=1e-10)
    # Relative agreement even for the hypotheses the data all but rule out (down to ~1e-62
    # here): each pair's log π from solve(tol=1e-13) is within ~1e-12 nats of the reference,
    # so 48 pairs move a log-posterior by ≲ 1e-10. Measured: 2e-13 relative, 7e-15 absolute.
    assert np.all(expected > 0)
    np.testing.assert_allclose(post.probabilities, expected, rtol=1e-9, atol=0)
    # The data must actually discriminate, or the comparison above would be vacuous.
    assert expected.max() > 0.25 and expected.min() < 1e-40


def test_posterior_matches_brute_force_eq13_nonuniform_prior(corridor, hyp, ref_log_policy, trajs):
    w = np.random.default_rng(3).uniform(0.1, 5.0, size=len(hyp))
    post = DiscreteBelief.from_mdp(corridor, hyp, prior=w, tol=1e-13).update(trajs)
    np.testing.assert_allclose(post.probabilities, brute_force_posterior(ref_log_policy, w, trajs),
                               rtol=0, atol=1e-10)


def test_from_log_policy_is_exactly_eq13(hyp, ref_log_policy, trajs):
    """The belief's algebra alone (same log-policy table on both sides): rounding-level."""
    post = DiscreteBelief.from_log_policy(hyp, ref_log_policy).update(trajs)
    np.testing.assert_allclose(post.probabilities, brute_force_posterior(ref_log_policy, np.ones(9), trajs),
                               rtol=1e-12, atol=1e-15)


def test_from_mdp_rejects_feature_count_mismatch(corridor):
    with pytest.raises(InputError, match="features"):
        DiscreteBelief.from_mdp(corridor, HypothesisSet(np.eye(3), [1.0]))


def test_from_log_policy_rejects_bad_shape(hyp):
    with pytest.raises(ArgumentError, match="shape"):
        DiscreteBelief.from_log_policy(hyp, np.zeros((len(hyp) + 1, 4, 4)))
    with pytest.raises(ArgumentError, match="shape"):
        DiscreteBelief.from_log_policy(hyp, np.zeros((len(hyp), 4)))


# --------------------------------------------------- per-action = per-trajectory
def test_per_action_equals_per_trajectory(prior, trajs):
    tol = summation_tol(prior, trajs)
    by_traj = prior.update(trajs)
    by_action = prior.update(trajs, per_action=True)
    streamed = prior
    for s, a in zip(trajs.state.tolist(), trajs.action.tolist(), strict=True):
        streamed = streamed.update_action(s, a)
    one_batch = prior.update_pairs(trajs.state, trajs.action)
    manual = prior
    for states, actions in trajs.episodes():
        manual = manual.update_trajectory(states, actions)
    for other in (by_action, streamed, one_batch, manual):
        assert other.n_observed == by_traj.n_observed == len(trajs)
        assert np.all(np.abs(other.log_likelihood - by_traj.log_likelihood) <= tol)
        # |Δp| ≤ p·|Δ log p| ≤ 2·max tol (the normaliser moves by at most max tol).
        np.testing.assert_allclose(other.probabilities, by_traj.probabilities, rtol=0, atol=2 * tol.max())
    # The tolerance is tiny in absolute terms, so a mistake in either path cannot hide in it.
    assert tol.max() < 1e-10
    assert np.ptp(by_traj.log_likelihood) > 1.0


def test_episode_order_does_not_matter(prior, trajs):
    tol = summation_tol(prior, trajs)
    base = prior.update(trajs)
    for order in ([3, 2, 1, 0], [1, 3, 0, 2]):
        shuffled = reorder_episodes(trajs, order)
        assert shuffled.episode_ids.tolist() == [trajs.episode_ids[i] for i in order]
        for per_action in (False, True):
            other = prior.update(shuffled, per_action=per_action)
            assert np.all(np.abs(other.log_likelihood - base.log_likelihood) <= tol)


def test_updates_in_two_batches_equal_one(prior, trajs):
    rest = episodes_from(trajs, 2)
    two = prior.update(trajs.first(2)).update(rest)
    one = prior.update(trajs)
    assert two.n_observed == len(trajs)
    assert np.all(np.abs(two.log_likelihood - one.log_likelihood) <= summation_tol(prior, trajs))


def test_updates_return_new_beliefs(prior, trajs):
    post = prior.update(trajs)
    assert post is not prior
    assert prior.n_observed == 0 and np.all(prior.log_likelihood == 0)
    assert np.any(post.log_likelihood != 0)


def test_empty_update_is_identity(prior):
    b = prior.update_pairs([], [])
    assert b.n_observed == 0
    np.testing.assert_array_equal(b.log_likelihood, prior.log_likelihood)


# ------------------------------------------------------------------------- trace
def test_trace_endpoints_match_prior_and_batch_posterior(prior, trajs):
    h = TRUTH[0] * len(BETAS) + TRUTH[1]
    tr = prior.trace(trajs, truth=h)
    post = prior.update(trajs)
    n = len(trajs)
    assert tr.mean_beta.shape == (n + 1,) and tr.mean_theta.shape == (n + 1, 5)
    assert tr.entropy.shape == (n + 1,) and tr.truth_probability.shape == (n + 1,)
    # Index 0: the prior (uniform: mean of the betas, mean of the thetas, log H, 1/H).
    assert tr.mean_beta[0] == pytest.approx(np.mean(BETAS), abs=1e-14)
    np.testing.assert_allclose(tr.mean_theta[0], THETAS.mean(axis=0), atol=1e-14)
    assert tr.entropy[0] == pytest.approx(math.log(9), abs=1e-14)
    assert tr.truth_probability[0] == pytest.approx(1 / 9, abs=1e-15)
    # Last index: the batch posterior (cumsum vs per-trajectory sums: summation order only).
    tol = 2 * summation_tol(prior, trajs).max()
    assert tr.mean_beta[-1] == pytest.approx(post.mean_beta, abs=tol * max(BETAS))
    np.testing.assert_allclose(tr.mean_theta[-1], post.mean_theta, atol=tol)
    assert tr.entropy[-1] == pytest.approx(post.entropy, abs=1e-9)
    assert tr.truth_probability[-1] == pytest.approx(post.probabilities[h], abs=tol)


def test_trace_matches_streaming_at_every_step(prior, trajs):
    tr = prior.trace(trajs, truth=4)
    b = prior
    tol = 2 * summation_tol(prior, trajs).max()
    for i, (s, a) in enumerate(zip(trajs.state.tolist(), trajs.action.tolist(), strict=True), start=1):
        b = b.update_action(s, a)
        assert tr.mean_beta[i] == pytest.approx(b.mean_beta, abs=tol * max(BETAS))
        np.testing.assert_allclose(tr.mean_theta[i], b.mean_theta, atol=tol)
        assert tr.entropy[i] == pytest.approx(b.entropy, abs=1e-9)
        assert tr.truth_probability[i] == pytest.approx(b.probabilities[4], abs=tol)


def test_trace_blocking_does_not_change_result(prior, trajs):
    full = prior.trace(trajs, truth=2)
    # max_block // H = 3 pairs per block: many blocks, with a ragged last one.
    blocked = prior.trace(trajs, truth=2, max_block=3 * len(prior.hypotheses) + 1)
    for a, b in zip(full, blocked, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_trace_starts_from_current_belief_and_truth_column_nan_without_truth(prior, trajs):
    mid = prior.update(trajs.first(1))
    rest = episodes_from(trajs, 1)
    tr = mid.trace(rest)
    assert tr.mean_beta[0] == pytest.approx(mid.mean_beta, abs=1e-13)
    assert tr.entropy[0] == pytest.approx(mid.entropy, abs=1e-13)
    assert np.all(np.isnan(tr.truth_probability))
    final = prior.update(trajs)
    assert tr.entropy[-1] == pytest.approx(final.entropy, abs=1e-9)


# ------------------------------------------------------------------ read-outs
def test_marginals_means_map_entropy(prior, trajs):
    post = prior.update(trajs)
    p = post.probabilities
    assert p.sum() == pytest.approx(1.0, abs=1e-14)
    betas, pb = post.marginal_beta()
    thetas, pt = post.marginal_theta()
    np.testing.assert_array_equal(betas, BETAS)
    np.testing.assert_allclose(thetas, THETAS, atol=1e-15)
    assert pb.sum() == pytest.approx(1.0, abs=1e-14) and pt.sum() == pytest.approx(1.0, abs=1e-14)
    # Explicit marginalisation with the documented flattening h = i * n_beta + j.
    for j in range(3):
        assert pb[j] == pytest.approx(sum(p[i * 3 + j] for i in range(3)), abs=1e-15)
    for i in range(3):
        assert pt[i] == pytest.approx(sum(p[i * 3 + j] for j in range(3)), abs=1e-15)
    assert post.mean_beta == pytest.approx(float(np.dot(BETAS, pb)), abs=1e-14)
    np.testing.assert_allclose(post.mean_theta, pt @ THETAS, atol=1e-15)
    assert np.abs(post.mean_theta).sum() == pytest.approx(1.0, abs=1e-14)
    theta_map, beta_map, p_map = post.map_hypothesis()
    h = int(np.argmax(p))
    np.testing.assert_array_equal(theta_map, THETAS[h // 3])
    assert beta_map == BETAS[h % 3]
    assert p_map == pytest.approx(p.max(), abs=0)
    assert post.entropy == pytest.approx(-np.sum(p * np.log(p)), abs=1e-13)


def test_entropy_uniform_prior_is_log_h_and_decreases_with_data(prior, trajs):
    assert prior.entropy == pytest.approx(math.log(9), abs=1e-14)
    e1 = prior.update(trajs.first(1)).entropy
    e4 = prior.update(trajs).entropy
    # Measured (fixed data): log 9 = 2.197, e1 = 1.760, e4 = 1.434 — the 12-step episodes of
    # a β = 0.5 person are only mildly informative, but each step down is > 0.3 nats.
    assert e4 < e1 - 0.2
    assert e1 < math.log(9) - 0.2


def test_group_probabilities(corridor):
    hyp = HypothesisSet(THETAS[:2], BETA_PRESETS["paper-sim"])
    b = DiscreteBelief.from_mdp(corridor, hyp)
    g0 = b.group_probabilities()
    assert set(g0) == {"high", "medium", "low"}
    for group in g0:  # uniform prior: 2 of the 6 betas in each group
        assert g0[group] == pytest.approx(1 / 3, abs=1e-14)
    t = simulate(corridor, THETAS[0], 0.01, 3, np.random.default_rng(0), max_steps=30)
    post = b.update(t)
    g = post.group_probabilities()
    assert sum(g.values()) == pytest.approx(1.0, abs=1e-14)
    betas, pb = post.marginal_beta()
    for group, members in EXPERTISE_GROUPS.items():
        assert g[group] == pytest.approx(sum(q for bb, q in zip(betas, pb, strict=True) if bb in members),
                                         abs=1e-15)
    assert g["high"] > 0.99  # near-greedy demonstrations of β = 0.01


# ---------------------------------------------------------------------- priors
def test_zero_prior_stays_zero(corridor, hyp, ref_log_policy, trajs):
    h = TRUTH[0] * 3 + TRUTH[1]  # even the hypothesis that generated the data
    w = np.ones(9)
    w[h] = 0.0
    post = DiscreteBelief.from_mdp(corridor, hyp, prior=w, tol=1e-13).update(trajs)
    assert post.probabilities[h] == 0.0
    assert post.n_impossible == 0  # a zero prior is not an impossible action
    np.testing.assert_allclose(post.probabilities, brute_force_posterior(ref_log_policy, w, trajs),
                               rtol=0, atol=1e-10)
    assert post.trace(trajs, truth=h).truth_probability.max() == 0.0


def test_prior_scale_does_not_matter(hyp, ref_log_policy, trajs):
    w = np.arange(1.0, 10.0)
    a = DiscreteBelief.from_log_policy(hyp, ref_log_policy, prior=w).update(trajs)
    b = DiscreteBelief.from_log_policy(hyp, ref_log_policy, prior=1000 * w).update(trajs)
    np.testing.assert_allclose(a.probabilities, b.probabilities, rtol=1e-12)
    np.testing.assert_allclose(np.exp(a.log_prior), w / w.sum(), rtol=1e-14)


@pytest.mark.parametrize("bad", [
    np.ones(8),  # wrong length
    np.ones((9, 1)),  # wrong shape
    -np.ones(9),  # negative
    np.r_[np.ones(8), -0.5],
    np.r_[np.ones(8), np.nan],
    np.r_[np.ones(8), np.inf],
    np.zeros(9),  # no mass
])
def test_bad_prior_raises(hyp, ref_log_policy, bad):
    with pytest.raises(InputError, match="prior"):
        DiscreteBelief.from_log_policy(hyp, ref_log_policy, prior=bad)


# ------------------------------------------------------------ impossible actions
H4 = HypothesisSet(np.array([[1.0, 0.0], [0.0, 1.0]]), [0.5, 2.0])  # H = 4, h = i * 2 + j
# [H=4, S=3, A=2] hand-made log-policy table.
#   state 0: h0 (½, ½)  h1 (1, 0)  h2 (0, 1)  h3 (¼, ¾)
#   state 1: everyone (½, ½)
#   state 2: h0, h3 (0, 1); h1, h2 (1, 0)
with np.errstate(divide="ignore"):
    TABLE = np.log(np.array([
        [[0.5, 0.5], [0.5, 0.5], [0.0, 1.0]],
        [[1.0, 0.0], [0.5, 0.5], [1.0, 0.0]],
        [[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]],
        [[0.25, 0.75], [0.5, 0.5], [0.0, 1.0]],
    ]))


@pytest.fixture
def b4():
    return DiscreteBelief.from_log_policy(H4, TABLE)


def test_impossible_hypotheses_are_counted_and_zeroed(b4):
    assert b4.n_impossible == 0
    b = b4.update_action(0, 1)  # impossible under h1 only
    assert b.n_impossible == 1
    np.testing.assert_allclose(b.probabilities, np.array([0.5, 0.0, 1.0, 0.75]) / 2.25, rtol=1e-14)
    assert b.probabilities[1] == 0.0
    b = b.update_action(0, 0)  # now also impossible under h2
    assert b.n_impossible == 2
    np.testing.assert_allclose(b.probabilities, np.array([0.25, 0.0, 0.0, 0.1875]) / 0.4375, rtol=1e-14)
    b = b.update_action(1, 1)  # uninformative: nobody new dies, nobody revives
    assert b.n_impossible == 2 and b.probabilities[1] == 0.0 and b.probabilities[2] == 0.0
    assert np.isfinite(b.entropy) and b.entropy == pytest.approx(
        -sum(q * math.log(q) for q in (0.25 / 0.4375, 0.1875 / 0.4375)), abs=1e-14)
    # Read-outs ignore the dead hypotheses: β̂ over h0 (β=0.5) and h3 (β=2).
    assert b.mean_beta == pytest.approx((0.25 * 0.5 + 0.1875 * 2.0) / 0.4375, rel=1e-14)


def test_all_impossible_raises_naming_the_pair(b4):
    # Pair 0 kills h1, pair 1 kills h2, pair 2 kills h0 and h3: the update fails at pair 2.
    with pytest.raises(InputError, match=r"observed pair 2: action 0 in state 2 is impossible"):
        b4.update_pairs([0, 0, 2], [1, 0, 0])
    # Counted from the start of the stream, not the start of the batch.
    b = b4.update_action(1, 0).update_action(1, 1)
    with pytest.raises(InputError, match=r"observed pair 4: action 0 in state 2"):
        b.update_pairs([0, 0, 2], [1, 0, 0])
    with pytest.raises(InputError, match=r"observed pair 2:"):
        b4.update_action(0, 1).update_action(0, 0).update_action(2, 0)


def test_all_impossible_raises_naming_episode_and_step(b4):
    # Episode labels 10 and 11 (not 0, 1): the message must use the labels.
    t = Trajectories([10, 11, 11, 11], [0, 0, 1, 2], [0, 0, 2, 1], [1, 0, 0, 0])
    for per_action in (False, True):
        with pytest.raises(InputError, match=r"episode 11 step 1: action 0 in state 2 is impossible"):
            b4.update(t, per_action=per_action)
    with pytest.raises(InputError, match=r"episode 11 step 1: action 0 in state 2 is impossible"):
        b4.trace(t)
    with pytest.raises(InputError, match=r"episode 5 step 2:"):
        b4.update_trajectory([0, 0, 2], [1, 0, 0], episode=5)


def test_trace_with_impossible_actions(b4):
    t = Trajectories([0, 0, 0], [0, 1, 2], [0, 0, 1], [1, 0, 1])
    tr = b4.trace(t, truth=1)
    assert tr.truth_probability.tolist() == [0.25, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(tr.mean_beta[-1], b4.update(t).mean_beta, rtol=1e-14)
    assert np.all(np.isfinite(tr.entropy))


def test_zero_probability_hypotheses_emit_no_warning(b4):
    b = b4.update_action(0, 1)
    t = Trajectories([0], [0], [0], [1])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isfinite(b.entropy)
        assert np.all(np.isfinite(b4.trace(t).entropy))


@pytest.mark.parametrize(("states", "actions"), [
    ([3], [0]),  # state past the end (S = 3)
    ([-1], [0]),  # negative state
    ([0], [2]),  # action past the end (A = 2)
    ([0], [-1]),
    ([0, 1], [0]),  # lengths differ
    ([[0, 1]], [[0, 1]]),  # not 1-D
])
def test_bad_pairs_raise(b4, states, actions):
    with pytest.raises(InputError):
        b4.update_pairs(states, actions)


def test_out_of_range_raise_in_every_entry_point(b4):
    with pytest.raises(InputError, match="outside the MDP"):
        b4.update_action(5, 0)
    with pytest.raises(InputError, match="outside the MDP"):
        b4.update_trajectory([0, 1], [0, 7])
    t = Trajectories([0, 0], [0, 1], [0, 9], [0, 0])
    for per_action in (False, True):
        with pytest.raises(InputError):
            b4.update(t, per_action=per_action)
    with pytest.raises(InputError, match="outside the MDP"):
        b4.trace(t)


def test_per_action_out_of_range_message_says_out_of_range(b4):
    t = Trajectories([0, 0], [0, 1], [0, 9], [0, 0])
    with pytest.raises(InputError, match="outside the MDP"):
        b4.update(t, per_action=True)


@pytest.mark.parametrize("entry", ["update", "trace"])
def test_out_of_range_message_names_episode_and_step(b4, entry):
    # Episode 4 has 3 pairs; the bad pair is episode 5, step 0 (flat index 3).
    t = Trajectories([4, 4, 4, 5], [0, 1, 2, 0], [0, 1, 0, 9], [0, 0, 0, 0])
    with pytest.raises(InputError, match="episode 5 step 0"):
        b4.update(t) if entry == "update" else b4.trace(t)


# -------------------------------------------------------------------- recovery
GROUPS = ("high", "medium", "low")


@pytest.fixture(scope="module")
def crossroads():
    return load_bundled("crossroads").to_mdp()


def recovery_case(mdp, seed: int, group: str):
    """Paper protocol (Sec. VI-A), k = 10: Ψ_k = Θ_k × B_paper, truth uniform in Ψ_k within
    ``group``, 20 simulated episodes. Independent streams for set, truth and simulation."""
    set_seq, truth_seq, sim_seq = np.random.SeedSequence([seed, GROUPS.index(group)]).spawn(3)
    thetas = sample_thetas(theta_grid(THETA_PRESETS["paper-sim"], 5), 10, np.random.default_rng(set_seq))
    hyp = HypothesisSet(thetas, BETA_PRESETS["paper-sim"])
    theta, beta = sample_in_set_truth(hyp, group, np.random.default_rng(truth_seq))
    prior = DiscreteBelief.from_mdp(mdp, hyp)
    truth = hyp.index(theta, beta)
    trajs = simulate(mdp, theta, beta, 20, np.random.default_rng(sim_seq), log_policy=prior.log_policy[truth])
    post = prior.update(trajs)
    lp = post.log_posterior
    margin = lp[truth] - np.max(np.delete(lp, truth))  # log-likelihood ratio truth : best other
    return post, truth, margin


def test_recovery_seed0(crossroads):
    """One seeded run per expertise group (seed 0, taken as it came, not chosen).

    Measured for this seed (log-likelihood ratio truth : best other hypothesis, nats):
    high (β*=0.09) +25.3, medium (β*=0.5) +31.4, so the truth has the top probability
    (> 1 − 1e-10); the assertion asks for 5 nats. low (β*=5): ratio +0.7, P(truth) ≈ 0.48
    — not a margin to rely on (over 200 seeds the low-group truth is the MAP only ~33% of
    the time: the paper reports β = 5 and 10 are hard to tell apart from 20 episodes), so
    only the group is asserted; here P(low) = 1 − 5e-11. Rates over seeds are checked below.
    """
    for group in GROUPS:
        post, truth, margin = recovery_case(crossroads, 0, group)
        if group == "low":
            assert expertise_group(post.mean_beta) == "low"
            assert post.group_probabilities()["low"] > 0.99
        else:
            assert int(np.argmax(post.probabilities)) == truth, (group, margin)
            assert margin > 5.0, (group, margin)


@pytest.mark.slow
def test_recovery_rates_over_seeds(crossroads):
    """Seeds 1..20 per group. Over seeds 0..199 (measured with this protocol) the truth was
    the MAP in 89% of high-, 98% of medium- and 33% of low-expertise runs; the median
    log-likelihood ratio truth : best other was ~6 nats (high; 10% of runs ≤ 0) and ~21
    nats (medium; 10% of runs ≤ 2.6) — typically a few to a few tens of nats. High-group
    misses are mostly another θ with the same near-greedy paths (θ is identified only
    through the actions it makes optimal). The group was right in 600/600 runs, with
    P(group) ≥ 0.99996. (Seeds 1..20 themselves: 18, 19 and 9 hits.)

    Thresholds, so that a pass does not hinge on one random stream: with p = 0.89,
    P(X ≤ 13 of 20) ≈ 0.007; with p = 0.98, P(X ≤ 17 of 20) ≈ 0.007. A broken likelihood
    would give ~1/60 MAP hits and a wrong group in most runs.
    """
    hits = {g: 0 for g in GROUPS}
    for seed in range(1, 21):
        for group in GROUPS:
            post, truth, _ = recovery_case(crossroads, seed, group)
            assert expertise_group(post.mean_beta) == group, (seed, group, post.mean_beta)
            assert post.group_probabilities()[group] > 0.99, (seed, group)
            hits[group] += int(np.argmax(post.probabilities)) == truth
    assert hits["high"] >= 14, hits
    assert hits["medium"] >= 18, hits
