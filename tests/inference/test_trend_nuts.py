"""NUTS on the learning curve log β_e = log β_0 + λ·e/(E−1) (inference/trend.py: nuts_trend)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.inference.methods import get_method
from expertise_irl.inference.priors import LOG_UNIFORM_RANGE
from expertise_irl.inference.trend import (
    fit_trend_nuts,
    map_trend,
    nuts_trend,
    trend_objective,
    trend_posterior,
)
from expertise_irl.worlds.maps import load_bundled_world

THETA_STAR = np.array([0.5, 0.25, 0.25, 0.0, 0.0])
MODEL = "maxent-relative"


@pytest.fixture(scope="module")
def mdp():
    return load_bundled_world("crossroads").to_mdp()


def learner(mdp, betas, seed):
    """One simulated episode per β, labelled 0, 1, … in that order."""
    rng = np.random.default_rng(seed)
    parts = [simulate(mdp, THETA_STAR, b, 1, rng, model=MODEL) for b in betas]
    episode = np.concatenate([np.full(len(t), e) for e, t in enumerate(parts)])
    return Trajectories(episode, *(np.concatenate([getattr(t, k) for t in parts])
                                   for k in ("step", "state", "action")))


@pytest.fixture(scope="module")
def falling(mdp):
    # β falls geometrically 2 → 0.05 over 7 episodes: λ = log(0.05/2) ≈ −3.7.
    return learner(mdp, list(np.geomspace(2.0, 0.05, 7)), seed=11)


@pytest.mark.slow
def test_potential_is_negative_log_posterior_plus_jacobian(mdp, falling):
    post, g = trend_posterior(mdp, falling, model=MODEL)
    K = mdp.n_features
    assert post.dim == K + 1 and len(g) == 7
    x = jnp.asarray([0.3, -0.7, 0.2, 0.9, -0.4, -1.1])  # (u [K−1], u_b, λ)
    u, u_b, slope = x[:K - 1], x[K - 1], x[K]
    theta, b_slope = post.constrained(x)
    # By hand: log β_0 = lo + (hi − lo)·σ(u_b); λ = x[K]; θ on the simplex.
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)
    sig = 1 / (1 + math.exp(-float(u_b)))
    log_beta0 = lo + (hi - lo) * sig
    assert float(b_slope[0]) == pytest.approx(log_beta0, rel=1e-12)
    assert float(b_slope[1]) == float(slope)
    assert float(theta.sum()) == pytest.approx(1.0) and np.all(np.asarray(theta) > 0)
    # Jacobians: θ's free coordinates θ_{1:K−1} as a function of u (autodiff, not numpyro's
    # formula), and the interval's (hi − lo)·σ(1 − σ); λ's is 1.
    jac = jax.jacfwd(lambda v: post.constrained(jnp.concatenate([v, x[K - 1:]]))[0][:K - 1])(u)
    log_jac = math.log(abs(float(jnp.linalg.det(jac)))) + math.log((hi - lo) * sig * (1 - sig))
    f, _ = trend_objective(mdp, falling, tol=1e-8, model=MODEL)
    ll, lp = f(theta, log_beta0, float(slope))
    assert float(lp) == pytest.approx(-float(slope) ** 2 / 8)
    expected = -(float(ll) + float(lp) + log_jac)
    assert float(post.potential(x, jnp.zeros(()), np.zeros(()))) == pytest.approx(expected, rel=1e-9)


@pytest.mark.slow
def test_short_run_on_a_falling_learner(mdp, falling):
    E, K = 7, mdp.n_features
    r = nuts_trend(mdp, falling, num_warmup=100, num_samples=100, num_chains=2, seed=0, model=MODEL)
    assert r.theta.shape == (2, 100, K)
    assert r.log_beta0.shape == r.slope.shape == (2, 100)
    assert r.betas.shape == (2, 100, E)
    np.testing.assert_allclose(r.theta.sum(axis=-1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.log(r.betas[..., -1]) - np.log(r.betas[..., 0]), r.slope, atol=1e-9)
    for d in (r.r_hat, r.ess):
        assert set(d) == {"slope", "log_beta0", "theta"} and len(d["theta"]) == K
        assert all(v is None or math.isfinite(v) for v in [d["slope"], d["log_beta0"], *d["theta"]])
    assert r.ess["slope"] > 0
    p_falls = float(np.mean(r.slope < 0))
    assert p_falls > 0.5
    # The MAP is the posterior's mode, the test compares the posterior *mean* of λ with it. With
    # 7 one-episode β's the slope's posterior is wide (sd ≈ 0.8 in this run) and skewed towards
    # zero by the prior Normal(0, 2) (mean −3.26 vs mode −3.72 here), and 200 correlated draws
    # add Monte-Carlo error of ≈ sd/√ESS ≈ 0.07. A tolerance of 1.5 (≈ 2 posterior sd, well
    # under |λ*| ≈ 3.7) leaves room for the skew and the noise yet catches a wrong density (a
    # missing Jacobian or prior, or a sign error in λ would move the mean by more or flip it).
    m = map_trend(mdp, falling, n_starts=2, rng=np.random.default_rng(0), model=MODEL, tol=1e-8)
    sd = float(r.slope.std())
    print(f"NUTS slope mean {r.slope.mean():.3f} sd {sd:.3f}; MAP slope {m.slope:.3f}; "
          f"p_falls {p_falls:.3f}; r_hat {r.r_hat}; ess {r.ess}; divergences {r.divergences}")
    assert abs(float(r.slope.mean()) - m.slope) < 1.5

    opts = get_method("nuts").options_from({"chains": 2, "warmup": 30, "samples": 30, "model": MODEL})
    out = fit_trend_nuts(mdp, falling, opts, 1)
    assert set(out) == {"theta_hat", "beta_hat", "expertise_by_episode", "trend", "diagnostics"}
    assert len(out["theta_hat"]) == K and math.isfinite(out["beta_hat"]) and out["beta_hat"] > 0
    assert [row["episode"] for row in out["expertise_by_episode"]] == list(range(E))
    for row in out["expertise_by_episode"]:
        assert 0 < row["q05"] <= row["median"] <= row["q95"] and math.isfinite(row["mean"])
    t = out["trend"]
    assert t["slope_q05"] <= t["slope"] <= t["slope_q95"] and t["log_ratio_mean"] == t["slope"]
    assert 0 <= t["p_falls"] <= 1 and t["beta0"] > 0
    d = out["diagnostics"]
    assert d["chains"] == 2 and d["draws_per_chain"] == 30 and isinstance(d["warnings"], list)
    assert {"r_hat", "ess_bulk", "divergences", "unavailable"} <= set(d)
