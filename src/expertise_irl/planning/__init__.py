"""Planning: soft value iteration for many hypotheses at once, and the likelihoods built on it.

- :mod:`.kernels`: the lane-pool kernels (red-black sweeps, over-relaxation, the final backup)
  and the MDP in their layout;
- :mod:`.level_order`: sweeps in order of the distance to the goal (the ``levels`` method's
  start values);
- :mod:`.soft_vi`: :func:`solve`, batched soft value iteration (Eqs. 8–9) with per-hypothesis
  stopping, chunking and progress;
- :mod:`.tuning`: the lane width measured per machine, cached in the user cache;
  :mod:`.jax_cache`: JAX's persistent compilation cache in the same place;
- :mod:`.table_likelihood`: log π read from a solved ``[H, S, A]`` table (the discrete set);
- :mod:`.differentiable`: the log-likelihood solved inside JAX with an implicit gradient
  (MAP, NUTS, Algorithm 1).

Float64 is switched on by a call, not by an import: :func:`.soft_vi.solve`, :func:`.kernels.prepare`
(where every solve and likelihood moves its MDP to the device), :class:`.differentiable.LogLikelihood`
and the tuner call :func:`expertise_irl.numerics.enable_float64` before their first JAX array, so
soft value iteration at small β gets the precision it needs whoever calls it. This package's own
names are imported on first use, so :mod:`.jax_cache` and :mod:`.tuning`'s cache reads do not
load JAX.
"""

from __future__ import annotations

import importlib
from typing import Any

#: public name -> submodule that defines it
_EXPORTS = {"DEFAULT_TOL": ".soft_vi", "SoftSolution": ".soft_vi", "solve": ".soft_vi",
            "log_likelihood": ".table_likelihood"}

__all__ = ["DEFAULT_TOL", "SoftSolution", "log_likelihood", "solve"]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(module, __name__), name)
