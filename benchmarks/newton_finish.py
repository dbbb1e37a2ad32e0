"""Newton's finish against the sweeps alone, per hypothesis, on a large floor plan.

    python benchmarks/newton_finish.py [--size 200] [--out FILE]

On the ``SIZE × SIZE`` floor plan of ``benchmarks/large_worlds.py`` (seed 0, γ = 0.99), each
hypothesis below is solved alone to 1e-8 nats twice in one process, after one warm-up solve of
each (compilation): ``solve(..., newton=False)`` (the ``levels`` start and the pool's sweeps) and
``solve(..., newton=True)`` (sweeps to 0.1 nats, chord and Newton steps, sweeps to certify). The
hypotheses: the large-worlds person (0.4, 0.2, 0.4) at β = 0.3, the slowest people of the
paper-real set (length first and roads first at β = 0.1, the diffusive (0.2, 0.4, 0.4) at β = 1)
and a wanderer (β = 3). Reported: seconds, sweeps and Newton steps of each, and the largest
difference of the two solutions' V/β (both certified to 1e-8, so at most 2e-8).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import header

from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.floorplans import generate_floor_plan

PEOPLE = [((0.4, 0.2, 0.4), 0.3), ((1.0, 0.0, 0.0), 0.1), ((0.0, 0.0, 1.0), 0.1), ((0.2, 0.4, 0.4), 1.0),
          ((0.4, 0.2, 0.4), 3.0)]


def timed(mdp, theta, beta, newton: bool):
    t0 = time.perf_counter()
    sol = solve(mdp, theta[None], np.array([beta]), newton=newton)
    return time.perf_counter() - t0, sol


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=200)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args()
    lines = header("newton_finish.py")
    mdp = generate_floor_plan(a.size, seed=0).to_mdp()
    lines.append(f"plan {a.size}x{a.size}: {mdp.n_states:,} states, gamma {mdp.gamma}")
    for flag in (False, True):  # compile both paths' shapes
        timed(mdp, np.array(PEOPLE[0][0]), PEOPLE[0][1], flag)
    totals = np.zeros(2)
    for theta, beta in PEOPLE:
        th = np.array(theta)
        t_sw, sw = timed(mdp, th, beta, False)
        t_nw, nw = timed(mdp, th, beta, True)
        totals += (t_sw, t_nw)
        dv = float(np.max(np.abs(sw.value - nw.value)) / beta)
        lines.append(f"theta {theta} beta {beta}: sweeps alone {t_sw:.2f} s "
                     f"({int(sw.iterations[0])} sweeps) | "
                     f"Newton's finish {t_nw:.2f} s ({int(nw.iterations[0])} sweeps, "
                     f"{int(nw.newton_steps[0])} steps) | {t_nw / t_sw:.2f}x | max |dV/beta| {dv:.1e}")
        print(lines[-1], flush=True)
    lines.append(f"all: sweeps alone {totals[0]:.1f} s, Newton's finish {totals[1]:.1f} s "
                 f"({totals[1] / totals[0]:.2f}x)")
    print(lines[-1])
    if a.out:
        a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
