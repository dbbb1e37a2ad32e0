"""The batched soft value iteration on an accelerator: 95 hypotheses on large floor plans, in float64.

    python benchmarks/gpu_solve.py [--sizes 200,400] [--methods sweeps,levels] [--lanes default,32]
        [--budget 420] [--out FILE.jsonl]

For each SIZE the floor plan of :mod:`benchmarks.large_worlds` (``generate_floor_plan(SIZE, seed=0)``,
γ = 0.99) is compiled, and the paper's real-data set (paper-real Θ over its three features × paper-real
B: 95 hypotheses) is solved by :func:`expertise_irl.planning.soft_vi.solve` in float64 with each solver
method (``--methods``) and lane width (``--lanes``: ``default`` is the library's choice, a number sets
``lanes=`` and a chunk of 95 rounded up to whole lane groups). Each configuration is solved twice in
one process: the first time includes compiling, the second is the solve alone. Printed and written
(one JSON line per configuration): the JAX backend and device, the plan's states, the seconds of
both solves, the sweeps and the largest difference in log-policy from the first configuration
solved on that plan. Configurations that would start after ``--budget`` seconds are skipped, so a
run on a lent machine ends inside its time. Runs on whatever JAX finds (CPU here, a GPU where one
is present).
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


def configurations(methods: str, lanes: str):
    for m in methods.split(","):
        for w in lanes.split(","):
            yield m, (None if w == "default" else int(w))


def solve_twice(mdp, theta, beta, method: str, lanes: int | None) -> dict:
    from expertise_irl.planning.soft_vi import solve

    kw = {"method": method}
    if lanes is not None:
        kw.update(lanes=lanes, chunk_size=lanes * -(-len(beta) // lanes))
    out = {}
    for label in ("first_s", "second_s"):
        t0 = time.perf_counter()
        sol = solve(mdp, theta, beta, **kw)
        lp = np.asarray(sol.log_policy)
        out[label] = time.perf_counter() - t0
    out["sweeps"] = int(np.asarray(sol.iterations).sum())
    out["log_policy"] = lp
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="200,400")
    ap.add_argument("--methods", default="sweeps,levels")
    ap.add_argument("--lanes", default="default")
    ap.add_argument("--budget", type=float, default=420.0)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args()
    import jax

    from expertise_irl.hypotheses import HypothesisSet, resolve_betas, resolve_thetas
    from expertise_irl.worlds.floorplans import generate_floor_plan

    t_start = time.perf_counter()
    head = {"command": "python benchmarks/gpu_solve.py " + " ".join(sys.argv[1:]), "machine": machine_info(),
            "backend": jax.default_backend(), "devices": [str(d) for d in jax.devices()],
            "x64": bool(jax.config.jax_enable_x64)}
    lines = [json.dumps(head)]
    print(lines[-1], flush=True)
    for size in (int(s) for s in a.sizes.split(",")):
        mdp = generate_floor_plan(size, seed=0).to_mdp()
        hyp = HypothesisSet(resolve_thetas("paper-real", mdp.n_features), resolve_betas("paper-real"))
        first = None
        for method, lanes in configurations(a.methods, a.lanes):
            if time.perf_counter() - t_start > a.budget:
                skipped = {"size": size, "method": method, "lanes": lanes, "skipped": "budget"}
                lines.append(json.dumps(skipped))
                print(lines[-1], flush=True)
                continue
            r = solve_twice(mdp, hyp.theta, hyp.beta, method, lanes)
            lp = r.pop("log_policy")
            fin = np.isfinite(lp)
            diff = None if first is None else float(np.max(np.abs(lp[fin] - first[fin])))
            first = lp if first is None else first
            lines.append(json.dumps({"size": size, "states": mdp.n_states, "hypotheses": len(hyp),
                                     "method": method, "lanes": lanes or "default", **r,
                                     "max_log_policy_difference": diff}))
            print(lines[-1], flush=True)
            if a.out:
                a.out.write_text("\n".join(lines) + "\n")
    if a.out:
        a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
