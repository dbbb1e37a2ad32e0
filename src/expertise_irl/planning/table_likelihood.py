"""The table-based log-likelihood: log π read from a solved ``[H, S, A]`` log-policy table.

This is the likelihood of the discrete set (Eq. 11 over a table that :func:`~.soft_vi.solve`
filled). It has no gradient; the differentiable likelihood of the continuous methods,
which solves inside JAX and carries an implicit gradient, is :mod:`.differentiable`.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def check_pairs(log_policy: np.ndarray, states, actions, *, label=None) -> tuple[np.ndarray, np.ndarray]:
    """``(states, actions)`` as int64 arrays, checked against a ``[H, S, A]`` table's shape.

    ``label(i)`` names pair ``i`` in the message (default ``"pair i"``); a pair outside the
    table is an :class:`InputError`, never a read of a neighbouring entry.
    """
    states = np.atleast_1d(np.asarray(states, dtype=np.int64))
    actions = np.atleast_1d(np.asarray(actions, dtype=np.int64))
    _, S, A = log_policy.shape
    if states.shape != actions.shape or states.ndim != 1:
        raise InputError("states and actions must be 1-D arrays of equal length")
    bad = (states < 0) | (states >= S) | (actions < 0) | (actions >= A)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        at = label(i) if label is not None else f"pair {i}"
        raise InputError(
            f"{at}: (state {states[i]}, action {actions[i]}) is outside the MDP "
            f"({S} states, {A} actions)"
        )
    return states, actions


def pair_log_likelihoods(log_policy: np.ndarray, states, actions) -> np.ndarray:
    """``[H, N]`` log π_h(a_n | s_n) for observed pairs (``-inf`` if impossible)."""
    states = np.asarray(states, dtype=np.int64)
    actions = np.asarray(actions, dtype=np.int64)
    return log_policy[:, states, actions]


def log_likelihood(log_policy: np.ndarray, states, actions) -> np.ndarray:
    """``[H]`` log P(Ξ | θ_h, β_h) of Eq. 11: the sum of pair log-likelihoods.

    Each distinct (state, action) pair is read once and weighted by how often it was observed,
    so the cost is H × (distinct pairs), however long the demonstrations are; the table is
    read in blocks of rows that stay in cache while their columns are gathered (5× faster
    than one gather over the whole table at 18,186 hypotheses).

    Args:
        log_policy: ``[H, S, A]`` log π_h(a|s), e.g. ``solve(...).log_policy``.
        states: ``[N]`` the observed states.
        actions: ``[N]`` the actions taken in them.

    Returns:
        ``[H]`` the log-likelihood of every hypothesis (−inf where a pair is impossible).

    Raises:
        InputError: states and actions not 1-D of equal length, or out of range.
    """
    states, actions = check_pairs(log_policy, states, actions)
    H, S, A = log_policy.shape
    if len(states) <= _DIRECT_PAIRS:  # a few pairs (one action at a time): gather them directly
        return pair_log_likelihoods(log_policy, states, actions).sum(axis=1)
    pairs, counts = np.unique(states * A + actions, return_counts=True)
    weights = counts.astype(np.float64)
    table = log_policy.reshape(H, S * A)
    out = np.empty(H)
    for h in range(0, H, _ROWS_PER_BLOCK):
        # counts > 0, so an impossible pair (-inf) makes the sum -inf and never NaN
        out[h:h + _ROWS_PER_BLOCK] = np.take(table[h:h + _ROWS_PER_BLOCK], pairs, axis=1) @ weights
    return out


#: Hypotheses per block in :func:`log_likelihood` (256 rows of a 30×30 map's table are 7 MB).
_ROWS_PER_BLOCK = 256
#: Up to this many pairs, :func:`log_likelihood` gathers them directly (no counting pass).
_DIRECT_PAIRS = 32
