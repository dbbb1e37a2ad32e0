"""Checks a user study makes before inference: features a participant's tasks never vary, and
the default β grid of ``expertise-irl study``.

**Constant features** (:func:`constant_features`). Feature ``i`` is *constant on an MDP* when it
takes one value (equal to within :data:`CONSTANT_ATOL` × max(1, |value|)) at every available
(state, action) pair of the non-terminal states, i.e. at every entry of ``mdp.available``.
Terminal states do not count: they are absorbing, have no available action
(:attr:`~expertise_irl.mdp.TabularMDP.available` is all False on their rows) and their features
never enter a reward; the moves *into* a terminal state are actions of non-terminal states and do
count. A feature constant on every task of a participant is listed, with the common value when it
is the same on every task (to the same tolerance) and ``None`` otherwise.

- A feature that is **0 on every task** adds nothing to any reward: with θ on the simplex the
  reward is ``(1 − θ_i)·θ'·φ`` for the other components θ' renormalised, so θ_i only rescales β
  (``β_eff = β/(1 − θ_i)``) and is not identified. The study keeps θ_i = 0
  (:func:`zero_feature_mask` conditions a discrete posterior on it) and warns
  (:func:`constant_feature_warning`).
- A feature with a **nonzero constant** c pays c·θ_i on every move: a per-step reward that the
  tasks tell from the other features' scale and from β only through how many moves the paths
  take. θ_i is kept in θ, and the warning says its estimate is weakly identified.

**Default β grid** (:func:`auto_beta_grid`). β is in reward units, so a grid must follow the
scale of the rewards' differences on the participants' maps. The typical Q gap ``g`` is the median,
pooled over the maps, the θ's of the set and the states, of the gap between the best and the
second-best action's optimal value Q* at every non-terminal state with at least two available
actions; gaps of at most :data:`TIE_ATOL` × max(1, R_θ) (R_θ = the reward bound of θ,
:func:`~expertise_irl.planning.soft_vi.reward_bound`) are ties and are left out, and a θ whose
reward is 0 everywhere has no gaps. Q* is the β → 0 limit of every observation model's Q
(``maxent``, ``maxent-relative`` and ``boltzmann`` alike); it is solved exactly with the solver's
hard-value model at β = :data:`PROBE_BETA` × R_θ, where the solver's tolerance (1e-8 nats of V/β)
bounds the error of Q* by about 1e-11·R_θ, far below the tie threshold.

Why Q* rather than a soft Q at a small β: measured on the bundled maps with the paper-real Θ,
``maxent`` at β = 1e-6·R_θ is within 1.4e-4 of Q* everywhere, but its entropy bonus splits every
exact tie of Q* (two moves toward the goal with different numbers of shortest paths behind
them) into a gap of order β, which a tie threshold of 1e-9 keeps. Those splits are as many as
the real gaps on open maps and drag the median down tenfold (zones30: 0.011 against Q*'s 0.129).

The grid is log-spaced from ``low·g`` to ``high·g`` with ``per_decade`` points per decade
(``ceil(per_decade·log10(high/low))`` intervals, both ends included), each value rounded to 3
significant figures (duplicates after rounding kept once). With the defaults (1e-3, 100, 3) it
has 16 values spanning 5 decades around g. The ends: at β = 1e-3·g a choice between actions g
apart is 1 in e^1000 wrong, an expert beyond anything the data can tell from optimal; at
β = 100·g it is 99% uniform. The top must be that high for the paper's own noisy people: its
low-expertise group has β = 5–10 on zone maps whose g is 0.13–0.33 (zones30, corridor), where a
grid ending at 10·g would stop at 1.3–3.3 and every noisy person would pile on its edge.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..mdp import TabularMDP
from ..models import check_model

#: Two values of a feature are one value when they differ by at most this × max(1, |value|).
CONSTANT_ATOL = 1e-12
#: A θ's components listed by :func:`zero_feature_mask` count as 0 when at most this.
ZERO_ATOL = 1e-12
#: Gaps of Q* of at most this × max(1, R_θ) are ties, not gaps.
TIE_ATOL = 1e-9
#: Q* is solved at β = PROBE_BETA × R_θ (the hard values do not depend on β; a small β keeps the
#: solver's absolute error, tol·β, far below the tie threshold).
PROBE_BETA = 1e-3
#: The default grid's ends (multiples of g) and its density.
AUTO_LOW, AUTO_HIGH, AUTO_PER_DECADE = 1e-3, 100.0, 3


def _as_mdps(mdps, *, same_features: bool = True) -> list[TabularMDP]:
    if isinstance(mdps, TabularMDP):
        return [mdps]
    out = list(mdps)
    if not out:
        raise InputError("no tasks given: need at least one MDP")
    if not same_features:
        return out
    k = out[0].n_features
    for m in out[1:]:
        if m.n_features != k:
            raise InputError(f"{m.source}: {m.n_features} features, but {out[0].source} has {k}: "
                             "every task must have the same features")
    return out


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= CONSTANT_ATOL * max(1.0, abs(a), abs(b))


def _constant_value(mdp: TabularMDP, k: int) -> float | None:
    """The one value of feature ``k`` on ``mdp``'s available pairs, or None if it varies."""
    x = mdp.features[..., k][mdp.available]
    lo, hi = float(x.min()), float(x.max())
    return lo if _same(lo, hi) else None


def constant_features(mdps: TabularMDP | Sequence[TabularMDP]) -> list[tuple[int, float | None]]:
    """The features that never vary on any of ``mdps`` (one participant's tasks).

    Returns ``[(i, value)]`` in feature order: feature ``i`` is constant on every MDP (one value at
    every available pair of the non-terminal states; see the module docstring), and ``value`` is
    that value when it is the same on every MDP, else ``None``.

    Raises:
        InputError: no MDP, or MDPs with different numbers of features.
    """
    ms = _as_mdps(mdps)
    out: list[tuple[int, float | None]] = []
    for k in range(ms[0].n_features):
        values = [_constant_value(m, k) for m in ms]
        if any(v is None for v in values):
            continue
        first = values[0]
        common = first if all(_same(first, v) for v in values) else None
        out.append((k, None if common is None else float(common) + 0.0))  # + 0.0: no -0.0
    return out


def constant_feature_warning(name: str, value: float | None) -> str:
    """One line on a feature constant on every task of a participant (``value`` from
    :func:`constant_features`; None: constant on each task, but not the same on all)."""
    if value is not None and value == 0:
        return (f"feature {name} is 0 on every task of this participant: its θ is not identified and "
                f"would only rescale β (β_eff = β/(1 − θ_{name})); the study keeps θ_{name} = 0")
    what = (f"is {value:g} on every move of every task" if value is not None
            else "is constant on each task (not the same on all)")
    return (f"feature {name} {what} of this participant: it acts as a per-step reward that the "
            f"tasks tell from the other features' scale and from β only through the paths' lengths; "
            f"θ_{name} is kept in θ, but its estimate is weakly identified")


def zero_feature_mask(thetas, features: Sequence[int]) -> np.ndarray:
    """``bool [n_theta]``: the θ's of ``thetas [n_theta, K]`` whose components ``features`` are all 0
    (to :data:`ZERO_ATOL`); the θ's a discrete posterior conditioned on those θ_i = 0 keeps.

    Raises:
        InputError: a feature index outside ``[0, K)``, or no θ of the set has them all 0.
    """
    th = np.asarray(thetas, dtype=np.float64)
    if th.ndim != 2:
        raise InputError(f"thetas must have shape [n_theta, K], got {th.shape}")
    idx = [int(i) for i in features]
    K = th.shape[1]
    bad = [i for i in idx if not 0 <= i < K]
    if bad:
        raise InputError(f"feature index {bad[0]} is outside [0, {K})")
    mask = np.all(np.abs(th[:, idx]) <= ZERO_ATOL, axis=1) if idx else np.ones(len(th), dtype=bool)
    if not mask.any():
        raise InputError(f"no θ of the set has θ = 0 on feature(s) {', '.join(map(str, idx))}: "
                         "use a Θ grid whose component values include 0")
    return mask


def q_gaps(mdp: TabularMDP, thetas) -> np.ndarray:
    """The positive gaps (ties left out) between the best and second-best Q* of every non-terminal
    state with ≥ 2 available actions, for every θ of ``thetas [n_theta, K]``, pooled (1-D)."""
    from ..planning.soft_vi import reward_bound, solve

    th = np.asarray(thetas, dtype=np.float64)
    if th.ndim != 2 or th.shape[1] != mdp.n_features:
        raise InputError(f"thetas must have shape [n_theta, K] with K = {mdp.n_features}, got {th.shape}")
    scale = reward_bound(mdp, th)
    live = scale > 0  # a θ with no reward anywhere: every action ties
    if not live.any():
        return np.zeros(0)
    th, scale = th[live], scale[live]
    sol = solve(mdp, th, PROBE_BETA * scale, model="boltzmann")
    avail = mdp.available
    multi = avail.sum(axis=1) >= 2
    if not multi.any():
        return np.zeros(0)
    q = np.where(avail[None], sol.q, -np.inf)[:, multi, :]  # [n, S', A]
    top2 = -np.sort(-q, axis=-1)[..., :2]
    gap = top2[..., 0] - top2[..., 1]  # [n, S']
    keep = gap > TIE_ATOL * np.maximum(1.0, scale)[:, None]
    return gap[keep]


def _round3(x: float) -> float:
    return float(f"{x:.3g}")


def auto_beta_grid(mdps: TabularMDP | Sequence[TabularMDP], thetas, *, model: str = "maxent",
                   low: float = AUTO_LOW, high: float = AUTO_HIGH,
                   per_decade: int = AUTO_PER_DECADE) -> tuple[np.ndarray, dict]:
    """The default β grid of ``expertise-irl study``: log-spaced around the typical Q gap.

    Args:
        mdps: the study's tasks (one per distinct map is enough; repeats only weight the median).
        thetas: ``[n_theta, K]`` the Θ of the hypothesis set, or ``{K: [n_theta, K]}`` for maps with
            different numbers of features (each map's gaps under the Θ of its K, pooled).
        model: the study's observation model; checked, but the gaps are those of Q*, which every
            model's Q approaches as β → 0 (module docstring), so it does not change the grid.
        low, high: the grid's ends as multiples of the median gap g.
        per_decade: points per decade.

    Returns:
        ``(betas, info)``: ``betas`` ascending, 3 significant figures; ``info`` = ``{"rule": one
        sentence, "q_gap_median": g, "low", "high", "per_decade", "n_gaps": gaps pooled}``.

    Raises:
        InputError: bad arguments, or no positive gap anywhere (no state offers a choice that
        matters under any θ), so there is no scale to build a grid on.
    """
    check_model(model)
    ms = _as_mdps(mdps, same_features=not isinstance(thetas, dict))
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low < high):
        raise InputError(f"the β grid's ends must satisfy 0 < low < high, got low={low:g}, high={high:g}")
    if isinstance(per_decade, bool) or not isinstance(per_decade, int | np.integer) or per_decade < 1:
        raise InputError(f"per_decade must be a whole number >= 1, got {per_decade!r}")
    gaps = np.concatenate([q_gaps(m, thetas[m.n_features] if isinstance(thetas, dict) else thetas)
                           for m in ms])
    if gaps.size == 0:
        raise InputError("no state of these tasks offers two actions of different value under any θ "
                         "of the set: there is no Q gap to scale a β grid by; give the β's explicitly")
    g = float(np.median(gaps))
    n = max(1, math.ceil(per_decade * math.log10(high / low) - 1e-9))
    raw = np.logspace(math.log10(low * g), math.log10(high * g), n + 1)
    betas = np.unique([_round3(b) for b in raw])
    rule = (f"β grid log-spaced from {low:g}·g to {high:g}·g, {per_decade} per decade (3 significant "
            f"figures), g = {g:.3g} the median gap between the best and second-best action's optimal "
            f"value Q* over {gaps.size} (state, θ) pairs of {len(ms)} task(s)")
    info = {"rule": rule, "q_gap_median": g, "low": float(low), "high": float(high),
            "per_decade": int(per_decade), "n_gaps": int(gaps.size)}
    return betas, info
