"""A simulated person: episodes drawn from the policy of one hypothesis (θ, β) on an MDP
(:func:`simulate`), or of a teacher who shows it to a literal observer (:func:`simulate_teacher`);
how each episode ended (:func:`episode_outcomes`) and, for those cut at the step cap, why
(:func:`cap_note`)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from ..errors import ArgumentError, InputError
from ..hypotheses import GROUP_BOUNDARIES
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL, check_model
from ..planning.soft_vi import solve
from .trajectories import Trajectories

DEFAULT_MAX_STEPS = 500

__all__ = ["BATCH_EPISODES", "DEFAULT_MAX_STEPS", "best_move", "cap_note", "capped_episodes", "capped_flags",
           "check_start_states", "episode_outcomes", "simulate", "simulate_batches", "simulate_teacher"]


def _check_hypothesis(mdp: TabularMDP, theta, beta) -> tuple[np.ndarray, float]:
    th = np.asarray(theta, dtype=np.float64)
    if th.shape != (mdp.n_features,):
        raise InputError(
            f"theta must have shape [K] with K = {mdp.n_features} features "
            f"({', '.join(mdp.feature_names)}), got shape {th.shape}"
        )
    if not np.all(np.isfinite(th)) or np.any(th < 0):
        raise InputError(f"theta must be finite and non-negative, got {th.tolist()}")
    b = np.asarray(beta, dtype=np.float64)
    if b.shape != () or not np.isfinite(b) or b <= 0:
        raise InputError(f"beta must be a single finite number > 0, got {beta!r}")
    return th, float(b)


def _check_log_policy(mdp: TabularMDP, log_policy) -> np.ndarray:
    lp = np.asarray(log_policy, dtype=np.float64)
    S, A = mdp.n_states, mdp.n_actions
    if lp.shape != (S, A):
        raise ArgumentError(f"log_policy must have shape [S, A] = [{S}, {A}], got {lp.shape}")
    pi = np.exp(lp)
    if np.isnan(pi).any() or np.any(pi[~mdp.available] > 0):
        raise InputError("log_policy must be -inf on unavailable actions and contain no NaN")
    row = pi.sum(axis=1)
    bad = ~mdp.terminal & ~(np.abs(row - 1.0) <= 1e-6)
    if bad.any():
        s = int(np.flatnonzero(bad)[0])
        raise InputError(f"log_policy of {mdp.describe_state(s)} sums to {row[s]:.6g}, not 1")
    return lp


def check_start_states(mdp: TabularMDP, starts, what: str = "starts") -> np.ndarray:
    """``starts`` as an int array of non-terminal states (default: ``mdp.initial_states()``).

    :class:`InputError` named after ``what`` for an empty list, a non-integer, an index out of
    range or a terminal state.
    """
    if starts is None:
        return np.asarray(mdp.initial_states(), dtype=np.int64)
    st = np.atleast_1d(np.asarray(starts))
    if st.ndim != 1 or st.size == 0 or not np.issubdtype(st.dtype, np.integer):
        raise InputError(f"{what} must be a non-empty 1-D array of state indices")
    st = st.astype(np.int64)
    out = (st < 0) | (st >= mdp.n_states)
    if out.any():
        raise InputError(f"{what}: {int(st[out][0])} is not a state index in [0, {mdp.n_states})")
    term = mdp.terminal[st]
    if term.any():
        raise InputError(f"{what}: {mdp.describe_state(int(st[term][0]))} is terminal (a goal)")
    return st


def simulate(
    mdp: TabularMDP,
    theta,
    beta,
    n_episodes: int,
    rng: np.random.Generator | int,
    *,
    starts=None,
    max_steps: int = DEFAULT_MAX_STEPS,
    log_policy: np.ndarray | None = None,
    model: str = DEFAULT_MODEL,
) -> Trajectories:
    """Episodes of a simulated person acting with the policy π(θ, β) of ``model``.

    All episodes are advanced together, one step at a time; each step draws one
    uniform number per active episode and picks the action by inverse-CDF sampling
    from the cumulative policy. The same ``rng`` state gives identical output.

    Args:
        mdp: the task.
        theta: ``[K]`` reward weights, finite and ``>= 0``; used as given (not normalised).
        beta: expertise (temperature), ``> 0``.
        n_episodes: number of episodes N (``>= 0``).
        rng: source of all randomness (start states and actions), a
            :class:`numpy.random.Generator`; an int is used as a seed.
        starts: ``[M]`` non-terminal states to start from, drawn uniformly per episode.
            Default: ``mdp.initial_states()`` (the map's start cells, else every non-terminal
            state).
        max_steps: an episode ends on entering a terminal state or after ``max_steps`` actions.
            Truncating at a fixed step count does not bias the likelihood of the recorded
            pairs: the stopping rule does not depend on the actions' probabilities under
            any hypothesis, so it contributes the same factor to every hypothesis.
        log_policy: ``[S, A]``, used instead of solving for ``(theta, beta)`` (e.g. one row of
            ``planning.solve(...).log_policy``); ``theta`` and ``beta`` may then be None.
        model: the observation model of :mod:`expertise_irl.models` (default ``"maxent"``, the
            paper's); ignored when ``log_policy`` is given.

    Returns:
        ``[n]`` pairs; episodes labelled ``0..N-1``, steps ``0..T-1`` within each.

    Raises:
        InputError: bad θ, β, ``starts``, ``max_steps``, ``n_episodes`` or ``log_policy``.
        ArgumentError: ``log_policy`` of the wrong shape.
    """
    lp = _policy(mdp, theta, beta, log_policy, model)
    st = check_start_states(mdp, starts)
    rng = _check_counts(n_episodes, max_steps, rng)
    return _walk(mdp, _policy_cdf(lp), st, int(n_episodes), int(max_steps), rng)


def simulate_teacher(mdp: TabularMDP, theta, beta, lam: float, n_episodes: int,
                     rng: np.random.Generator | int, *, observer, starts=None,
                     max_steps: int = DEFAULT_MAX_STEPS) -> Trajectories:
    """Episodes of a teacher (θ, β, λ) showing the task to a literal observer (``--model pedagogical``).

    The teacher acts by :func:`~expertise_irl.inference.pedagogical.teacher_log_policy`: the ``maxent``
    policy of (θ, β) reweighted by ``exp(λ/β · I_θ)``, I_θ what each action tells the observer about θ;
    λ = 0 is a doer (:func:`simulate` under ``maxent``, episode for episode with the same ``rng``).

    Args:
        mdp: the task.
        theta: ``[K]`` reward weights, finite and ``>= 0`` (need not be in the observer's set).
        beta: expertise (temperature), ``> 0``.
        lam: the teaching weight λ ``>= 0`` (reward units per nat of the observer's belief).
        n_episodes: number of episodes N (``>= 0``).
        rng: source of all randomness; an int is used as a seed.
        observer: the literal observer on every state of ``mdp``
            (:func:`~expertise_irl.inference.pedagogical.solved_observer`), or the
            :class:`~expertise_irl.hypotheses.HypothesisSet` it believes in (solved here).
        starts: as :func:`simulate`'s.
        max_steps: as :func:`simulate`'s.

    Returns:
        ``[n]`` pairs; episodes labelled ``0..N-1``, steps ``0..T-1`` within each.

    Raises:
        InputError: bad θ, β, λ, ``starts``, ``max_steps`` or ``n_episodes``, or an observer of
            another task.
    """
    from ..hypotheses import HypothesisSet
    from ..planning.teaching import solved_observer, teacher_log_policy

    th, b = _check_hypothesis(mdp, theta, beta)
    if isinstance(observer, HypothesisSet):
        observer = solved_observer(mdp, observer)
    lp = teacher_log_policy(mdp, th, b, float(lam), observer)
    return simulate(mdp, th, b, n_episodes, rng, starts=starts, max_steps=max_steps, log_policy=lp)


#: :func:`simulate_batches` walks at most this many episodes at once.
BATCH_EPISODES = 100_000


def simulate_batches(mdp: TabularMDP, theta, beta, n_episodes: int, rng: np.random.Generator | int, *,
                     max_steps: int = DEFAULT_MAX_STEPS, model: str = DEFAULT_MODEL,
                     batch: int = BATCH_EPISODES,
                     log_policy: np.ndarray | None = None) -> Iterator[Trajectories]:
    """:func:`simulate`'s episodes in batches of at most ``batch`` (memory stays bounded however many
    are asked for), episodes numbered on across batches. The policy is solved once (or ``log_policy``
    is used, as :func:`simulate`'s) and ``rng`` runs on from batch to batch; with
    ``n_episodes <= batch`` the one batch is exactly :func:`simulate`'s output for the same ``rng``
    state."""
    cdf = _policy_cdf(_policy(mdp, theta, beta, log_policy, model))
    st = check_start_states(mdp, None)
    rng = _check_counts(n_episodes, max_steps, rng)
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise InputError(f"batch must be an integer >= 1, got {batch!r}")
    done = 0
    while done < n_episodes:
        k = min(batch, int(n_episodes) - done)
        t = _walk(mdp, cdf, st, k, int(max_steps), rng)
        yield Trajectories(t.episode + done, t.step, t.state, t.action)
        done += k


def _check_counts(n_episodes, max_steps, rng) -> np.random.Generator:
    """Refuse a bad episode count, step cap or ``rng``; the Generator to draw from."""
    if isinstance(n_episodes, bool) or not isinstance(n_episodes, int | np.integer) or n_episodes < 0:
        raise InputError(f"n_episodes must be an integer >= 0, got {n_episodes!r}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise InputError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    if not isinstance(rng, np.random.Generator):
        if isinstance(rng, bool) or not isinstance(rng, int | np.integer) or rng < 0:
            raise InputError(f"rng must be a numpy Generator or a seed >= 0, got {rng!r}")
        rng = np.random.default_rng(int(rng))
    return rng


def _policy(mdp: TabularMDP, theta, beta, log_policy, model: str) -> np.ndarray:
    """The checked ``[S, A]`` log-policy: ``log_policy`` if given, else that of (θ, β) under ``model``."""
    if log_policy is None:
        if theta is None or beta is None:
            raise InputError("simulate needs theta and beta (or a log_policy)")
        th, b = _check_hypothesis(mdp, theta, beta)
        log_policy = solve(mdp, th, b, model=check_model(model)).log_policy[0]
    else:
        if theta is not None or beta is not None:
            _check_hypothesis(mdp, theta, beta)
    return _check_log_policy(mdp, log_policy)


def _policy_cdf(lp: np.ndarray) -> np.ndarray:
    """``[S, A]`` cumulative policy, each non-terminal row ending at exactly 1.0."""
    cdf = np.cumsum(np.exp(lp), axis=1)
    total = cdf[:, -1:]
    # Dividing by the row total makes the last entry exactly 1.0, so u in [0, 1) never
    # runs past the last action with positive probability. Terminal rows are never used.
    return np.where(total > 0, cdf / np.where(total > 0, total, 1.0), 1.0)


def _walk(mdp: TabularMDP, cdf: np.ndarray, st: np.ndarray, n_episodes: int, max_steps: int,
          rng: np.random.Generator) -> Trajectories:
    """``n_episodes`` episodes from starts drawn from ``st``, advanced together by inverse-CDF
    draws (one start draw for all, then one uniform per active episode and step)."""
    current = st[rng.integers(0, st.size, size=n_episodes)]
    active = np.arange(n_episodes, dtype=np.int64)
    chunks: list[tuple[np.ndarray, ...]] = []
    for t in range(max_steps):
        if active.size == 0:
            break
        s = current[active]
        u = rng.random(active.size)
        a = np.sum(cdf[s] <= u[:, None], axis=1)
        chunks.append((active, np.full(active.size, t, dtype=np.int64), s, a))
        nxt = mdp.next_state[s, a]
        current[active] = nxt
        active = active[~mdp.terminal[nxt]]
    if not chunks:
        empty = np.zeros(0, dtype=np.int64)
        return Trajectories(empty, empty, empty, empty)
    ep, step, state, action = (np.concatenate(c) for c in zip(*chunks, strict=True))
    order = np.lexsort((step, ep))
    return Trajectories(ep[order], step[order], state[order], action[order])


def capped_flags(trajs: Trajectories, mdp: TabularMDP, max_steps: int) -> np.ndarray:
    """``[n_episodes]`` whether each episode ran to ``max_steps`` actions without entering a
    terminal state (in episode order)."""
    if len(trajs) == 0:
        return np.zeros(0, dtype=bool)
    last = np.flatnonzero(np.append(trajs.episode[1:] != trajs.episode[:-1], True))
    ended = mdp.terminal[mdp.next_state[trajs.state[last], trajs.action[last]]]
    return ~ended & (trajs.step[last] + 1 >= max_steps)


def capped_episodes(trajs: Trajectories, mdp: TabularMDP, max_steps: int) -> int:
    """Episodes that ran to ``max_steps`` actions without entering a terminal state."""
    return int(np.sum(capped_flags(trajs, mdp, max_steps)))


def episode_outcomes(trajs: Trajectories, mdp: TabularMDP, max_steps: int | None) -> list[str]:
    """``"goal"`` (entered a terminal state), ``"cap"`` (stopped after ``max_steps`` actions
    without reaching one) or ``"cut"`` (shorter, not in a goal: a recording that ends early)."""
    out = []
    for states, actions in trajs.episodes():
        last = int(mdp.next_state[states[-1], actions[-1]])
        if last >= 0 and mdp.terminal[last]:
            out.append("goal")
        elif max_steps is not None and len(states) >= max_steps:
            out.append("cap")
        else:
            out.append("cut")
    return out


def best_move(mdp: TabularMDP, theta) -> tuple[float, str | None]:
    """Largest reward θ·φ of a move that does not enter a goal, and the feature that pays most in it."""
    ns = np.asarray(mdp.next_state)
    ok = ns >= 0
    ok &= ~np.asarray(mdp.terminal)[np.where(ok, ns, 0)]
    if not ok.any():
        return -np.inf, None
    contrib = np.asarray(mdp.features)[ok] * np.asarray(theta, dtype=float)  # [moves, K]
    r = np.asarray(mdp.reward(theta))[ok]
    i = int(np.argmax(r))
    return float(r[i]), str(mdp.feature_names[int(np.argmax(contrib[i]))])


def cap_note(outcomes: Sequence[str], max_steps: int | None, beta_true: float | None = None,
             move: tuple[float, str | None] | None = None, model: str = "maxent") -> str | None:
    """Sentences on the episodes that hit the step cap and why (None when none did).

    Causes, all part of the model: moves that pay (``move`` = (largest reward of a move that
    does not enter the goal, the feature behind it)), and, for the paper's ``maxent`` model,
    the entropy bonus, which grows with β.
    """
    n_cap, n = sum(o == "cap" for o in outcomes), len(outcomes)
    if n_cap == 0:
        return None
    text = (f"{n_cap} of {n} episode{'s' if n != 1 else ''} hit the {max_steps}-step cap without "
            "reaching the goal. That is the model, not a bug:")
    reasons = []
    pays = move is not None and move[0] > 0
    if pays:
        reasons.append(f"some moves pay (reward θ*·φ up to +{move[0]:.2g}, from {move[1]}), so "
                       "going round can be worth more than finishing")
    if model == "maxent" and (not pays or beta_true is None or beta_true >= GROUP_BOUNDARIES[0]):
        who = f"β* = {beta_true:g}" if beta_true is not None else "a large β"
        reasons.append("the paper's max-ent person is paid for randomness (β × entropy per step) "
                       f"while entering the goal ends all pay, and with {who} wandering is worth "
                       "more than finishing")
    if not reasons:
        reasons.append(f"under the {model} model with these weights the goal is not worth the "
                       "way there")
    return f"{text} {'; and '.join(reasons)}."
