"""The learning curve of ``infer --expertise changing``: an honest β axis, episodes from 0."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

from expertise_irl.plots import results as rp


def _doc(mean, q05, q95, beta_hat):
    curve = [{"episode": e, "mean": m, "median": m, "q05": lo, "q95": hi}
             for e, (m, lo, hi) in enumerate(zip(mean, q05, q95, strict=True))]
    return {"expertise_by_episode": curve, "beta_hat": beta_hat,
            "changing": {"log_bayes_factor": -1.2, "p_changing": 0.23}, "trend": {"p_falls": 0.0}}


def _axis(doc):
    ax = Figure().subplots()
    rp.draw_learning_curve(ax, doc)
    ax.figure.canvas.draw()
    return ax


def _line(ax, gid):
    (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == gid]
    return line


def test_a_constant_person_is_drawn_flat_with_distinct_ticks_and_episodes_from_0():
    # β̂_e = 0.5 up to 1e-8 of rounding, a band of width 0: the axis spans at least a factor of 4
    # centred on 0.5, so the wiggle is far below a pixel; every tick label is a different number.
    rng = np.random.default_rng(0)
    mean = 0.5 + 1e-8 * rng.random(20)
    ax = _axis(_doc(mean, [0.5] * 20, [0.5] * 20, 0.5))
    lo, hi = ax.get_ylim()
    assert hi / lo >= rp.CURVE_MIN_SPAN * (1 - 1e-12)
    assert np.sqrt(lo * hi) == pytest.approx(0.5, rel=1e-6)
    pixels = ax.transData.transform(np.c_[np.arange(20), mean])[:, 1]
    assert np.ptp(pixels) < 0.01
    labels = [t.get_text() for t in ax.get_yticklabels() if lo <= t.get_position()[1] <= hi]
    assert labels and len(set(labels)) == len(labels)
    assert "0.5" in labels
    x = _line(ax, "curve-mean").get_xdata()
    assert list(x) == list(range(20))


def test_a_curve_that_changes_fills_the_axis_it_needs():
    # β falls 40-fold: the axis holds every mean and band edge, and the change spans most of it.
    mean = np.exp(np.linspace(np.log(2.0), np.log(0.05), 8))
    ax = _axis(_doc(mean, mean / 1.5, mean * 1.5, 0.3))
    lo, hi = ax.get_ylim()
    assert lo <= (mean / 1.5).min() and hi >= (mean * 1.5).max()
    assert np.log(mean.max() / mean.min()) > 0.6 * np.log(hi / lo)


def test_curve_limits_by_hand():
    lo, hi = rp.curve_limits(np.array([1.0, 1.0]), min_span=4.0)
    assert (lo, hi) == (0.5, 2.0)
    lo, hi = rp.curve_limits(np.array([0.1, 10.0, np.nan, -1.0]))
    assert np.isclose(np.log10(lo), -1.16) and np.isclose(np.log10(hi), 1.16)
