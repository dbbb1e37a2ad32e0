"""Active start choice: the Monte Carlo expected information gain against exact enumeration,
determinism for a seed, and the known answer on a hand-built map."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference.active import expected_information_gain, next_start
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.online import OnlineEstimator
from expertise_irl.worlds.zones import parse_map

# Row 3 holds a dead end below the goal: from (3, 3) the only move is up, into the goal, so an
# episode started there is the same under every hypothesis and tells nothing.
MAP = """\
.......
..xx...
..#G#..
..#.#..
..###..
"""


@pytest.fixture(scope="module")
def world():
    zm = parse_map(MAP, name="dead-end")
    mdp = zm.to_mdp()
    thetas = theta_grid((0.0, 0.5, 1.0), 5)
    thetas = thetas[thetas[:, 0] > 0][::4]  # a length weight, so β changes behaviour
    hyp = HypothesisSet(thetas, BETA_PRESETS["paper-sim"])
    est = OnlineEstimator.from_mdp(mdp, hyp)
    idx = zm.state_index()
    return mdp, hyp, est, idx


def _entropy(logw):
    lp = logw - np.logaddexp.reduce(logw)
    p = np.exp(lp)
    return float(-np.sum(p[p > 0] * lp[p > 0]))


def exact_gain(belief: DiscreteBelief, mdp, start: int, steps: int) -> float:
    """Σ_τ Σ_h P(h) P(τ | h) [H(now) − H(after τ)] over every episode τ of at most ``steps`` actions."""
    log_post = belief.log_posterior
    now = _entropy(log_post)
    total = 0.0

    def walk(s, ll, t):
        nonlocal total
        if t == steps or mdp.terminal[s]:
            logw = log_post + ll
            p_tau = np.exp(np.logaddexp.reduce(logw))  # Σ_h P(h) P(τ | h)
            total += p_tau * (now - _entropy(logw))
            return
        for a in np.flatnonzero(mdp.next_state[s] >= 0):
            walk(int(mdp.next_state[s, a]), ll + belief.log_policy[:, s, a], t + 1)

    walk(start, np.zeros(len(log_post)), 0)
    return total


@pytest.mark.slow
def test_monte_carlo_gain_matches_exact_enumeration(world):
    mdp, _, est, idx = world
    on = OnlineEstimator.from_belief(mdp, est.belief())
    on.observe(int(idx[0, 6]), 2)  # a non-uniform posterior to draw hypotheses from
    on.observe(int(idx[0, 5]), 2)
    belief = on.belief()
    starts = [int(idx[0, 0]), int(idx[1, 5]), int(idx[3, 3])]
    r = expected_information_gain(on, starts, n_samples=3000, max_steps=4, rng=1)
    for c, g, se in zip(r.candidates, r.gain, r.stderr, strict=True):
        exact = exact_gain(belief, mdp, int(c), 4)
        # 4.5 standard errors: a false alarm has probability ~1e-5 per candidate.
        assert abs(g - exact) <= 4.5 * se + 1e-12, (int(c), g, exact, se)
    assert r.entropy == pytest.approx(belief.entropy)


def test_deterministic_for_a_seed(world):
    mdp, _, est, _ = world
    a = expected_information_gain(est.belief(), None, mdp, rng=7, max_candidates=8)
    b = expected_information_gain(est, rng=np.random.default_rng(7), max_candidates=8)
    np.testing.assert_array_equal(a.candidates, b.candidates)
    np.testing.assert_array_equal(a.gain, b.gain)
    assert a.best == b.best == next_start(est, rng=7, max_candidates=8)
    c = expected_information_gain(est, rng=8, max_candidates=8)
    assert not np.array_equal(c.gain, a.gain) or not np.array_equal(c.candidates, a.candidates)
    assert a.n_offered == int((~mdp.terminal).sum())


def test_beats_the_uninformative_dead_end(world):
    _mdp, _, est, idx = world
    dead_end, corner = int(idx[3, 3]), int(idx[0, 0])
    for target in ("joint", "beta"):
        r = expected_information_gain(est, [dead_end, corner], target=target, rng=0)
        gain = dict(zip(r.candidates.tolist(), r.gain.tolist(), strict=True))
        assert gain[dead_end] == pytest.approx(0.0, abs=1e-12)
        assert gain[corner] > 0.1
        assert r.best == corner
        assert next_start(est, [corner, dead_end], target=target, rng=0) == corner


def test_bad_arguments(world):
    mdp, _, est, _idx = world
    goal = int(np.flatnonzero(mdp.terminal)[0])
    with pytest.raises(InputError, match="terminal"):
        next_start(est, [goal])
    with pytest.raises(InputError, match="not a state index"):
        next_start(est, [mdp.n_states])
    with pytest.raises(InputError, match="needs the MDP"):
        next_start(est.belief(), [0])
    with pytest.raises(InputError, match="target"):
        next_start(est, [0], target="theta")
    with pytest.raises(InputError, match="n_samples"):
        next_start(est, [0], n_samples=0)
