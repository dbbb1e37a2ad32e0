"""The differentiable likelihood of demonstrations on one task or several (Eq. 11).

From trajectories to observed-pair counts (:func:`pair_counts`) and to the
log-likelihood in θ and β with its implicit gradient
(:mod:`expertise_irl.planning.differentiable`), summed over tasks that share θ.
"""

from __future__ import annotations

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from ..planning.differentiable import LogLikelihood, TaskSum, make_log_likelihood


def pair_counts(mdp: TabularMDP, trajs: Trajectories) -> np.ndarray:
    """``[S, A]`` number of times each (state, action) pair was observed."""
    counts = np.zeros((mdp.n_states, mdp.n_actions))
    np.add.at(counts, (trajs.state, trajs.action), 1.0)
    bad = (counts > 0) & ~mdp.available
    if bad.any():
        s, a = np.argwhere(bad)[0]
        raise InputError(f"observed action {a} is not available in {mdp.describe_state(int(s))}")
    return counts


def as_tasks(mdp, trajs) -> list[tuple[TabularMDP, Trajectories]]:
    """``[(mdp, trajs), ...]`` from one MDP and its trajectories or equal-length lists of both.

    Raises :class:`InputError` when the lists differ in length, are empty, or the MDPs do not
    share their features (the same θ must mean the same thing on every task).
    """
    if isinstance(mdp, TabularMDP) != isinstance(trajs, Trajectories):
        raise InputError("give one MDP with its trajectories, or a list of each")
    if isinstance(mdp, TabularMDP):
        return [(mdp, trajs)]
    mdps, trajss = list(mdp), list(trajs)
    if not mdps or len(mdps) != len(trajss):
        raise InputError(f"need one list of trajectories per MDP, got {len(trajss)} for {len(mdps)} MDPs")
    names = tuple(mdps[0].feature_names)
    for i, m in enumerate(mdps[1:], start=2):
        if tuple(m.feature_names) != names:
            raise InputError(f"task {i} has features {', '.join(m.feature_names)}, task 1 has "
                             f"{', '.join(names)}: every task must share the features")
    return list(zip(mdps, trajss, strict=True))


def tasks_log_likelihood(mdp, trajs, *, tol: float = 1e-10, max_iter: int = 200_000,
                         model: str = DEFAULT_MODEL) -> LogLikelihood | TaskSum:
    """The log-likelihood of ``trajs`` on ``mdp`` (:class:`LogLikelihood`), or, given lists of
    MDPs and trajectories (one per task, see :func:`as_tasks`), their sum (:class:`TaskSum`)."""
    tasks = as_tasks(mdp, trajs)
    parts = [make_log_likelihood(m, pair_counts(m, t), tol=tol, max_iter=max_iter, model=model)
             for m, t in tasks]
    return parts[0] if isinstance(mdp, TabularMDP) else TaskSum(parts)
