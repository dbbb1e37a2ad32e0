"""A coarse set or a missing feature? The fast check's verdict on crossroads, fixed set against refined.

    python benchmarks/coarse_or_missing.py [--people 8] [--episodes 20] [--check fast|full] [--out FILE]

Two groups of ``--people`` careful people (β* = 0.05) on the bundled map ``crossroads``, person ``i``
of group ``g`` drawn from ``default_rng([44, g, i])``, ``--episodes`` episodes each:

- **complete**: θ* ~ Dirichlet(1, …, 1) over all five features, inferred with all five: the features
  explain them, so every "do not explain" verdict is a false alarm;
- **hidden**: θ* with θ_avoid ~ U(0.4, 0.6) and the rest Dirichlet(1, …, 1) over the other four,
  inferred *without* the avoid feature: their detours around avoid zones are structure the features
  do not describe, so a "do not explain" verdict is a hit.

Each person is inferred by ``get_method("discrete")`` with the set ``infer`` refines by default
(``adaptive``) and with the set it used before (``fixed``: paper-real Θ × paper-sim B), then checked
by ``--check fast`` or ``full`` (:func:`expertise_irl.inference.misspecification.misspecification`).
Reported: the verdict counts of each group under each set.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import header

from expertise_irl.demos.simulation import simulate
from expertise_irl.inference.methods import get_method
from expertise_irl.inference.misspecification import VERDICTS, misspecification, posterior_of_run
from expertise_irl.mdp import TabularMDP
from expertise_irl.worlds.zones import resolve_map

SETS = {"adaptive": {}, "fixed": {"thetas": "paper-real", "betas": "paper-sim"}}
AVOID = 2


def without_avoid(mdp: TabularMDP) -> TabularMDP:
    keep = [k for k in range(mdp.n_features) if k != AVOID]
    return TabularMDP(mdp.next_state, mdp.features[..., keep], mdp.terminal, gamma=mdp.gamma,
                      feature_names=tuple(mdp.feature_names[k] for k in keep), start_states=mdp.start_states,
                      state_xy=mdp.state_xy, source="crossroads (no avoid)")


def theta_of(rng: np.random.Generator, hidden: bool) -> np.ndarray:
    if not hidden:
        return rng.dirichlet(np.ones(5))
    avoid = rng.uniform(0.4, 0.6)
    rest = rng.dirichlet(np.ones(4)) * (1 - avoid)
    return np.insert(rest, AVOID, avoid)


def verdict(mdp, trajs, values: dict, seed: int, check: str) -> str:
    m = get_method("discrete")
    run = m.run(mdp, trajs, m.options_from(values), 0)
    post = run.result.posterior
    mis = misspecification([(mdp, trajs)], check=check, theta_hat=post.mean_theta, beta_hat=post.mean_beta,
                           model="maxent", seed=seed, **posterior_of_run(run, mdp))
    return mis["verdict"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=8)
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--check", choices=("fast", "full"), default="fast")
    ap.add_argument("--out", type=Path)
    a = ap.parse_args()
    lines = header("coarse_or_missing.py")
    full = resolve_map("crossroads").to_mdp()
    for g, group in enumerate(("complete", "hidden")):
        mdp = full if group == "complete" else without_avoid(full)
        counts = {s: dict.fromkeys(VERDICTS, 0) for s in SETS}
        for i in range(a.people):
            rng = np.random.default_rng([44, g, i])
            trajs = simulate(full, theta_of(rng, group == "hidden"), 0.05, a.episodes, rng)
            for s, values in SETS.items():
                counts[s][verdict(mdp, trajs, values, i, a.check)] += 1
        for s, c in counts.items():
            lines.append(f"{group:8s} people, {s:8s} set: " + "; ".join(f"{v}: {n}" for v, n in c.items()))
            print(lines[-1], flush=True)
    if a.out:
        a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
