"""The baseline: soft value iteration as a researcher would write it from Eqs. 8-9.

One hypothesis at a time (a Python loop over hypotheses), each vectorised over
states with NumPy and SciPy's logsumexp, in reward units. It stops on the same
guarantee as the library (the error of V/β bounded by ``tol``), so the two are
compared at matched accuracy. Kept here, not in the package: it exists only to
be measured against.
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp


def naive_soft_vi(next_state, features, terminal, theta, beta, gamma, tol=1e-8, max_iter=100_000):
    """Returns (V [S], log π [S, A], iterations) for one hypothesis (θ, β)."""
    avail = (next_state >= 0) & ~terminal[:, None]
    nxt = np.where(avail, next_state, 0)
    reward = features @ theta
    thresh = tol * beta * (1 - gamma) / gamma  # |V_n+1 - V_n| <= thresh  =>  |V/β - V*/β| <= tol
    v = np.zeros(len(terminal))
    it = 0
    while it < max_iter:
        it += 1
        q = np.where(avail, reward + gamma * v[nxt], -np.inf)
        q[terminal, 0] = 0.0  # terminal rows: value 0
        v_new = beta * logsumexp(q / beta, axis=1)
        v_new[terminal] = 0.0
        done = np.max(np.abs(v_new - v)) <= thresh
        v = v_new
        if done:
            break
    q = np.where(avail, reward + gamma * v[nxt], -np.inf)
    with np.errstate(invalid="ignore"):
        log_pi = np.where(avail, (q - v[:, None]) / beta, -np.inf)
    return v, log_pi, it


def naive_solve(mdp, thetas, betas, tol=1e-8):
    """Loop over hypotheses; returns (V [H, S], log π [H, S, A], iterations [H])."""
    out_v, out_lp, its = [], [], []
    for theta, beta in zip(thetas, betas, strict=True):
        v, lp, it = naive_soft_vi(mdp.next_state, mdp.features, mdp.terminal, theta, beta, mdp.gamma, tol)
        out_v.append(v)
        out_lp.append(lp)
        its.append(it)
    return np.array(out_v), np.array(out_lp), np.array(its)
