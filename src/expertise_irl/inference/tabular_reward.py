"""A richer competitor at the same expertise scale: the features' reward plus a per-state reward.

The observation model is the person's (soft-optimal with temperature β, the same ``model``); only
the reward is richer:

    R(s, a) = θ̂·φ(s, a) + r(s'),   s' = next(s, a),

with θ̂ the features' estimate (‖θ̂‖₁ = 1, which fixes the scale, so β means the same as under the
features) and r a free reward for entering each state of the *support*: every state on a map of
at most :data:`ALL_STATES` states, else the states the person visited and every state one move from
them (a state that no demonstration comes near says little about r). This is max-ent IRL with a
tabular reward and a Gaussian penalty on the departure in the policy's units, nats:
``PENALTY/2 · Σ_s (r(s)/β)²``, i.e. r(s)/β ~ Normal(0, 1/PENALTY) a priori. (A penalty on r in
reward units would let β shrink and r/β grow unchecked: the fit then memorises the training
paths.) It is fitted jointly with β by L-BFGS-B on the differentiable likelihood
(:mod:`expertise_irl.planning.differentiable`, its implicit gradient in r and β alike): the
features and the per-state rewards are one MDP's features (:func:`augmented_mdp`), θ' = (θ̂, r).

**Held-out comparison** (:func:`compare`). The episodes are split in two folds by their position
(even, odd); on each fold's training half the features' model is fitted (θ on the simplex, β; ML)
and the richer one from that θ̂; both predict the other half. The gain is the difference of their
held-out log-likelihoods per action (nats), with a standard error from the per-episode differences
(episodes are the independent units). The β each needs is fitted on all episodes with the
result's θ̂: ``beta_features`` (r ≡ 0) and ``beta_richer``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from ..planning.differentiable import make_log_likelihood
from .task_likelihood import pair_counts

#: The penalty λ of Σ (r(s)/β)²/2: a departure of 1 nat at one state costs half a nat, about what
#: one choice between two actions is worth.
PENALTY = 1.0
#: β is searched in [BETA_LO, BETA_HI].
BETA_LO, BETA_HI = 1e-3, 1e2
#: The competitor is not fitted with more per-state rewards than this (its cost grows with their square).
MAX_SUPPORT = 3000
#: On maps of at most this many states every state has its r (else those near the demonstrations).
ALL_STATES = 400


def support_states(mdp: TabularMDP, trajs: Trajectories) -> np.ndarray:
    """The visited states and every state one available move from them, sorted."""
    visited = np.unique(np.concatenate([trajs.state, mdp.next_state[trajs.state, trajs.action]]))
    live = visited[~mdp.terminal[visited]]
    nxt = mdp.next_state[live][mdp.available[live]]
    return np.unique(np.concatenate([visited, nxt]))


def augmented_mdp(mdp: TabularMDP, support: np.ndarray) -> TabularMDP:
    """``mdp`` with one more feature per support state: 1 for a move that enters it."""
    S, A = mdp.n_states, mdp.n_actions
    col = np.full(S, -1)
    col[support] = np.arange(len(support))
    onehot = np.zeros((S, A, len(support)))
    s, a = np.nonzero(mdp.next_state >= 0)
    j = col[mdp.next_state[s, a]]
    keep = j >= 0
    onehot[s[keep], a[keep], j[keep]] = 1.0
    return TabularMDP(mdp.next_state, np.concatenate([mdp.features, onehot], axis=2), mdp.terminal,
                      gamma=mdp.gamma, feature_names=(*mdp.feature_names, *(f"r{k}" for k in support)),
                      start_states=mdp.start_states, state_xy=mdp.state_xy, source=mdp.source,
                      state_heading=mdp.state_heading, reward_offset=mdp.reward_offset)


class _Task:
    """One task's richer MDP and its compiled likelihood (the counts are an input)."""

    def __init__(self, mdp: TabularMDP, support: np.ndarray, model: str):
        self.mdp, self.support = mdp, support
        self.aug = augmented_mdp(mdp, support)
        self.ll = make_log_likelihood(self.aug, np.zeros((mdp.n_states, mdp.n_actions)), model=model)
        self.K = mdp.n_features


def _layout_counts(task: _Task, trajs: Trajectories):
    """The counts of ``trajs`` in the likelihood's layout (a fresh likelihood would recompile)."""
    from ..planning import kernels

    prep = kernels.prepared(task.aug, "float64")
    nb = prep.n_block
    mdp = task.mdp
    counts = pair_counts(mdp, trajs)
    n_blk = np.zeros((2, mdp.n_actions, nb))
    live = np.flatnonzero(~mdp.terminal)
    rows = prep.rows[live]
    n_blk[rows // nb, :, rows % nb] = np.where(mdp.available, counts, 0.0)[live]
    return jnp.asarray(n_blk)


def _minimise(fun, x0, bounds, maxiter: int = 300) -> tuple[np.ndarray, float]:
    def f(x):
        v, g = fun(jnp.asarray(x))
        v = float(v)
        if not math.isfinite(v):
            return 1e300, np.zeros_like(x)
        return v, np.asarray(g, dtype=np.float64)

    res = minimize(f, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": maxiter, "ftol": 1e-10, "gtol": 1e-6})
    return np.asarray(res.x), float(res.fun)


class Competitor:
    """The features' model and the richer one on a person's task MDPs, compiled once (see
    :func:`competitor_for`, which keeps them for the next person on the same maps)."""

    def __init__(self, mdps: Sequence[TabularMDP], supports: Sequence[np.ndarray], model: str = DEFAULT_MODEL,
                 penalty: float = PENALTY):
        if not (math.isfinite(penalty) and penalty > 0):
            raise InputError(f"penalty must be a finite number > 0, got {penalty!r}")
        self.penalty = penalty
        self.model = model
        self.tasks = [_Task(m, s, model) for m, s in zip(mdps, supports, strict=True)]
        self.K = self.tasks[0].K
        self.splits = splits = np.cumsum([0, *(len(t.support) for t in self.tasks)])
        lls = [t.ll for t in self.tasks]
        K = self.K

        def total(theta, u, beta, counts):
            # u: the per-state rewards in the policy's units, r/β
            out = 0.0
            for i, f in enumerate(lls):
                r = beta * u[splits[i]:splits[i + 1]]
                out = out + f(jnp.concatenate([theta, r]), beta, counts=counts[i])[0]
            return out

        def features_objective(x, counts):
            return -total(jax.nn.softmax(x[:K]), jnp.zeros(splits[-1]), jnp.exp(x[-1]), counts)

        def richer_objective(x, theta, counts, lam):
            u = x[:-1]
            return -total(theta, u, jnp.exp(x[-1]), counts) + 0.5 * lam * jnp.sum(u ** 2)

        self._features = jax.jit(jax.value_and_grad(features_objective))
        self._richer = jax.jit(jax.value_and_grad(richer_objective))

    def counts(self, trajs: Sequence[Trajectories]) -> tuple:
        return tuple(_layout_counts(t, tr) for t, tr in zip(self.tasks, trajs, strict=True))

    def fit_features(self, counts, rng: np.random.Generator, starts: int = 2) -> tuple[np.ndarray, float]:
        """(θ̂, β̂) of the features' model by ML from ``starts`` random starts."""
        best = None
        lo, hi = math.log(BETA_LO), math.log(BETA_HI)
        bounds = [(None, None)] * self.K + [(lo, hi)]
        for _ in range(starts):
            x0 = np.concatenate([np.log(np.maximum(rng.dirichlet(np.ones(self.K)), 1e-12)),
                                 [rng.uniform(math.log(0.01), math.log(10.0))]])
            x, v = _minimise(lambda x: self._features(x, counts), x0, bounds)
            if best is None or v < best[1]:
                best = (x, v)
        x = best[0]
        return np.asarray(jax.nn.softmax(jnp.asarray(x[:self.K]))), float(math.exp(x[-1]))

    def fit_richer(self, theta, beta0: float, counts, *, free_r: bool = True) -> tuple[np.ndarray, float]:
        """(r [support], β) of the richer model from θ̂ = ``theta``, starting at r = 0, β = ``beta0``
        (r in reward units); ``free_r=False`` keeps r = 0 (the features' β at θ̂)."""
        n = int(self.splits[-1])
        theta = jnp.asarray(theta, jnp.float64)
        lo, hi = math.log(BETA_LO), math.log(BETA_HI)
        b0 = min(max(math.log(beta0), lo), hi)
        bounds = [(None, None) if free_r else (0.0, 0.0)] * n + [(lo, hi)]
        x, _ = _minimise(lambda x: self._richer(x, theta, counts, self.penalty), np.r_[np.zeros(n), b0],
                         bounds)
        beta = float(math.exp(x[-1]))
        return x[:-1] * beta, beta

    def episode_log_likelihoods(self, theta, r, beta: float, trajs: Sequence[Trajectories]) -> np.ndarray:
        """``[E]`` the log-likelihood of each episode (the tasks' episodes in turn)."""
        from ..planning.soft_vi import solve

        out = []
        for i, (t, tr) in enumerate(zip(self.tasks, trajs, strict=True)):
            if len(tr) == 0:
                continue
            w = np.concatenate([theta, r[self.splits[i]:self.splits[i + 1]]])
            lp = solve(t.aug, w[None], np.array([beta]), model=self.model, tol=1e-10).log_policy[0]
            pair = lp[tr.state, tr.action]
            out += [float(pair[tr.episode == e].sum()) for e in tr.episode_ids]
        return np.array(out)


_CACHE: dict[tuple, Competitor] = {}


def competitor_for(tasks: Sequence[tuple[TabularMDP, Trajectories]], model: str = DEFAULT_MODEL,
                   penalty: float = PENALTY) -> Competitor:
    """The compiled competitor of ``tasks``' MDPs: every state is a support state on a map of at most
    :data:`ALL_STATES` states (so people on one map share one compiled program), else the states
    near the demonstrations (:func:`support_states`)."""
    mdps = [m for m, _ in tasks]
    supports = [np.arange(m.n_states) if m.n_states <= ALL_STATES else support_states(m, t) for m, t in tasks]
    n = sum(len(s) for s in supports)
    if n > MAX_SUPPORT:
        raise InputError(f"the competitor would have {n} per-state rewards (more than {MAX_SUPPORT})")
    key = (tuple(id(m) for m in mdps), tuple(s.tobytes() for s in supports), model, penalty)
    comp = _CACHE.get(key)
    if comp is None or any(a is not b for a, b in zip(comp.mdps, mdps, strict=True)):
        if len(_CACHE) >= 4:
            _CACHE.pop(next(iter(_CACHE)))
        comp = _CACHE[key] = Competitor(mdps, supports, model, penalty)
        comp.mdps = mdps
    return comp


def _fold(trajs: Trajectories, keep: int) -> Trajectories:
    ids = trajs.episode_ids
    chosen = ids[keep::2]
    m = np.isin(trajs.episode, chosen)
    return Trajectories(trajs.episode[m], trajs.step[m], trajs.state[m], trajs.action[m])


def compare(tasks: Sequence[tuple[TabularMDP, Trajectories]], theta_hat, *, model: str = DEFAULT_MODEL,
            penalty: float = PENALTY, rng: np.random.Generator | None = None) -> dict[str, Any]:
    """The held-out comparison of the features' model and the richer one (see the module docstring).

    ``theta_hat``: the result's θ̂ (the departure is measured from θ̂·φ). Every task needs at least
    two episodes (one per fold). Returns ``{"heldout_actions", "heldout_nats_per_action":
    {"features", "richer"}, "gain", "gain_se", "beta_features", "beta_richer", "beta_ratio",
    "departure": [per task: {"states": [...], "values": [...]}], "penalty"}``.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    for i, (_, t) in enumerate(tasks):
        if t.n_episodes < 2:
            raise InputError(f"task {i + 1}: the held-out comparison needs at least 2 episodes, got "
                             f"{t.n_episodes}")
    comp = competitor_for(tasks, model, penalty)
    trajs = [t for _, t in tasks]
    diffs, feats_ll, rich_ll, actions = [], 0.0, 0.0, 0
    for k in (0, 1):
        train = [_fold(t, 1 - k) for t in trajs]
        test = [_fold(t, k) for t in trajs]
        c = comp.counts(train)
        th, b = comp.fit_features(c, rng)
        r, b_r = comp.fit_richer(th, b, c)
        lf = comp.episode_log_likelihoods(th, np.zeros_like(r), b, test)
        lr = comp.episode_log_likelihoods(th, r, b_r, test)
        diffs.append(lr - lf)
        feats_ll += float(lf.sum())
        rich_ll += float(lr.sum())
        actions += sum(len(t) for t in test)
    d = np.concatenate(diffs)
    gain = float(d.sum() / actions)
    se = float(d.std(ddof=1) * math.sqrt(len(d)) / actions) if len(d) > 1 else math.inf
    c_all = comp.counts(trajs)
    theta_hat = np.asarray(theta_hat, dtype=np.float64)
    _, beta_f = comp.fit_richer(theta_hat, 1.0, c_all, free_r=False)
    r_all, beta_r = comp.fit_richer(theta_hat, beta_f, c_all)
    departure = [{"states": t.support.tolist(),
                  "values": r_all[comp.splits[i]:comp.splits[i + 1]].tolist()}
                 for i, t in enumerate(comp.tasks)]
    return {"penalty": penalty, "heldout_actions": actions,
            "heldout_nats_per_action": {"features": feats_ll / actions, "richer": rich_ll / actions},
            "gain": gain, "gain_se": se, "beta_features": beta_f, "beta_richer": beta_r,
            "beta_ratio": beta_r / beta_f, "departure": departure}
