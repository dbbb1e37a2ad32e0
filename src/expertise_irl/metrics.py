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
"""

from __future__ import annotations

import numpy as np

from .errors import InputError
from .mdp import TabularMDP
from .planning.soft_vi import solve


def expertise_distance(beta_true: float, beta_hat: float) -> float:
    """``|β* − β̂|``; smaller is better."""
    return float(abs(float(beta_true) - float(beta_hat)))


def cosine_similarity(theta_true, theta_hat) -> float:
    """``θ*·θ̂ / (‖θ*‖ ‖θ̂‖)`` in [−1, 1]; 1 means the same direction."""
    a = np.asarray(theta_true, dtype=np.float64)
    b = np.asarray(theta_hat, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1:
        raise InputError(f"theta vectors must be 1-D of equal length, got {a.shape} and {b.shape}")
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        raise InputError("cosine similarity is undefined for a zero vector")
    return float(a @ b / (na * nb))


def regret_from_values(v_true: np.ndarray, v_hat: np.ndarray, terminal: np.ndarray) -> float:
    """Eq. 17 from two value vectors ``[S]`` (see the module docstring)."""
    keep = ~np.asarray(terminal, dtype=bool)
    vt, vh = np.asarray(v_true)[keep], np.asarray(v_hat)[keep]
    if vt.size == 0:
        raise InputError("policy regret is undefined: every state is terminal")
    scale = np.max(np.abs(vt))
    if scale == 0:
        raise InputError("policy regret is undefined: the true value function is zero everywhere")
    return float(np.mean(np.abs(vt - vh)) / scale)


def policy_regret(mdp: TabularMDP, theta_true, beta_true: float, theta_hat, **solve_kwargs) -> float:
    """Eq. 17: how far the soft values of θ̂ (at the true β*) are from those of θ*; 0 is best."""
    sol = solve(mdp, np.stack([np.asarray(theta_true, float), np.asarray(theta_hat, float)]),
                np.array([beta_true, beta_true], dtype=float), **solve_kwargs)
    return regret_from_values(sol.value[0], sol.value[1], mdp.terminal)
