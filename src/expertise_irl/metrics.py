"""The paper's three performance metrics (Sec. V-E), with its misprints corrected.

- Expertise distance ``|β* − β̂|``.
- Cosine similarity ``θ*·θ̂ / (‖θ*‖ ‖θ̂‖)``. The paper's Eq. 16 prints
  ``1 − θ*·θ̂ / (‖θ*‖² ‖θ̂‖²)``, which is neither a similarity (it is 0 for equal unit
  vectors while the text says "closer to 1 is more similar") nor scale-free; we use the
  standard cosine the text describes.
- Policy regret (Eq. 17): the mean over non-terminal states of
  ``|V_{θ*,β*}(s) − V_{θ̂,β*}(s)|``, divided by ``max_s |V_{θ*,β*}(s)|``. The paper divides
  by ``max_s V``, which is zero or negative whenever rewards are costs; the absolute value
  keeps the normalisation positive. Terminal states (V = 0 under every hypothesis) are
  left out of the mean so that the number of goals does not dilute the metric.

Eq. 17 compares soft values of θ̂ and θ* at β*: values of two rewards, not returns of two
policies, so it does not rank estimates by what acting on them earns (an estimate with a better
cosine and a better policy can have a larger Eq. 17). Beside it, :func:`return_regret`:

- **Return regret**: the expected return under θ* of the policy θ̂ would produce (the optimal
  policy for θ̂, ties split evenly), short of the optimal policy's, as a share of the shortfall of
  the uniform random policy, averaged over the non-terminal states as Eq. 17 is:
  ``mean_s [V*_θ*(s) − V^π_θ̂_θ*(s)] / mean_s [V*_θ*(s) − V^uniform_θ*(s)]``. 0: θ̂'s policy is
  optimal for θ*; 1: it earns no more than acting at random (it can exceed 1). Returns are hard
  (no entropy term), values exact (the policy's linear system solved directly), and the metric
  does not depend on β or on the scale of θ.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve

from .errors import InputError
from .mdp import TabularMDP
from .planning.soft_vi import solve


def expertise_distance(beta_true: float, beta_hat: float) -> float:
    """``|β* − β̂|``; smaller is better.

    Args:
        beta_true: the true expertise β*.
        beta_hat: the estimate β̂.

    Returns:
        The absolute difference.
    """
    return float(abs(float(beta_true) - float(beta_hat)))


def cosine_similarity(theta_true, theta_hat) -> float:
    """``θ*·θ̂ / (‖θ*‖ ‖θ̂‖)`` in [−1, 1]; 1 means the same direction.

    Args:
        theta_true: the true reward weights θ* ``[K]``.
        theta_hat: the estimate θ̂ ``[K]``.

    Returns:
        The cosine of the angle between them.

    Raises:
        InputError: the two are not 1-D of equal length, or one of them is zero.
    """
    a = np.asarray(theta_true, dtype=np.float64)
    b = np.asarray(theta_hat, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1:
        raise InputError(f"theta vectors must be 1-D of equal length, got {a.shape} and {b.shape}")
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        raise InputError("cosine similarity is undefined for a zero vector")
    return float(a @ b / (na * nb))


def regret_from_values(v_true: np.ndarray, v_hat: np.ndarray, terminal: np.ndarray) -> float:
    """Eq. 17 from two value vectors ``[S]`` (see the module docstring).

    Args:
        v_true: the soft values of θ* at β*.
        v_hat: the soft values of θ̂ at β*.
        terminal: ``[S]`` which states are terminal (left out of the mean).

    Returns:
        The mean absolute difference over non-terminal states, divided by ``max |v_true|``.

    Raises:
        InputError: every state is terminal, or ``v_true`` is zero everywhere.
    """
    keep = ~np.asarray(terminal, dtype=bool)
    vt, vh = np.asarray(v_true)[keep], np.asarray(v_hat)[keep]
    if vt.size == 0:
        raise InputError("policy regret is undefined: every state is terminal")
    scale = np.max(np.abs(vt))
    if scale == 0:
        raise InputError("policy regret is undefined: the true value function is zero everywhere")
    return float(np.mean(np.abs(vt - vh)) / scale)


def policy_regret(mdp: TabularMDP, theta_true, beta_true: float, theta_hat, **solve_kwargs) -> float:
    """Eq. 17: how far the soft values of θ̂ (at the true β*) are from those of θ*; 0 is best.

    Args:
        mdp: the task.
        theta_true: the true reward weights θ* ``[K]``.
        beta_true: the true expertise β*, at which both values are computed.
        theta_hat: the estimate θ̂ ``[K]``.
        **solve_kwargs: passed to :func:`~expertise_irl.planning.soft_vi.solve` (``tol``, ...).

    Returns:
        The regret of :func:`regret_from_values`.

    Raises:
        InputError: as :func:`regret_from_values`.
    """
    sol = solve(mdp, np.stack([np.asarray(theta_true, float), np.asarray(theta_hat, float)]),
                np.array([beta_true, beta_true], dtype=float), **solve_kwargs)
    return regret_from_values(sol.value[0], sol.value[1], mdp.terminal)


def _optimal_values(mdp: TabularMDP, reward: np.ndarray, tol: float) -> np.ndarray:
    """Hard (β → 0) optimal values ``[S]`` of ``reward [S, A]`` by value iteration, to ``tol``."""
    avail, nxt = mdp.available, np.where(mdp.available, mdp.next_state, 0)
    v = np.zeros(mdp.n_states)
    g = mdp.gamma
    for _ in range(100_000):
        q = np.where(avail, reward + g * v[nxt], -np.inf)
        new = np.where(mdp.terminal, 0.0, q.max(axis=1))
        if np.max(np.abs(new - v)) <= tol * (1 - g) / g:
            return new
        v = new
    raise RuntimeError("value iteration did not converge")  # pragma: no cover (γ < 1 bounds it)


def greedy_policy(mdp: TabularMDP, theta, *, tol: float = 1e-10) -> np.ndarray:
    """``[S, A]`` the optimal policy of reward θ (β → 0).

    Each state's optimal actions (within 1e-9 of the best Q, relative to the values' scale) share
    its probability evenly; terminal rows are 0.

    Args:
        mdp: the task.
        theta: the reward weights ``[K]``.
        tol: the tolerance of value iteration on the optimal (hard) values.

    Returns:
        The policy's action probabilities, ``[S, A]``.
    """
    reward = mdp.reward(np.asarray(theta, dtype=np.float64))
    v = _optimal_values(mdp, reward, tol)
    avail, nxt = mdp.available, np.where(mdp.available, mdp.next_state, 0)
    q = np.where(avail, reward + mdp.gamma * v[nxt], -np.inf)
    best = q.max(axis=1, keepdims=True)
    slack = 1e-9 * max(1.0, float(np.max(np.abs(v))))
    pick = avail & (q >= best - slack)
    n = pick.sum(axis=1, keepdims=True)
    return np.where(pick, 1.0 / np.maximum(n, 1), 0.0)


def uniform_policy(mdp: TabularMDP) -> np.ndarray:
    """``[S, A]`` every available action equally likely; terminal rows 0.

    Args:
        mdp: the task.

    Returns:
        The policy's action probabilities, ``[S, A]``.
    """
    avail = mdp.available
    return avail / np.maximum(avail.sum(axis=1, keepdims=True), 1)


def policy_values(mdp: TabularMDP, theta, policy: np.ndarray) -> np.ndarray:
    """``[S]`` the exact expected discounted return of ``policy [S, A]`` under reward θ.

    The values are 0 at terminal states; ``(I − γ P_π) V = r_π`` is solved directly (sparse LU).

    Args:
        mdp: the task.
        theta: the reward weights ``[K]`` the return is counted in.
        policy: ``[S, A]`` action probabilities (those of unavailable actions are ignored).

    Returns:
        The values ``[S]``.
    """
    reward = mdp.reward(np.asarray(theta, dtype=np.float64))
    avail = mdp.available
    S = mdp.n_states
    pi = np.where(avail, policy, 0.0)
    r_pi = (np.where(avail, reward, 0.0) * pi).sum(axis=1)
    s_idx, a_idx = np.nonzero(pi)
    P = sparse.csr_matrix((pi[s_idx, a_idx], (s_idx, mdp.next_state[s_idx, a_idx])), shape=(S, S))
    A = sparse.identity(S, format="csr") - mdp.gamma * P
    return np.asarray(spsolve(A.tocsc(), r_pi), dtype=np.float64)


def return_regret_table(mdp: TabularMDP, theta_true, thetas_hat) -> np.ndarray:
    """:func:`return_regret` of each row of ``thetas_hat [N, K]`` against one θ*.

    The optimal and the uniform policies' returns are computed once.

    Args:
        mdp: the task.
        theta_true: the true reward weights θ* ``[K]``.
        thetas_hat: the estimates ``[N, K]``.

    Returns:
        ``[N]`` the return regret of each estimate; NaN where it is undefined (every policy earns
        the same under θ*).
    """
    theta_true = np.asarray(theta_true, dtype=np.float64)
    keep = ~mdp.terminal
    best = policy_values(mdp, theta_true, greedy_policy(mdp, theta_true))[keep]
    scale = float(np.mean(best - policy_values(mdp, theta_true, uniform_policy(mdp))[keep]))
    out = np.full(len(thetas_hat), np.nan)
    if not scale > 1e-12 * max(1.0, float(np.max(np.abs(best)))):
        return out
    for i, th in enumerate(np.asarray(thetas_hat, dtype=np.float64)):
        mine = policy_values(mdp, theta_true, greedy_policy(mdp, th))[keep]
        out[i] = max(float(np.mean(best - mine)), 0.0) / scale
    return out


def return_regret(mdp: TabularMDP, theta_true, theta_hat) -> float:
    """What acting on θ̂ costs under θ* (see the module docstring); 0 is best, 1 is acting at random.

    Args:
        mdp: the task.
        theta_true: the true reward weights θ* ``[K]``.
        theta_hat: the estimate θ̂ ``[K]``.

    Returns:
        The shortfall of θ̂'s optimal policy's return under θ*, as a share of the uniform policy's.

    Raises:
        InputError: θ̂ or θ* of the wrong length, or every policy earns the same under θ* (the
            metric's scale is 0).
    """
    theta_true = np.asarray(theta_true, dtype=np.float64)
    theta_hat = np.asarray(theta_hat, dtype=np.float64)
    K = mdp.n_features
    if theta_true.shape != (K,) or theta_hat.shape != (K,):
        raise InputError(f"theta vectors must have {K} components, got {theta_true.shape} and "
                         f"{theta_hat.shape}")
    value = float(return_regret_table(mdp, theta_true, theta_hat[None])[0])
    if not np.isfinite(value):
        raise InputError("return regret is undefined: under θ* every policy earns the same return")
    return value
