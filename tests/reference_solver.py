"""Slow, obvious reference solvers for ONE hypothesis, used to check ``planning.solve``.

Written directly from the paper's Eqs. 8–9 in reward units, with plain Python
loops over states and actions (no vectorisation, no scaled-units trick):

    Q[s, a] = θ · φ(s, a) + γ V[next(s, a)]          for available actions
    V[s]    = β log Σ_a exp(Q[s, a] / β)               (shifted by max_a Q[s, a])
    V[s]    = 0                                        at terminal states
    log π(a | s) = (Q[s, a] − V[s]) / β                (−inf where unavailable)

and the hard (β = 0) value iteration ``V[s] = max_a Q[s, a]`` with its greedy action sets.

Iteration runs until the largest change of V is a few ulps of ``max(1, max|V|)``, so
the truncation error is negligible next to the rounding error of the arithmetic
itself. ``extended=True`` does the same arithmetic in ``np.longdouble`` (80-bit on
x86-64, eps ≈ 1.1e-19): a reference far more accurate than any float64 code, for
checking accuracy at the float64 limit.

``random_mdp`` builds the random test MDPs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from expertise_irl.mdp import TabularMDP

MAX_ITER = 200_000
#: Stop when max|ΔV| <= STOP_ULPS * eps * max(1, max|V|).
STOP_ULPS = 8


class ReferenceSoft(NamedTuple):
    q: np.ndarray  # [S, A] soft Q in reward units, -inf where unavailable / terminal
    value: np.ndarray  # [S] soft V in reward units, 0 at terminal states
    log_policy: np.ndarray  # [S, A] (Q - V) / β, -inf where unavailable / terminal
    iterations: int


class ReferenceHard(NamedTuple):
    q: np.ndarray  # [S, A] hard Q, -inf where unavailable / terminal
    value: np.ndarray  # [S] hard V = max_a Q, 0 at terminal states
    greedy: list[set[int]]  # per state: the argmax actions (empty at terminal states)
    iterations: int


class _Arith(NamedTuple):
    num: Callable  # number type: float or np.longdouble
    exp: Callable
    log: Callable
    eps: float


_FLOAT = _Arith(float, math.exp, math.log, float(np.finfo(np.float64).eps))
_EXTENDED = _Arith(np.longdouble, np.exp, np.log, float(np.finfo(np.longdouble).eps))


def _rewards(mdp: TabularMDP, theta, ar: _Arith) -> tuple[list[list[int]], list[list]]:
    """Per state: its available actions and their rewards θ · φ(s, a) + offset (none if terminal)."""
    theta = [ar.num(t) for t in np.asarray(theta, dtype=np.float64).tolist()]
    actions: list[list[int]] = []
    rewards: list[list] = []
    for s in range(mdp.n_states):
        acts, rews = [], []
        if not mdp.terminal[s]:
            for a in range(mdp.n_actions):
                if mdp.next_state[s, a] >= 0:
                    r = ar.num(0)
                    for k in range(mdp.n_features):
                        r += theta[k] * ar.num(float(mdp.features[s, a, k]))
                    if mdp.reward_offset is not None:  # a reward every hypothesis gets alike
                        r += ar.num(float(mdp.reward_offset[s, a]))
                    acts.append(a)
                    rews.append(r)
        actions.append(acts)
        rewards.append(rews)
    return actions, rewards


def _q_table(mdp: TabularMDP, actions, rewards, value, ar: _Arith) -> list[list]:
    """Q[s][i] = r + γ V[next] for the i-th available action of state s."""
    g = ar.num(mdp.gamma)
    q = []
    for s in range(mdp.n_states):
        row = []
        for a, r in zip(actions[s], rewards[s], strict=True):
            row.append(r + g * value[int(mdp.next_state[s, a])])
        q.append(row)
    return q


def _soft_max(qs: list, beta, ar: _Arith):
    """β log Σ exp(q / β), shifted by the largest q."""
    m = max(qs)
    total = ar.num(0)
    for q in qs:
        total += ar.exp((q - m) / beta)
    return m + beta * ar.log(total)


def _value_iteration(mdp: TabularMDP, actions, rewards, state_value, ar: _Arith):
    """Iterate V[s] = state_value(Q[s]) (0 at terminals) until max|ΔV| is a few ulps."""
    S = mdp.n_states
    value = [ar.num(0)] * S
    for it in range(1, MAX_ITER + 1):
        q = _q_table(mdp, actions, rewards, value, ar)
        new = [ar.num(0) if mdp.terminal[s] else state_value(q[s]) for s in range(S)]
        delta = max(abs(x - y) for x, y in zip(new, value, strict=True))
        value = new
        if delta <= STOP_ULPS * ar.eps * max(1.0, max(abs(v) for v in value)):
            return value, it
    raise RuntimeError(f"reference value iteration did not converge in {MAX_ITER} iterations")


def soft_value_iteration(mdp: TabularMDP, theta, beta: float, *,
                         extended: bool = False) -> ReferenceSoft:
    """Soft value iteration (Eqs. 8–9) for one hypothesis (θ, β), in reward units."""
    assert beta > 0
    ar = _EXTENDED if extended else _FLOAT
    b = ar.num(beta)
    actions, rewards = _rewards(mdp, theta, ar)
    value, it = _value_iteration(mdp, actions, rewards, lambda qs: _soft_max(qs, b, ar), ar)
    # One more backup, so that V is exactly the log-partition of the returned Q.
    q = _q_table(mdp, actions, rewards, value, ar)
    value = [ar.num(0) if mdp.terminal[s] else _soft_max(q[s], b, ar)
             for s in range(mdp.n_states)]
    Q = np.full((mdp.n_states, mdp.n_actions), -np.inf)
    log_pi = np.full((mdp.n_states, mdp.n_actions), -np.inf)
    for s in range(mdp.n_states):
        for a, qa in zip(actions[s], q[s], strict=True):
            Q[s, a] = float(qa)
            log_pi[s, a] = float((qa - value[s]) / b)
    return ReferenceSoft(Q, np.array([float(v) for v in value]), log_pi, it)


def relative_value_iteration(mdp: TabularMDP, theta, beta: float) -> ReferenceSoft:
    """``maxent-relative`` for one hypothesis, in reward units, straight from its definition:

        V[s] = β log( (1/|A(s)|) Σ_a exp(Q[s, a] / β) ),   π(a|s) = exp((Q − V)/β) / |A(s)|.
    """
    assert beta > 0
    ar = _FLOAT
    actions, rewards = _rewards(mdp, theta, ar)

    def value_of(qs):
        return _soft_max(qs, beta, ar) - beta * math.log(len(qs))

    value, it = _value_iteration(mdp, actions, rewards, value_of, ar)
    q = _q_table(mdp, actions, rewards, value, ar)
    value = [0.0 if mdp.terminal[s] else value_of(q[s]) for s in range(mdp.n_states)]
    Q = np.full((mdp.n_states, mdp.n_actions), -np.inf)
    log_pi = np.full((mdp.n_states, mdp.n_actions), -np.inf)
    for s in range(mdp.n_states):
        for a, qa in zip(actions[s], q[s], strict=True):
            Q[s, a] = qa
            log_pi[s, a] = (qa - value[s]) / beta - math.log(len(actions[s]))
    return ReferenceSoft(Q, np.array(value), log_pi, it)


def boltzmann_policy(mdp: TabularMDP, theta, beta: float) -> ReferenceSoft:
    """``boltzmann`` for one hypothesis: π(a|s) ∝ exp(Q*(s, a)/β) with Q* from hard value iteration."""
    assert beta > 0
    hard = hard_value_iteration(mdp, theta)
    log_pi = np.full((mdp.n_states, mdp.n_actions), -np.inf)
    for s in range(mdp.n_states):
        acts = np.flatnonzero(np.isfinite(hard.q[s]))
        if len(acts) == 0:
            continue
        qs = [hard.q[s, a] / beta for a in acts]
        m = max(qs)
        log_z = m + math.log(sum(math.exp(x - m) for x in qs))
        for a, x in zip(acts, qs, strict=True):
            log_pi[s, a] = x - log_z
    return ReferenceSoft(hard.q, hard.value, log_pi, hard.iterations)


def reference(mdp: TabularMDP, theta, beta: float, model: str = "maxent") -> ReferenceSoft:
    """The slow reference of any observation model."""
    if model == "maxent":
        return soft_value_iteration(mdp, theta, beta)
    if model == "maxent-relative":
        return relative_value_iteration(mdp, theta, beta)
    if model == "boltzmann":
        return boltzmann_policy(mdp, theta, beta)
    raise ValueError(model)


def hard_value_iteration(mdp: TabularMDP, theta, *, tie_atol: float = 1e-9) -> ReferenceHard:
    """Hard (β = 0) value iteration; greedy sets hold the actions within ``tie_atol`` of max Q."""
    ar = _FLOAT
    actions, rewards = _rewards(mdp, theta, ar)
    value, it = _value_iteration(mdp, actions, rewards, max, ar)
    q = _q_table(mdp, actions, rewards, value, ar)
    Q = np.full((mdp.n_states, mdp.n_actions), -np.inf)
    greedy: list[set[int]] = []
    for s in range(mdp.n_states):
        best = max(q[s]) if q[s] else 0.0
        greedy.append({a for a, qa in zip(actions[s], q[s], strict=True) if qa >= best - tie_atol})
        for a, qa in zip(actions[s], q[s], strict=True):
            Q[s, a] = qa
    return ReferenceHard(Q, np.array(value), greedy, it)


def random_mdp(rng: np.random.Generator, n_states: int, n_actions: int, n_features: int,
               gamma: float = 0.95, *, p_unavailable: float = 0.3,
               n_terminal: int = 1) -> TabularMDP:
    """A random valid MDP: random successors (some -1), features uniform in [-1, 1].

    Validity is guaranteed by a chain: in a random order of the states the first
    ``n_terminal`` are terminal, and every later state has one (random) action that
    leads to the state before it in the order.
    """
    S, A = n_states, n_actions
    next_state = rng.integers(0, S, size=(S, A))
    next_state[rng.random((S, A)) < p_unavailable] = -1
    order = rng.permutation(S)
    terminal = np.zeros(S, dtype=bool)
    terminal[order[:n_terminal]] = True
    for i in range(n_terminal, S):
        next_state[order[i], rng.integers(A)] = order[i - 1]
    features = rng.uniform(-1.0, 1.0, size=(S, A, n_features))
    return TabularMDP(next_state, features, terminal, gamma=gamma)
