"""Continuous inference vs the discrete set in the paper's Sec. VII setting.

    python benchmarks/continuous.py [--quick] [--instances 5] [--json out.json]

Each instance: a random zone map (Sec. V-A generator, 10-14 cells a side), a truth with
β* ~ U(0.01, 5) and θ* drawn from the paper-sim grid but outside the discrete set Θ_20
(Sec. VII-A), and 40 simulated episodes. Every method sees the same data:
  discrete      Θ_20 × paper-sim B (Eq. 13), posterior means;
  birl-box      Algorithm 1 as printed (1,000 iterations), posterior mean;
  birl-simplex  Algorithm 1 on the simplex (‖θ‖₁ = 1), posterior mean;
  map           L-BFGS-B on the simplex and β > 0 from 4 starts;
  nuts          NumPyro NUTS, 2 chains × (300 warm-up + 300 draws), posterior mean.
Reported per method: wall time (each method's first call in the process includes its
compilation, as a user would see), |β* − β̂|, cosine(θ*, θ̂), policy regret (Eq. 17 at β*),
averaged over instances.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info

from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, sample_thetas, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.birl import extended_birl
from expertise_irl.inference.gradient import map_estimate
from expertise_irl.inference.hypothesis_sets import out_of_set_truth
from expertise_irl.inference.nuts import nuts_posterior
from expertise_irl.metrics import cosine_similarity, expertise_distance, policy_regret
from expertise_irl.worlds.zones import generate_map

warnings.filterwarnings("ignore", category=FutureWarning)


def run_instance(seed: int, nuts_draws: int) -> list[dict]:
    map_seq, set_seq, truth_seq, sim_seq, *method_seqs = np.random.SeedSequence(seed).spawn(8)
    mdp = generate_map(np.random.default_rng(map_seq), min_size=10, max_size=14).to_mdp()
    grid = theta_grid(THETA_PRESETS["paper-sim"], mdp.n_features)
    theta_k = sample_thetas(grid, 20, np.random.default_rng(set_seq))
    theta_true, _ = out_of_set_truth(grid, theta_k, np.random.default_rng(truth_seq))
    beta_true = float(np.random.default_rng(truth_seq).uniform(0.01, 5.0))
    trajs = simulate(mdp, theta_true, beta_true, 40, np.random.default_rng(sim_seq))

    def discrete():
        b = DiscreteBelief.from_mdp(mdp, HypothesisSet(theta_k, BETA_PRESETS["paper-sim"])).update(trajs)
        return b.mean_theta, b.mean_beta

    def birl(variant, rs):
        r = extended_birl(mdp, trajs, n_iter=1000, variant=variant, rng=np.random.default_rng(rs))
        return r.mean_theta, r.mean_beta

    def map_():
        r = map_estimate(mdp, trajs, n_starts=4, rng=np.random.default_rng(method_seqs[2]))
        return r.theta, r.beta

    def nuts():
        r = nuts_posterior(mdp, trajs, num_warmup=nuts_draws, num_samples=nuts_draws, num_chains=2,
                           seed=int(method_seqs[3].generate_state(1)[0]))
        return r.mean_theta, r.mean_beta

    methods = {"discrete": discrete, "birl-box": lambda: birl("box", method_seqs[0]),
               "birl-simplex": lambda: birl("simplex", method_seqs[1]), "map": map_, "nuts": nuts}
    rows = []
    for name, fn in methods.items():
        t = time.perf_counter()
        theta_hat, beta_hat = fn()
        wall = time.perf_counter() - t
        rows.append({
            "instance": seed, "method": name, "states": mdp.n_states, "actions": len(trajs),
            "beta_true": beta_true, "beta_hat": float(beta_hat), "wall_s": wall,
            "expertise_distance": expertise_distance(beta_true, beta_hat),
            "cosine_similarity": cosine_similarity(theta_true, theta_hat),
            "policy_regret": policy_regret(mdp, theta_true, beta_true, np.asarray(theta_hat)),
        })
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 instances, shorter NUTS")
    ap.add_argument("--instances", type=int, default=5)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    info = machine_info()
    print("machine:", ", ".join(f"{k}={v}" for k, v in info.items()))
    n = 2 if args.quick else args.instances
    rows = []
    for seed in range(n):
        rows += run_instance(seed, 150 if args.quick else 300)
        print(f"instance {seed}: {rows[-1]['states']} states, {rows[-1]['actions']} actions, "
              f"β* = {rows[-1]['beta_true']:.3g}")
    print(f"\n{'method':13s} {'wall s':>7s} {'|β*−β̂|':>8s} {'cosine':>7s} {'regret':>8s}   (mean over {n})")
    for name in dict.fromkeys(r["method"] for r in rows):
        sel = [r for r in rows if r["method"] == name]
        m = {k: float(np.mean([r[k] for r in sel])) for k in
             ("wall_s", "expertise_distance", "cosine_similarity", "policy_regret")}
        print(f"{name:13s} {m['wall_s']:7.2f} {m['expertise_distance']:8.3f} {m['cosine_similarity']:7.3f} "
              f"{m['policy_regret']:8.4f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": info, "rows": rows}, indent=1))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
