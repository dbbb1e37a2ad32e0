"""Time per action of the online estimator at the paper's real-data size.

    python benchmarks/online.py [--actions 5000] [--json out.json]

Workload a of benchmarks/soft_vi.py: the paper-real set (19 θ over length, road, avoid ×
5 β = 95 hypotheses) on a warehouse-sized zone map of about 4,600 states. A person with a
hypothesis of the set acts out episodes; every action goes through
``OnlineEstimator.observe`` (a gather of the 95 log-probabilities of that (s, a), stored
contiguously, and a log-sum-exp over them, plus the summary: β marginal, groups, θ̂,
entropy, MAP). For comparison the same stream through ``DiscreteBelief.update_action``
(immutable, validates and gathers from the [H, S, A] table) and the batch posterior over
all pairs at once. The estimator's last estimate is checked against the batch posterior.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_flags, machine_info
from soft_vi import build_workload

from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.online import OnlineEstimator


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--actions", type=int, default=5000, help="actions to stream (at least)")
    ap.add_argument("--json", type=Path, help="write the numbers here")
    args = ap.parse_args()
    info = machine_info()
    info["cpu_flags"] = cpu_flags()
    for k, v in info.items():
        print(f"{k}: {v}")

    mdp, _, _, desc = build_workload("a")
    hyp = HypothesisSet(theta_grid(THETA_PRESETS["paper-real"], 3), BETA_PRESETS["paper-real"])
    print(f"workload: {desc}")
    t = time.perf_counter()
    est = OnlineEstimator.from_mdp(mdp, hyp)
    build_s = time.perf_counter() - t
    print(f"build (solve {len(hyp)} hypotheses, first call includes JAX compilation): {build_s:.1f} s")

    h = hyp.index(hyp.thetas[7], 1.0)
    rng = np.random.default_rng(0)
    lp = est.belief().log_policy[h]
    trajs = simulate(mdp, None, None, 1, rng, log_policy=lp, max_steps=400)
    while len(trajs) < args.actions:  # more episodes until there are enough actions
        more = simulate(mdp, None, None, 20, rng, log_policy=lp, max_steps=400)
        trajs = Trajectories(np.concatenate([trajs.episode, more.episode + trajs.episode.max() + 1]),
                             np.concatenate([trajs.step, more.step]),
                             np.concatenate([trajs.state, more.state]),
                             np.concatenate([trajs.action, more.action]))
    pairs = list(zip(trajs.episode.tolist(), trajs.state.tolist(), trajs.action.tolist(), strict=True))
    print(f"stream: {len(pairs)} actions in {trajs.n_episodes} episodes")

    times = np.empty(len(pairs))
    prev = None
    for i, (e, s, a) in enumerate(pairs):
        if prev is not None and e != prev:
            est.end_episode()
        t = time.perf_counter()
        est.observe(s, a)
        times[i] = time.perf_counter() - t
        prev = e
    us = times * 1e6

    belief = DiscreteBelief.from_log_policy(hyp, est.belief().log_policy)
    n_ref = min(len(pairs), 1000)
    b = belief
    t = time.perf_counter()
    for _, s, a in pairs[:n_ref]:
        b = b.update_action(s, a)
        _ = b.mean_beta, b.entropy
    ref_us = (time.perf_counter() - t) / n_ref * 1e6
    t = time.perf_counter()
    batch = belief.update_pairs(trajs.state, trajs.action)
    batch_ms = (time.perf_counter() - t) * 1e3
    err = abs(est.estimate.beta_hat - batch.mean_beta)
    out = {
        "machine": info, "workload": desc, "n_hypotheses": len(hyp), "n_states": mdp.n_states,
        "actions": len(pairs), "build_s": build_s,
        "observe_us": {"median": float(np.median(us)), "p95": float(np.percentile(us, 95)),
                       "p99": float(np.percentile(us, 99)), "mean": float(us.mean()),
                       "max": float(us.max())},
        "belief_update_action_us": ref_us, "batch_all_pairs_ms": batch_ms,
        "beta_hat_abs_error_vs_batch": err,
    }
    print(f"OnlineEstimator.observe: median {out['observe_us']['median']:.1f} µs, "
          f"p95 {out['observe_us']['p95']:.1f} µs, p99 {out['observe_us']['p99']:.1f} µs, "
          f"mean {out['observe_us']['mean']:.1f} µs, max {out['observe_us']['max']:.0f} µs per action")
    print(f"DiscreteBelief.update_action (+ β̂, entropy): {ref_us:.1f} µs per action (first {n_ref} actions)")
    print(f"batch posterior over all {len(pairs)} pairs: {batch_ms:.1f} ms")
    print(f"|β̂ online − β̂ batch| = {err:.2e}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
