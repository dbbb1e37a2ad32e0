"""The ``cardinality`` study (paper Sec. VI-E, Table III): the discrete set as Ψ_k grows.

The paper's last sensitivity check runs the discrete set with larger hypothesis sets,
k ∈ {20, 40, 60, 80, 100} preference vectors (|Ψ_k| = 6k), in a single environment, for in-set
and out-of-set truths, and correlates each metric with the cardinality (Table III). The paper
gives neither the number of runs nor the episode count; we take 20 episodes, as in Sec. VI-A, and
at ``paper`` scale 27 runs × 3 expertise groups per k and truth kind (5 runs at ``small``): Table
III's weakest significant cell is ρ = 0.14, and a two-sided Pearson test at α = 0.05 has 80% power
for ρ = 0.14 from n = ((z₀.₉₇₅ + z₀.₈) / atanh 0.14)² + 3 = 398 pairs (Fisher's z), so each truth
kind needs 5 k × 27 runs × 3 groups = 405 people (10 runs, n = 150, gave ≈ 40%).

It is the ``conditions`` study's machinery with another config: the people, their seeds
``(e, r, k, g, t)`` and their rows are exactly those of ``conditions`` for the same
identity (the Full set only; no Fig. 3 extension, so low-expertise people show 20 episodes),
so a person with k = 20 in environment 0 is the same person in both sweeps. Table II's
factors (episodes, |Ψ_k|, number of states) come from ``conditions``' rows.
"""

from __future__ import annotations

import dataclasses

from .fixed_vs_joint import STUDY as CONDITIONS_STUDY
from .fixed_vs_joint import ConditionsConfig

_BASE = {"environments": 1, "ks": (20, 40, 60, 80, 100), "conditions": ("full",), "low_episodes": 20}

SCALES = {
    "smoke": ConditionsConfig(**{**_BASE, "ks": (4, 8), "low_episodes": 3}, runs=1, episodes=3,
                              map_min_size=5, map_max_size=7, max_steps=60),
    "small": ConditionsConfig(**_BASE, runs=5),
    "paper": ConditionsConfig(**_BASE, runs=27),  # 80% power at ρ = 0.14 (see the docstring)
}

STUDY = dataclasses.replace(
    CONDITIONS_STUDY,
    name="cardinality",
    version=5,  # 5: return_regret; 4: goal_reward_mode (the protocol) and random_theta_regret
    description="Sec. VI-E: the discrete set with k = 20..100 preference vectors, in- and out-of-set truths",
    scales=SCALES,
    report="expertise_irl.experiments.report.cardinality:build",
)
