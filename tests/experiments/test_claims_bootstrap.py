"""The two-stage cluster bootstrap (maps, then the people or instances within them)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from expertise_irl.experiments.report import claims as C
from expertise_irl.experiments.report.stats import (
    cluster_bootstrap_means,
    cluster_difference_ci,
    cluster_ratio_ci,
    ratio_ci,
)


def _whole_map_ratios(sizes, num_by_map, den_by_map):
    """Every ratio a resample of whole maps can give: maps drawn with replacement, counts summing to G."""
    g = len(sizes)
    out = set()
    for counts in itertools.product(range(g + 1), repeat=g):
        if sum(counts) != g:
            continue
        n = sum(c * s * a for c, s, a in zip(counts, sizes, num_by_map, strict=True))
        d = sum(c * s * b for c, s, b in zip(counts, sizes, den_by_map, strict=True))
        out.add(round(n / d, 9))
    return out


@pytest.mark.parametrize("paired", [True, False])
def test_resampling_is_by_map_first(paired):
    """Values constant within a map: every replicate's ratio is one formed from whole maps."""
    sizes, a, b = [4, 6, 5], [1.0, 2.0, 7.0], [1.0, 3.0, 0.5]
    env = np.repeat([0, 1, 2], sizes)
    num, den = np.repeat(a, sizes), np.repeat(b, sizes)
    clusters = env if paired else (env, env)
    rn, rd = cluster_bootstrap_means(num, den, clusters, paired=paired, resamples=500, seed=3)
    allowed = _whole_map_ratios(sizes, a, b)
    got = {round(x, 9) for x in rn / rd}
    assert got <= allowed and len(got) > 3  # many whole-map combinations are drawn, nothing else
    # the iid bootstrap mixes people of different maps freely: ratios outside that set
    rng = np.random.default_rng(0)
    i = rng.integers(0, len(num), size=(200, len(num)))
    iid = {round(x, 9) for x in num[i].mean(axis=1) / den[i].mean(axis=1)}
    assert not iid <= allowed


def test_within_a_map_the_people_are_resampled_too():
    """One map: the second stage alone, the same spread as an iid bootstrap."""
    rng = np.random.default_rng(1)
    num, den = rng.exponential(size=300), rng.exponential(size=300)
    one = cluster_ratio_ci(num, den, np.zeros(300), paired=True)
    iid = ratio_ci(num, den, paired=True)
    assert one[0] < num.mean() / den.mean() < one[1]
    assert one[1] - one[0] == pytest.approx(iid[1] - iid[0], rel=0.2)


def test_clustered_rows_widen_the_ci():
    """Maps that differ a lot and people alike within a map: the iid CI is far too narrow."""
    rng = np.random.default_rng(2)
    level = np.repeat(rng.lognormal(0, 1, 6), 30)  # six maps of 30 people
    env = np.repeat(np.arange(6), 30)
    num = 2.0 * level * rng.lognormal(0, 0.05, 180)
    den = level * rng.lognormal(0, 0.05, 180)
    other = rng.permutation(den)  # unpaired: another sample of people
    iid = ratio_ci(num, other, paired=False)
    clustered = cluster_ratio_ci(num, other, (env, env), paired=False)
    assert clustered[1] - clustered[0] > 1.5 * (iid[1] - iid[0])
    # paired, the map level cancels in each person's pair: both CIs are tight
    paired = cluster_ratio_ci(num, den, env, paired=True)
    assert paired[1] - paired[0] < 0.2


def test_a_duplicated_map_widens_the_ci_against_the_iid_bootstrap():
    rng = np.random.default_rng(4)
    num_map, den_map = rng.exponential(size=(2, 40)), rng.exponential(size=(2, 40))
    num = np.concatenate([num_map[0], num_map[1], num_map[1]])  # map 1 entered twice
    den = np.concatenate([den_map[0], den_map[1], den_map[1]])
    env = np.repeat([0, 1, 1], 40)
    iid = ratio_ci(num, den, paired=True)
    clustered = cluster_ratio_ci(num, den, env, paired=True)
    assert clustered[1] - clustered[0] > iid[1] - iid[0]


def test_units_move_together():
    """An instance's rows (several episode counts) are drawn whole: with values constant per instance,
    each replicate's mean is a weighted mean of instance means with integer weights."""
    env = np.repeat([0, 0, 1, 1], 4)
    unit = np.repeat([0, 1, 0, 1], 4)
    num = np.repeat([1.0, 2.0, 4.0, 8.0], 4)
    rn, _ = cluster_bootstrap_means(num, np.ones(16), env, paired=True, units=unit, resamples=300, seed=0)
    means = {1.0, 2.0, 4.0, 8.0}
    combos = {round(float(np.mean(c)), 9) for c in itertools.product(sorted(means), repeat=4)}
    assert {round(x, 9) for x in rn} <= combos


def test_seeded_and_the_difference_ci():
    rng = np.random.default_rng(5)
    a, b = rng.normal(1, 0.2, 60), rng.normal(1.3, 0.2, 60)
    env = np.arange(60) % 4
    first = cluster_difference_ci(a, b, (env, env), paired=False)
    assert first == cluster_difference_ci(a, b, (env, env), paired=False)
    assert first[0] < a.mean() - b.mean() < first[1] < 0


def test_ratio_claim_uses_the_cluster_bootstrap_where_given():
    rng = np.random.default_rng(6)
    level = np.repeat(rng.lognormal(0, 1, 5), 10)
    env = np.repeat(np.arange(5), 10)
    num, den = 3.0 * level * rng.lognormal(0, 0.3, 50), level * rng.lognormal(0, 0.3, 50)
    other = rng.permutation(den)
    plain = C.ratio_claim("x", "s", "c", "p", num, other, "a", "b", "q", 3.0, paired=False, who="people")
    clustered = C.ratio_claim("x", "s", "c", "p", num, other, "a", "b", "q", 3.0, paired=False,
                              who="people", clusters=(env, env))
    assert plain.value == clustered.value
    assert (clustered.ci_high - clustered.ci_low) > (plain.ci_high - plain.ci_low)
    assert "two-stage cluster bootstrap: the 5 maps" in clustered.why
    assert "two-stage" not in plain.why
