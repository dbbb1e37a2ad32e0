"""The ``expertise-irl demo`` job: simulate one person, infer who they are, report.

Following the paper's protocol (Sec. VI-A): sample Θ_k (k preference vectors)
from the ``paper-sim`` grid, take Ψ_k = Θ_k × B with the paper's six
temperatures, draw the truth (θ*, β*) from Ψ_k, simulate episodes from random
start states, and run discrete-set inference on them.

By default β* is drawn from the high expertise group (``DEMO_BETAS``: 0.01 or 0.09),
people who reach the goal, so that the first figure shows the method at work; the
inference still weighs all six temperatures. A less expert person (β* from 0.5 to 10:
under the paper's max-ent model, one who may wander until the step cap) is the
``beta`` argument (``expertise-irl demo --beta 10``).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..demos.simulation import DEFAULT_MAX_STEPS, best_move, cap_note, episode_outcomes, simulate
from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..hypotheses import (
    BETA_PRESETS,
    GROUP_NAMES,
    THETA_PRESETS,
    HypothesisSet,
    expertise_group,
    sample_thetas,
    theta_grid,
)
from ..inference.belief import DiscreteBelief
from ..inference.identifiability import absent_features
from ..mdp import TabularMDP
from ..metrics import cosine_similarity, expertise_distance, policy_regret, return_regret
from ..models import DEFAULT_MODEL
from ..worlds.grid import DEFAULT_GOAL_REWARD_MODE
from ..worlds.zones import ZoneMap, generate_map, resolve_map

DEFAULT_EPISODES = 20
DEFAULT_K = 20
#: Side range of the random map the demo generates when no map is given.
DEMO_MAP_SIZE = (10, 20)
#: The temperatures the default person's β* is drawn from: the paper's, in the high expertise group.
DEMO_BETAS = tuple(b for b in BETA_PRESETS["paper-sim"] if expertise_group(b) == GROUP_NAMES[0])


@dataclass(frozen=True)
class DemoRun:
    """Everything the demo computed."""

    zone_map: ZoneMap
    mdp: TabularMDP
    hypotheses: HypothesisSet
    theta_true: np.ndarray
    beta_true: float
    trajectories: Trajectories
    belief: DiscreteBelief
    metrics: dict[str, float]
    #: The observation model the person acts by and the inference assumes.
    model: str = DEFAULT_MODEL
    #: Episode length cap of the simulation (actions); an episode that reaches it is cut.
    max_steps: int = DEFAULT_MAX_STEPS

    @property
    def truth_index(self) -> int:
        idx = self.hypotheses.index(self.theta_true, self.beta_true)
        assert idx is not None
        return idx

    def outcomes(self) -> list[str]:
        """How each episode ended: ``"goal"``, ``"cap"`` or ``"cut"``
        (:func:`~expertise_irl.demos.simulation.episode_outcomes`)."""
        return episode_outcomes(self.trajectories, self.mdp, self.max_steps)

    def cap_note(self) -> str | None:
        """Why episodes hit the step cap under the person's model and (θ*, β*), None when none did
        (:func:`~expertise_irl.demos.simulation.cap_note`)."""
        return cap_note(self.outcomes(), self.max_steps, self.beta_true, best_move(self.mdp, self.theta_true),
                        model=self.model)

    def absent_features(self) -> list[bool]:
        """Per feature, whether it never occurs on the map
        (:func:`~expertise_irl.inference.identifiability.absent_features`)."""
        return absent_features(self.mdp)

    def summary(self) -> dict[str, Any]:
        b = self.belief
        return {
            "theta_true": self.theta_true.tolist(),
            "beta_true": self.beta_true,
            "group_true": expertise_group(self.beta_true),
            "theta_hat": b.mean_theta.tolist(),
            "beta_hat": b.mean_beta,
            "group_hat": expertise_group(b.mean_beta),
            "truth_probability": float(b.probabilities[self.truth_index]),
            **self.metrics,
        }


def run_demo(
    seed: int,
    *,
    map_spec: str | None = None,
    zone_map: ZoneMap | None = None,
    episodes: int = DEFAULT_EPISODES,
    k: int = DEFAULT_K,
    progress: Callable[[int, int], None] | None = None,
    model: str = DEFAULT_MODEL,
    beta: float | None = None,
    goal_reward_mode: str | None = None,
) -> DemoRun:
    """Run the demo job deterministically from ``seed`` (no files written).

    The map is ``zone_map`` if given, else ``map_spec`` (a file or bundled name), else a
    random map generated from the seed. ``model`` is the observation model of the simulated
    person and of the inference (:mod:`expertise_irl.models`). ``beta`` is the person's β*,
    one of the paper's six temperatures; by default it is drawn from ``DEMO_BETAS``.
    ``goal_reward_mode`` sets how a generated map's goal pays (a given map keeps its own).
    """
    choices = DEMO_BETAS if beta is None else (paper_beta(beta),)
    map_seq, set_seq, truth_seq, sim_seq = np.random.SeedSequence(seed).spawn(4)
    if zone_map is None and map_spec is not None:
        zone_map = resolve_map(map_spec)
    if zone_map is None:
        lo, hi = DEMO_MAP_SIZE
        zone_map = generate_map(np.random.default_rng(map_seq), min_size=lo, max_size=hi,
                                name=f"generated (seed {seed})",
                                goal_reward_mode=goal_reward_mode or DEFAULT_GOAL_REWARD_MODE)
    mdp = zone_map.to_mdp()
    all_thetas = theta_grid(THETA_PRESETS["paper-sim"], mdp.n_features)
    thetas = sample_thetas(all_thetas, k, np.random.default_rng(set_seq))
    hyp = HypothesisSet(thetas, BETA_PRESETS["paper-sim"])
    rng_truth = np.random.default_rng(truth_seq)
    theta_true = hyp.thetas[int(rng_truth.integers(hyp.n_theta))]
    beta_true = float(choices[int(rng_truth.integers(len(choices)))])
    prior = DiscreteBelief.from_mdp(mdp, hyp, progress=progress, model=model)
    truth = hyp.index(theta_true, beta_true)
    assert truth is not None
    trajs = simulate(mdp, theta_true, beta_true, episodes, np.random.default_rng(sim_seq),
                     log_policy=prior.log_policy[truth], max_steps=DEFAULT_MAX_STEPS)
    post = prior.update(trajs)
    metrics = {
        "expertise_distance": expertise_distance(beta_true, post.mean_beta),
        "cosine_similarity": cosine_similarity(theta_true, post.mean_theta),
        "policy_regret": policy_regret(mdp, theta_true, beta_true, post.mean_theta, model=model),
        "return_regret": return_regret(mdp, theta_true, post.mean_theta),
    }
    return DemoRun(zone_map, mdp, hyp, theta_true, beta_true, trajs, post, metrics, model=model,
                   max_steps=DEFAULT_MAX_STEPS)


def paper_beta(beta: float) -> float:
    """``beta`` as one of the paper's temperatures (the demo's hypothesis set holds only those)."""
    for b in BETA_PRESETS["paper-sim"]:
        if np.isclose(beta, b, rtol=1e-9, atol=0.0):
            return float(b)
    raise InputError(f"--beta {beta:g}: the demo's person has one of the paper's temperatures "
                     f"({', '.join(f'{b:g}' for b in BETA_PRESETS['paper-sim'])})")


def demo_outputs(out_dir: Path, seed: int, map_spec: str | None = None,
                 beta: float | None = None, goal_reward_mode: str = "scaled") -> tuple[Path, Path]:
    """Paths of the demo's figure and result JSON inside ``out_dir``: one pair per seed, map and β*.

    The random map of a seed gives ``demo-seed{seed}.png``; ``--map`` (a bundled name or a file)
    adds the map's name, ``demo-{name}-seed{seed}.png``, so demos on several maps share a folder;
    ``--beta`` adds ``-beta{β*}`` (``demo-seed0-beta10.png``) and a fixed goal reward ``-fixed``.
    """
    tag = ""
    if map_spec is not None:
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(map_spec).stem).strip("._") or "map"
        tag = f"{stem}-"
    end = "" if beta is None else f"-beta{paper_beta(beta):g}"
    end += "-fixed" if goal_reward_mode == "fixed" else ""
    return out_dir / f"demo-{tag}seed{seed}{end}.png", out_dir / f"result-{tag}seed{seed}{end}.json"
