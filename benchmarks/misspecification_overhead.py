"""What ``--check fast`` adds to a discrete ``infer`` on ``crossroads`` with 20 episodes.

    python benchmarks/misspecification_overhead.py [--repeats 5] [--json out.json]

One person (θ* = 0.5, 0.2, 0.2, 0.05, 0.05, β* = 0.09, seed 3) is simulated once; then
``expertise-irl infer crossroads`` (the discrete set, its defaults) runs ``--repeats`` times with
``--check off`` and with ``--check fast``, alternating, each in a fresh process with JAX's
persistent cache warm (a first unmeasured run of each fills it). Reported: the median wall time of
each and their ratio; the issue's bound is fast/off < 1.2.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info, report, timed_cli


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    info = machine_info()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        cache = d / "jax-cache"
        demos = d / "d.csv"
        timed_cli(["simulate", "crossroads", "--theta", "0.5,0.2,0.2,0.05,0.05", "--beta", "0.09",
                   "--episodes", 20, "--seed", 3, "--out", demos], cache)
        times = {"off": [], "fast": []}
        for i in range(args.repeats + 1):
            for check in times:
                t = timed_cli(["infer", "crossroads", "--demos", demos, "--out", d / f"{check}{i}.json",
                               "--check", check], cache)
                if i > 0:
                    times[check].append(t)
    off, fast = float(np.median(times["off"])), float(np.median(times["fast"]))
    report({**info, "repeats": args.repeats, "wall_s_off": times["off"], "wall_s_fast": times["fast"],
            "median_off_s": round(off, 3), "median_fast_s": round(fast, 3),
            "ratio_fast_over_off": round(fast / off, 3)}, args.json)


if __name__ == "__main__":
    main()
