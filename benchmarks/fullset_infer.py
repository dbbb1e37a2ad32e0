"""Wall time and peak memory of the whole full-set ``infer`` command, as a user runs it.

    python benchmarks/fullset_infer.py [--map zones30] [--episodes 20] [--json FILE]

A person (θ* from the paper-sim set, β* = 0.5, seed 0) is simulated on MAP with
``expertise-irl simulate``; then ``expertise-irl infer MAP --demos demos.csv --thetas paper-sim
--betas paper-sim`` (3,031 θ × 6 β = 18,186 hypotheses) runs in a fresh process, twice: ``cold``
with an empty JAX compilation cache, ``warm`` with the cache the cold run filled. The wall time
covers everything: start-up and imports, reading the map and the demonstrations, compiling and
solving, the belief update over every action, and writing the result JSON. Peak memory is
the child process's maximum resident set. Both runs must write the same estimates (β̂, θ̂, log evidence).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from _machine import machine_info, measured_cli, report, timed_cli

THETA = "0.3,0.5,0,0.7,1"
BETA = 0.5


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--map", default="zones30")
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    info = machine_info()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cache = tmp / "jax-cache"
        demos = tmp / "demos.csv"
        timed_cli(["simulate", args.map, "--theta", THETA, "--beta", BETA, "--episodes", args.episodes,
                   "--seed", 0, "--out", demos], cache)
        actions = sum(1 for _ in demos.open()) - 1
        runs = {}
        for label in ("cold", "warm"):
            out = tmp / f"{label}.json"
            wall, peak = measured_cli(["infer", args.map, "--demos", demos, "--thetas", "paper-sim",
                                       "--betas", "paper-sim", "--out", out], cache)
            runs[label] = {"wall_s": round(wall, 1), "peak_rss_mb": peak}
            result = json.loads(out.read_text())
            runs[label]["answer"] = {k: result[k] for k in ("beta_hat", "theta_hat", "log_evidence")}
        answers = [runs[k].pop("answer") for k in ("cold", "warm")]
        same = answers[0] == answers[1]
    command = (f"expertise-irl infer {args.map} --demos demos.csv --thetas paper-sim --betas paper-sim "
               "--out r.json")
    result = {**info, "infer_command": command, "episodes": args.episodes, "actions": actions,
              "theta_star": THETA, "beta_star": BETA,
              **{f"{k}_{m}": v for k, r in runs.items() for m, v in r.items()},
              "estimate": answers[0], "identical_estimates": same}
    report(result, args.json)
    if not same:
        raise SystemExit("the two runs wrote different estimates")


if __name__ == "__main__":
    main()
