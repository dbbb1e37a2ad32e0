"""A simulated teacher (demos.simulation.simulate_teacher): the teaching policy of inference.pedagogical,
walked like any other policy."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate, simulate_batches, simulate_teacher
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import HypothesisSet, theta_grid
from expertise_irl.inference import pedagogical as P
from expertise_irl.numerics import enable_float64
from expertise_irl.worlds.maps import resolve_world

THETA = np.array([0.4, 0.3, 0.1, 0.1, 0.1])


@pytest.fixture(scope="module")
def task():
    enable_float64()
    mdp = resolve_world("crossroads").to_mdp()
    hyp = HypothesisSet(theta_grid((0.0, 1.0), mdp.n_features), np.array([0.1, 1.0]))
    return mdp, hyp, P.solved_observer(mdp, hyp)


def test_a_teacher_walks_the_teaching_policy(task):
    """Episode for episode the walk of :func:`teacher_log_policy` (one rng), whether the observer is
    given solved or as its set; λ = 0 is the maxent person of :func:`simulate`."""
    mdp, hyp, obs = task
    lp = P.teacher_log_policy(mdp, THETA, 0.2, 0.5, obs)
    want = simulate(mdp, None, None, 6, np.random.default_rng(4), log_policy=lp, max_steps=60)
    for observer in (obs, hyp):
        got = simulate_teacher(mdp, THETA, 0.2, 0.5, 6, np.random.default_rng(4), observer=observer,
                               max_steps=60)
        np.testing.assert_array_equal(got.action, want.action)
        np.testing.assert_array_equal(got.state, want.state)
    doer = simulate_teacher(mdp, THETA, 0.2, 0.0, 6, np.random.default_rng(4), observer=obs, max_steps=60)
    maxent = simulate(mdp, THETA, 0.2, 6, np.random.default_rng(4), max_steps=60)
    np.testing.assert_array_equal(doer.action, maxent.action)
    assert not np.array_equal(got.action, maxent.action)  # teaching changes the walk


def test_batches_take_a_given_policy(task):
    mdp, _, obs = task
    lp = P.teacher_log_policy(mdp, THETA, 0.2, 0.5, obs)
    (one,) = simulate_batches(mdp, None, None, 5, np.random.default_rng(1), max_steps=40, log_policy=lp)
    want = simulate(mdp, None, None, 5, np.random.default_rng(1), max_steps=40, log_policy=lp)
    np.testing.assert_array_equal(one.action, want.action)


def test_a_negative_teaching_weight_is_refused(task):
    mdp, _, obs = task
    with pytest.raises(InputError, match="lambda must be a number from 0 to 1000"):
        simulate_teacher(mdp, THETA, 0.2, -0.1, 1, 0, observer=obs)
