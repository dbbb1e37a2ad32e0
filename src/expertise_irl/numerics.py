"""The package's numerical configuration: JAX computes in float64.

Soft value iteration at small β needs float64 (``V = β · logsumexp(Q / β)`` loses every digit of a
Q difference below β · 1e-7 in float32), and so do the likelihoods, gradients and samplers built
on it. JAX computes in float32 unless ``jax_enable_x64`` is set, so :func:`enable_float64` sets it.

Nothing is switched on by importing a module of the package. The functions that compute with JAX
call :func:`enable_float64` before they make their first array: :func:`~expertise_irl.planning.solve`
and the solver's kernels, the differentiable likelihood behind MAP, NUTS and Algorithm 1, the
population model, the lane-width tuner. A Python user calling any of them gets float64 without
doing anything; the command line calls it when it starts. The call is cheap and idempotent, and it
switches JAX for the whole process (JAX has one such setting): a program that mixes its own
float32 JAX code with this package should create its arrays with an explicit ``dtype``.

Before JAX is imported the call only sets ``JAX_ENABLE_X64=1`` in the environment, which JAX reads
when it is imported (so the command line's ``--help`` does not load JAX, and worker processes
started from the command inherit the setting); once JAX is imported it sets the flag itself.
"""

from __future__ import annotations

import os
import sys

import numpy as np

__all__ = ["enable_float64", "log_sum_exp"]

_enabled = False


def enable_float64() -> None:
    """Switch JAX to float64 for this process (``jax_enable_x64``); idempotent.

    Called by every entry point of the package that computes with JAX, before its first array, so
    a caller never needs to. Before JAX is imported it only sets ``JAX_ENABLE_X64=1`` in the
    environment, which JAX reads on import.
    """
    global _enabled
    if _enabled:
        return
    if "jax" not in sys.modules:
        os.environ["JAX_ENABLE_X64"] = "1"
        return  # checked again once JAX is imported
    import jax

    jax.config.update("jax_enable_x64", True)
    _enabled = True


def log_sum_exp(x: np.ndarray, axis=None) -> np.ndarray:
    """log Σ exp(x) over ``axis`` (every axis by default) with the max taken out: −inf (no NaN, no
    warning) where every term is −inf. The plain form of :func:`scipy.special.logsumexp`, which
    costs twice as much on large arrays and about 1 ms a call in its checks on small ones."""
    x = np.asarray(x)
    m = np.max(x, axis=axis, keepdims=True)
    m0 = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        return np.squeeze(m0, axis=axis) + np.log(np.sum(np.exp(x - m0), axis=axis))
