"""Summaries of a participant's β, one shape for every inference method.

Each function returns ``{"mean", "median", "geomean", "q05", "q95"}``:

- ``mean``: E[β]; ``geomean``: exp(E[log β]), the centre on β's natural (log) scale;
- ``median``, ``q05``, ``q95``: the 50%, 5% and 95% quantiles.

How each is taken:

- :func:`beta_summary_grid` (a discrete posterior on a β grid): the expectations are sums over
  the grid; the q-quantile is the **smallest grid value whose cumulative probability is ≥ q**
  (the lower quantile of a discrete distribution; cumulative sums are compared with
  ``q − 1e-12`` so that rounding in the sums does not push a quantile one grid step up). The
  quantiles are therefore always grid values, never interpolated between them.
- :func:`beta_summary_draws` (posterior draws, NUTS or Algorithm 1): sample mean and
  exp(mean of log β); the quantiles are :func:`numpy.quantile`'s default (``method="linear"``:
  linear interpolation between the order statistics, so the median of an even number of draws
  is the mean of the middle two).
- :func:`beta_summary_point` (a MAP estimate β̂): mean = median = geomean = β̂ and no interval
  (``q05 = q95 = None``).

Every β must be a finite number > 0 (the geometric mean needs log β); anything else raises
:class:`~expertise_irl.errors.InputError`.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

KEYS = ("mean", "median", "geomean", "q05", "q95")
#: Slack on the cumulative sums of :func:`beta_summary_grid` (rounding, not probability).
CDF_SLACK = 1e-12


def _positive(values, what: str) -> np.ndarray:
    x = np.asarray(values, dtype=np.float64).reshape(-1)
    if x.size == 0:
        raise InputError(f"{what}: no values")
    if not np.all(np.isfinite(x) & (x > 0)):
        bad = x[~(np.isfinite(x) & (x > 0))][0]
        raise InputError(f"{what}: every β must be a finite number > 0, got {bad:g}")
    return x


def grid_quantile(values: np.ndarray, cdf: np.ndarray, q: float) -> float:
    """The smallest of the ascending ``values`` whose cumulative probability ``cdf`` is ≥ q."""
    i = int(np.searchsorted(cdf, q - CDF_SLACK, side="left"))
    return float(values[min(i, len(values) - 1)])


def beta_summary_grid(values, probabilities) -> dict:
    """Summary of a discrete distribution of β: ``probabilities[i]`` on ``values[i]``.

    The values need not be sorted; the probabilities must be ≥ 0 and sum to 1 (within 1e-6; they
    are then renormalised). See the module docstring for the quantile rule.
    """
    v = _positive(values, "β grid")
    p = np.asarray(probabilities, dtype=np.float64).reshape(-1)
    if p.shape != v.shape:
        raise InputError(f"β grid: {v.size} values but {p.size} probabilities")
    if not np.all(np.isfinite(p) & (p >= 0)):
        raise InputError("β grid: probabilities must be finite and ≥ 0")
    total = float(p.sum())
    if abs(total - 1.0) > 1e-6:
        raise InputError(f"β grid: probabilities must sum to 1, got {total:.6g}")
    p = p / total
    order = np.argsort(v, kind="stable")
    v, p = v[order], p[order]
    cdf = np.cumsum(p)
    return {
        "mean": float(p @ v),
        "median": grid_quantile(v, cdf, 0.5),
        "geomean": float(math.exp(p @ np.log(v))),
        "q05": grid_quantile(v, cdf, 0.05),
        "q95": grid_quantile(v, cdf, 0.95),
    }


def beta_summary_draws(draws) -> dict:
    """Summary of draws of β (any shape, flattened): sample moments and linear-interpolation
    quantiles (:func:`numpy.quantile`'s default)."""
    x = _positive(draws, "β draws")
    q05, q50, q95 = np.quantile(x, [0.05, 0.5, 0.95])
    return {"mean": float(x.mean()), "median": float(q50), "geomean": float(np.exp(np.log(x).mean())),
            "q05": float(q05), "q95": float(q95)}


def beta_summary_point(beta: float) -> dict:
    """Summary of a point estimate β̂ (MAP): every centre is β̂, and there is no interval."""
    b = float(_positive([beta], "β̂")[0])
    return {"mean": b, "median": b, "geomean": b, "q05": None, "q95": None}
