"""Wall time of ``expertise-irl study example`` (the bundled study) through the CLI.

The bundled study: 8 participants, 9 recordings on 3 floor plans of 4,604 heading-states,
the paper-real set (19 θ × 5 β = 95 hypotheses). Two runs into fresh directories: ``cold``
with an empty JAX compilation cache (every worker compiles the solver kernels) and ``warm``
with the cache the cold run filled. Both must write the same study.csv. The wall time
covers everything: start-up, reading and discretising the recordings, the engine's worker
processes, both solve phases, the tables and the eight figures.

    python benchmarks/study_example.py [--workers N] [--json FILE]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from _machine import machine_info, report, timed_cli

ARGS = ["--fill-gaps", "--model", "maxent-relative"]


def _run(out: Path, cache: Path, workers: int | None) -> float:
    extra = ["--workers", str(workers)] if workers else []
    return timed_cli(["study", "example", "--out", out, *ARGS, *extra], cache)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None, help="local workers (default: one per core)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    info = machine_info()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cache = tmp / "jax-cache"
        cold = _run(tmp / "cold", cache, args.workers)
        warm = _run(tmp / "warm", cache, args.workers)
        same = (tmp / "cold" / "study.csv").read_bytes() == (tmp / "warm" / "study.csv").read_bytes()
    result = {**info, "study": "example", "args": ARGS, "workers": args.workers, "cold_s": round(cold, 1),
              "warm_s": round(warm, 1), "identical_study_csv": same}
    report(result, args.json)
    if not same:
        raise SystemExit("the two runs wrote different study.csv files")


if __name__ == "__main__":
    main()
