"""Features whose weights a task cannot identify: constant or collinear over its reachable moves.

The *reachable transitions* of a task are the available moves of every state reachable from its
start states (the episodes' first states when given, else the MDP's
:meth:`~expertise_irl.mdp.TabularMDP.initial_states`). Over them, with each feature a column of
values:

- a feature that is **0 on every reachable move** adds nothing to any reward the person can meet:
  with θ on the simplex, θ_i only rescales the other weights and so β (β_eff = β/(1 − θ_i)). Its
  θ is **not identified**.
- a feature with a **nonzero constant** value c pays c·θ_i on every move, a per-step reward that
  the data tell from the others only through how long the paths are. It is listed under
  ``constant`` (weakly identified), not warned about: ``length`` under a fixed goal reward is one.
- two features that are **collinear** (one column a multiple of the other, both not all 0) enter
  the reward only through θ_i + c·θ_j: neither θ is identified on its own.

Values are one value when they differ by at most :data:`ATOL` × max(1, |value|).
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from ..mdp import TabularMDP

ATOL = 1e-12


def reachable_states(mdp: TabularMDP, starts=None) -> np.ndarray:
    """``[S]`` bool: reachable from ``starts`` (default: the MDP's initial states) by available moves."""
    starts = mdp.initial_states() if starts is None else np.asarray(starts, dtype=np.int64)
    seen = np.zeros(mdp.n_states, dtype=bool)
    queue = deque(int(s) for s in np.unique(starts))
    seen[list(queue)] = True
    avail = mdp.available
    while queue:
        s = queue.popleft()
        for t in mdp.next_state[s][avail[s]].tolist():
            if not seen[t]:
                seen[t] = True
                queue.append(t)
    return seen


def feature_identifiability(mdp: TabularMDP, starts=None) -> dict[str, Any]:
    """The task's constant and collinear features and the θ's it cannot identify (module docstring).

    Returns ``{"constant": [{"feature", "value"}], "collinear": [{"features": [a, b], "ratio"}],
    "not_identified": [names], "warnings": [lines], "reachable_moves": n}``.
    """
    names = list(mdp.feature_names)
    reach = reachable_states(mdp, starts)
    moves = mdp.available & reach[:, None]
    X = mdp.features[moves]  # [n, K]
    out: dict[str, Any] = {"constant": [], "collinear": [], "not_identified": [], "warnings": [],
                           "reachable_moves": int(moves.sum())}
    if X.shape[0] == 0:
        return out
    zero = []
    for k, name in enumerate(names):
        lo, hi = float(X[:, k].min()), float(X[:, k].max())
        if abs(hi - lo) <= ATOL * max(1.0, abs(lo), abs(hi)):
            out["constant"].append({"feature": name, "value": lo + 0.0})
            if abs(lo) <= ATOL:
                zero.append(k)
                out["not_identified"].append(name)
                out["warnings"].append(
                    f"feature {name} is 0 on every move reachable from the start states: θ_{name} is not "
                    f"identified (it only rescales the other weights and β, β_eff = β/(1 − θ_{name})); "
                    f"read θ̂_{name} as a prior's guess, not an estimate")
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if i in zero or j in zero:
                continue
            a, b = X[:, i], X[:, j]
            ratio = float(a @ b / (b @ b))
            if np.all(np.abs(a - ratio * b) <= ATOL * np.maximum(1.0, np.abs(a))):
                out["collinear"].append({"features": [names[i], names[j]], "ratio": ratio})
                for n in (names[i], names[j]):
                    if n not in out["not_identified"]:
                        out["not_identified"].append(n)
                out["warnings"].append(
                    f"features {names[i]} and {names[j]} are collinear on every move reachable from the "
                    f"start states ({names[i]} = {ratio:.4g} × {names[j]}): only θ_{names[i]} + "
                    f"{ratio:.4g}·θ_{names[j]} is identified, not either θ on its own")
    return out


def absent_features(mdp: TabularMDP) -> list[bool]:
    """Per feature: True when no move of the MDP has a non-zero value (e.g. no road on the map)."""
    f = np.asarray(mdp.features)
    avail = np.asarray(mdp.next_state) >= 0
    return [not bool(np.any(f[..., k][avail] != 0)) for k in range(f.shape[-1])]
