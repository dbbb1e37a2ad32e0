"""The second baseline: soft value iteration as a researcher fluent in JAX would write it.

One jitted function per chunk of hypotheses: ``jax.vmap`` of a ``lax.while_loop`` of the
Eq. 8-9 backup (gather the successors' values, ``logsumexp`` over actions), in reward units,
stopping on the library's guarantee (the error of V/β bounded by ``tol``). Under ``vmap`` the
loop runs until the slowest hypothesis of the chunk has converged. Kept here, not in the
package: it exists only to be measured against.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import logsumexp

jax.config.update("jax_enable_x64", True)

CHUNK = 512


def make_vmap_solver(mdp, tol: float = 1e-8, max_iter: int = 100_000):
    """``solve(thetas [H, K], betas [H]) -> (log π [H, S, A], iterations [H])`` for one chunk."""
    terminal = jnp.asarray(mdp.terminal)
    avail = jnp.asarray((mdp.next_state >= 0) & ~mdp.terminal[:, None])
    nxt = jnp.asarray(np.where(mdp.next_state >= 0, mdp.next_state, 0))
    features = jnp.asarray(mdp.features)
    gamma = float(mdp.gamma)

    def one(theta, beta):
        reward = features @ theta
        thresh = tol * beta * (1 - gamma) / gamma  # |V_n+1 - V_n| <= thresh => |V/β - V*/β| <= tol

        def backup(v):
            q = jnp.where(avail, reward + gamma * v[nxt], -jnp.inf)
            return q, jnp.where(terminal, 0.0, beta * logsumexp(q / beta, axis=1))

        def body(carry):
            v, _, it = carry
            v_new = backup(v)[1]
            delta = jnp.max(jnp.abs(v_new - v))
            return v_new, delta, it + (delta > thresh)  # a lane's own count, not the chunk's

        v, _, it = jax.lax.while_loop(lambda c: (c[1] > thresh) & (c[2] < max_iter), body,
                                      (jnp.zeros(terminal.shape), jnp.inf, 0))
        q, _ = backup(v)
        return jnp.where(avail, (q - v[:, None]) / beta, -jnp.inf), it + 1

    return jax.jit(jax.vmap(one))


def vmap_solve(mdp, thetas, betas, tol: float = 1e-8, chunk: int = CHUNK):
    """All hypotheses, ``chunk`` at a time (the last chunk padded with copies of the first, so
    one compiled program serves every chunk); returns (log π [H, S, A], iterations [H])."""
    solve = make_vmap_solver(mdp, tol)
    H = len(betas)
    out_lp, out_it = [], []
    for lo in range(0, H, chunk):
        t, b = np.asarray(thetas[lo:lo + chunk]), np.asarray(betas[lo:lo + chunk])
        n = len(b)
        if n < chunk and H > chunk:
            t = np.concatenate([t, np.repeat(t[:1], chunk - n, axis=0)])
            b = np.concatenate([b, np.repeat(b[:1], chunk - n)])
        lp, it = solve(jnp.asarray(t), jnp.asarray(b))
        out_lp.append(np.asarray(lp)[:n])
        out_it.append(np.asarray(it)[:n])
    return np.concatenate(out_lp), np.concatenate(out_it)
