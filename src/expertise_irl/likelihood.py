"""Differentiable log-likelihood of demonstrations (paper Eq. 11) in θ and β.

``L(θ, β) = Σ_{s,a} N[s, a] log π_{θ,β}(a|s)`` with counts ``N`` of the observed pairs.
Only ``w = θ/β`` matters; values are solved in scaled units ``v = V/β`` as the fixed point
of the observation model's backup (:mod:`expertise_irl.models`), with the same red-black
sweep (:func:`expertise_irl.solver.sweep`, one lane) and the same solver layout as the
batched solver, so the two cannot disagree.

Gradients come from implicit differentiation of that fixed point (a ``custom_vjp``:
reverse-mode through the solver's ``while_loop`` is neither possible nor wanted). With
the cotangent ``g`` of ``v``, the adjoint ``λ = g + (∂S/∂v)ᵀ λ`` of the sweep map ``S`` is a
discounted visitation under π, and ``(∂S/∂w)ᵀ λ`` the expected feature counts it weights.
For ``maxent``:

    ∂L/∂w = Σ N φ(s, a)  −  (discounted expected features under π from the observed states,
                              corrected for their successors),

the familiar max-ent IRL gradient; ∂L/∂θ = ∂L/∂w / β and ∂L/∂β = −(∂L/∂w · θ) / β².
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import solver as kernel
from .demos import Trajectories
from .errors import InputError
from .mdp import TabularMDP
from .models import DEFAULT_MODEL, check_model

jax.config.update("jax_enable_x64", True)


def pair_counts(mdp: TabularMDP, trajs: Trajectories) -> np.ndarray:
    """``[S, A]`` number of times each (state, action) pair was observed."""
    counts = np.zeros((mdp.n_states, mdp.n_actions))
    np.add.at(counts, (trajs.state, trajs.action), 1.0)
    bad = (counts > 0) & ~mdp.available
    if bad.any():
        s, a = np.argwhere(bad)[0]
        raise InputError(f"observed action {a} is not available in {mdp.describe_state(int(s))}")
    return counts


def _iterate(step, x0, gamma, tol, max_iter):
    """Iterate a γ-contraction to ||x_n+1 - x_n|| <= tol (1-γ)/γ (floored at 8 ulps of |x|).

    Returns ``(x, iterations)``; ``x`` is NaN if ``max_iter`` was reached first, so a solve that
    did not converge shows as a non-finite likelihood or gradient (MAP rejects the point, NUTS
    counts a divergence) instead of a silently wrong number.
    """
    eps = jnp.finfo(x0.dtype).eps
    thresh = tol * (1 - gamma) / gamma

    def unconverged(x, d):
        return d > jnp.maximum(thresh, 8 * eps * jnp.max(jnp.abs(x)))

    def cond(c):
        x, d, k = c
        return unconverged(x, d) & (k < max_iter)

    def body(c):
        x, _, k = c
        x_new = step(x)
        return x_new, jnp.max(jnp.abs(x_new - x)), k + 1

    x, d, k = jax.lax.while_loop(cond, body, (x0, jnp.inf, 0))
    return jnp.where(unconverged(x, d), jnp.nan, x), k


def _fixed_point_fn(prep: kernel.Prepared, gamma: float, tol: float, max_iter: int, model: str):
    """``v*(w, v0)``: the model's fixed point for one hypothesis, with an implicit gradient.

    Forward: red-black sweeps of the batched solver (:func:`expertise_irl.solver.sweep`) on one
    lane. Backward: the adjoint ``λ = g + (∂S/∂v)ᵀ λ`` of the same sweep map ``S`` (it has the
    same fixed point, so implicit differentiation through it is exact), iterated to ``tol``.
    """
    def step(w, v):
        # The zero row (terminal states, padding) is a constant 0, not a fixed point of its own:
        # left as the identity it would give the adjoint an eigenvalue 1 that never decays.
        return kernel.sweep(prep, w, v, gamma, model)[0].at[-1].set(0.0)

    @jax.custom_vjp
    def fixed_point(w, v0):
        return _iterate(lambda v: step(w, v), v0, gamma, tol, max_iter)[0]

    def fwd(w, v0):
        v = fixed_point(w, v0)
        return v, (w, v)

    def bwd(res, g):
        w, v = res
        _, vjp_v = jax.vjp(lambda v_: step(w, v_), v)
        lam, _ = _iterate(lambda lam: g + vjp_v(lam)[0], g, gamma, tol, max_iter)
        _, vjp_w = jax.vjp(lambda w_: step(w_, v), w)
        return vjp_w(lam)[0], jnp.zeros_like(v)

    fixed_point.defvjp(fwd, bwd)
    return fixed_point


def make_log_likelihood(
    mdp: TabularMDP, counts: np.ndarray, *, tol: float = 1e-10, max_iter: int = 200_000,
    model: str = DEFAULT_MODEL,
) -> Callable:
    """``f(theta, beta, v0=None) -> (L, v)``: JAX-differentiable Eq. 11 for one hypothesis.

    ``theta [K]`` and ``beta`` are JAX scalars/arrays; ``v`` is the converged scaled value
    ``V/β`` ``[S]``, which callers may pass back as ``v0`` to warm-start the next solve.
    ``jax.grad(lambda t, b: f(t, b)[0], argnums=(0, 1))`` gives the exact gradient.
    ``model`` is the observation model (:mod:`expertise_irl.models`); the backup is the one
    the batched solver uses.
    """
    check_model(model)
    counts = np.asarray(counts, dtype=np.float64)
    if counts.shape != (mdp.n_states, mdp.n_actions):
        raise InputError(f"counts must have shape [S, A] = [{mdp.n_states}, {mdp.n_actions}]")
    prep = kernel.prepare(mdp, jnp.float64)
    nb = prep.n_block
    # Counts in the solver's layout [2, A, n_block]; terminal and padding rows observe nothing.
    n_blk = np.zeros((2, mdp.n_actions, nb))
    live = np.flatnonzero(~mdp.terminal)
    rows = prep.rows[live]
    n_blk[rows // nb, :, rows % nb] = np.where(mdp.available, counts, 0.0)[live]
    n_blk = jnp.asarray(n_blk)
    observed = n_blk > 0
    gamma = float(mdp.gamma)
    fixed_point = _fixed_point_fn(prep, gamma, tol, max_iter, model)
    state_rows = jnp.asarray(prep.rows)

    def f(theta, beta, v0=None):
        w = (jnp.asarray(theta, jnp.float64) / beta)[:, None]  # [K, 1 lane]
        v_init = jnp.zeros((prep.n_rows, 1))
        if v0 is not None:
            v_init = v_init.at[state_rows, 0].set(jnp.asarray(v0, jnp.float64)).at[-1, 0].set(0.0)
        v = fixed_point(w, jax.lax.stop_gradient(v_init))
        log_pi = jnp.stack([kernel.block_backup(prep, b, w, v, gamma, model)[1][..., 0] for b in (0, 1)])
        # Unobserved pairs (including unavailable ones, log π = -inf) contribute nothing.
        return jnp.sum(jnp.where(observed, n_blk * log_pi, 0.0)), v[state_rows, 0]

    return f
