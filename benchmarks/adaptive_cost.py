"""What the adaptive set costs: ``infer``'s default against the fixed sets, on the same demonstrations.

    python benchmarks/adaptive_cost.py [--seeds 0,1,2,3,4] [--repeats 3] [--out FILE]

The demonstrations: the demo's people (``run_demo(seed)``: a random map, θ* from the paper's set, an
expert's β*, 20 episodes) for each of ``--seeds``, and the README's example (crossroads, θ* = (0.5,
0.5, 0, 0, 0), β* = 0.5, 20 episodes, ``simulate --seed 1``). On each, ``get_method("discrete")`` runs
with three sets: ``demo`` (the demo's own Θ_k × paper-sim B, 120 hypotheses; demo people only),
``fixed`` (paper-real Θ × paper-sim B, 1,266 hypotheses: ``infer``'s set before refinement) and
``adaptive`` (``infer``'s default). Each set first runs once to compile its shapes (JAX's persistent
cache keeps them, as it does for the command line), then ``--repeats`` times; the median seconds of
the repeats are reported, with the hypotheses solved and the ratio adaptive / fixed, all in one run.

A user waits for the command, not the solver: the last row times ``expertise-irl infer crossroads
--demos demos.csv`` on the README's example, end to end in a fresh process (reading, JAX's start,
the compiled shapes loaded from its persistent cache, the solve, the checks, writing the result),
with ``--thetas paper-real --betas paper-sim`` (fixed) and with the default (adaptive), the median of
``--repeats`` runs after one that fills the cache.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import header

from expertise_irl.demos.simulation import simulate
from expertise_irl.experiments.demo import run_demo
from expertise_irl.inference.methods import get_method
from expertise_irl.worlds.zones import resolve_map


def timed(mdp, trajs, values: dict, repeats: int) -> tuple[float, int]:
    m = get_method("discrete")
    opts = m.options_from(values)
    run = m.run(mdp, trajs, opts, 0)  # compiles what is not compiled yet
    seconds = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        m.run(mdp, trajs, opts, 0)
        seconds.append(time.perf_counter() - t0)
    refined = run.result.refined
    solved = refined.record["solved"] if refined is not None else len(run.result.posterior.hypotheses)
    return statistics.median(seconds), solved


def cases(seeds: list[int]):
    for s in seeds:
        d = run_demo(s)
        spec = ",".join(f"{b:g}" for b in d.hypotheses.betas)
        yield f"demo seed {s}", d.mdp, d.trajectories, d.hypotheses.thetas, spec
    mdp = resolve_map("crossroads").to_mdp()
    trajs = simulate(mdp, np.array([0.5, 0.5, 0, 0, 0]), 0.5, 20, np.random.default_rng(1))
    yield "README example", mdp, trajs, None, None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2,3,4")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args()
    lines = header("adaptive_cost.py")
    ratios = []
    for name, mdp, trajs, thetas, betas in cases([int(x) for x in a.seeds.split(",")]):
        row = f"{name:15s} {len(trajs):5d} actions"
        if thetas is not None:  # the demo's set, as the demo names it
            t, n = timed_set(mdp, trajs, thetas, betas, a.repeats)
            row += f" | demo {t:.2f} s ({n})"
        tf, nf = timed(mdp, trajs, {"thetas": "paper-real", "betas": "paper-sim"}, a.repeats)
        ta, na = timed(mdp, trajs, {}, a.repeats)
        ratios.append(ta / tf)
        row += (f" | fixed {tf:.2f} s ({nf}) | adaptive {ta:.2f} s ({na} solved) | adaptive/fixed "
                f"{ta / tf:.2f}")
        lines.append(row)
        print(row, flush=True)
    lines.append(f"adaptive/fixed: median {statistics.median(ratios):.2f}, max {max(ratios):.2f}")
    print(lines[-1])
    tf, ta = (command_seconds(extra, a.repeats) for extra in (["--thetas", "paper-real", "--betas",
                                                                "paper-sim"], []))
    lines.append(f"command line (README example, end to end): fixed {tf:.2f} s | adaptive {ta:.2f} s | "
                 f"adaptive/fixed {ta / tf:.2f}")
    print(lines[-1])
    if a.out:
        a.out.write_text("\n".join(lines) + "\n")


def timed_set(mdp, trajs, thetas, betas: str, repeats: int) -> tuple[float, int]:
    """:func:`timed` on an explicit Θ (rows) × B: the demo's set."""
    from expertise_irl.hypotheses import HypothesisSet
    from expertise_irl.inference.belief import DiscreteBelief

    hyp = HypothesisSet(thetas, [float(b) for b in betas.split(",")])
    DiscreteBelief.from_mdp(mdp, hyp).update(trajs)
    seconds = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        DiscreteBelief.from_mdp(mdp, hyp).update(trajs)
        seconds.append(time.perf_counter() - t0)
    return statistics.median(seconds), len(hyp)


def command_seconds(extra: list[str], repeats: int) -> float:
    """Median wall seconds of ``expertise-irl infer`` on the README's example (after one warm-up run)."""
    cli = [sys.executable, "-c", "from expertise_irl.cli import main; main()"]
    with tempfile.TemporaryDirectory() as d:
        demos = str(Path(d) / "demos.csv")
        subprocess.run([*cli, "simulate", "crossroads", "--theta", "0.5,0.5,0,0,0", "--beta", "0.5",
                              "--episodes", "20", "--seed", "1", "--out", demos], check=True,
                       capture_output=True)
        seconds = []
        for k in range(repeats + 1):
            out = str(Path(d) / f"result{k}.json")
            t0 = time.perf_counter()
            subprocess.run([*cli, "infer", "crossroads", "--demos", demos, "--out", out, *extra],
                           check=True, capture_output=True)
            seconds.append(time.perf_counter() - t0)
    return statistics.median(seconds[1:])


if __name__ == "__main__":
    main()
