"""Several tasks per person: the joint posterior over one hypothesis set is the product over tasks."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import HypothesisSet, resolve_betas, resolve_thetas
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.multitask import MultiTaskBelief
from expertise_irl.worlds.warehouse import parse_floor_plan
from expertise_irl.worlds.zones import parse_map

# Two specifications of one floor (same features, different roads and restricted cells) and a
# second floor of another size: three MDPs with the warehouse features.
PLAN_A = "S>>>v\n.#..v\n.xx.v\n....G\n"
PLAN_B = "S...v\n.#xxv\n^...v\n^<<<G\n"
PLAN_C = "S..#..G\n.>>>>>^\n.x.....\n"


@pytest.fixture(scope="module")
def hyp():
    return HypothesisSet(resolve_thetas("paper-real", 3), resolve_betas("paper-real"))


@pytest.fixture(scope="module")
def tasks():
    rng = np.random.default_rng(7)
    out = []
    for text in (PLAN_A, PLAN_B, PLAN_C):
        mdp = parse_floor_plan(text).to_mdp()
        out.append((mdp, simulate(mdp, [0.5, 0.2, 0.3], 0.5, 3, rng, max_steps=60, model="maxent-relative")))
    return out


def test_joint_posterior_is_the_normalised_product_of_the_per_task_posteriors(hyp, tasks):
    multi = MultiTaskBelief.from_tasks(tasks, hyp, model="maxent-relative")
    singles = [DiscreteBelief.from_mdp(m, hyp, model="maxent-relative").update(t) for m, t in tasks]
    product = np.prod([b.probabilities for b in singles], axis=0)
    joint = multi.joint()
    np.testing.assert_allclose(joint.probabilities, product / product.sum(), rtol=1e-9, atol=1e-300)
    # The point estimates and evidence follow from that posterior and the summed likelihood.
    np.testing.assert_allclose(joint.log_likelihood, np.sum([b.log_likelihood for b in singles], axis=0))
    assert joint.n_observed == sum(len(t) for _, t in tasks)
    assert joint.mean_beta == pytest.approx(float(hyp.beta @ (product / product.sum())), rel=1e-12)
    # A posterior concentrated by three tasks differs from every single task's (the test has teeth).
    for b in singles:
        assert np.abs(b.probabilities - joint.probabilities).max() > 1e-3


def test_one_mdp_twice_equals_one_belief_on_all_the_trajectories(hyp, tasks):
    mdp, trajs = tasks[0]
    half = trajs.episode_ids[1]
    first = Trajectories(*(a[trajs.episode < half] for a in (trajs.episode, trajs.step, trajs.state,
                                                               trajs.action)))
    rest = Trajectories(*(a[trajs.episode >= half] for a in (trajs.episode, trajs.step, trajs.state,
                                                              trajs.action)))
    multi = MultiTaskBelief.from_tasks([(mdp, first), (mdp, rest)], hyp, model="maxent-relative")
    single = DiscreteBelief.from_mdp(mdp, hyp, model="maxent-relative").update(trajs)
    np.testing.assert_allclose(multi.joint().log_posterior, single.log_posterior, atol=1e-9)


def test_a_prior_counts_once_not_once_per_task(hyp, tasks):
    prior = np.linspace(1.0, 3.0, len(hyp))
    multi = MultiTaskBelief.from_tasks(tasks[:2], hyp, prior=prior, model="maxent-relative")
    singles = [DiscreteBelief.from_mdp(m, hyp, prior=prior, model="maxent-relative").update(t)
               for m, t in tasks[:2]]
    expected = singles[0].probabilities * singles[1].probabilities / prior
    np.testing.assert_allclose(multi.joint().probabilities, expected / expected.sum(), rtol=1e-9)


def test_update_of_one_task_moves_the_joint_posterior(hyp, tasks):
    (ma, ta), (mb, tb) = tasks[:2]
    empty = MultiTaskBelief.from_tasks([(ma, ta), (mb, None)], hyp, model="maxent-relative")
    full = MultiTaskBelief.from_tasks([(ma, ta), (mb, tb)], hyp, model="maxent-relative")
    np.testing.assert_allclose(empty.update(1, tb).joint().log_posterior, full.joint().log_posterior,
                               atol=1e-12)
    with pytest.raises(InputError, match="task 2: there are 2 tasks"):
        empty.update(2, tb)


def test_tasks_must_share_features_and_hypotheses(hyp, tasks):
    zones = parse_map("S..\n...\n..G\n").to_mdp()  # five zone features, not the warehouse's three
    with pytest.raises(InputError, match=r"task 1: features .* differ from task 0's"):
        MultiTaskBelief.from_tasks([tasks[0], (zones, None)], hyp)
    mdp = tasks[0][0]
    a = DiscreteBelief.from_mdp(mdp, hyp)
    other = HypothesisSet(hyp.thetas, [0.1, 1.0])
    b = DiscreteBelief.from_mdp(mdp, other)
    with pytest.raises(InputError, match="task 1: its hypothesis set differs"):
        MultiTaskBelief((a, b))
