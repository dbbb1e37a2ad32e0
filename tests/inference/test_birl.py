"""Tests for inference/birl.py: Extended BIRL (Algorithm 1), box and simplex variants.

The sampler is checked against an exact target: on a 4-state, 3-feature MDP every lattice
point is enumerated, its posterior computed with the slow reference solver, and the
chain's means compared within Monte-Carlo error (batch means, see ``_z``).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from reference_solver import soft_value_iteration

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.inference.birl import extended_birl, paper_log_prior
from expertise_irl.inference.birl_kernel import _count_table, _uniform_lattice_point
from expertise_irl.mdp import TabularMDP
from expertise_irl.metrics import cosine_similarity
from expertise_irl.worlds.zones import load_bundled

# Tiny task: states 0, 1, 2 and the goal 3; three actions; every move costs length and
# some also cost feature 1 or 2, so the three weights trade off against each other.
TINY_NEXT = np.array([[3, 1, 2], [3, 0, 2], [3, 1, 0], [-1, -1, -1]])
TINY_FEATURES = np.zeros((4, 3, 3))
TINY_FEATURES[0] = [[-1, -1, 0], [-1, 0, -1], [-1, 0, 0]]
TINY_FEATURES[1] = [[-1, 0, 0], [0, -1, 0], [-1, -1, -1]]
TINY_FEATURES[2] = [[-1, 0, -1], [0, 0, -1], [-1, -1, 0]]
# Nine (state, action) pairs in three wandering episodes. With the tiny lattice below the
# posterior is spread out: largest point mass 0.06–0.09, mass on every θ level and on
# three or four β levels.
TINY_EPISODES = [[(0, 1), (1, 2), (2, 0)], [(1, 1), (0, 2), (2, 2), (0, 0)], [(2, 1), (1, 0)]]
# Tiny lattice: δ = 0.25 (θ ∈ {0, .25, .5, .75, 1}^3) and β ∈ {0.2, 0.4, 0.6, 0.8}. (With β = 0.1
# on the grid the box posterior gets a weakly connected mode at ‖θ‖₁ = 0.25, β = 0.1 that the
# chain visits too rarely for a 60k-iteration check.)
TINY_GRID = dict(delta=0.25, beta_step=0.2, beta_range=(0.2, 0.8))
TINY_BETAS = np.arange(0.2, 0.8 + 1e-9, 0.2)

THETA_STAR = np.array([0.6, 0.25, 0.15, 0.0, 0.0])  # off the paper's grids
BETA_STAR = 0.5


@pytest.fixture(scope="module")
def tiny():
    mdp = TabularMDP(TINY_NEXT, TINY_FEATURES, np.array([0, 0, 0, 1], dtype=bool))
    rows = [(e, t, s, a) for e, ep in enumerate(TINY_EPISODES) for t, (s, a) in enumerate(ep)]
    trajs = Trajectories(*(np.array(c) for c in zip(*rows, strict=True)))
    return mdp, trajs


@pytest.fixture(scope="module")
def corridor():
    mdp = load_bundled("corridor").to_mdp()
    return mdp, simulate(mdp, THETA_STAR, BETA_STAR, 40, np.random.default_rng(200))


def _steps(res) -> tuple[np.ndarray, np.ndarray]:
    """Integer lattice coordinates (m [T, K], j [T]) of a chain."""
    m = res.theta / res.delta
    j = (res.beta - res.beta[0]) / res.beta_step  # relative to the start
    np.testing.assert_allclose(m, np.round(m), atol=1e-9)
    np.testing.assert_allclose(j, np.round(j), atol=1e-9)
    return np.round(m).astype(int), np.round(j).astype(int)


# ------------------------------------------------------------------------ basic properties
@pytest.mark.parametrize("variant", ["box", "simplex"])
def test_seeded_chains_are_reproducible(tiny, variant):
    mdp, trajs = tiny
    a, b, c = (extended_birl(mdp, trajs, variant=variant, n_iter=300, rng=np.random.default_rng(s),
                             **TINY_GRID) for s in (5, 5, 6))
    for field in ("theta", "beta", "log_posterior", "accepted"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert not np.array_equal(a.theta, c.theta)


def test_box_chain_stays_on_lattice_in_bounds(corridor):
    mdp, trajs = corridor
    n = 400
    res = extended_birl(mdp, trajs, n_iter=n, rng=np.random.default_rng(1))  # defaults: δ .05, λ 1
    assert res.theta.shape == (n + 1, 5) and res.beta.shape == (n + 1,)
    m, j = _steps(res)
    assert (m >= 0).all() and (m <= 20).all()  # θ ∈ [0, θmax = 1]
    assert (m.sum(axis=1) <= 20).all() and (m.sum(axis=1) >= 1).all()  # ‖θ‖₁ ≤ λ = 1, θ ≠ 0
    jb = (res.beta - 0.01) / 0.1  # β on 0.01 + 0.1 Z within [0.01, 10]
    np.testing.assert_allclose(jb, np.round(jb), atol=1e-9)
    assert (res.beta >= 0.01 - 1e-12).all() and (res.beta <= 10.0).all()
    # Each accepted move changes one θ coordinate by ±δ AND β by ±step; a rejection changes nothing.
    dm, dj = np.abs(np.diff(m, axis=0)), np.abs(np.diff(j))
    moved = res.accepted
    assert (dm[moved].sum(axis=1) == 1).all() and (dj[moved] == 1).all()
    assert (dm[~moved] == 0).all() and (dj[~moved] == 0).all()
    # Hence the parity of Σm + j never changes (see the module docstring).
    assert len(set(((m.sum(axis=1) + j) % 2).tolist())) == 1
    assert 0 < res.acceptance_rate < 1 and res.acceptance_rate == moved.mean()
    assert 0 < res.n_out_of_bounds <= n - moved.sum()
    assert np.isfinite(res.log_posterior).all()
    assert res.best_log_posterior >= res.log_posterior.max()
    assert res.n_solves + res.n_cache_hits == n - res.n_out_of_bounds + 1  # +1: the start


def test_simplex_chain_sums_to_one(corridor):
    mdp, trajs = corridor
    res = extended_birl(mdp, trajs, n_iter=400, variant="simplex", rng=np.random.default_rng(2))
    m, j = _steps(res)
    assert (m >= 0).all() and (m.sum(axis=1) == 20).all()
    np.testing.assert_allclose(res.theta.sum(axis=1), 1.0, atol=1e-12)
    # A θ move transfers δ between two coordinates; moves="either" (the simplex default)
    # changes θ or β, never both.
    dm, dj = np.abs(np.diff(m, axis=0)), np.abs(np.diff(j))
    theta_moves = dm.sum(axis=1) == 2
    assert ((dm.sum(axis=1) == 0) | theta_moves).all() and (dm.max(axis=1) <= 1).all()
    assert not (theta_moves & (dj > 0)).any()
    assert 0 < res.acceptance_rate < 1 and res.moves == "either"
    np.testing.assert_allclose(res.mean_theta_normalized, res.mean_theta)
    assert res.mean_beta_normalized == pytest.approx(res.mean_beta)


def test_means_summaries_and_burn_in(tiny):
    mdp, trajs = tiny
    res = extended_birl(mdp, trajs, n_iter=999, burn_in=0.3, lam=3.0, rng=np.random.default_rng(3),
                        **TINY_GRID)
    assert res.n_burn == 300  # ⌊0.3 · 1000 chain points⌋
    kt, kb = res.theta[300:], res.beta[300:]
    np.testing.assert_allclose(res.mean_theta, kt.mean(axis=0))
    assert res.mean_beta == pytest.approx(kb.mean())
    l1 = kt.sum(axis=1)
    np.testing.assert_allclose(res.mean_theta_normalized, (kt / l1[:, None]).mean(axis=0))
    assert res.mean_beta_normalized == pytest.approx((kb / l1).mean())
    np.testing.assert_allclose(res.mean_theta_normalized.sum(), 1.0)
    # The box's normalised estimates differ from its raw means (the scale ridge).
    assert not np.allclose(res.mean_theta_normalized, res.mean_theta)


def test_start_is_uniform_on_the_lattice():
    # Exact point counts against brute-force enumeration ...
    for K, M, L, exact in [(3, 4, 4, False), (3, 4, 4, True), (4, 2, 5, False), (2, 3, 6, True)]:
        pts = [p for p in itertools.product(range(M + 1), repeat=K)
               if (sum(p) == L if exact else sum(p) <= L)]
        assert _count_table(K, M, L, exact)[0][L] == len(pts)
    # ... and the draw is uniform: 35 box points (K = 3, Σm ≤ 4), 17,500 draws, 500 expected
    # per point. Chi-square with 34 dof has mean 34, sd 8.2; P(χ² > 80) ≈ 1e-5.
    rng = np.random.default_rng(7)
    draws = [tuple(_uniform_lattice_point(rng, 3, 4, 4, exact=False)) for _ in range(17_500)]
    _, counts = np.unique(np.array(draws), axis=0, return_counts=True)
    assert counts.size == 35
    assert ((counts - 500.0) ** 2 / 500.0).sum() < 80


# -------------------------------------------------------------------- exact-target check
def _exact_posterior(mdp, trajs, variant, log_prior, parity=None):
    """Every lattice point of the tiny grid with its exact posterior probability."""
    thetas, betas, logp = [], [], []
    for m in itertools.product(range(5), repeat=3):
        s = sum(m)
        if (variant == "box" and not 0 < s <= 4) or (variant == "simplex" and s != 4):
            continue
        theta = 0.25 * np.array(m)
        for j, beta in enumerate(TINY_BETAS):
            if parity is not None and (s + j) % 2 != parity:
                continue
            ref = soft_value_iteration(mdp, theta, float(beta))
            thetas.append(theta)
            betas.append(beta)
            logp.append(ref.log_policy[trajs.state, trajs.action].sum() + log_prior(theta, beta))
    logp = np.array(logp)
    p = np.exp(logp - logp.max())
    return np.array(thetas), np.array(betas), p / p.sum()


def _z(x: np.ndarray, expected: float, variance: float, n_batches: int = 25) -> float:
    """(chain mean − exact mean) / its standard error, the error estimated by batch means.

    The chain is cut into 25 consecutive batches of ~2,350 iterations, about ten times the
    longest integrated autocorrelation time measured here (3–250 iterations across the
    checks), so the batch means are close to independent and their spread gives the error of
    the mean including autocorrelation. It is floored at the i.i.d. error sqrt(Var_exact / n),
    which a positively autocorrelated chain can only exceed (and which guards against a level
    the chain never visited). Under a correct sampler z is about t with 24 dof: |z| > 5 has
    probability ≈ 4e-5 per check, so the 14 checks of a configuration fail by chance < 1e-3.
    Measured over 8 seeds × 4 configurations: sd(z) 0.8–1.1, max |z| 2.7. Wrong samplers
    give |z| ≥ 13: ignoring the prior (20–60), ignoring the parity restriction of the
    printed algorithm (76–124), re-drawing out-of-bounds proposals instead of staying
    (13–29), accepting on the likelihood ratio alone (20).
    """
    n = x.size // n_batches * n_batches
    batch = x[x.size - n:].reshape(n_batches, -1).mean(axis=1)
    se = max(batch.std(ddof=1) / math.sqrt(n_batches), math.sqrt(max(variance, 0.0) / n), 1e-12)
    return (x[x.size - n:].mean() - expected) / se


def _z_scores(checks: dict, p: np.ndarray) -> dict[str, float]:
    """``_z`` of each check ``name: (values along the chain, values on the lattice)`` against the
    exact lattice posterior ``p``."""
    z = {}
    for name, (chain, values) in checks.items():
        chain, values = chain.astype(float), values.astype(float)
        mean = p @ values
        z[name] = _z(chain, mean, p @ values**2 - mean**2)
    return z


def _flat(theta, beta):
    return 0.0


def _small_beta(theta, beta):
    return -5.0 * beta  # a user prior: exponential in β, 1 nat per β step


def _log_uniform(theta, beta):
    return -math.log(beta)  # the default prior, p(β) ∝ 1/β (every lattice β is inside its range)


@pytest.mark.slow
@pytest.mark.parametrize("variant, moves, prior", [
    ("box", "both", paper_log_prior),  # Algorithm 1 as printed, the paper's prior
    ("box", "either", None),  # the library's default prior
    ("simplex", "both", _small_beta),
    ("simplex", "either", _flat),
])
def test_chain_matches_exact_posterior(tiny, variant, moves, prior):
    mdp, trajs = tiny
    res = extended_birl(mdp, trajs, variant=variant, moves=moves, log_prior=prior, n_iter=60_000,
                        burn_in=0.02, rng=np.random.default_rng(11), **TINY_GRID)
    parity = None
    if variant == "box" and moves == "both":
        # The printed algorithm keeps Σm + j fixed mod 2: its target is the posterior on
        # the half of the lattice that holds the start.
        m0, j0 = round(res.theta[0].sum() / 0.25), round((res.beta[0] - TINY_BETAS[0]) / 0.2)
        parity = (m0 + j0) % 2
    thetas, betas, p = _exact_posterior(mdp, trajs, variant, prior or _log_uniform, parity)
    assert p.max() < 0.1  # a spread-out target, not a point mass
    kt, kb = res.kept_theta, res.kept_beta
    # Each check: a function f of the point, its values along the chain and on the lattice.
    checks = {f"E[theta_{k}]": (kt[:, k], thetas[:, k]) for k in range(3)}
    checks["E[beta]"] = (kb, betas)
    for b in TINY_BETAS:
        checks[f"P(beta={b})"] = (np.isclose(kb, b), np.isclose(betas, b))
    for k, level in itertools.product(range(3), (0.0, 0.5)):
        checks[f"P(theta_{k}={level})"] = (np.isclose(kt[:, k], level), np.isclose(thetas[:, k], level))
    z = _z_scores(checks, p)
    assert max(abs(v) for v in z.values()) < 5, z
    assert 0 < res.acceptance_rate < 1


# ------------------------------------------------------------------------------ recovery
@pytest.mark.slow
def test_simplex_recovers_truth_on_corridor():
    """40 simulated episodes from an off-grid (θ*, β*); the simplex variant's estimate.

    As the paper does (Sec. VII-A), the inference is run 4 times; we keep the chain with
    the highest mean log posterior after burn-in. Single chains (2,000 iterations) from
    some random starts stay in a secondary mode that the coarse β step at small β makes
    hard to leave (cos 0.45–0.77, 5–10 nats lower): 7 of 40 chains over two data sets.
    The other 33 had cos ≥ 0.92 and |β̂ − β*| ≤ 0.21. Best of 4, over 10 data sets
    (seeds 300–309): cos 0.972–0.994, |β̂ − β*| 0.012–0.123. Bounds: cos ≥ 0.93 and
    |β̂ − β*| ≤ 0.25 (the vertex θ = (1, 0, 0, 0, 0) has cos 0.90, the trapped modes ≤ 0.77).
    """
    mdp = load_bundled("corridor").to_mdp()
    for data_seed in (300, 301):
        trajs = simulate(mdp, THETA_STAR, BETA_STAR, 40, np.random.default_rng(data_seed))
        runs = [extended_birl(mdp, trajs, variant="simplex", n_iter=2000, rng=np.random.default_rng(s))
                for s in range(4)]
        best = max(runs, key=lambda r: r.log_posterior[r.n_burn:].mean())
        assert cosine_similarity(THETA_STAR, best.mean_theta_normalized) >= 0.93
        assert abs(best.mean_beta_normalized - BETA_STAR) <= 0.25
        assert 0.02 < best.acceptance_rate < 0.5


# ----------------------------------------------------------------------------- warm start
def test_warm_start_needs_fewer_sweeps(corridor):
    """Same seed, same proposals; every proposal solved (no cache). Measured on corridor and
    crossroads: ≈ 120–140 sweeps per solve warm against ≈ 160–176 cold."""
    mdp, trajs = corridor
    warm, cold = (extended_birl(mdp, trajs, n_iter=150, cache=False, warm_start=w,
                                rng=np.random.default_rng(4)) for w in (True, False))
    assert warm.n_solves > 50 and cold.n_solves > 50
    assert warm.sweeps_per_solve < 0.9 * cold.sweeps_per_solve
    # Solver tolerance 1e-6 nats: both runs evaluate the same posterior.
    np.testing.assert_allclose(warm.log_posterior[0], cold.log_posterior[0], atol=1e-3)


def test_cache_skips_repeated_points(tiny):
    mdp, trajs = tiny
    res = extended_birl(mdp, trajs, n_iter=2000, rng=np.random.default_rng(9), **TINY_GRID)
    assert res.n_solves <= 34 * 5  # at most one solve per lattice point
    assert res.n_cache_hits > 0
    assert res.n_solves + res.n_cache_hits == 2000 - res.n_out_of_bounds + 1


# ------------------------------------------------------------------------ bad parameters
@pytest.mark.parametrize("kwargs, name", [
    (dict(n_iter=0), "n_iter"),
    (dict(n_iter=2.5), "n_iter"),
    (dict(delta=0.0), "delta"),
    (dict(delta=-0.1), "delta"),
    (dict(delta=0.3), "theta_max"),  # 1 / 0.3 is not an integer
    (dict(delta=0.3, variant="simplex"), "delta"),
    (dict(beta_step=0.0), "beta_step"),
    (dict(beta_step=math.inf), "beta_step"),
    (dict(theta_max=-1.0), "theta_max"),
    (dict(beta_range=(0.0, 1.0)), "beta_range"),
    (dict(beta_range=(2.0, 1.0)), "beta_range"),
    (dict(beta_range=(1.0, 1.05)), "beta_step"),  # a single β
    (dict(beta_range=3.0), "beta_range"),
    (dict(lam=0.01), "lam"),
    (dict(lam=0.0), "lam"),
    (dict(variant="cube"), "variant"),
    (dict(moves="all"), "moves"),
    (dict(burn_in=1.0), "burn_in"),
    (dict(burn_in=-0.1), "burn_in"),
    (dict(tol=0.0), "tol"),
    (dict(rng="seed"), "rng"),
    (dict(log_prior=3), "log_prior"),
    (dict(log_prior=lambda t, b: math.nan), "log_prior"),
    (dict(log_prior=lambda t, b: -math.inf), "log_prior"),
])
def test_bad_parameters_raise(tiny, kwargs, name):
    mdp, trajs = tiny
    args = dict(n_iter=10, rng=np.random.default_rng(0)) | kwargs
    with pytest.raises(InputError, match=name) as info:
        extended_birl(mdp, trajs, **args)
    assert "\n" not in str(info.value)


def test_impossible_demonstration_raises(tiny):
    mdp, _ = tiny
    bad = Trajectories(np.array([0]), np.array([0]), np.array([3]), np.array([0]))  # acts from the goal
    with pytest.raises(InputError, match="terminal"):
        extended_birl(mdp, bad, n_iter=10, rng=0)


# ------------------------------------------------------------------------ a chain that does not move
def _document(res, names):
    """The result document of an Algorithm 1 chain, as `infer` writes it."""
    from expertise_irl.inference.methods import BIRLOptions, ContinuousFit, MethodRun, document, get_method

    fit = ContinuousFit(res)  # what the registry's fit returns
    fields = {**get_method("birl").describe(fit, BIRLOptions(variant="simplex"), names), "run_time_s": 1.0}
    return document(MethodRun("birl", res, fields, {}), feature_names=names, settings={}, data={})


def test_a_chain_frozen_in_beta_reports_no_interval_and_says_so(tiny):
    """The prior allows one β (0.4), so every β proposal is rejected while θ moves: β's interval and
    R-hat are null with the reason, its ESS 0 (ArviZ would say 400, the chain's length), and the
    first warning says the chain did not move in β and what to change."""
    mdp, trajs = tiny
    res = extended_birl(mdp, trajs, n_iter=500, variant="simplex", rng=np.random.default_rng(7),
                        log_prior=lambda t, b: 0.0 if abs(b - 0.4) < 1e-9 else -math.inf, **TINY_GRID)
    assert (res.kept_beta == 0.4).all() and len(np.unique(res.kept_theta, axis=0)) > 1
    names = list(mdp.feature_names)
    doc = _document(res, names)
    diag = doc["diagnostics"]
    assert doc["credible_intervals"]["beta"] is None
    assert all(ci is not None and ci[0] < ci[1] for ci in doc["credible_intervals"]["theta"])
    assert diag["ess_bulk"]["beta"] == 0.0 and diag["r_hat"]["beta"] is None
    assert all(v > 0 for v in diag["ess_bulk"]["theta"])
    why = "the chain did not move in β (always 0.4): no posterior to summarise"
    assert diag["unavailable"] == {"r_hat.beta": why, "credible_intervals.beta": why}
    assert diag["warnings"][0].startswith("the chain did not move in β: every kept draw has β = 0.4, ")
    assert "try a smaller --beta-step or --delta, or more --iterations" in diag["warnings"][0]


def test_a_chain_frozen_everywhere_reports_no_posterior(tiny):
    """The prior allows one lattice point: the chain never moves; no ESS, R-hat or interval is reported
    as a posterior's (in the issue every ESS read the chain's length)."""
    mdp, trajs = tiny
    point = np.array([0.5, 0.25, 0.25])
    res = extended_birl(mdp, trajs, n_iter=300, variant="simplex", rng=np.random.default_rng(8),
                        log_prior=lambda t, b: 0.0 if np.allclose(t, point) and abs(b - 0.6) < 1e-9
                        else -math.inf, **TINY_GRID)
    assert res.acceptance_rate == 0.0
    names = list(mdp.feature_names)
    doc = _document(res, names)
    diag = doc["diagnostics"]
    assert doc["credible_intervals"] == {"beta": None, "theta": [None] * 3}
    assert diag["ess_bulk"] == {"beta": 0.0, "theta": [0.0] * 3}
    assert diag["r_hat"] == {"beta": None, "theta": [None] * 3}
    assert len(diag["unavailable"]) == 8  # R-hat and interval of β and of each θ_k
    stuck = [w for w in diag["warnings"] if "did not move" in w]
    assert len(stuck) == 1 and stuck[0].startswith(f"the chain did not move in β, θ[{names[0]}], ")
    assert not any(w.startswith("bulk ESS of ") for w in diag["warnings"])  # said once, by the stuck warning


@pytest.mark.parametrize("prior", [None, _small_beta])
def test_a_log_spaced_beta_lattice_matches_its_exact_posterior(tiny, prior):
    """``beta_ratio``: β ∈ {0.2, 0.4, 0.8}; each lattice point stands for its cell's prior mass,
    density × β (a cell of a log-spaced lattice is β·ln 2 wide), so the exact target weighs the
    prior density by β. With the default log-uniform prior that is flat over the lattice. A
    sampler that took the density alone would be off by a factor of 4 between the ends (|z| ≫ 5)."""
    mdp, trajs = tiny
    res = extended_birl(mdp, trajs, variant="simplex", log_prior=prior, n_iter=60_000, burn_in=0.02,
                        rng=np.random.default_rng(12), delta=0.25, beta_ratio=2.0, beta_range=(0.2, 0.8))
    assert res.beta_ratio == 2.0 and set(np.round(res.beta, 9)) == {0.2, 0.4, 0.8}
    density = prior or _log_uniform
    thetas, betas, logp = [], [], []
    for m in itertools.product(range(5), repeat=3):
        if sum(m) != 4:
            continue
        theta = 0.25 * np.array(m)
        for beta in (0.2, 0.4, 0.8):
            ref = soft_value_iteration(mdp, theta, beta)
            thetas.append(theta)
            betas.append(beta)
            ll = ref.log_policy[trajs.state, trajs.action].sum()
            logp.append(ll + density(theta, beta) + math.log(beta))
    p = np.exp(np.array(logp) - max(logp))
    p /= p.sum()
    thetas, betas = np.array(thetas), np.array(betas)
    checks = {f"E[theta_{k}]": (res.kept_theta[:, k], thetas[:, k]) for k in range(3)}
    checks["E[beta]"] = (res.kept_beta, betas)
    for b in (0.2, 0.4, 0.8):
        checks[f"P(beta={b})"] = (np.isclose(res.kept_beta, b), np.isclose(betas, b))
    z = _z_scores(checks, p)
    assert max(abs(v) for v in z.values()) < 5, z


def test_a_log_spaced_beta_lattice_refuses_a_bad_ratio(tiny):
    mdp, trajs = tiny
    for ratio, match in ((1.0, "beta_ratio must be"), (10.0, "leaves a single")):
        with pytest.raises(InputError, match=match):
            extended_birl(mdp, trajs, n_iter=5, rng=0, beta_ratio=ratio, beta_range=(0.2, 0.8))


# ------------------------------------------------------------------------ several chains
def test_chains_run_until_they_agree_and_pool_to_the_exact_posterior(tiny):
    """Four chains (simplex, moves either) in blocks of 2,000 until split R-hat < 1.01: they stop
    once they agree, and the pooled means match the exact lattice posterior (|z| < 5 as above,
    the batch-means error taken over the pooled draws of the four chains, which the shared
    target makes exchangeable)."""
    from expertise_irl.inference.birl_chains import birl_chains

    mdp, trajs = tiny
    r = birl_chains(mdp, trajs, chains=4, rhat_below=1.01, block=2000, max_iter=40_000, variant="simplex",
                    rng=np.random.default_rng(5), burn_in=0.05, **TINY_GRID)
    assert r.converged and r.max_rhat < 1.01 and r.iterations % 2000 == 0 and r.iterations < 40_000
    assert r.theta.shape == (4, r.iterations + 1, 3)
    thetas, betas, p = _exact_posterior(mdp, trajs, "simplex", _log_uniform)
    kt = r.theta[:, r.n_burn:].reshape(-1, 3)
    kb = r.beta[:, r.n_burn:].reshape(-1)
    checks = {f"E[theta_{k}]": (kt[:, k], thetas[:, k]) for k in range(3)}
    checks["E[beta]"] = (kb, betas)
    z = _z_scores(checks, p)
    assert max(abs(v) for v in z.values()) < 5, z
    np.testing.assert_allclose(r.mean_theta, kt.mean(axis=0))


def test_chains_with_a_fixed_budget_are_reproducible_and_share_their_solves(tiny):
    from expertise_irl.inference.birl_chains import birl_chains

    mdp, trajs = tiny
    kw = dict(chains=3, n_iter=300, variant="box", rng=None, **TINY_GRID)
    a = birl_chains(mdp, trajs, **{**kw, "rng": np.random.default_rng(1)})
    b = birl_chains(mdp, trajs, **{**kw, "rng": np.random.default_rng(1)})
    assert a.iterations == 300 and not a.converged and a.theta.shape == (3, 301, 3)
    np.testing.assert_array_equal(a.theta, b.theta)
    assert not math.isnan(a.max_rhat)  # two or more chains: an R-hat (inf where a chain never moved)
    # one shared cache: the tiny box lattice has 34 θ × 4 β points, far fewer than 900 proposals
    assert a.n_solves <= 34 * 4 and a.n_cache_hits > 0
    with pytest.raises(InputError, match="chains must be"):
        birl_chains(mdp, trajs, **{**kw, "chains": 0, "rng": np.random.default_rng(1)})
    with pytest.raises(InputError, match="rhat_below must be"):
        birl_chains(mdp, trajs, **{**kw, "rhat_below": 0.9, "rng": np.random.default_rng(1)})
