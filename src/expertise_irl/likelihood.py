"""Differentiable log-likelihood of demonstrations (paper Eq. 11) in θ and β.

``L(θ, β) = Σ_{s,a} N[s, a] log π_{θ,β}(a|s)`` with counts ``N`` of the observed pairs.
Only ``w = θ/β`` matters; soft values are solved in scaled units ``v = V/β`` as the
fixed point ``v = T(w, v) = logsumexp_a(φ·w + γ v[next])``.

Gradients come from implicit differentiation of that fixed point (a ``custom_vjp``:
reverse-mode through the solver's ``while_loop`` is neither possible nor wanted). With
the cotangent ``g`` of ``v``, the adjoint ``λ = g + (∂T/∂v)ᵀ λ`` is a discounted
visitation under π, and ``(∂T/∂w)ᵀ λ`` the expected feature counts it weights. So

    ∂L/∂w = Σ N φ(s, a)  −  (discounted expected features under π from the observed states,
                              corrected for their successors),

the familiar max-ent IRL gradient; ∂L/∂θ = ∂L/∂w / β and ∂L/∂β = −(∂L/∂w · θ) / β².
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .demos import Trajectories
from .errors import InputError
from .mdp import TabularMDP

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


def _arrays(mdp: TabularMDP):
    S, A = mdp.n_states, mdp.n_actions
    term = mdp.terminal
    self_idx = np.broadcast_to(np.arange(S)[:, None], (S, A))
    avail = mdp.available.copy()
    avail[term, 0] = True  # terminal rows: one zero-reward self-loop keeps v = 0
    next_idx = np.where((mdp.next_state >= 0) & ~term[:, None], mdp.next_state, self_idx)
    feats = np.where(term[:, None, None], 0.0, mdp.features)
    return jnp.asarray(feats), jnp.asarray(next_idx, dtype=jnp.int32), jnp.asarray(avail)


def _bellman(feats, next_idx, avail, gamma, w, v):
    """One soft backup T(w, v) in scaled units; also returns the log-policy."""
    q = jnp.where(avail, feats @ w, -jnp.inf) + gamma * v[next_idx]
    m = jax.lax.stop_gradient(jnp.max(q, axis=1, keepdims=True))
    log_norm = m[:, 0] + jnp.log(jnp.sum(jnp.exp(q - m), axis=1))
    return log_norm, q - log_norm[:, None]


def _iterate(step, x0, gamma, tol, max_iter):
    """Iterate a γ-contraction to ||x_n+1 - x_n|| <= tol (1-γ)/γ (floored at 8 ulps of |x|)."""
    eps = jnp.finfo(x0.dtype).eps
    thresh = tol * (1 - gamma) / gamma

    def cond(c):
        x, d, k = c
        return (d > jnp.maximum(thresh, 8 * eps * jnp.max(jnp.abs(x)))) & (k < max_iter)

    def body(c):
        x, _, k = c
        x_new = step(x)
        return x_new, jnp.max(jnp.abs(x_new - x)), k + 1

    x, _, k = jax.lax.while_loop(cond, body, (x0, jnp.inf, 0))
    return x, k


@partial(jax.custom_vjp, nondiff_argnums=(0, 1, 2, 3, 4, 5))
def _fixed_point(feats, next_idx, avail, gamma, tol, max_iter, w, v0):
    v, _ = _iterate(lambda v: _bellman(feats, next_idx, avail, gamma, w, v)[0], v0, gamma, tol, max_iter)
    return v


def _fixed_point_fwd(feats, next_idx, avail, gamma, tol, max_iter, w, v0):
    v = _fixed_point(feats, next_idx, avail, gamma, tol, max_iter, w, v0)
    return v, (w, v)


def _fixed_point_bwd(feats, next_idx, avail, gamma, tol, max_iter, res, g):
    w, v = res
    _, vjp_v = jax.vjp(lambda v_: _bellman(feats, next_idx, avail, gamma, w, v_)[0], v)
    lam, _ = _iterate(lambda lam: g + vjp_v(lam)[0], g, gamma, tol, max_iter)
    _, vjp_w = jax.vjp(lambda w_: _bellman(feats, next_idx, avail, gamma, w_, v)[0], w)
    return vjp_w(lam)[0], jnp.zeros_like(v)


_fixed_point.defvjp(_fixed_point_fwd, _fixed_point_bwd)


def make_log_likelihood(
    mdp: TabularMDP, counts: np.ndarray, *, tol: float = 1e-10, max_iter: int = 200_000
) -> Callable:
    """``f(theta, beta, v0=None) -> (L, v)``: JAX-differentiable Eq. 11 for one hypothesis.

    ``theta [K]`` and ``beta`` are JAX scalars/arrays; ``v`` is the converged scaled value
    ``V/β`` ``[S]``, which callers may pass back as ``v0`` to warm-start the next solve.
    ``jax.grad(lambda t, b: f(t, b)[0], argnums=(0, 1))`` gives the exact gradient.
    """
    counts = np.asarray(counts, dtype=np.float64)
    if counts.shape != (mdp.n_states, mdp.n_actions):
        raise InputError(f"counts must have shape [S, A] = [{mdp.n_states}, {mdp.n_actions}]")
    feats, next_idx, avail = _arrays(mdp)
    n = jnp.asarray(np.where(mdp.available, counts, 0.0))
    gamma = float(mdp.gamma)
    S = mdp.n_states

    def f(theta, beta, v0=None):
        w = jnp.asarray(theta, jnp.float64) / beta
        v0 = jnp.zeros(S) if v0 is None else v0
        v = _fixed_point(feats, next_idx, avail, gamma, tol, max_iter, w, jax.lax.stop_gradient(v0))
        _, log_pi = _bellman(feats, next_idx, avail, gamma, w, v)
        # Unobserved pairs (including unavailable ones, log π = -inf) contribute nothing.
        return jnp.sum(n * jnp.where(n > 0, log_pi, 0.0)), v

    return f
