"""Machine description printed with every benchmark result."""

from __future__ import annotations

import os
import sys
from datetime import UTC, datetime


def cpu_flags() -> str:
    """The SIMD flags of this CPU that change NumPy's and XLA's code (the solver's tuning key's)."""
    from expertise_irl.planning.tuning import cpu_description

    return cpu_description()[1] or "(none of interest)"


def machine_info() -> dict[str, object]:
    import jax
    import numpy as np

    from expertise_irl.planning.tuning import lane_choice

    lanes = lane_choice("float64")  # measured here at the machine's first use

    from expertise_irl.planning.tuning import cpu_description

    cpu = cpu_description()[0]
    try:
        mem_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError):
        mem_gib = float("nan")
    return {
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": cpu,
        "cpu_flags": cpu_flags(),
        "cores": os.cpu_count(),
        "load_average_1_5_15_min": [round(x, 2) for x in os.getloadavg()],  # other work on the machine
        "memory_gib": round(mem_gib, 1),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "jax": jax.__version__,
        "jax_backend": jax.default_backend(),
        "solver_lanes": lanes.lanes,
        "solver_lanes_source": lanes.source + (f" {lanes.measured}" if lanes.measured else ""),
        "solver_lanes_backups_per_s": {str(k): round(v) for k, v in lanes.backups_per_s.items()},
        "command": " ".join([os.path.basename(sys.executable), *sys.argv]),
    }


def header(script: str) -> list[str]:
    """The first lines of a benchmark's output, printed: the command and the machine. JAX's
    persistent compilation cache is switched on first, as the command line does."""
    from expertise_irl.planning.jax_cache import enable_jax_cache

    enable_jax_cache()
    lines = [f"command: python benchmarks/{script} {' '.join(sys.argv[1:])}", f"machine: {machine_info()}"]
    print("\n".join(lines), flush=True)
    return lines


def report(result: dict, json_path) -> None:
    """Print a benchmark's result as ``key: value`` lines, and write it as JSON if asked."""
    import json

    for k, v in result.items():
        print(f"{k}: {v}")
    if json_path:
        json_path.write_text(json.dumps(result, indent=2) + "\n")


def timed_cli(args: list[str], jax_cache) -> float:
    """Wall seconds of ``expertise-irl ARGS`` in a fresh process with JAX's persistent cache in
    ``jax_cache``; exits with the command's stderr if it fails."""
    import subprocess
    import time
    from pathlib import Path

    env = {**os.environ, "EXPERTISE_IRL_JAX_CACHE": str(jax_cache)}
    cmd = [str(Path(sys.executable).with_name("expertise-irl")), *map(str, args)]
    t = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return wall


def measured_cli(args: list, jax_cache, env: dict[str, str] | None = None) -> tuple[float, int]:
    """(wall seconds, peak resident MB) of ``expertise-irl ARGS`` in a fresh process with JAX's
    persistent cache in ``jax_cache`` and ``env`` added to the environment; exits with the
    command's stderr if it fails."""
    import subprocess
    import time
    from pathlib import Path

    env = {**os.environ, "EXPERTISE_IRL_JAX_CACHE": str(jax_cache), **(env or {})}
    cmd = [str(Path(sys.executable).with_name("expertise-irl")), *map(str, args)]
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr.read().decode()[-2000:]}")
    return wall, round(usage.ru_maxrss / 1024)  # ru_maxrss is in KB on Linux
