"""Tests for inference/hypothesis_sets.py: the hypothesis sets of Sec. VI-A and out-of-set truths."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.hypotheses import (
    BETA_PRESETS,
    EXPERTISE_GROUPS,
    THETA_PRESETS,
    HypothesisSet,
    expertise_group,
    sample_thetas,
    theta_grid,
)
from expertise_irl.inference.hypothesis_sets import (
    fixed_beta_set,
    fixed_theta_set,
    full_set,
    out_of_set_truth,
    sample_in_set_truth,
)

PAPER_BETAS = BETA_PRESETS["paper-sim"]
N_SEEDS = 200


@pytest.fixture(scope="module")
def all_thetas():
    return theta_grid(THETA_PRESETS["paper-sim"], 5)


@pytest.fixture(scope="module")
def theta_k(all_thetas):
    return sample_thetas(all_thetas, 10, np.random.default_rng(0))


def row_in(theta, thetas) -> bool:
    return bool(np.any(np.all(np.isclose(thetas, theta, atol=1e-9), axis=1)))


def rng(seed):
    return np.random.default_rng(seed)


# ---------------------------------------------------------------------- full set
def test_full_set(theta_k):
    hyp = full_set(theta_k, [10.0, 0.5, 0.01, 0.5])  # unsorted, with a duplicate
    assert isinstance(hyp, HypothesisSet)
    np.testing.assert_allclose(hyp.thetas, theta_k, rtol=0, atol=1e-15)  # renormalised
    np.testing.assert_array_equal(hyp.betas, [0.01, 0.5, 10.0])
    assert len(hyp) == 30
    hyp = full_set(theta_k, PAPER_BETAS)
    assert len(hyp) == 60 and hyp.n_beta == 6


def test_full_set_errors(theta_k):
    with pytest.raises(InputError):
        full_set(theta_k, [])
    with pytest.raises(InputError):
        full_set(theta_k, [0.5, 0.0])
    with pytest.raises(InputError):
        full_set(-theta_k, PAPER_BETAS)


# ------------------------------------------------------------------ fixed θ
def test_fixed_theta_never_contains_truth_and_keeps_betas(theta_k):
    theta_star = theta_k[3]
    chosen = set()
    for seed in range(N_SEEDS):
        hyp = fixed_theta_set(theta_k, PAPER_BETAS, theta_star, rng(seed))
        assert hyp.n_theta == 1
        assert not np.allclose(hyp.thetas[0], theta_star, atol=1e-9)
        assert row_in(hyp.thetas[0], theta_k)
        np.testing.assert_array_equal(hyp.betas, PAPER_BETAS)
        chosen.add(tuple(hyp.thetas[0]))
    # Uniform over the 9 others: the chance that one is never drawn in 200 tries is
    # 9·(8/9)^200 ≈ 5e-10, so all 9 must appear.
    assert len(chosen) == 9


def test_fixed_theta_compares_directions(theta_k):
    # θ* given at another scale is still recognised as θ*.
    for seed in range(50):
        hyp = fixed_theta_set(theta_k, PAPER_BETAS, 7.5 * theta_k[0], rng(seed))
        assert not np.allclose(hyp.thetas[0], theta_k[0], atol=1e-9)


def test_fixed_theta_errors(theta_k):
    with pytest.raises(InputError, match="other than"):
        fixed_theta_set(theta_k[:1], PAPER_BETAS, theta_k[0], rng(0))
    with pytest.raises(InputError):
        fixed_theta_set(theta_k, PAPER_BETAS, np.zeros(5), rng(0))
    with pytest.raises(InputError):
        fixed_theta_set(theta_k, PAPER_BETAS, -theta_k[0], rng(0))


# ------------------------------------------------------------------ fixed β
@pytest.mark.parametrize("beta_star", PAPER_BETAS)
def test_fixed_beta_from_another_group(theta_k, beta_star):
    group = expertise_group(beta_star)
    expected = {b for b in PAPER_BETAS if b not in EXPERTISE_GROUPS[group]}
    assert len(expected) == 4
    chosen = set()
    for seed in range(N_SEEDS):
        hyp = fixed_beta_set(theta_k, PAPER_BETAS, beta_star, rng(seed))
        assert hyp.n_beta == 1
        b = float(hyp.betas[0])
        assert expertise_group(b) != group
        assert b in expected
        np.testing.assert_allclose(hyp.thetas, theta_k, rtol=0, atol=1e-15)
        chosen.add(b)
    # Uniform over the 4 candidates: P(one never drawn in 200) ≈ 4·(3/4)^200 ≈ 4e-25.
    assert chosen == expected


def test_fixed_beta_errors(theta_k):
    with pytest.raises(InputError, match="outside the 'high'"):
        fixed_beta_set(theta_k, [0.01, 0.09], 0.05, rng(0))
    with pytest.raises(InputError):
        fixed_beta_set(theta_k, [], 0.05, rng(0))


# --------------------------------------------------------------- in-set truth
@pytest.mark.parametrize("group", ["high", "medium", "low"])
def test_sample_in_set_truth_respects_group(theta_k, group):
    hyp = full_set(theta_k, PAPER_BETAS)
    betas, thetas = set(), set()
    for seed in range(N_SEEDS):
        theta, beta = sample_in_set_truth(hyp, group, rng(seed))
        assert expertise_group(beta) == group
        assert beta in EXPERTISE_GROUPS[group]
        assert hyp.index(theta, beta) is not None
        betas.add(beta)
        thetas.add(tuple(theta))
    # Uniform: both group members and all 10 θ's appear (P(miss) ≤ 10·0.9^200 ≈ 7e-9).
    assert betas == set(EXPERTISE_GROUPS[group])
    assert len(thetas) == 10


def test_sample_in_set_truth_returns_a_copy(theta_k):
    hyp = full_set(theta_k, PAPER_BETAS)
    theta, _ = sample_in_set_truth(hyp, "high", rng(0))
    theta[:] = -1.0
    assert np.all(hyp.thetas >= 0)


def test_sample_in_set_truth_errors(theta_k):
    hyp = full_set(theta_k, [0.01, 0.09])
    with pytest.raises(InputError, match="'low'"):
        sample_in_set_truth(hyp, "low", rng(0))
    with pytest.raises(InputError):
        sample_in_set_truth(full_set(theta_k, PAPER_BETAS), "expert", rng(0))


# ---------------------------------------------------------------- out-of-set truth
def test_out_of_set_truth_outside_theta_k_and_beta_in_range(all_thetas, theta_k):
    betas = []
    for seed in range(N_SEEDS):
        theta, beta = out_of_set_truth(all_thetas, theta_k, rng(seed))
        assert not row_in(theta, theta_k)
        assert row_in(theta, all_thetas)
        assert theta.sum() == pytest.approx(1.0, abs=1e-12)
        assert 0.01 <= beta <= 10.0
        betas.append(beta)
    # β ~ U(0.01, 10): mean 5.005, sd 2.88/√200 = 0.20; ±1.0 is a 5-sigma band.
    assert abs(np.mean(betas) - 5.005) < 1.0
    assert min(betas) < 1.0 and max(betas) > 9.0


def test_out_of_set_truth_excludes_every_set_member():
    # A tiny grid where only one θ is outside the set: it must always be returned.
    grid = np.array([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]])
    for seed in range(20):
        theta, beta = out_of_set_truth(grid, grid[[0, 2]], rng(seed), beta_range=(2.0, 3.0))
        np.testing.assert_allclose(theta, [0.5, 0.5])
        assert 2.0 <= beta <= 3.0
    # A single θ (1-D) as the set.
    for seed in range(20):
        theta, _ = out_of_set_truth(grid, grid[1], rng(seed))
        assert not np.allclose(theta, grid[1])


def test_out_of_set_truth_errors(all_thetas, theta_k):
    with pytest.raises(InputError, match="every θ"):
        out_of_set_truth(theta_k, theta_k, rng(0))
    for bad in [(0.0, 10.0), (-1.0, 1.0), (5.0, 1.0), (2.0, 2.0)]:
        with pytest.raises(InputError, match="beta_range"):
            out_of_set_truth(all_thetas, theta_k, rng(0), beta_range=bad)


# ------------------------------------------------------------------ reproducibility
def test_seeded_reproducibility(all_thetas, theta_k):
    hyp = full_set(theta_k, PAPER_BETAS)
    calls = [
        lambda r: fixed_theta_set(theta_k, PAPER_BETAS, theta_k[0], r).thetas,
        lambda r: fixed_beta_set(theta_k, PAPER_BETAS, 1.0, r).betas,
        lambda r: np.r_[sample_in_set_truth(hyp, "medium", r)],
        lambda r: np.r_[out_of_set_truth(all_thetas, theta_k, r)],
    ]
    for f in calls:
        for seed in (0, 1, 2):
            np.testing.assert_array_equal(f(rng(seed)), f(rng(seed)))
        # Different seeds give different draws for some seed (not a constant function).
        outs = {tuple(np.ravel(f(rng(s)))) for s in range(20)}
        assert len(outs) > 1


def test_set_composition_by_hand():
    from expertise_irl.inference.hypothesis_sets import set_composition

    thetas = np.array([[1.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.0, 1.0]])
    got = set_composition([1.0, 0.0, 0.0], 0.7, thetas, [0.01, 0.5, 1.0])
    # cosines with the truth: 1, 1/√2, 0; pairs: (1,2) 1/√2, (1,3) 0, (2,3) 0.
    assert got["theta_k_truth_similarity"] == pytest.approx((1 + 2 ** -0.5) / 3, abs=1e-12)
    assert got["theta_k_diversity"] == pytest.approx(2 ** -0.5 / 3, abs=1e-12)
    assert got["beta_set_distance"] == pytest.approx(0.2, abs=1e-12)
    single = set_composition([0.0, 1.0, 0.0], 1.0, thetas[:1], [1.0])
    assert single["theta_k_diversity"] == 1.0 and single["beta_set_distance"] == 0.0
    assert single["theta_k_truth_similarity"] == 0.0
