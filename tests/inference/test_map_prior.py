"""MAP's prior in its own coordinates, θ's concentration, and the Laplace approximation."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats
from scipy.optimize import minimize_scalar

from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.inference import laplace
from expertise_irl.inference.diagnostics import map_warnings
from expertise_irl.inference.methods import MAPOptions, NUTSOptions, get_method
from expertise_irl.inference.priors import (
    BETA_PRIOR_MEAN,
    BETA_PRIOR_SD,
    LOG_UNIFORM_RANGE,
    concentration_of,
    log_prior_jax,
    log_prior_unconstrained,
    prior_text,
    unconstrained_from_density,
)
from expertise_irl.worlds.zones import load_bundled


# ----------------------------------------------------------------------------- the density in (z, b)
def test_log_uniform_is_flat_in_log_beta():
    """The Jacobian of b = log β cancels p(β) ∝ 1/β: no b inside the range is preferred, so the
    mode in b is the likelihood's (the density of β itself would put it at the lower edge)."""
    g = log_prior_unconstrained("log-uniform", 1.0)
    z = jnp.zeros(5)
    lo, hi = (math.log(v) for v in LOG_UNIFORM_RANGE)
    values = [float(g(z, b)) for b in np.linspace(lo, hi, 7)]
    assert max(values) - min(values) < 1e-12
    assert float(g(z, hi + 1e-3)) == -math.inf and float(g(z, lo - 1e-3)) == -math.inf
    dens = log_prior_jax("log-uniform", 1.0)  # on (θ, β): decreasing in β
    assert float(dens(jnp.ones(5) / 5, 0.01)) > float(dens(jnp.ones(5) / 5, 1.0))


def test_paper_prior_mode_in_log_beta():
    """Normal(μ, σ) in β times the Jacobian β has its mode where β² − μβ − σ² = 0."""
    g = log_prior_unconstrained("paper")
    res = minimize_scalar(lambda b: -float(g(jnp.zeros(3), b)), bounds=(math.log(0.011), math.log(9.9)),
                          method="bounded", options={"xatol": 1e-10})
    mu, sd = BETA_PRIOR_MEAN, BETA_PRIOR_SD
    assert math.exp(res.x) == pytest.approx((mu + math.sqrt(mu**2 + 4 * sd**2)) / 2, rel=1e-6)


@pytest.mark.parametrize("alpha", [0.5, 1.0, 2.0])
def test_theta_part_is_log_gamma_coordinates(alpha):
    """z_i = log g_i, g_i ~ Gamma(α): the density of z is Σ log Gamma(e^{z_i}; α) + z_i, whose
    push-forward through the softmax is Dirichlet(α)."""
    g = log_prior_unconstrained("log-uniform", alpha)
    rng = np.random.default_rng(0)
    zs = rng.normal(size=(4, 5))
    ref = [stats.gamma(alpha).logpdf(np.exp(z)).sum() + z.sum() for z in zs]
    got = [float(g(jnp.asarray(z), 0.0)) for z in zs]
    np.testing.assert_allclose(np.diff(got), np.diff(ref), rtol=1e-10, atol=1e-10)


def test_mode_in_z_maximises_theta_to_the_alpha():
    """Maximised over z's free scale (z + c), the density in z is α·Σ log θ_i plus a constant:
    the mode in z maximises L·∏θ_i^α whatever the scale z starts at."""
    alpha, K = 2.0, 4
    g = log_prior_unconstrained("log-uniform", alpha)
    rng = np.random.default_rng(1)
    profiles = []
    for _ in range(3):
        z = rng.normal(size=K)
        best = minimize_scalar(lambda c, z=z: -float(g(jnp.asarray(z + c), 0.0)))
        theta = np.exp(z) / np.exp(z).sum()
        profiles.append(-best.fun - alpha * np.log(theta).sum())
    assert np.ptp(profiles) < 1e-8
    assert profiles[0] == pytest.approx(K * alpha * math.log(K * alpha) - K * alpha, abs=1e-8)


def test_a_given_density_is_written_in_z_like_the_named_one():
    """A caller's density on (θ, β) in (z, b): for a Dirichlet(1) θ and p(β) ∝ 1/β it is the
    named log-uniform prior's at α = 1, up to a constant."""
    mine = unconstrained_from_density(log_prior_jax("log-uniform", 1.0))
    named = log_prior_unconstrained("log-uniform", 1.0)
    rng = np.random.default_rng(2)
    diffs = [float(mine(jnp.asarray(z), b) - named(jnp.asarray(z), b))
             for z, b in zip(rng.normal(size=(4, 5)), rng.uniform(-3, 3, 4), strict=True)]
    assert np.ptp(diffs) < 1e-10


def test_concentration_is_checked_and_stated():
    assert concentration_of("paper") == 1.0
    with pytest.raises(InputError, match=r"^concentration must be a finite number > 0"):
        MAPOptions(concentration=0.0)
    with pytest.raises(InputError, match=r"^concentration"):
        NUTSOptions(concentration=float("nan"))
    assert "Dirichlet(2)" in prior_text("log-uniform", 2.0)
    assert "log β uniform on [0.001, 100]" in prior_text("log-uniform", 2.0)


# ----------------------------------------------------------------------------- Laplace
def test_laplace_of_a_gaussian_is_exact():
    """For a Gaussian in (z, b) the Laplace interval of β is exp(b̂ ± 1.645 sd) exactly, and θ's
    quantiles come from draws: 4,000 draws put the 5% quantile within ~0.01 of the truth (its
    standard error is √(0.05·0.95/4000)/density ≈ 0.003 here)."""
    x = np.array([0.0, 0.5, -0.5, math.log(0.3)])
    H = np.diag([4.0, 4.0, 4.0, 25.0])
    out = laplace.laplace_summary(x, H, np.zeros(4), LOG_UNIFORM_RANGE, np.random.default_rng(0))
    assert out["positive_definite"] and out["edge"] == 0 and out["ridge"] is None
    lo, hi = out["credible_intervals"]["beta"]
    assert lo == pytest.approx(0.3 * math.exp(-laplace.Z90 * 0.2), rel=1e-12)
    assert hi == pytest.approx(0.3 * math.exp(laplace.Z90 * 0.2), rel=1e-12)
    z = np.random.default_rng(1).normal(x[:3], 0.5, size=(200_000, 3))
    ref = np.quantile(np.exp(z) / np.exp(z).sum(axis=1, keepdims=True), [0.05, 0.95], axis=0).T
    np.testing.assert_allclose(out["credible_intervals"]["theta"], ref, atol=0.01)


def test_a_flat_direction_is_a_ridge_and_warned():
    """Curvature 0.01 along log β: its 90% interval spans a factor e^(2·1.645·10), far past 10."""
    x = np.array([0.0, 0.0, 0.0, math.log(0.3)])
    H = np.diag([4.0, 4.0, 4.0, 0.01])
    out = laplace.laplace_summary(x, H, np.zeros(4), LOG_UNIFORM_RANGE, np.random.default_rng(0))
    assert out["ridge"] is not None and out["ridge"]["curvature"] == pytest.approx(0.01)
    assert any("flat ridge" in w for w in map_warnings({"optima": [0.0]}, 0.3, LOG_UNIFORM_RANGE, out))
    saddle = laplace.laplace_summary(x, np.diag([4.0, 4.0, -1.0, 1.0]), np.zeros(4), LOG_UNIFORM_RANGE,
                                     np.random.default_rng(0))
    assert not saddle["positive_definite"]
    assert any("not positive definite" in w
               for w in map_warnings({"optima": [0.0]}, 0.3, LOG_UNIFORM_RANGE, saddle))


def test_hessian_by_differences_of_the_gradient():
    """f(x) = xᵀAx/2 − cos x_0: gradient Ax + (sin x_0, 0), Hessian A + diag(cos x_0, 0); central
    differences of the gradient err by ~h²/6 ≈ 2e-9 at h = 1e-4."""
    A = np.array([[3.0, 1.0], [1.0, 2.0]])
    H = laplace.hessian(lambda x: A @ x + np.array([np.sin(x[0]), 0.0]), np.array([0.3, -1.0]))
    np.testing.assert_allclose(H, A + np.diag([np.cos(0.3), 0.0]), atol=1e-7)


@pytest.fixture(scope="module")
def crossroads():
    return load_bundled("crossroads").to_mdp()


@pytest.mark.slow
def test_an_expert_at_the_prior_edge_is_warned_with_a_one_sided_interval(crossroads):
    """Five short episodes of an expert (β* = 0.05, θ* from a Dirichlet) in which every action is
    optimal for some θ: the likelihood rises all the way to β's lower bound. MAP stops there, says
    so, and reports a Laplace interval that starts at the bound."""
    rng = np.random.default_rng([0, 0, 0])
    theta = rng.dirichlet(np.ones(5))
    trajs = simulate(crossroads, theta, 0.05, 5, rng)
    run = get_method("map").run(crossroads, trajs, MAPOptions(), 0)
    f = run.fields
    assert f["beta_hat"] == pytest.approx(LOG_UNIFORM_RANGE[0], rel=1e-6)
    assert any("lower edge of the prior's range" in w for w in f["diagnostics"]["warnings"])
    assert f["diagnostics"]["laplace"]["edge"] == -1 and "Laplace" in f["diagnostics"]["intervals"]
    lo, hi = f["credible_intervals"]["beta"]
    assert lo == pytest.approx(LOG_UNIFORM_RANGE[0], rel=1e-6) and 0.05 < hi
    assert len(f["credible_intervals"]["theta"]) == 5
    assert run.settings["concentration"] == concentration_of("log-uniform")


def test_a_medium_person_is_read_with_an_interval_that_holds_the_truth(crossroads):
    """β* = 0.5, θ* from a Dirichlet, 5 episodes (2,500 actions): no edge, no warning about one,
    and β* inside the Laplace 90% interval (a 10% miss chance for a calibrated interval; this
    seed's interval is [0.36, 0.85], β̂ 0.55)."""
    rng = np.random.default_rng([0, 1, 1])
    theta = rng.dirichlet(np.ones(5))
    trajs = simulate(crossroads, theta, 0.5, 5, rng)
    f = get_method("map").run(crossroads, trajs, MAPOptions(), 0).fields
    assert not any("edge" in w for w in f["diagnostics"]["warnings"])
    lo, hi = f["credible_intervals"]["beta"]
    assert lo < 0.5 < hi and lo < f["beta_hat"] < hi
