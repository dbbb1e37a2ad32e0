"""Differentiable log-likelihood of demonstrations (paper Eq. 11) in θ and β.

``L(θ, β) = Σ_{s,a} N[s, a] log π_{θ,β}(a|s)`` with counts ``N`` of the observed pairs.
Only ``w = θ'/β`` matters, with θ' = θ, or (θ, 1) on an MDP with a fixed reward
(:meth:`~expertise_irl.mdp.TabularMDP.reward_weights`); values are solved in scaled units
``v = V/β`` as the fixed point of the observation model's backup (:mod:`expertise_irl.models`),
with the same red-black sweep (:func:`expertise_irl.planning.kernels.sweep`, one lane) and the
same solver layout as the batched solver, so the two cannot disagree.

Gradients come from implicit differentiation of that fixed point (a ``custom_vjp``:
reverse-mode through the solver's ``while_loop`` is neither possible nor wanted). With
the cotangent ``g`` of ``v``, the adjoint ``λ = g + (∂S/∂v)ᵀ λ`` of the sweep map ``S`` is a
discounted visitation under π, and ``(∂S/∂w)ᵀ λ`` the expected feature counts it weights.
For ``maxent``:

    ∂L/∂w = Σ N φ(s, a)  −  (discounted expected features under π from the observed states,
                              corrected for their successors),

the familiar max-ent IRL gradient; ∂L/∂θ = ∂L/∂w / β and ∂L/∂β = −(∂L/∂w · θ') / β²
(the fixed reward's weight, 1, enters ∂L/∂β but is not a parameter).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ArgumentError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL, check_model
from ..numerics import enable_float64
from . import kernels as kernel


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


class WarmStart(NamedTuple):
    """Where to start the next solve: converged values and adjoint of a nearby hypothesis.

    Both are in the solver's layout (``[n_rows, 1]``); the result of a solve never depends
    on the start beyond its tolerance, only the number of sweeps does.
    """

    v: jnp.ndarray  # scaled values V/β
    lam: jnp.ndarray  # adjoint of the fixed point for the log-likelihood's gradient


def _fixed_point_fn(prep: kernel.Prepared, gamma: float, tol: float, max_iter: int, model: str):
    """``v*(w, v0, lam0)``: the model's fixed point for one hypothesis, with an implicit gradient.

    Forward: red-black sweeps of the batched solver (:func:`expertise_irl.planning.kernels.sweep`) on one
    lane, from ``v0``. Backward: the adjoint ``λ = g + (∂S/∂v)ᵀ λ`` of the same sweep map ``S``
    (it has the same fixed point, so implicit differentiation through it is exact), iterated
    to ``tol`` from ``lam0`` (or from ``g`` when ``lam0`` is None). Returns the fixed point and
    ``adjoint(w, v, g, lam0)``, the backward iteration on its own.
    """
    def step(w, v):
        # The zero row (terminal states, padding) is a constant 0, not a fixed point of its own:
        # left as the identity it would give the adjoint an eigenvalue 1 that never decays.
        return kernel.sweep(prep, w, v, gamma, model)[0].at[-1].set(0.0)

    def adjoint(w, v, g, lam0):
        _, vjp_v = jax.vjp(lambda v_: step(w, v_), v)
        start = g if lam0 is None else lam0
        return _iterate(lambda lam: g + vjp_v(lam)[0], start, gamma, tol, max_iter)[0]

    @jax.custom_vjp
    def fixed_point(w, v0, lam0):
        return _iterate(lambda v: step(w, v), v0, gamma, tol, max_iter)[0]

    def fwd(w, v0, lam0):
        v = fixed_point(w, v0, lam0)
        return v, (w, v, lam0)

    def bwd(res, g):
        w, v, lam0 = res
        lam = adjoint(w, v, g, lam0)
        _, vjp_w = jax.vjp(lambda w_: step(w_, v), w)
        return vjp_w(lam)[0], jnp.zeros_like(v), None if lam0 is None else jnp.zeros_like(lam0)

    fixed_point.defvjp(fwd, bwd)
    return fixed_point, adjoint


class LogLikelihood:
    """``f(theta, beta, v0=None, *, start=None) -> (L, v)``: JAX-differentiable Eq. 11 for one
    hypothesis (built by :func:`make_log_likelihood`).

    ``theta [K]`` and ``beta`` are JAX scalars/arrays; ``v`` is the converged scaled value
    ``V/β`` ``[S]``, which callers may pass back as ``v0`` to warm-start the next solve.
    ``start`` (a :class:`WarmStart` from :meth:`start_at`) warm-starts both the forward solve
    and the adjoint of the gradient. ``counts`` replaces the observed counts (in the layout of
    :attr:`counts`), as an input rather than a constant of a compiled program.
    ``jax.grad(lambda t, b: f(t, b)[0], argnums=(0, 1))`` gives the exact gradient.
    """

    def __init__(self, mdp: TabularMDP, counts: np.ndarray, tol: float, max_iter: int, model: str):
        enable_float64()
        check_model(model)
        counts = np.asarray(counts, dtype=np.float64)
        if counts.shape != (mdp.n_states, mdp.n_actions):
            raise ArgumentError(f"counts must have shape [S, A] = [{mdp.n_states}, {mdp.n_actions}]")
        self._prep = prep = kernel.prepare(mdp, jnp.float64)
        nb = prep.n_block
        # Counts in the solver's layout [2, A, n_block]; terminal and padding rows observe nothing.
        n_blk = np.zeros((2, mdp.n_actions, nb))
        live = np.flatnonzero(~mdp.terminal)
        rows = prep.rows[live]
        n_blk[rows // nb, :, rows % nb] = np.where(mdp.available, counts, 0.0)[live]
        #: The counts in the solver's layout; pass them back as ``counts=`` so that a compiled
        #: program takes the data as an input (one compile serves every data set on this map).
        self.counts = jnp.asarray(n_blk)
        self._gamma = float(mdp.gamma)
        self._model = model
        self._offset = mdp.has_offset
        self._fixed_point, self._adjoint = _fixed_point_fn(prep, self._gamma, tol, max_iter, model)
        self._state_rows = jnp.asarray(prep.rows)
        # Compiled as a whole: called eagerly (NumPyro traces its model outside any jit to find
        # the sample sites), it would otherwise run, and compile, one primitive at a time.
        self._call = jax.jit(self._evaluate)

    def _weights(self, theta, beta):
        theta = jnp.asarray(theta, jnp.float64)
        if self._offset:  # the fixed reward's weight (see TabularMDP.reward_weights)
            theta = jnp.concatenate([theta, jnp.ones(1)])
        return (theta / beta)[:, None]  # [K', 1 lane]

    def _from_values(self, w, v, counts):
        """Eq. 11 given the converged values ``v`` (solver layout)."""
        prep, gamma, model = self._prep, self._gamma, self._model
        log_pi = jnp.stack([kernel.block_backup(prep, b, w, v, gamma, model)[1][..., 0] for b in (0, 1)])
        # Unobserved pairs (including unavailable ones, log π = -inf) contribute nothing.
        return jnp.sum(jnp.where(counts > 0, counts * log_pi, 0.0))

    def zero_start(self) -> WarmStart:
        """The cold start: values and adjoint 0."""
        z = jnp.zeros((self._prep.n_rows, 1))
        return WarmStart(z, z)

    def __call__(self, theta, beta, v0=None, *, start: WarmStart | None = None, counts=None):
        return self._call(theta, beta, v0, start, self.counts if counts is None else counts)

    def _evaluate(self, theta, beta, v0, start, counts):
        w = self._weights(theta, beta)
        lam0 = None
        if start is not None:
            v_init, lam0 = start.v, jax.lax.stop_gradient(start.lam)
        elif v0 is not None:
            v_init = (jnp.zeros((self._prep.n_rows, 1)).at[self._state_rows, 0]
                      .set(jnp.asarray(v0, jnp.float64)).at[-1, 0].set(0.0))
        else:
            v_init = jnp.zeros((self._prep.n_rows, 1))
        v = self._fixed_point(w, jax.lax.stop_gradient(v_init), lam0)
        return self._from_values(w, v, counts), v[self._state_rows, 0]

    def start_at(self, theta, beta, start: WarmStart | None = None, counts=None) -> WarmStart:
        """The converged values and gradient adjoint at ``(theta, beta)``, solved from ``start``:
        the best start for hypotheses near this one."""
        start = self.zero_start() if start is None else start
        w = jax.lax.stop_gradient(self._weights(theta, beta))
        v = jax.lax.stop_gradient(self._fixed_point(w, start.v, None))
        counts = self.counts if counts is None else counts
        g = jax.grad(lambda v_: self._from_values(w, v_, counts))(v)
        return WarmStart(v, self._adjoint(w, v, g, start.lam))


def make_log_likelihood(
    mdp: TabularMDP, counts: np.ndarray, *, tol: float = 1e-10, max_iter: int = 200_000,
    model: str = DEFAULT_MODEL,
) -> LogLikelihood:
    """``f(theta, beta, v0=None, *, start=None) -> (L, v)``: JAX-differentiable Eq. 11 for one
    hypothesis (see :class:`LogLikelihood`).

    ``model`` is the observation model (:mod:`expertise_irl.models`); the backup is the one
    the batched solver uses. Solves stop when ``V/β`` is within ``tol``; one that has not
    converged after ``max_iter`` sweeps gives NaN.
    """
    return LogLikelihood(mdp, counts, tol, max_iter, model)


class TaskSum:
    """The log-likelihood of one person's demonstrations on several tasks: the sum over tasks.

    Each task is an MDP with the same features (a person who did several maps, specifications
    or start points) and its own counts. Same interface as :class:`LogLikelihood`; a start and
    the counts are tuples with one entry per task, and ``v`` is None.
    """

    def __init__(self, parts: list[LogLikelihood]):
        self._parts = parts
        self.counts = tuple(p.counts for p in parts)

    def zero_start(self) -> tuple:
        return tuple(p.zero_start() for p in self._parts)

    def _each(self, start, counts):
        n = len(self._parts)
        return zip(self._parts, (None,) * n if start is None else start,
                   (None,) * n if counts is None else counts, strict=True)

    def __call__(self, theta, beta, v0=None, *, start: tuple | None = None, counts: tuple | None = None):
        if v0 is not None:
            raise ArgumentError("v0 warm starts a single task; pass start= for several")
        return sum(p(theta, beta, start=s, counts=c)[0] for p, s, c in self._each(start, counts)), None

    def start_at(self, theta, beta, start: tuple | None = None, counts: tuple | None = None) -> tuple:
        return tuple(p.start_at(theta, beta, s, c) for p, s, c in self._each(start, counts))
