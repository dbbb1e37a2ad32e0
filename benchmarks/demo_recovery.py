"""How often does `expertise-irl demo` recover the true expertise group, and how fast is it?

    python benchmarks/demo_recovery.py [--seeds 20] [--map NAME] [--json out.json]

Runs the demo job (random map, truth drawn from the paper's Ψ_k, 20 episodes,
discrete-set inference) for seeds 0..N-1 and reports, per seed, the true and
inferred β and expertise group, the posterior probability of the truth, the
paper's metrics and the wall time; then the recovery rate.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _machine import machine_info

from expertise_irl.experiments.demo import run_demo


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--map", default=None, help="bundled map name or file (default: random per seed)")
    ap.add_argument("--json", default=None, help="write the results here as JSON")
    args = ap.parse_args()
    info = machine_info()
    print("machine:", ", ".join(f"{k}={v}" for k, v in info.items()))
    run_demo(0, map_spec=args.map)  # compile once so per-seed times are steady-state
    rows = []
    head = f"{'seed':>4} {'S':>4} {'actions':>7} {'β*':>5} {'β̂':>7} {'group*':>7} {'group̂':>7} "
    print(head + f"{'P(truth)':>8} {'cos':>6} {'regret':>7} {'time s':>6}")
    for seed in range(args.seeds):
        t = time.perf_counter()
        run = run_demo(seed, map_spec=args.map)
        s = run.summary()
        s.update(seed=seed, n_states=run.mdp.n_states, actions=len(run.trajectories),
                 time_s=time.perf_counter() - t)
        rows.append(s)
        print(f"{seed:>4} {s['n_states']:>4} {s['actions']:>7} {s['beta_true']:>5g} {s['beta_hat']:>7.3g} "
              f"{s['group_true']:>7} {s['group_hat']:>7} {s['truth_probability']:>8.3f} "
              f"{s['cosine_similarity']:>6.3f} {s['policy_regret']:>7.3g} {s['time_s']:>6.2f}")
    hit = sum(r["group_true"] == r["group_hat"] for r in rows)
    times = np.array([r["time_s"] for r in rows])
    print(f"expertise group recovered: {hit}/{len(rows)}; "
          f"median time per demo {np.median(times):.2f} s (max {times.max():.2f} s)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"machine": info, "rows": rows, "recovered": hit, "n": len(rows)}, fh, indent=1)


if __name__ == "__main__":
    main()
