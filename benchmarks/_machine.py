"""Machine description printed with every benchmark result."""

from __future__ import annotations

import os
import platform
import sys
from datetime import UTC, datetime

#: SIMD extensions that matter for NumPy's and XLA's exp/log and reduction kernels.
SIMD_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512vl", "neon", "asimd")


def cpu_flags() -> str:
    """The SIMD flags of this CPU among :data:`SIMD_FLAGS` (from /proc/cpuinfo)."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith(("flags", "Features")):
                    have = set(line.split(":", 1)[1].split())
                    return " ".join(f for f in SIMD_FLAGS if f in have) or "(none of interest)"
    except OSError:
        pass
    return "unknown"


def machine_info() -> dict[str, object]:
    import jax
    import numpy as np

    from expertise_irl.tuning import lane_choice

    lanes = lane_choice("float64")  # measured here at the machine's first use

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        mem_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError):
        mem_gib = float("nan")
    return {
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": cpu,
        "cpu_flags": cpu_flags(),
        "cores": os.cpu_count(),
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
