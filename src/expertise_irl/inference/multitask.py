"""One belief over one hypothesis set from demonstrations on several tasks (MDPs).

A person who did several maps, specifications or start points gives demonstrations on
several MDPs that share their features. Each task has its own policy table for every
hypothesis, but the hypotheses are the same, so the likelihood of everything the person
did is the product over tasks (Eq. 11 over all their trajectories) and the posterior is

    P(h | Ξ_1, …, Ξ_T) ∝ P(h) Π_t P(Ξ_t | h).

With a uniform prior this is the normalised product of the per-task posteriors.
:class:`MultiTaskBelief` keeps one :class:`~expertise_irl.inference.belief.DiscreteBelief`
per task (all with the same prior) and gives the joint posterior as a ``DiscreteBelief``
whose log-likelihood is the sum over tasks; the joint belief holds no policy table (its
``log_policy`` has no states), so it is read, not updated: update a task instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..hypotheses import HypothesisSet
from ..mdp import TabularMDP
from .belief import DiscreteBelief


@dataclass(frozen=True, eq=False)
class MultiTaskBelief:
    """Per-task beliefs over one hypothesis set, and their joint posterior.

    Attributes:
        tasks: one belief per task, same hypotheses and prior, each with its own
            ``log_policy [H, S_t, A]``.
    """

    tasks: tuple[DiscreteBelief, ...]

    def __post_init__(self) -> None:
        if not self.tasks:
            raise InputError("a multi-task belief needs at least one task")
        first = self.tasks[0]
        for i, b in enumerate(self.tasks[1:], start=1):
            same = (b.hypotheses.thetas.shape == first.hypotheses.thetas.shape
                    and np.array_equal(b.hypotheses.thetas, first.hypotheses.thetas)
                    and np.array_equal(b.hypotheses.betas, first.hypotheses.betas))
            if not same:
                raise InputError(f"task {i}: its hypothesis set differs from task 0's")
            if not np.array_equal(b.log_prior, first.log_prior):
                raise InputError(f"task {i}: its prior differs from task 0's")
        object.__setattr__(self, "tasks", tuple(self.tasks))

    @classmethod
    def from_tasks(cls, tasks: Sequence[tuple[TabularMDP, Trajectories | None]], hypotheses: HypothesisSet,
                   *, prior: np.ndarray | None = None, **solve_kwargs) -> MultiTaskBelief:
        """Solve every hypothesis on each task's MDP and condition on its trajectories.

        ``tasks`` is a list of ``(mdp, trajectories)`` pairs (trajectories may be ``None``:
        nothing observed there yet). The MDPs must have the same features, in order.
        ``solve_kwargs`` go to :func:`~expertise_irl.planning.soft_vi.solve`.
        """
        if not tasks:
            raise InputError("a multi-task belief needs at least one task")
        names = tasks[0][0].feature_names
        beliefs = []
        for i, (mdp, trajs) in enumerate(tasks):
            if tuple(mdp.feature_names) != tuple(names):
                raise InputError(f"task {i}: features {', '.join(mdp.feature_names)} differ from task 0's "
                                 f"({', '.join(names)}); the tasks must share their features")
            b = DiscreteBelief.from_mdp(mdp, hypotheses, prior=prior, **solve_kwargs)
            beliefs.append(b.update(trajs) if trajs is not None else b)
        return cls(tuple(beliefs))

    def update(self, task: int, trajs: Trajectories) -> MultiTaskBelief:
        """Condition task ``task`` on more trajectories (a new belief; this one is unchanged)."""
        if not 0 <= task < len(self.tasks):
            raise InputError(f"task {task}: there are {len(self.tasks)} tasks")
        beliefs = list(self.tasks)
        beliefs[task] = beliefs[task].update(trajs)
        return replace(self, tasks=tuple(beliefs))

    @property
    def n_tasks(self) -> int:
        return len(self.tasks)

    @property
    def log_likelihood(self) -> np.ndarray:
        """``[H]`` Σ_t log P(Ξ_t | h)."""
        return np.sum([b.log_likelihood for b in self.tasks], axis=0)

    def joint(self) -> DiscreteBelief:
        """The posterior given every task, as a read-only belief (no policy table)."""
        first = self.tasks[0]
        H, A = first.log_policy.shape[0], first.log_policy.shape[2]
        return DiscreteBelief(first.hypotheses, np.zeros((H, 0, A)), first.log_prior, self.log_likelihood,
                              sum(b.n_observed for b in self.tasks))
