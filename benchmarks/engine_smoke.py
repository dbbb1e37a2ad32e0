"""Wall time of a sweep through the CLI: 1 and 2 local workers and a Dask LocalCluster.

Each engine runs ``expertise-irl experiment run STUDY --out DIR --scale SCALE`` into a fresh
directory, twice: with an empty JAX compilation cache (``cold``: every worker compiles the
solver kernels) and with the cache the cold run filled (``warm``: a second sweep on the same
machine). The Dask cluster (2 worker processes, 1 thread each, on 127.0.0.1) is started
before the clock starts, as a user's cluster would be. All runs must give identical rows.

    python benchmarks/engine_smoke.py [--study conditions] [--scale smoke] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
from pathlib import Path

from _machine import machine_info, timed_cli


def _cli_run(study: str, scale: str, out: Path, extra: list[str], cache: Path) -> float:
    return timed_cli(["experiment", "run", study, "--out", out, "--scale", scale, *extra], cache)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="conditions")
    ap.add_argument("--scale", default="smoke")
    ap.add_argument("--json", default=None, help="write the results here as JSON")
    args = ap.parse_args()
    from distributed import Client, LocalCluster

    from expertise_irl.experiments import load

    info = machine_info()
    print("machine:", ", ".join(f"{k}={v}" for k, v in info.items()))
    root = Path(tempfile.mkdtemp(prefix="engine-bench-"))
    results, frames = [], {}
    try:
        def measure(name: str, extra: list[str], cache: Path, restart=None) -> None:
            for state in ("cold", "warm"):
                out = root / f"out-{len(results)}"
                wall = _cli_run(args.study, args.scale, out, extra, cache)
                df = load(out)
                frames[(name, state)] = df[[c for c in df.columns if not c.endswith("_time_s")]]
                results.append({"engine": name, "cache": state, "wall_s": round(wall, 2), "rows": len(df)})
                print(f"{name:34s} {state:5s} {wall:7.2f} s  {len(df)} rows", flush=True)
                if restart is not None:
                    restart()  # fresh worker processes: the warm run loads kernels, it does not reuse them

        for i, workers in enumerate((1, 2)):
            measure(f"local, --workers {workers}", ["--workers", str(workers)], root / f"cache-{i}")
        cache = root / "cache-dask"
        os.environ["EXPERTISE_IRL_JAX_CACHE"] = str(cache)  # the cluster's workers inherit it
        with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None) as cluster, Client(cluster) as client:
            measure("Dask LocalCluster (2 processes)", ["--scheduler", cluster.scheduler_address], cache,
                    restart=client.restart)
        first = next(iter(frames.values()))
        same = all(f.equals(first) for f in frames.values())
        print("identical rows across all runs:", same)
        if args.json:
            Path(args.json).write_text(json.dumps({"machine": info, "study": args.study, "scale": args.scale,
                                                   "results": results, "identical": same}, indent=2))
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
