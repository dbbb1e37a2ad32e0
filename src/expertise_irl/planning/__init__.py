"""Planning: soft value iteration for many hypotheses at once, and the likelihoods built on it.

- :mod:`.kernels`: the lane-pool kernels (red-black sweeps, over-relaxation, the final backup)
  and the MDP in their layout;
- :mod:`.soft_vi`: :func:`solve`, batched soft value iteration (Eqs. 8–9) with per-hypothesis
  stopping, chunking and progress;
- :mod:`.tuning`: the lane width measured per machine, cached in the user cache;
  :mod:`.jax_cache`: JAX's persistent compilation cache in the same place;
- :mod:`.table_likelihood`: log π read from a solved ``[H, S, A]`` table (the discrete set);
- :mod:`.differentiable`: the log-likelihood solved inside JAX with an implicit gradient
  (MAP, NUTS, Algorithm 1).

Float64 is switched on here, once, for the whole process: soft value iteration at small β
needs it, and every module that computes with JAX imports this package first.
"""

import jax

jax.config.update("jax_enable_x64", True)

from .soft_vi import DEFAULT_TOL, SoftSolution, solve  # noqa: E402  (after float64 is on)
from .table_likelihood import log_likelihood  # noqa: E402

__all__ = ["DEFAULT_TOL", "SoftSolution", "log_likelihood", "solve"]
