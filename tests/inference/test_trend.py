"""The parametric learning curve log β_e = log β_0 + λ·e/(E−1) (inference/trend.py)."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import spearmanr

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.inference.methods import get_method
from expertise_irl.inference.priors import concentration_of
from expertise_irl.inference.task_likelihood import tasks_log_likelihood
from expertise_irl.inference.trend import (
    episode_grid,
    fit_trend,
    log_prior_trend,
    map_trend,
    split_episodes,
    trend_objective,
)
from expertise_irl.worlds.maps import load_bundled_world

THETA_STAR = np.array([0.5, 0.25, 0.25, 0.0, 0.0])
MODEL = "maxent-relative"


@pytest.fixture(scope="module")
def mdp():
    return load_bundled_world("crossroads").to_mdp()


def learner(mdp, betas, seed, labels=None):
    """One simulated episode per β, relabelled 0, 1, … (or ``labels``) in that order."""
    rng = np.random.default_rng(seed)
    parts = [simulate(mdp, THETA_STAR, b, 1, rng, model=MODEL) for b in betas]
    labels = list(range(len(betas))) if labels is None else labels
    episode = np.concatenate([np.full(len(t), lab) for lab, t in zip(labels, parts, strict=True)])
    return Trajectories(episode, *(np.concatenate([getattr(t, k) for t in parts])
                                   for k in ("step", "state", "action")))


@pytest.fixture(scope="module")
def demo(mdp):
    # Labels out of sorted order: the episodes' order is the order given, not the labels'.
    return learner(mdp, [1.5, 0.7, 0.3, 0.2], seed=3, labels=[7, 2, 9, 4])


def test_grid_and_split(demo):
    assert episode_grid(1).tolist() == [0.0]
    assert episode_grid(4).tolist() == [0.0, 1 / 3, 2 / 3, 1.0]
    eps = split_episodes(demo)
    assert [int(t.episode[0]) for t in eps] == [7, 2, 9, 4]
    assert sum(len(t) for t in eps) == len(demo)


def test_objective_is_sum_of_episode_likelihoods_plus_prior(mdp, demo):
    f, _ = trend_objective(mdp, demo, model=MODEL)
    theta = np.array([0.3, 0.1, 0.4, 0.15, 0.05])
    beta0, beta_last = 1.2, 0.15
    slope = math.log(beta_last / beta0)
    ll, lp = f(jnp.asarray(theta), math.log(beta0), slope)
    # Independently: β_e interpolates geometrically between β_0 and β_last over E = 4 episodes.
    expected = 0.0
    for e, t in enumerate(split_episodes(demo)):
        beta_e = beta0 * (beta_last / beta0) ** (e / 3)
        expected += float(tasks_log_likelihood(mdp, t, model=MODEL)(theta, beta_e)[0])
    assert float(ll) == pytest.approx(expected, rel=1e-10)
    assert float(lp) == pytest.approx(-slope**2 / 8, rel=1e-12)  # λ ~ Normal(0, 2)
    # The prior's support is log β_0 in [log 1e-3, log 1e2]; λ is unbounded.
    assert float(log_prior_trend(math.log(1e-3) - 1e-6, 0.0)) == -math.inf
    assert float(log_prior_trend(math.log(1e2) + 1e-6, 0.0)) == -math.inf
    assert float(log_prior_trend(math.log(1e2), -30.0)) == pytest.approx(-30.0**2 / 8)


def test_zero_slope_is_the_one_beta_likelihood(mdp, demo):
    f, _ = trend_objective(mdp, demo, model=MODEL)
    theta = np.array([0.2, 0.2, 0.2, 0.2, 0.2])
    for beta in (0.05, 0.4, 3.0):
        ll, lp = f(jnp.asarray(theta), math.log(beta), 0.0)
        one = float(tasks_log_likelihood(mdp, demo, model=MODEL)(theta, beta)[0])
        assert float(ll) == pytest.approx(one, rel=1e-11)
        assert float(lp) == 0.0


def test_gradient_matches_finite_differences(mdp, demo):
    f, _ = trend_objective(mdp, demo, model=MODEL)
    K = mdp.n_features

    def obj(x):
        ll, lp = f(jax.nn.softmax(x[:K]), x[K], x[K + 1])
        return ll + lp

    x = jnp.asarray([0.3, -0.2, 0.5, -1.0, 0.1, math.log(0.8), -1.3])
    grad = np.asarray(jax.jit(jax.grad(obj))(x))
    value = jax.jit(obj)
    h = 1e-5
    fd = np.array([(float(value(x.at[i].add(h))) - float(value(x.at[i].add(-h)))) / (2 * h)
                   for i in range(x.size)])
    assert np.all(np.abs(grad[K:]) > 1e-2)  # β_0 and λ matter at this point
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-5)


@pytest.mark.slow
def test_fit_trend_dict(mdp, demo):
    opts = get_method("map").options_from({"starts": 2, "model": MODEL})
    out = fit_trend(mdp, demo, opts, seed=0)
    assert set(out) == {"theta_hat", "beta_hat", "expertise_by_episode", "trend", "diagnostics"}
    assert set(out["trend"]) == {"beta0", "slope", "g", "prior", "log_ratio_mean"}
    assert {"warnings", "optima"} <= set(out["diagnostics"])
    rows = out["expertise_by_episode"]
    assert [r["episode"] for r in rows] == [7, 2, 9, 4]
    assert all(r["q05"] is None and r["q95"] is None and r["mean"] == r["median"] for r in rows)
    t = out["trend"]
    betas = [r["mean"] for r in rows]
    assert betas[0] == pytest.approx(t["beta0"], rel=1e-12)
    assert betas[-1] == pytest.approx(t["beta0"] * math.exp(t["slope"]), rel=1e-12)
    assert t["log_ratio_mean"] == t["slope"]
    assert out["beta_hat"] == pytest.approx(t["beta0"] * math.exp(t["slope"] / 2), rel=1e-12)
    assert sum(out["theta_hat"]) == pytest.approx(1.0)
    # The reported optimum is the objective's value there: log-likelihood, the (log β_0, λ) prior and
    # θ's Dirichlet(α) written in z, which at its optimal scale is α·Σ log θ_i + Kα·log(Kα) − Kα.
    f, _ = trend_objective(mdp, demo, model=MODEL)
    ll, lp = f(jnp.asarray(out["theta_hat"]), math.log(t["beta0"]), t["slope"])
    a, K = concentration_of("log-uniform"), len(out["theta_hat"])
    theta_part = a * np.log(out["theta_hat"]).sum() + K * a * math.log(K * a) - K * a
    assert max(out["diagnostics"]["optima"]) == pytest.approx(float(ll + lp) + theta_part, abs=1e-6)
    with pytest.raises(InputError):
        fit_trend(mdp, demo, get_method("map").options_from({"prior": "paper"}), seed=0)


# Simulated learner: β falls log-linearly from 2 to 0.05 over 12 episodes (λ* = log 0.025 ≈ −3.69).
# Tolerance, measured (n_starts=2, seeds 0–7, crossroads, maxent-relative): λ̂ − λ* = +0.48, −0.43,
# −0.13, −0.25, +0.77, +0.20, +1.26, −1.01 (sd ≈ 0.7); a steady β = 0.3 gave λ̂ = +0.16, +1.19, −0.01,
# +0.11, +1.46, −0.63, −0.69, −0.51. So |error| < 2 (≈ 3 sd, above every measured one) for both;
# still far below the 3.69 that separates the learner from a steady person, so a wrong g
# (reversed, or a slope that does nothing) fails either test.
SLOPE_TOL = 2.0
E = 12
TRUE_BETAS = np.exp(np.linspace(math.log(2.0), math.log(0.05), E))
TRUE_SLOPE = math.log(0.05 / 2.0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_learner_recovered(mdp, seed):
    trajs = learner(mdp, TRUE_BETAS, seed)
    r = map_trend(mdp, trajs, n_starts=2, rng=np.random.default_rng(seed), model=MODEL)
    assert r.slope < 0
    assert spearmanr(r.betas, TRUE_BETAS).statistic == pytest.approx(1.0)
    assert abs(r.slope - TRUE_SLOPE) < SLOPE_TOL
    assert np.allclose(r.betas, r.beta0 * np.exp(r.slope * episode_grid(E)))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_steady_person_has_small_slope(mdp, seed):
    trajs = learner(mdp, np.full(E, 0.3), seed)
    r = map_trend(mdp, trajs, n_starts=2, rng=np.random.default_rng(seed), model=MODEL)
    assert abs(r.slope) < SLOPE_TOL


@pytest.mark.slow
def test_several_tasks_make_one_curve_in_the_tasks_order(mdp, demo):
    """Two tasks (two maps with the same features): their episodes are one curve, the first task's
    in turn and then the second's, g(e) running over all six; each episode's likelihood is taken
    on its own task's map."""
    from expertise_irl.inference.trend import episode_tasks

    other = dataclasses.replace(load_bundled_world("crossroads"), goal_reward_mode="fixed").to_mdp()
    second = learner(other, [0.2, 0.1], seed=5, labels=[3, 1])
    f, g = trend_objective([mdp, other], [demo, second], model=MODEL)
    assert g.tolist() == pytest.approx([e / 5 for e in range(6)])
    labels = [lab for _, _, lab in episode_tasks([mdp, other], [demo, second])]
    assert labels == [{"episode": k, "task": t, "task_episode": e}
                      for k, (t, e) in enumerate([(0, 7), (0, 2), (0, 9), (0, 4), (1, 3), (1, 1)])]
    theta = np.array([0.3, 0.1, 0.4, 0.15, 0.05])
    beta0, slope = 1.1, -2.0
    ll, _ = f(jnp.asarray(theta), math.log(beta0), slope)
    expected = 0.0
    for e, (m, t) in enumerate([(mdp, t) for t in split_episodes(demo)]
                               + [(other, t) for t in split_episodes(second)]):
        expected += float(tasks_log_likelihood(m, t, model=MODEL)(theta, beta0 * math.exp(slope * e / 5))[0])
    assert float(ll) == pytest.approx(expected, rel=1e-10)
    opts = get_method("map").options_from({"starts": 1, "model": MODEL})
    out = fit_trend([mdp, other], [demo, second], opts, seed=0)
    rows = out["expertise_by_episode"]
    assert [{k: r[k] for k in ("episode", "task", "task_episode")} for r in rows] == labels
    with pytest.raises(InputError, match="one list of trajectories per MDP"):
        trend_objective([mdp, other], [demo])
