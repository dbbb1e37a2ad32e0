"""Float32 first phase vs a cold float64 solve, at the same float64 guarantee.

    python benchmarks/float32_start.py [--map zones30] [--n N] [--json out.json]

The full paper-sim set (3,031 θ × 6 β = 18,186 hypotheses) on a map, solved by
``planning.solve`` with ``float32_start=False`` (every sweep in float64 from zero) and with the
default ``float32_start=True`` (float32 sweeps down to float32 resolution, then float64 sweeps
from there to the same tolerance, 1e-8 on V/β). Each is run twice, alternating; the second
run of each is reported as warm (compilation served), the first as cold. Also reported: the
mean sweeps per hypothesis and the largest difference between the two solutions' V/β and
log π (both must be within the tolerance of the fixed point, so it is at most 2e-8).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info

from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.maps import resolve_world


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--map", default="zones30")
    ap.add_argument("--n", type=int, default=None, help="first N hypotheses only (default: all)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    info = machine_info()
    print("machine:", ", ".join(f"{k}={v}" for k, v in info.items()))
    mdp = resolve_world(args.map).to_mdp()
    hyp = HypothesisSet(theta_grid(THETA_PRESETS["paper-sim"], mdp.n_features), BETA_PRESETS["paper-sim"])
    n = args.n or len(hyp)
    theta, beta = hyp.theta[:n], hyp.beta[:n]
    print(f"{args.map}: {mdp.n_states} states, {n} hypotheses")
    times: dict[bool, list[float]] = {False: [], True: []}
    sols = {}
    for _ in range(2):
        for f32 in (False, True):
            t = time.perf_counter()
            sols[f32] = solve(mdp, theta, beta, float32_start=f32)
            times[f32].append(time.perf_counter() - t)
    a, b = sols[False], sols[True]
    dv = float(np.max(np.abs(a.value - b.value) / beta[:, None]))
    fin = np.isfinite(a.log_policy)
    dlp = float(np.max(np.abs(np.where(fin, a.log_policy, 0) - np.where(fin, b.log_policy, 0))))
    rows = {}
    for f32, label in ((False, "float64 from zero"), (True, "float32 start")):
        s = sols[f32]
        rows[label] = {"cold_s": times[f32][0], "warm_s": times[f32][1], "sweeps": float(s.iterations.mean())}
        print(f"{label:18s} cold {times[f32][0]:6.1f} s  warm {times[f32][1]:6.1f} s  "
              f"sweeps per hypothesis {s.iterations.mean():.0f}")
    warm, cold = times[False][1] / times[True][1], times[False][0] / times[True][0]
    print(f"warm speed-up {warm:.2f}x, cold {cold:.2f}x; max |ΔV/β| {dv:.1e}, max |Δ log π| {dlp:.1e}")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": info, "map": args.map, "states": mdp.n_states,
                                               "hypotheses": n, "rows": rows, "max_dv": dv, "max_dlp": dlp},
                                              indent=1))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
