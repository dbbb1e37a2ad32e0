"""Θ grids, paper presets, Θ_k sampling, Ψ = Θ × B flattening and expertise groups."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.hypotheses import (
    BETA_PRESETS,
    EXPERTISE_GROUPS,
    GROUP_BOUNDARIES,
    THETA_PRESETS,
    HypothesisSet,
    expertise_group,
    normalize_theta,
    parse_betas,
    resolve_betas,
    resolve_thetas,
    sample_thetas,
    theta_grid,
    unique_rows,
)


def directions_by_integer_ratio(int_values, k):
    """Independent count: a non-zero integer vector's direction is its gcd-reduced form;
    returns the reduced vectors in order of first appearance in the lexicographic product."""
    seen: dict[tuple[int, ...], None] = {}
    for t in itertools.product(sorted(int_values), repeat=k):
        if sum(t) == 0:
            continue
        g = math.gcd(*t)
        seen.setdefault(tuple(x // g for x in t), None)
    return [np.array(t, float) / sum(t) for t in seen]


@pytest.fixture(scope="module")
def sim_grid():
    return theta_grid(THETA_PRESETS["paper-sim"], 5)


def test_paper_sim_grid(sim_grid):
    assert sim_grid.shape == (3031, 5)
    assert 5**5 - 1 == 3124  # the paper's count, before removing duplicate directions
    expected = directions_by_integer_ratio([0, 3, 5, 7, 10], 5)
    assert len(expected) == 3031
    np.testing.assert_allclose(sim_grid, np.array(expected), rtol=0, atol=1e-15)


def test_paper_real_grid():
    grid = theta_grid(THETA_PRESETS["paper-real"], 3)
    assert grid.shape == (19, 3)
    np.testing.assert_allclose(grid, np.array(directions_by_integer_ratio([0, 1, 2], 3)),
                               rtol=0, atol=1e-15)


@pytest.mark.parametrize(("preset", "k"), [("paper-sim", 5), ("paper-real", 3), ("paper-sim", 2)])
def test_grid_rows_are_unit_l1_nonnegative_unique(preset, k):
    grid = theta_grid(THETA_PRESETS[preset], k)
    assert grid.dtype == np.float64 and grid.shape[1] == k
    assert np.all(grid >= 0)
    np.testing.assert_allclose(grid.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    # unique even at 6 decimals: no two rows are parallel (unit-l1 rows of one direction agree)
    assert len(np.unique(np.round(grid, 6), axis=0)) == len(grid)


def test_grid_order_is_deterministic(sim_grid):
    again = theta_grid((1.0, 0.7, 0.5, 0.3, 0.0, 0.5), 5)  # order/duplicates of values irrelevant
    np.testing.assert_array_equal(sim_grid, again)
    np.testing.assert_array_equal(sim_grid[0], [0, 0, 0, 0, 1])
    np.testing.assert_array_equal(sim_grid[1], [0, 0, 0, 1, 0])
    np.testing.assert_allclose(sim_grid[-1], np.array([1, 1, 1, 1, 0.7]) / 4.7, rtol=1e-15)
    np.testing.assert_array_equal(resolve_thetas("paper-sim", 5), sim_grid)


def test_resolve_thetas_values_equal_paper_real():
    np.testing.assert_array_equal(resolve_thetas("0,0.5,1", 3), theta_grid((0, 0.5, 1), 3))
    np.testing.assert_array_equal(resolve_thetas(" 0, .5 ,1 ", 3), resolve_thetas("paper-real", 3))


def test_resolve_betas():
    np.testing.assert_array_equal(resolve_betas("paper-sim"), BETA_PRESETS["paper-sim"])
    np.testing.assert_array_equal(resolve_betas("10, 0.1,1,0.1"), [0.1, 1.0, 10.0])


@pytest.mark.parametrize(("spec", "match"), [
    ("0,abc", "'abc' is neither a number nor a preset"),
    ("paper-simm", "neither a number nor a preset.*paper-sim"),
    ("0,-0.5,1", "non-negative"),
    ("0", "positive"),
    ("0,nan", "finite"),
])
def test_bad_theta_specs(spec, match):
    with pytest.raises(InputError, match=match):
        resolve_thetas(spec, 3)


@pytest.mark.parametrize(("spec", "match"), [
    ("0.1,0", "must be > 0, got 0"),
    ("-1", "must be > 0, got -1"),
    ("1,inf", "must be > 0, got inf"),
    ("1,x", "'x' is neither a number nor a preset"),
])
def test_bad_beta_specs(spec, match):
    with pytest.raises(InputError, match=match):
        resolve_betas(spec)


def test_bad_grid_arguments():
    with pytest.raises(InputError, match="non-empty"):
        theta_grid((), 3)
    with pytest.raises(InputError, match="n_features"):
        theta_grid((0, 1), 0)
    with pytest.raises(InputError, match="sample a subset"):
        theta_grid(np.linspace(0, 1, 11), 7)
    with pytest.raises(InputError, match="empty"):
        parse_betas([])


def test_normalize_theta():
    np.testing.assert_allclose(normalize_theta([2.0, 0.0, 6.0]), [0.25, 0.0, 0.75])
    for bad, match in (([0.0, 0.0], "positive"), ([-1.0, 2.0], "non-negative"),
                       ([np.nan, 1.0], "finite")):
        with pytest.raises(InputError, match=match):
            normalize_theta(bad)


def test_unique_rows_keeps_first_appearance():
    x = np.array([[0.5, 0.5], [1.0, 0.0], [0.5, 0.5 + 1e-15], [0.0, 1.0], [1.0, -0.0]])
    np.testing.assert_array_equal(unique_rows(x), x[[0, 1, 3]])


# --------------------------------------------------------------------------- sampling
def test_sample_thetas_reproducible_and_distinct(sim_grid):
    a = sample_thetas(sim_grid, 50, np.random.default_rng(7))
    b = sample_thetas(sim_grid, 50, np.random.default_rng(7))
    c = sample_thetas(sim_grid, 50, np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.shape == (50, 5)
    assert len(np.unique(a, axis=0)) == 50
    # every sampled row is a grid row
    assert all(np.any(np.all(sim_grid == row, axis=1)) for row in a)
    everything = sample_thetas(sim_grid, len(sim_grid), np.random.default_rng(0))
    np.testing.assert_array_equal(everything, sim_grid)  # sorted indices: grid order


@pytest.mark.parametrize("seed", range(5))
def test_sample_thetas_include(sim_grid, seed):
    truth = sim_grid[1234]
    out = sample_thetas(sim_grid, 10, np.random.default_rng(seed), include=3.0 * truth)
    np.testing.assert_allclose(out[0], truth, rtol=0, atol=1e-15)
    matches = np.all(np.isclose(out, truth, atol=1e-9), axis=1)
    assert matches.sum() == 1  # present exactly once
    assert len(np.unique(np.round(out, 12), axis=0)) == 10
    # a θ outside the grid is still included
    off = np.array([0.11, 0.0, 0.0, 0.0, 0.89])
    out = sample_thetas(sim_grid, 10, np.random.default_rng(seed), include=off)
    np.testing.assert_allclose(out[0], off)
    assert len(out) == 10
    # k = 1 gives just the included θ
    np.testing.assert_allclose(sample_thetas(sim_grid, 1, np.random.default_rng(seed),
                                             include=truth), truth[None])


def test_sample_thetas_bad_k(sim_grid):
    for k in (0, len(sim_grid) + 1):
        with pytest.raises(InputError, match="k must be between 1 and 3031"):
            sample_thetas(sim_grid, k, np.random.default_rng(0))


# --------------------------------------------------------------------------- Ψ = Θ × B
def test_hypothesis_set_flattening():
    thetas = theta_grid((0, 0.5, 1), 3)
    hs = HypothesisSet(thetas, BETA_PRESETS["paper-real"])
    assert (hs.n_theta, hs.n_beta, len(hs)) == (19, 5, 95)
    assert hs.theta.shape == (95, 3) and hs.beta.shape == (95,)
    for h in range(len(hs)):
        np.testing.assert_array_equal(hs.theta[h], hs.thetas[h // hs.n_beta])
        assert hs.beta[h] == hs.betas[h % hs.n_beta]
        assert hs.index(hs.theta[h], hs.beta[h]) == h
    assert hs.index(4 * thetas[3], 0.3) == 3 * 5 + 1  # θ compared after normalising
    assert hs.index(thetas[3], 0.25) is None
    assert hs.index([0.1, 0.2, 0.7], 0.3) is None


def test_hypothesis_set_normalises_and_sorts():
    hs = HypothesisSet(np.array([[2.0, 2.0], [0.0, 3.0]]), [10.0, 0.1, 1.0, 0.1])
    np.testing.assert_array_equal(hs.thetas, [[0.5, 0.5], [0.0, 1.0]])
    np.testing.assert_array_equal(hs.betas, [0.1, 1.0, 10.0])
    assert len(hs) == 6
    assert hs.index([1, 1], 10.0) == 2
    single = HypothesisSet(np.array([1.0, 3.0]), [1.0])  # one θ as a vector
    np.testing.assert_array_equal(single.thetas, [[0.25, 0.75]])


@pytest.mark.parametrize(("thetas", "betas", "match"), [
    ([[0.5, 0.5]], [0.0], "beta must be > 0"),
    ([[0.5, 0.5]], [-1.0], "beta must be > 0"),
    ([[0.5, 0.5]], [], "empty"),
    ([[-0.5, 1.0]], [1.0], "non-negative"),
    ([[0.0, 0.0]], [1.0], "positive component"),
])
def test_hypothesis_set_bad_input(thetas, betas, match):
    with pytest.raises(InputError, match=match):
        HypothesisSet(np.array(thetas), betas)


# --------------------------------------------------------------------------- expertise groups
@pytest.mark.parametrize(("beta", "group"), [
    (0.01, "high"), (0.09, "high"), (0.5, "medium"), (1.0, "medium"), (5.0, "low"), (10.0, "low"),
    (1e-3, "high"), (100.0, "low"),
])
def test_expertise_group_paper_values(beta, group):
    assert expertise_group(beta) == group


def test_expertise_groups_cover_paper_set():
    assert sorted(b for bs in EXPERTISE_GROUPS.values() for b in bs) == list(BETA_PRESETS["paper-sim"])
    for group, betas in EXPERTISE_GROUPS.items():
        assert all(expertise_group(b) == group for b in betas)


def test_expertise_group_boundaries():
    lo, hi = GROUP_BOUNDARIES
    assert lo == pytest.approx(math.sqrt(0.09 * 0.5)) and hi == pytest.approx(math.sqrt(5.0))
    assert expertise_group(np.nextafter(lo, 0)) == "high"
    assert expertise_group(lo) == "medium"
    assert expertise_group(np.nextafter(hi, 0)) == "medium"
    assert expertise_group(hi) == "low"
    assert expertise_group(0.2) == "high" and expertise_group(0.22) == "medium"
    assert expertise_group(2.2) == "medium" and expertise_group(2.3) == "low"
