"""Demonstrations to and from the ``imitation`` library (HumanCompatibleAI/imitation), and our MDP as
a tabular environment for its maximum causal entropy IRL (``imitation.algorithms.mce_irl``).

**Trajectories.** One :class:`Trajectories` episode of T pairs is one
``imitation.data.types.Trajectory``, episodes in their order in ``trajs``:

- ``obs``: T + 1 observations of our states: ``state[0], …, state[T-1]`` and then the **final
  state**, the one the last action leads to (``mdp.next_state[state[T-1], action[T-1]]``: a goal
  when the episode ended there, else the state where it was cut). ``observations="one-hot"``
  (default): float32 rows of length S, 1 at the state's index, 0 elsewhere (a Box observation);
  ``"index"``: the state indices themselves, int64 (a Discrete observation, what
  ``MCEIRL``'s occupancy count of trajectories indexes with).
- ``acts``: our action indices, int64, unchanged (for the grid worlds 0 up, 1 down, 2 left,
  3 right: :data:`expertise_irl.mdp.ACTION_NAMES`).
- ``infos``: None.
- ``terminal``: True when the final state is terminal (the episode entered a goal); False when
  it is not: an episode cut at the step cap or a recording that stops before the goal, which
  imitation calls a fragment without the episode's end.

Episode labels are not carried (a Trajectory has no field for them): :func:`from_imitation`
numbers the episodes 0, 1, … in list order, or takes ``episode_ids``. It reads the four fields
by name, so anything with ``obs``, ``acts`` and ``terminal`` converts (``infos`` and
``TrajectoryWithRew``'s ``rews`` are ignored), and it checks what it reads: one-hot rows,
indices in range, the moves possible in ``mdp``, the final observation the successor of the
last pair, and ``terminal`` agreeing with whether that state is a goal.

imitation is imported only inside :func:`to_imitation` and :func:`tabular_pomdp`, so this package
does not depend on it. imitation 1.0.1 requires ``gymnasium~=0.29`` and this package
``gymnasium>=1.0``, so the two cannot share an environment: install imitation in one of its own
(``docs/vs-imitation.md``), or give ``trajectory_cls``, any class taking the keywords
``obs, acts, infos, terminal``.

**MCE IRL's environment.** imitation's MCE IRL learns a reward of the state alone, ``r(x)``, paid
in the state an action is taken from; ours is a reward of the move, ``θ·φ(s, a)``. The
:class:`ArrivalChain` makes the moves states: state ``(s, a)`` means "a was just taken from s",
so its successor under a′ is ``(next(s, a), a′)``; the first state of an episode is a start state
with no features. A reward paid on arrival comes one step later, so the chain's features are
``φ(s, a)/γ``; then MCE's soft values on the chain are ours, and a linear reward ``w·φ`` on it
gives exactly our max-ent policy of θ/β with ``w = θ/β`` (for θ on the simplex ``‖w‖₁ = 1/β``).
Moves into a goal lead to an absorbing ``sink``, moves that are unavailable to an absorbing
``dead`` state whose fixed reward :data:`DEAD_REWARD` gives them probability 0; the sink's other
actions lead there too, so entering a goal ends the episode with value 0 as in our model.

MCE IRL is finite-horizon (``horizon`` steps); as ``γ^horizon → 0`` its policy at the first steps
is our discounted infinite-horizon one. imitation 1.0.1's ``MCEIRL`` weights its occupancy
measures by ``discount`` but computes the policy it trains with undiscounted
(``mce_occupancy_measures`` calls ``mce_partition_fh`` without the discount), so a discounted
model has to be in the transitions: with ``discounted_transitions=True`` every move ends the
episode with probability 1 − γ (in an absorbing ``end`` state of value 0), which makes the
undiscounted soft backup ``γ·V`` and the undiscounted occupancy the discounted one; train that
chain with ``discount=1`` on the demonstrations' discounted occupancy (:meth:`ArrivalChain.occupancy`,
which is what ``MCEIRL(discount=γ)`` counts from :meth:`ArrivalChain.trajectories`).
``tests/demos/test_imitation_io.py`` checks the chain's soft values against
:func:`expertise_irl.planning.soft_vi.solve`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..mdp import TabularMDP
from .trajectories import Trajectories, validate

OBSERVATIONS = ("one-hot", "index")
#: Fixed reward of the chain's ``dead`` state, where unavailable actions lead: exp(−1e6) is 0.
DEAD_REWARD = -1e6
INSTALL_HINT = ("the imitation library is not installed: pip install imitation (in an environment of "
                "its own: imitation 1.0.1 requires gymnasium~=0.29, this package gymnasium>=1.0; see "
                "docs/vs-imitation.md), or pass trajectory_cls")


def _import(module: str, name: str):
    """``module.name``, or :class:`InputError` with :data:`INSTALL_HINT` when imitation is missing."""
    import importlib

    try:
        return getattr(importlib.import_module(module), name)
    except ImportError as e:
        raise InputError(f"{INSTALL_HINT} ({e})") from None


def _trajectory_class(trajectory_cls):
    if trajectory_cls is not None:
        return trajectory_cls
    return _import("imitation.data.types", "Trajectory")


def final_states(trajs: Trajectories, mdp: TabularMDP) -> np.ndarray:
    """``[E]`` the state each episode's last action leads to, episodes in order."""
    ids = trajs.episode_ids
    last = np.array([np.flatnonzero(trajs.episode == e)[-1] for e in ids], dtype=np.int64)
    return mdp.next_state[trajs.state[last], trajs.action[last]] if last.size else last


def to_imitation(trajs: Trajectories, mdp: TabularMDP, *, observations: str = "one-hot",
                 trajectory_cls=None) -> list[Any]:
    """One ``imitation.data.types.Trajectory`` per episode of ``trajs`` (the mapping: module docstring).

    Args:
        trajs: the demonstrations, checked against ``mdp`` first (:func:`~.trajectories.validate`).
        mdp: the task they belong to.
        observations: ``"one-hot"`` (float32 rows of length S) or ``"index"`` (int64 state
            indices).
        trajectory_cls: replaces imitation's class (called with the keywords ``obs``, ``acts``,
            ``infos``, ``terminal``); without it imitation must be importable.

    Returns:
        The trajectories, episodes in their order in ``trajs``.

    Raises:
        InputError: an unknown ``observations``, demonstrations not valid in ``mdp``, or imitation
            not installed and no ``trajectory_cls``.
    """
    if observations not in OBSERVATIONS:
        raise InputError(f"observations must be one of {', '.join(OBSERVATIONS)}, got {observations!r}")
    validate(trajs, mdp)
    cls = _trajectory_class(trajectory_cls)
    out = []
    for (states, actions), final in zip(trajs.episodes(), final_states(trajs, mdp), strict=True):
        visited = np.append(states, final)
        if observations == "index":
            obs = visited.astype(np.int64)
        else:
            obs = np.zeros((visited.size, mdp.n_states), dtype=np.float32)
            obs[np.arange(visited.size), visited] = 1.0
        out.append(cls(obs=obs, acts=np.asarray(actions, dtype=np.int64).copy(), infos=None,
                       terminal=bool(mdp.terminal[final])))
    return out


def _whole(a: np.ndarray) -> bool:
    """Integers, or floats that are whole numbers."""
    if np.issubdtype(a.dtype, np.integer):
        return True
    return bool(np.issubdtype(a.dtype, np.floating) and np.all(np.isfinite(a)) and np.all(a == np.round(a)))


def _states_of(obs, mdp: TabularMDP, i: int, source: str) -> np.ndarray:
    """The state indices of one trajectory's observations (one-hot rows or indices)."""
    if isinstance(obs, dict) or not hasattr(obs, "__len__"):
        raise InputError(f"{source}: trajectory {i}: obs must be an array (one-hot rows or state "
                         f"indices), got {type(obs).__name__}")
    o = np.asarray(obs)
    S = mdp.n_states
    if o.ndim == 2:
        if o.shape[1] != S:
            raise InputError(f"{source}: trajectory {i}: one-hot observations must have {S} columns "
                             f"(the MDP's states), got {o.shape[1]}")
        ones = o == 1
        if not np.all(ones | (o == 0)) or not np.all(ones.sum(axis=1) == 1):
            t = int(np.flatnonzero(~(np.all(ones | (o == 0), axis=1) & (ones.sum(axis=1) == 1)))[0])
            raise InputError(f"{source}: trajectory {i}: observation {t} is not one-hot "
                             "(one 1, the rest 0)")
        return np.argmax(ones, axis=1).astype(np.int64)
    if o.ndim == 1:
        if not _whole(o):
            raise InputError(f"{source}: trajectory {i}: observations must be state indices or "
                             f"one-hot rows, got dtype {o.dtype}")
        s = o.astype(np.int64)
        bad = (s < 0) | (s >= S)
        if bad.any():
            t = int(np.flatnonzero(bad)[0])
            raise InputError(f"{source}: trajectory {i}: observation {t} is state {s[t]}, outside "
                             f"0..{S - 1}")
        return s
    raise InputError(f"{source}: trajectory {i}: obs must be 1-D (state indices) or 2-D (one-hot "
                     f"rows), got shape {o.shape}")


def from_imitation(trajectories: Iterable[Any], mdp: TabularMDP, *, episode_ids: Sequence[int] | None = None,
                   source: str = "<imitation>") -> Trajectories:
    """:class:`Trajectories` from imitation's trajectories (or any objects with their fields).

    The inverse of :func:`to_imitation` for either kind of observation.

    Args:
        trajectories: objects with ``obs``, ``acts`` and ``terminal`` (``infos`` and ``rews`` are
            ignored).
        mdp: the task they belong to.
        episode_ids: the episodes' labels (default 0, 1, …), one per trajectory and distinct.
        source: a label for messages (a file name, say).

    Returns:
        The pairs of every trajectory, in list order.

    Raises:
        InputError: the ids do not match the trajectories, or a trajectory has a missing field,
            observations that are not one-hot rows or state indices, a move not possible in
            ``mdp``, or a final observation or ``terminal`` that disagrees with its last move; the
            message names the trajectory at fault.
    """
    trajectories = list(trajectories)
    if episode_ids is None:
        episode_ids = range(len(trajectories))
    episode_ids = [int(e) for e in episode_ids]
    if len(episode_ids) != len(trajectories):
        raise InputError(f"{source}: {len(episode_ids)} episode ids for {len(trajectories)} trajectories")
    if len(set(episode_ids)) != len(episode_ids):
        raise InputError(f"{source}: episode ids must be distinct")
    parts = []
    for i, tr in enumerate(trajectories):
        for name in ("obs", "acts", "terminal"):
            if not hasattr(tr, name):
                raise InputError(f"{source}: trajectory {i} has no field {name!r} (not a Trajectory)")
        states = _states_of(tr.obs, mdp, i, source)
        acts = np.asarray(tr.acts)
        if acts.ndim != 1 or not _whole(acts):
            raise InputError(f"{source}: trajectory {i}: acts must be a 1-D array of action indices, "
                             f"got shape {acts.shape} dtype {acts.dtype}")
        acts = acts.astype(np.int64)
        if acts.size == 0 or states.size != acts.size + 1:
            raise InputError(f"{source}: trajectory {i}: expected T >= 1 actions and T + 1 observations, "
                             f"got {acts.size} and {states.size}")
        parts.append((states, acts, bool(tr.terminal)))
    T = [a.size for _, a, _ in parts]
    out = Trajectories(
        np.repeat(np.array(episode_ids, dtype=np.int64), T),
        np.concatenate([np.arange(t) for t in T]) if T else np.zeros(0, np.int64),
        np.concatenate([s[:-1] for s, _, _ in parts]) if T else np.zeros(0, np.int64),
        np.concatenate([a for _, a, _ in parts]) if T else np.zeros(0, np.int64),
    )
    validate(out, mdp, source)
    for i, (states, acts, terminal) in enumerate(parts):
        final = int(mdp.next_state[states[-2], acts[-1]])
        if states[-1] != final:
            raise InputError(f"{source}: trajectory {i}: the final observation is state {states[-1]}, but "
                             f"the last action leads to {mdp.describe_state(final)}")
        if terminal != bool(mdp.terminal[final]):
            said = "terminal=True but it ends in" if terminal else "terminal=False but it ends in a goal,"
            raise InputError(f"{source}: trajectory {i}: {said} {mdp.describe_state(final)}")
    return out


# --------------------------------------------------------------------- MCE IRL's environment
@dataclass(frozen=True, eq=False)
class ArrivalChain:
    """Our MDP with its moves as states, for a reward of the state alone (module docstring).

    States ``x`` of the chain, in this order: one per available pair ``(s, a)``
    (``pair_index[s, a]``, −1 for none), one per start state (``start_index[s]``, −1 for states
    that are not starts), then ``sink``, ``dead`` and, with discounted transitions, ``end``.
    Built by :func:`arrival_chain`.

    Attributes:
        transition_matrix: ``[X, A, X]`` float64 (one 1 per row; with discounted transitions γ on
            the successor and 1 − γ on ``end``).
        features: ``[X, K′]`` ``φ(s, a)/γ`` (K′ = K, or K + 1 with the MDP's ``reward_offset``
            as the last feature, whose weight then is 1/β too); zero for the other states.
        fixed_reward: ``[X]`` reward outside the learned weights: :data:`DEAD_REWARD` on ``dead``.
        initial_state_dist: ``[X]`` uniform over the start states.
        pair_index: ``[S, A]`` the chain state of each pair, −1 for unavailable ones.
        start_index: ``[S]`` the chain state of each start state, −1 for the others.
        sink: index of ``sink``, where moves into a goal lead.
        dead: index of ``dead``, where unavailable actions lead.
        end: index of ``end``, −1 without discounted transitions.
        horizon: MCE IRL's number of steps.
        gamma: the MDP's discount.
        n_theta: K, the MDP's number of features.
    """

    transition_matrix: np.ndarray
    features: np.ndarray
    fixed_reward: np.ndarray
    initial_state_dist: np.ndarray
    pair_index: np.ndarray
    start_index: np.ndarray
    sink: int
    dead: int
    end: int
    horizon: int
    gamma: float
    n_theta: int

    @property
    def n_states(self) -> int:
        return int(self.transition_matrix.shape[0])

    @property
    def observation_matrix(self) -> np.ndarray:
        """``[X, K′ + 1]``: the features and, last, the fixed reward (a reward net adds it with weight 1)."""
        return np.concatenate([self.features, self.fixed_reward[:, None]], axis=1)

    def states(self, trajs: Trajectories, mdp: TabularMDP) -> list[np.ndarray]:
        """Each episode as chain states, T + 1 of them: its start, then ``(s_t, a_t)`` for each pair.

        Episodes are cut to ``horizon`` actions, the length of MCE IRL's model.

        Args:
            trajs: the demonstrations.
            mdp: the MDP the chain was built from.

        Returns:
            One int64 array of chain states per episode, in episode order.

        Raises:
            InputError: an episode starts in a state that is not a start state of the chain.
        """
        out = []
        for states, actions in trajs.episodes():
            x0 = self.start_index[states[0]]
            if x0 < 0:
                raise InputError(f"an episode starts in {mdp.describe_state(int(states[0]))}, which is not "
                                 "a start state of the chain (give it in starts)")
            n = min(states.size, self.horizon)
            out.append(np.concatenate([[x0], self.pair_index[states[:n], actions[:n]]]).astype(np.int64))
        return out

    def trajectories(self, trajs: Trajectories, mdp: TabularMDP, *, trajectory_cls=None) -> list[Any]:
        """:meth:`states` as imitation Trajectories (``obs``: chain state indices, what ``MCEIRL`` counts).

        ``terminal`` is as in :func:`to_imitation`, False for an episode cut at ``horizon``.

        Args:
            trajs: the demonstrations, checked against ``mdp`` first.
            mdp: the MDP the chain was built from.
            trajectory_cls: replaces imitation's class, as in :func:`to_imitation`.

        Returns:
            One trajectory per episode.

        Raises:
            InputError: as :meth:`states`, or imitation not installed and no ``trajectory_cls``.
        """
        validate(trajs, mdp)
        cls = _trajectory_class(trajectory_cls)
        out = []
        for x, (_, actions), final in zip(self.states(trajs, mdp), trajs.episodes(), final_states(trajs, mdp),
                                          strict=True):
            n = x.size - 1
            out.append(cls(obs=x, acts=np.asarray(actions[:n], dtype=np.int64), infos=None,
                           terminal=bool(n == actions.size and mdp.terminal[final])))
        return out

    def occupancy(self, trajs: Trajectories, mdp: TabularMDP) -> np.ndarray:
        """``[X]`` the demonstrations' discounted occupancy per episode.

        Σ_t γ^t [x_t = x] averaged over episodes (``MCEIRL(discount=γ)``'s count of
        :meth:`trajectories`).

        Args:
            trajs: the demonstrations.
            mdp: the MDP the chain was built from.

        Returns:
            The occupancy of every chain state.

        Raises:
            InputError: as :meth:`states`.
        """
        om = np.zeros(self.n_states)
        paths = self.states(trajs, mdp)
        for x in paths:
            np.add.at(om, x, self.gamma ** np.arange(x.size))
        return om / max(len(paths), 1)

    def theta_beta(self, weights) -> tuple[np.ndarray, float]:
        """``(θ̂, β̂)`` of learned weights ``w = θ/β`` over the MDP's K features.

        θ̂ = w/‖w‖₁ and β̂ = 1/‖w‖₁ (with a ``reward_offset`` feature, its own weight is left out).

        Args:
            weights: the learned weights, ``[K]`` or ``[K + 1]``.

        Returns:
            θ̂ ``[K]`` and β̂.

        Raises:
            InputError: the weights are all zero.
        """
        w = np.asarray(weights, dtype=np.float64)[: self.n_theta]
        norm = float(np.abs(w).sum())
        if norm == 0:
            raise InputError("the learned weights are all zero: no direction θ̂, and β̂ = ∞")
        return w / norm, 1.0 / norm


def arrival_chain(mdp: TabularMDP, horizon: int, starts=None, *,
                  discounted_transitions: bool = False) -> ArrivalChain:
    """The :class:`ArrivalChain` of ``mdp`` with MCE IRL's ``horizon``.

    Args:
        mdp: the task.
        horizon: MCE IRL's number of steps (>= 1).
        starts: the states episodes start in, uniformly (default ``mdp.initial_states()``; give
            the demonstrations' own starts when matching their occupancy).
        discounted_transitions: end each move with probability 1 − γ (module docstring), for an
            ``MCEIRL`` with ``discount=1``.

    Returns:
        The chain.

    Raises:
        InputError: ``horizon`` below 1, or ``starts`` not non-terminal states of ``mdp``.
    """
    if int(horizon) < 1:
        raise InputError(f"horizon must be >= 1, got {horizon}")
    starts = mdp.initial_states() if starts is None else np.unique(np.asarray(starts, dtype=np.int64))
    if starts.size == 0 or ((starts < 0) | (starts >= mdp.n_states)).any() or mdp.terminal[starts].any():
        raise InputError("starts must be non-terminal states of the MDP")
    S, A = mdp.n_states, mdp.n_actions
    avail = mdp.available
    n_pairs = int(avail.sum())
    pair_index = np.full((S, A), -1, dtype=np.int64)
    pair_index[avail] = np.arange(n_pairs)
    start_index = np.full(S, -1, dtype=np.int64)
    start_index[starts] = n_pairs + np.arange(starts.size)
    sink, dead = n_pairs + starts.size, n_pairs + starts.size + 1
    end = dead + 1 if discounted_transitions else -1
    X = dead + 2 if discounted_transitions else dead + 1

    def leave(s):
        """``[A]`` chain successors of arriving in (non-terminal) state s: its pairs, dead elsewhere."""
        return np.where(avail[s], pair_index[s], dead)

    succ = np.full((X, A), dead, dtype=np.int64)  # dead's own row: dead
    s_of, a_of = np.nonzero(avail)
    nxt = mdp.next_state[s_of, a_of]
    for x, s in enumerate(nxt):
        if mdp.terminal[s]:
            succ[x, 0] = sink  # the goal: on to the sink by action 0, the others are dead
        else:
            succ[x] = leave(s)
    for s in starts:
        succ[start_index[s]] = leave(s)
    succ[sink, 0] = sink
    if discounted_transitions:
        succ[end, 0] = end
    T = np.zeros((X, A, X))
    rows, acts = np.arange(X)[:, None], np.arange(A)[None, :]
    if discounted_transitions:
        T[rows, acts, succ] = mdp.gamma
        T[:, :, end] += 1.0 - mdp.gamma
    else:
        T[rows, acts, succ] = 1.0
    basis = mdp.reward_basis()
    features = np.zeros((X, basis.shape[2]))
    features[:n_pairs] = basis[s_of, a_of] / mdp.gamma
    fixed = np.zeros(X)
    fixed[dead] = DEAD_REWARD
    init = np.zeros(X)
    init[start_index[starts]] = 1.0 / starts.size
    return ArrivalChain(T, features, fixed, init, pair_index, start_index, int(sink), int(dead), int(end),
                        int(horizon), float(mdp.gamma), mdp.n_features)


def tabular_pomdp(chain: ArrivalChain):
    """The chain as imitation's ``seals.base_envs.TabularModelPOMDP``.

    Its observations are the chain's :attr:`~ArrivalChain.observation_matrix`; its own reward
    matrix is zero (MCE IRL learns one).

    Args:
        chain: the chain of :func:`arrival_chain`.

    Returns:
        The environment, for ``imitation.algorithms.mce_irl.MCEIRL``.

    Raises:
        InputError: seals (imitation's environments) is not installed.
    """
    cls = _import("seals.base_envs", "TabularModelPOMDP")
    return cls(transition_matrix=chain.transition_matrix, observation_matrix=chain.observation_matrix,
               reward_matrix=np.zeros(chain.n_states), horizon=chain.horizon,
               initial_state_dist=chain.initial_state_dist)
