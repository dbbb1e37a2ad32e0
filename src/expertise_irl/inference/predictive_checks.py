"""Posterior predictive checks: do demonstrations simulated from the posterior look like the person's?

For ``R`` replicates, each from one posterior draw (θ_r, β_r) (:func:`policies_of_draws`), the
person's episodes are simulated again from their own start states (episode ``e`` of a replicate
starts where observed episode ``e`` started) and every statistic below is computed on the observed
demonstrations and on each replicate:

- ``path_length``: mean number of moves per episode;
- ``steps_to_goal``: mean number of moves of the episodes that reached a goal (a replicate where
  none did is left out of this statistic's reference set);
- ``feature_<name>``: the mean per-episode sum of each feature φ_k over the moves;
- ``visit_discrepancy``: the total-variation distance between the demonstrations' visit
  distribution over states and the posterior predictive mean visit distribution; a replicate is
  compared with the mean of the *other* replicates (leave one out), so it is not measured against
  itself;
- ``agreement``: the share of moves that are the most probable action of the posterior
  predictive policy (the mean of the draws' policies; leave one out for a replicate).

**Cut-off episodes.** An observed episode that ends without entering a goal was cut off (a
recording's end, a simulation's step limit): its replicates are cut at the same number of moves,
so the person is compared with replicates cut the same way (``cut_episodes`` counts them). Other
replicates stop at a goal or after max(:data:`MIN_CAP`, :data:`CAP_FACTOR` × the task's longest
episode) moves (``capped_share``).

**p-values.** For a statistic T the posterior predictive p-value comes from the randomised
probability integral transform of the observed T among the R replicated ones,
``u = (#below + V·(#tied + 1)) / (R + 1)`` with V ~ Uniform(0, 1) (drawn from the check's seed):
when the observed and the replicated values are exchangeable, u is exactly uniform, also for
statistics with ties (an expert's path lengths are nearly all the shortest; a plain mid-p would
pile such p-values at 1). ``visit_discrepancy`` is one-sided, ``p = 1 − u`` (only a discrepancy
larger than the replicates' is a misfit); every other statistic is two-sided,
``p = 2·min(u, 1 − u)``.

**Multiple testing.** The statistics are tested together by Holm's step-down rule at family-wise
level :data:`ALPHA` = 0.05: sorted p_(1) ≤ … ≤ p_(m), reject while p_(i) ≤ α/(m − i + 1). Holm
holds the family-wise error rate at α whatever the dependence between the statistics (path length
and the length feature are nearly the same number). The checks *fail* when any statistic is
rejected.

Posterior predictive p-values use the data twice (to fit and to check), so under a correct model
they are conservative: concentrated towards ½ for statistics that the fit pins down (path length
fixes β), closer to uniform for the others. A failed check is therefore strong evidence; a passed
one is weak evidence of fit, which is why ``--check full`` adds the held-out comparison of
:mod:`.tabular_reward`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP

#: Family-wise level of the checks (Holm's rule).
ALPHA = 0.05
#: Replicated data sets of a check.
REPLICATES = 400
#: At most this many distinct posterior draws are solved (each is used for several replicates).
MAX_DRAWS = 100
#: A replicate's episode stops after max(MIN_CAP, CAP_FACTOR × the longest observed episode) moves.
MIN_CAP, CAP_FACTOR = 100, 4

ONE_SIDED = ("visit_discrepancy",)


@dataclass(frozen=True)
class Task:
    """One task of a person: the MDP, their demonstrations and, per draw, the policy ``[D, S, A]``."""

    mdp: TabularMDP
    trajs: Trajectories
    log_policy: np.ndarray  # [D, S, A]


def starts_of(trajs: Trajectories) -> np.ndarray:
    """``[E]`` the first state of each episode, in episode order."""
    return np.array([s[0] for s, _ in trajs.episodes() if len(s)], dtype=np.int64)


def simulate_from_starts(mdp: TabularMDP, log_policy: np.ndarray, which: np.ndarray, starts: np.ndarray,
                         rng: np.random.Generator, max_steps) -> tuple[np.ndarray, ...]:
    """Episodes of every replicate at once: replicate ``r`` acts by ``log_policy[which[r]]`` from
    each of ``starts``.

    Returns flat ``(replicate, episode, state, action)`` arrays in no particular order (the
    statistics below do not need one) and ``capped [R, E]``: the episode ran ``max_steps`` moves
    without entering a terminal state. ``max_steps``: one number, or one per episode ``[E]``.
    """
    R, E = len(which), len(starts)
    cdf = np.cumsum(np.exp(log_policy), axis=-1)
    cdf /= np.where(cdf[..., -1:] > 0, cdf[..., -1:], 1.0)
    rep = np.repeat(np.arange(R), E)
    ep = np.tile(np.arange(E), R)
    cur = np.tile(starts, R)
    pol = which[rep]
    active = np.arange(R * E)
    out_r, out_e, out_s, out_a = [], [], [], []
    caps = np.broadcast_to(np.asarray(max_steps, dtype=np.int64), (E,))
    capped = np.zeros(R * E, dtype=bool)
    for step in range(int(caps.max()) if E else 0):
        if active.size == 0:
            break
        s = cur[active]
        u = rng.random(active.size)
        a = np.minimum(np.sum(cdf[pol[active], s] <= u[:, None], axis=1), mdp.n_actions - 1)
        out_r.append(rep[active])
        out_e.append(ep[active])
        out_s.append(s)
        out_a.append(a)
        nxt = mdp.next_state[s, a]
        cur[active] = nxt
        active = active[~mdp.terminal[nxt]]
        cut = step + 1 >= caps[ep[active]]
        capped[active[cut]] = True
        active = active[~cut]
    def cat(xs):
        return np.concatenate(xs) if xs else np.zeros(0, dtype=np.int64)

    return cat(out_r), cat(out_e), cat(out_s), cat(out_a), capped.reshape(R, E)


class _Stats:
    """Accumulates each statistic's numerator and denominator over a person's tasks."""

    def __init__(self, n_sets: int, names: Sequence[str]):
        self.n = n_sets
        self.moves = np.zeros(n_sets)
        self.episodes = np.zeros(n_sets)
        self.goal_moves = np.zeros(n_sets)
        self.goal_episodes = np.zeros(n_sets)
        self.features = np.zeros((n_sets, len(names)))
        self.agree = np.zeros(n_sets)
        self._visit_keys: list[np.ndarray] = []  # set · (offset + state), until :meth:`visits_over`
        self.visits = np.zeros((n_sets, 0))

    def add(self, mdp: TabularMDP, set_id, episode_key, states, actions, n_episodes_per_set, best_action,
            visit_offset: int) -> None:
        n = self.n
        self.moves += np.bincount(set_id, minlength=n)
        self.episodes += n_episodes_per_set
        self.features += np.stack([np.bincount(set_id, weights=mdp.features[states, actions, k], minlength=n)
                                   for k in range(mdp.n_features)], axis=1)
        self.agree += np.bincount(set_id, weights=(actions == best_action[set_id, states]).astype(float),
                                  minlength=n)
        self._visit_keys.append(np.stack([set_id, visit_offset + np.asarray(states)]))
        # episodes that reached a goal: their last move enters a terminal state
        ends = mdp.terminal[mdp.next_state[states, actions]]
        self.goal_episodes += np.bincount(set_id[ends], minlength=n)
        reached = np.zeros(episode_key.max() + 1 if len(episode_key) else 0, dtype=bool)
        reached[episode_key[ends]] = True
        self.goal_moves += np.bincount(set_id, weights=reached[episode_key].astype(float), minlength=n)

    def visited(self) -> np.ndarray:
        """The (offset) states any set visited."""
        return np.unique(np.concatenate([k[1] for k in self._visit_keys])) if self._visit_keys else \
            np.zeros(0, dtype=np.int64)

    def visits_over(self, columns: np.ndarray) -> None:
        """``visits [sets, columns]``: the visit counts over ``columns`` (sorted; every visited
        state among them), dense only there: a check on a large map visits a sliver of its states."""
        keys = np.concatenate(self._visit_keys, axis=1) if self._visit_keys else np.zeros((2, 0), np.int64)
        flat = keys[0] * len(columns) + np.searchsorted(columns, keys[1])
        counts = np.bincount(flat, minlength=self.n * len(columns))
        self.visits = counts.reshape(self.n, len(columns)).astype(float)

    def values(self, names: Sequence[str], mean_visits: np.ndarray) -> dict[str, np.ndarray]:
        with np.errstate(invalid="ignore", divide="ignore"):
            out = {"path_length": self.moves / self.episodes,
                   "steps_to_goal": np.where(self.goal_episodes > 0, self.goal_moves / self.goal_episodes,
                                             np.nan)}
            for k, name in enumerate(names):
                out[f"feature_{name}"] = self.features[:, k] / self.episodes
            p = self.visits / np.maximum(self.visits.sum(axis=1, keepdims=True), 1.0)
            out["visit_discrepancy"] = 0.5 * np.abs(p - mean_visits).sum(axis=1)
            out["agreement"] = self.agree / np.maximum(self.moves, 1.0)
        return out


def _visit_distribution(visits: np.ndarray) -> np.ndarray:
    return visits / np.maximum(visits.sum(axis=-1, keepdims=True), 1.0)


def p_value(observed: float, replicated: np.ndarray, *, one_sided: bool, v: float = 0.5) -> float | None:
    """The posterior predictive p-value of ``observed`` against the finite ``replicated`` values, ``v``
    the uniform draw that places it among its ties (see the module docstring); None when either is
    missing."""
    x = replicated[np.isfinite(replicated)]
    if not np.isfinite(observed) or x.size == 0:
        return None
    tie = np.isclose(x, observed, rtol=1e-12, atol=1e-12)
    u = (np.sum((x < observed) & ~tie) + v * (np.sum(tie) + 1)) / (x.size + 1)
    if one_sided:
        return float(1.0 - u)
    return float(min(1.0, 2 * min(u, 1.0 - u)))


def holm_rejections(p: dict[str, float | None], alpha: float = ALPHA) -> dict[str, bool]:
    """Holm's step-down rejections at family-wise level ``alpha`` (None: not tested, not rejected)."""
    tested = sorted((v, k) for k, v in p.items() if v is not None)
    m = len(tested)
    out = dict.fromkeys(p, False)
    for i, (v, k) in enumerate(tested):
        if v > alpha / (m - i):
            break
        out[k] = True
    return out


def predictive_checks(tasks: Sequence[Task], which: np.ndarray, rng: np.random.Generator,
                      alpha: float = ALPHA) -> dict[str, Any]:
    """The posterior predictive checks of one person's ``tasks`` (see the module docstring).

    ``which [R]``: the draw each replicate uses (an index into every task's ``log_policy``).
    Returns ``{"replicates", "alpha", "rule", "max_steps", "capped_share", "failed", "statistics":
    {name: {"observed", "mean", "q05", "q95", "p_value", "sided", "rejected"}}, "replicated":
    {name: [R values]}}`` (JSON-ready; a statistic a replicate lacks is null there).
    """
    if not tasks:
        raise InputError("predictive checks need at least one task")
    names = list(tasks[0].mdp.feature_names)
    R = len(which)
    offsets = np.cumsum([0] + [t.mdp.n_states for t in tasks])
    obs = _Stats(1, names)
    rep = _Stats(R, names)
    caps, capped, cut_episodes = [], 0, 0
    n_eps = 0
    for i, t in enumerate(tasks):
        mdp, lp = t.mdp, np.asarray(t.log_policy, dtype=np.float64)
        D = lp.shape[0]
        pi = np.exp(lp)
        episodes = [(s, a) for s, a in t.trajs.episodes() if len(s)]
        lengths = [len(s) for s, _ in episodes]
        cap = max(MIN_CAP, CAP_FACTOR * max(lengths))
        caps.append(cap)
        # an episode that ends without entering a goal was cut off: its replicates are cut there too
        reached = [bool(mdp.terminal[mdp.next_state[s[-1], a[-1]]]) for s, a in episodes]
        cut_episodes += reached.count(False)
        episode_caps = np.array([cap if ok else n for ok, n in zip(reached, lengths, strict=True)])
        starts = starts_of(t.trajs)
        E = len(starts)
        n_eps += E
        r_id, e_id, s, a, cap_flags = simulate_from_starts(mdp, lp, which, starts, rng, episode_caps)
        capped += int(cap_flags[:, np.asarray(reached)].sum())
        # most probable action of the posterior predictive policy; a replicate's leaves its own draw out
        counts = np.bincount(which, minlength=D).astype(float)
        total = np.tensordot(counts, pi, axes=1)  # [S, A] sum over replicates of their policies
        loo = (total[None] - pi) / max(R - 1, 1)  # [D, S, A]: without one replicate of draw d
        best_rep = np.where(np.isfinite(lp), loo, -1.0).argmax(axis=-1)[which]  # [R, S]
        best_obs = np.where(np.isfinite(lp[0]), total / R, -1.0).argmax(axis=-1)[None]  # [1, S]
        obs.add(mdp, np.zeros(len(t.trajs), dtype=np.int64), _episode_index(t.trajs), t.trajs.state,
                t.trajs.action, np.array([E]), best_obs, int(offsets[i]))
        rep.add(mdp, r_id, r_id * E + e_id, s, a, np.full(R, E), best_rep, int(offsets[i]))
    columns = np.union1d(obs.visited(), rep.visited())
    obs.visits_over(columns)
    rep.visits_over(columns)
    rep_dist = _visit_distribution(rep.visits)
    mean_all = rep_dist.mean(axis=0)
    mean_loo = (mean_all[None] * R - rep_dist) / max(R - 1, 1)
    obs_values = obs.values(names, mean_all[None])
    rep_values = rep.values(names, mean_loo)
    stats, pvals = {}, {}
    for name, x in rep_values.items():
        o = float(obs_values[name][0])
        one = name in ONE_SIDED
        p = p_value(o, x, one_sided=one, v=float(rng.random()))
        fin = x[np.isfinite(x)]
        pvals[name] = p
        stats[name] = {"observed": o if np.isfinite(o) else None,
                       "mean": float(fin.mean()) if fin.size else None,
                       "q05": float(np.quantile(fin, 0.05)) if fin.size else None,
                       "q95": float(np.quantile(fin, 0.95)) if fin.size else None,
                       "p_value": p, "sided": "upper" if one else "two"}
    rejected = holm_rejections(pvals, alpha)
    for name in stats:
        stats[name]["rejected"] = rejected[name]
    return {
        "replicates": R, "alpha": alpha,
        "rule": f"Holm's step-down rule over the {sum(v is not None for v in pvals.values())} statistics at "
                f"family-wise level {alpha:g}",
        "max_steps": caps if len(caps) > 1 else caps[0],
        "capped_share": capped / max(R * n_eps, 1),
        "cut_episodes": cut_episodes,
        "failed": [k for k, v in rejected.items() if v],
        "statistics": stats,
        "replicated": {k: [round(float(v), 6) if np.isfinite(v) else None for v in x]
                       for k, x in rep_values.items()},
    }


def _episode_index(trajs: Trajectories) -> np.ndarray:
    order = {int(e): i for i, e in enumerate(trajs.episode_ids.tolist())}
    return np.array([order[int(e)] for e in trajs.episode.tolist()], dtype=np.int64)
