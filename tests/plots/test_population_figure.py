"""The population figure (plots/population.py) of a hand-made population result: a row per
participant with their independent and pooled 90% intervals, a curve per group, θ's mean. (The
pooled posteriors are the independent ones here: the figure draws what it is given.)"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from expertise_irl.hypotheses import HypothesisSet, resolve_thetas
from expertise_irl.inference.population import (
    Hyperparameters,
    independent_posteriors,
    population_data,
    population_theta_prior,
)
from expertise_irl.plots.population import population_figure, render_population_png

NAMES = ["length", "road", "avoid", "slow", "traffic"]


def result(groups):
    hyp = HypothesisSet(resolve_thetas("paper-real", 3), [0.1, 0.5, 1.0, 5.0])
    names = [f"p{i}" for i in range(1, 5)]
    data = population_data(np.random.default_rng(0).normal(-5, 1, (4, len(hyp))), hyp, groups=groups,
                           participants=names)
    k = hyp.thetas.shape[1]
    g = data.n_groups
    psi = Hyperparameters(np.log(0.5) * np.ones(g), np.ones(g), 20.0, np.full(k, 1 / k))
    mean = population_theta_prior(hyp, psi) @ hyp.thetas
    doc = {"theta_population_mean": {f: {"mean": m, "q05": m, "q95": m}
                                     for f, m in zip(NAMES[:k], mean, strict=True)}}
    post = SimpleNamespace(mu=psi.mu[None, :].repeat(3, axis=0), sigma=psi.sigma[None, :].repeat(3, axis=0))
    independent = independent_posteriors(data)
    return {"document": doc, "data": data, "posterior": post, "shrunk": independent,
            "independent": independent}, NAMES[:k], names


@pytest.mark.parametrize("groups", [None, ["A", "B", "A", "B"]])
def test_a_row_per_participant_and_a_curve_per_group(tmp_path, groups):
    res, features, names = result(groups)
    fig = population_figure(res, features, title="four people")
    ax, ax_t = fig.axes
    gids = {a.get_gid() for a in ax.get_children()}
    assert {"independent", "pooled"} <= gids
    assert {f"population-{k}" for k in range(1 if groups is None else 2)} <= gids
    assert sorted(t.get_text() for t in ax.get_yticklabels()) == names
    assert [t.get_text() for t in ax_t.get_yticklabels()] == features
    png = render_population_png(tmp_path / "population.png", res, features)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
