"""Where the time of a 100-participant study goes: inference against reports and figures.

Builds, in a temporary folder, a study like a maze-navigation study of real people: 12 random
zone maps (10–15 cells a side, Sec. V-A's generator, exported as ``.npz`` MDP archives), 100
participants, one episode per map each (1,200 manifest rows), simulated at θ = (0.5, 0.5, 0, 0,
0) and β drawn log-uniformly from [0.01, 3], with an extra manifest column ``group`` (β < 0.1
or not). Then runs, through the command line in a fresh process,

    expertise-irl study manifest.csv --out DIR --group-by group [--workers N]

(discrete, ``--betas auto``, every figure) and prints the split the command reports on its
last line: engine phases (inference), tables, figures; the same study again into a fresh
directory with ``--figures none``; and, with ``--population``, once more into a fresh directory
with ``--figures none --population`` (the hierarchical fit of ``study --population`` beside the
shared solves it reads).

    python benchmarks/study_scale.py [--participants 100] [--maps 12] [--workers N] [--population]
                                     [--population-only] [--check off|fast|full] [--json FILE]

``--check`` is passed to every run (the command's own default otherwise); ``--population-only``
skips the run with every figure (the ``--figures none`` run still comes first and warms the JAX
cache).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _machine import machine_info, report

THETA = (0.5, 0.5, 0.0, 0.0, 0.0)


def build(root: Path, participants: int, n_maps: int, seed: int = 0) -> Path:
    from expertise_irl.demos.csv_io import write_demos_csv
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.worlds.zones import generate_map

    rng = np.random.default_rng(seed)
    mdps = []
    for i in range(n_maps):
        mdp = generate_map(rng, min_size=10, max_size=15, name=f"maze-{i:02d}").to_mdp()
        mdp.save(root / f"maze-{i:02d}.npz")
        mdps.append(mdp)
    (root / "demos").mkdir()
    lines = ["participant,map,demos,group"]
    for p in range(participants):
        beta = float(np.exp(rng.uniform(np.log(0.01), np.log(3.0))))
        pid = f"P{p + 1:03d}"
        for i, mdp in enumerate(mdps):
            tr = simulate(mdp, np.array(THETA), beta, 1, rng, max_steps=300)
            path = root / "demos" / f"{pid}-{i:02d}.csv"
            write_demos_csv(path, tr, mdp, fmt="state")
            lines.append(f"{pid},maze-{i:02d}.npz,demos/{path.name},{'expert' if beta < 0.1 else 'novice'}")
    (root / "manifest.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return root / "manifest.csv"


SPLIT = re.compile(r"\(([\d.]+) s: reading and the β grid ([\d.]+) s, inference ([\d.]+) s, "
                   r"(?:population ([\d.]+) s, )?reports ([\d.]+) s, figures ([\d.]+) s\)")


def run(manifest: Path, out: Path, cache: Path, extra: list[str]) -> dict:
    env = {**os.environ, "EXPERTISE_IRL_JAX_CACHE": str(cache)}
    cmd = [str(Path(sys.executable).with_name("expertise-irl")), "study", str(manifest), "--out", str(out),
           "--group-by", "group", *extra]
    t = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    m = SPLIT.search(proc.stdout.strip().splitlines()[-1])
    total, setup, inference, population, reports, figures = (float(x) if x else None for x in m.groups())
    res = {"wall_s": round(wall, 1), "study_s": total, "setup_s": setup, "inference_s": inference,
           "reports_s": reports, "figures_s": figures, "figures_share": round(figures / total, 2)}
    if population is not None:
        timing = json.loads((out / "population.json").read_text())["timing_s"]
        res.update(population_s=population, population_share=round(population / total, 2),
                   population_parts_s={k: round(v, 1) for k, v in timing.items()})
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=100)
    ap.add_argument("--maps", type=int, default=12)
    ap.add_argument("--workers", type=int, default=None, help="local workers (default: one per core)")
    ap.add_argument("--population", action="store_true", help="also time study --population")
    ap.add_argument("--population-only", action="store_true",
                    help="time --figures none and --population only (implies --population)")
    ap.add_argument("--check", choices=("off", "fast", "full"), default=None,
                    help="pass --check to every run (default: the command's default)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    info = machine_info()
    extra = ["--workers", str(args.workers)] if args.workers else []
    if args.check:
        extra += ["--check", args.check]
    args.population = args.population or args.population_only
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t = time.perf_counter()
        manifest = build(tmp, args.participants, args.maps)
        built = time.perf_counter() - t
        cache = tmp / "jax-cache"
        every = None if args.population_only else run(manifest, tmp / "all", cache, extra)
        none = run(manifest, tmp / "none", cache, [*extra, "--figures", "none"])
        pooled = (run(manifest, tmp / "population", cache, [*extra, "--figures", "none", "--population"])
                  if args.population else None)
    result = {**info, "participants": args.participants, "maps": args.maps,
              "rows": args.participants * args.maps, "workers": args.workers, "build_s": round(built, 1),
              "check": args.check, **({"figures_all": every} if every else {}), "figures_none": none,
              **({"population": pooled} if pooled else {})}
    report(result, args.json)


if __name__ == "__main__":
    main()
