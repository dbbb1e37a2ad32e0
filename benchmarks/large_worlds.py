"""Wall time and peak memory of ``infer`` and ``simulate`` on large floor plans, library against sweeps.

    python benchmarks/large_worlds.py [--sizes 50,100,200] [--big 400] [--methods sweeps,jumps]
                                      [--fullset] [--json FILE]

For each SIZE a ``SIZE × SIZE`` floor plan is drawn
(:func:`expertise_irl.worlds.floorplans.generate_floor_plan`, seed 0: roads every 10 rows and 15
columns, restricted blocks, scattered obstacles, γ = 0.99),
a person (θ* = (0.4, 0.2, 0.4), β* = 0.3) is simulated for 3 episodes, and
``expertise-irl infer PLAN --demos demos.csv --thetas paper-real --betas paper-real`` (95
hypotheses) runs in a fresh process with an empty JAX compilation cache once per solver
method (``EXPERTISE_IRL_SOLVER``: ``sweeps``, the solver of earlier releases and the library's
default below ``soft_vi.LEVELS_MIN_STATES`` states, ``jumps``, greedy path jumps before the
sweeps, and ``levels``, sweeps in order of the distance to the goal before them, the default
from that size up). Wall time covers the whole command (start-up,
compilation, solve, belief update, writing the result); peak memory is the child's maximum
resident set. Both methods must give the same estimates. ``simulate`` of one episode on each
plan (one hypothesis' solve) is timed the same way. ``--big`` sizes run the first method only,
after the ``--fullset``. The cost's growth exponent is the least-squares slope of log(infer time) against
log(heading-states) over ``--sizes``. ``--fullset`` also times the 30 × 30 full set (zones30,
18,186 hypotheses, 20 episodes) with each method in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import numpy as np
from _machine import machine_info, measured_cli, report

THETA, BETA, EPISODES = "0.4,0.2,0.4", 0.3, 3


def run(args: list, cache: Path, method: str | None) -> tuple[float, int]:
    """(wall seconds, peak resident MB) of ``expertise-irl ARGS`` with solver ``method`` (None: the
    default)."""
    return measured_cli(args, cache, {"EXPERTISE_IRL_SOLVER": method} if method is not None else None)


def plan_files(size: int, where: Path) -> tuple[Path, int]:
    from expertise_irl.worlds.floorplans import floor_plan_text, generate_floor_plan

    plan = generate_floor_plan(size, seed=0)
    txt = where / f"plan{size}.txt"
    txt.write_text(floor_plan_text(plan))
    txt.with_suffix(".toml").write_text(plan.settings_text())
    return txt, plan.n_states


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="50,100,200")
    ap.add_argument("--big", default="", help="sizes run with the library's method only (e.g. 400)")
    ap.add_argument("--methods", default="sweeps,jumps")
    ap.add_argument("--fullset", action="store_true")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",") if s]
    big = [int(s) for s in args.big.split(",") if s]
    methods = args.methods.split(",")
    info = machine_info()
    info["load_before"] = [round(x, 2) for x in os.getloadavg()]
    print(f"machine: {info['cpu']} ({info['cores']} cores, {info['memory_gib']} GiB), "
          f"flags {info['cpu_flags']}, load {info['load_before']}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        def fullset_runs():
            demos = tmp / "zones30.csv"
            run(["simulate", "zones30", "--theta", "0.3,0.5,0,0.7,1", "--beta", 0.5, "--episodes", 20,
                 "--seed", 0, "--out", demos], tmp / "sim-cache-30", None)
            for method in methods:
                out = tmp / f"fullset-{method}.json"
                wall, peak = run(["infer", "zones30", "--demos", demos, "--thetas", "paper-sim", "--betas",
                                  "paper-sim", "--out", out], tmp / f"cache-30-{method}", method)
                fullset.append({"method": method, "infer_s": round(wall, 1), "peak_rss_mb": peak,
                                "load": round(os.getloadavg()[0], 2)})
                print(f"30x30 full set (18,186 hypotheses) | {method} | infer {wall:.1f} s | {peak} MB",
                      flush=True)

        fullset: list = []
        for size in sizes + big:
            if size == (big or [None])[0] and args.fullset:
                fullset_runs()
            txt, S = plan_files(size, tmp)
            demos = tmp / f"demos{size}.csv"
            run(["simulate", txt, "--theta", THETA, "--beta", BETA, "--episodes", EPISODES, "--seed", 0,
                 "--out", demos], tmp / f"sim-cache-{size}", None)
            answers = {}
            for method in (methods if size in sizes else methods[:1]):
                cache = tmp / f"cache-{size}-{method}"
                out = tmp / f"r{size}-{method}.json"
                wall, peak = run(["infer", txt, "--demos", demos, "--thetas", "paper-real", "--betas",
                                  "paper-real", "--out", out], cache, method)
                sim_wall, _ = run(["simulate", txt, "--theta", THETA, "--beta", BETA, "--episodes", 1,
                                   "--seed", 1, "--out", tmp / f"one{size}-{method}.csv"], cache, method)
                res = json.loads(out.read_text())
                answers[method] = res
                row = {"size": size, "heading_states": S, "method": method, "infer_s": round(wall, 1),
                       "peak_rss_mb": peak, "simulate_s": round(sim_wall, 1),
                       "load": round(os.getloadavg()[0], 2)}
                rows.append(row)
                print(f"{size}x{size} | {S:,} | {method} | infer {wall:.1f} s | {peak} MB | "
                      f"simulate {sim_wall:.1f} s | load {row['load']}", flush=True)
            if len(answers) > 1:
                ref = answers[methods[0]]
                for m, res in answers.items():
                    same_beta = abs(res["beta_hat"] - ref["beta_hat"]) <= 1e-6 * abs(ref["beta_hat"])
                    if not (same_beta and np.allclose(res["theta_hat"], ref["theta_hat"], rtol=0, atol=1e-6)):
                        raise SystemExit(f"{size}x{size}: {m} estimates differ from {methods[0]}'s")
        if args.fullset and not big:
            fullset_runs()
    exponents = {}
    for method in methods:
        pts = [(r["heading_states"], r["infer_s"]) for r in rows
               if r["method"] == method and r["size"] in sizes]
        if len(pts) >= 2:
            x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
            exponents[method] = round(float(np.polyfit(x, y, 1)[0]), 2)
    result = {**info, "load_after": [round(x, 2) for x in os.getloadavg()], "theta_star": THETA,
              "beta_star": BETA, "episodes": EPISODES, "rows": rows, "fullset": fullset,
              "growth_exponent": exponents}
    print("| plan | heading-states | method | infer | peak RSS | simulate (1 episode) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['size']} × {r['size']} | {r['heading_states']:,} | {r['method']} | {r['infer_s']} s | "
              f"{r['peak_rss_mb'] / 1024:.2f} GB | {r['simulate_s']} s |")
    report(result, args.json)


if __name__ == "__main__":
    main()
