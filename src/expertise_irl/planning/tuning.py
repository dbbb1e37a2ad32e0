"""The solver's lane width, measured on this machine at first use and cached.

The batched solver (:mod:`expertise_irl.planning.kernels`) puts hypotheses along the vector axis of a
lane group. The best width depends on the machine: one AVX-512 vector holds 8 float64, an
AVX2 vector 4, and XLA's code for wider groups differs again. The first solve in a dtype on a
machine times a short run of each candidate width on the bundled 30×30 map (a few seconds,
mostly compilation) and keeps the fastest; later processes read the choice back.

- ``EXPERTISE_IRL_LANES=N`` uses N lanes and measures nothing.
- The choices live in ``$XDG_CACHE_HOME/expertise-irl/tuning.json`` (else
  ``~/.cache/expertise-irl/tuning.json``), keyed by the machine (CPU model, SIMD flags,
  cores), the JAX and jaxlib versions, the backend and its device, and ``XLA_FLAGS``; a
  change of any of them measures again. ``EXPERTISE_IRL_TUNING_FILE`` names another file.
- ``expertise-irl tune`` shows the choice and its measurements, and measures again on request.

Results agree within the solver's tolerance whatever the width (bit for bit between widths
that XLA compiles alike); only the speed depends on it.
"""

from __future__ import annotations

import functools
import json
import os
import platform
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import NamedTuple

from ..atomic import write_atomic
from ..cache import user_cache_dir
from ..errors import InputError

LANES_ENV = "EXPERTISE_IRL_LANES"
TUNING_FILE_ENV = "EXPERTISE_IRL_TUNING_FILE"
#: Widths tried at first use, by backend (a GPU wants far more parallel lanes than a CPU).
CANDIDATES = {"cpu": (4, 8, 16), "gpu": (32, 128, 512)}
#: Sweeps per hypothesis in the timing run (6 checks), and pools of hypotheses it solves.
_SWEEPS = 48
_POOLS = 4
#: SIMD flags that change XLA's and NumPy's code (from /proc/cpuinfo).
SIMD_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512dq", "avx512vl",
         "neon", "asimd", "sve")

_CHOSEN: dict[str, LaneChoice] = {}
_READ: dict = {}  # the cache file's last reading: {"stamp": (path, mtime), "table": {...}}


class LaneChoice(NamedTuple):
    """The lane width in use for one dtype, and where it came from.

    Attributes:
        lanes: hypotheses per lane group.
        source: ``"environment"`` (``EXPERTISE_IRL_LANES``), ``"cache"`` (measured earlier on
            this machine), ``"measured"`` (just now, and cached), ``"uncached"`` (measured just
            now, but the cache file could not be written, so each process measures again) or
            ``"default"`` (the backend has no candidates).
        backups_per_s: the timing run's throughput per candidate width (empty if not measured).
        measured: when it was measured (ISO date, UTC), or ``""``.
    """

    lanes: int
    source: str
    backups_per_s: dict[int, float]
    measured: str = ""


def tuning_file() -> Path:
    """Where the measured choices are kept."""
    where = os.environ.get(TUNING_FILE_ENV, "")
    return Path(where) if where else user_cache_dir() / "tuning.json"


@functools.cache
def cpu_description() -> tuple[str, str]:
    """(CPU model, its SIMD flags among :data:`SIMD_FLAGS`) from /proc/cpuinfo where there is
    one (flags ``""`` where none is found)."""
    cpu, flags = platform.processor() or platform.machine(), ""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name") and cpu in ("", platform.machine(), platform.processor()):
                    cpu = line.split(":", 1)[1].strip()
                elif line.startswith(("flags", "Features")) and not flags:
                    have = set(line.split(":", 1)[1].split())
                    flags = " ".join(f for f in SIMD_FLAGS if f in have)
    except OSError:
        pass
    return cpu, flags


def machine_key(dtype: str) -> str:
    """What the choice depends on, as one string (the cache's key)."""
    import jax
    import jaxlib

    cpu, flags = cpu_description()
    device = jax.devices()[0]
    return " | ".join([
        f"cpu={cpu}", f"flags={flags}", f"cores={os.cpu_count()}", f"jax={jax.__version__}",
        f"jaxlib={jaxlib.__version__}", f"backend={jax.default_backend()}",
        f"device={getattr(device, 'device_kind', device.platform)}",
        f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')}", f"dtype={dtype}",
    ])


def lane_width(dtype: str = "float64", *, measure: bool = True) -> int:
    """The lane width for ``dtype`` on this machine (see the module's description).

    With ``measure=False`` a width not known yet (no override, nothing cached) is not measured:
    the built-in default :data:`expertise_irl.planning.kernels.LANES` is used. The solver does that for
    small sets, where the width hardly matters and a first-use pause would.
    """
    known = _known(dtype)
    if known is not None:
        return known.lanes
    if not measure:
        from .kernels import LANES

        return LANES
    return lane_choice(dtype).lanes


def is_settled(dtype: str = "float64") -> bool:
    """Whether :func:`lane_width` can answer without measuring (environment, this process or
    the cache file)."""
    return _known(dtype) is not None


def lane_choice(dtype: str = "float64", *, again: bool = False) -> LaneChoice:
    """The lane width for ``dtype`` and its provenance; ``again`` measures anew and caches it."""
    known = _known(dtype)
    if known is not None and (not again or known.source == "environment"):
        return known
    choice = _measure(dtype)
    if choice.backups_per_s:
        path = tuning_file()
        table = _read(path)
        table[machine_key(dtype)] = {
            "lanes": choice.lanes, "measured": choice.measured,
            "backups_per_s": {str(k): v for k, v in choice.backups_per_s.items()},
        }
        if not _write(path, table):
            choice = choice._replace(source="uncached")
    _CHOSEN[dtype] = choice
    return choice


def _known(dtype: str) -> LaneChoice | None:
    """The width from the environment, this process's earlier choice or the cache file, if any."""
    env = os.environ.get(LANES_ENV, "").strip()
    if env:
        try:
            lanes = int(env)
        except ValueError:
            lanes = 0
        if lanes < 1:
            raise InputError(f"{LANES_ENV} must be a whole number >= 1, got {env!r}")
        return LaneChoice(lanes, "environment", {})
    if dtype in _CHOSEN:
        return _CHOSEN[dtype]
    entry = _read(tuning_file()).get(machine_key(dtype))
    if entry is None:
        return None
    choice = LaneChoice(entry["lanes"], "cache", entry["backups_per_s"], entry["measured"])
    _CHOSEN[dtype] = choice
    return choice


def _read(path: Path) -> dict:
    """The cached choices; an unreadable or malformed file counts as empty (it is ours to
    rewrite, not the user's). Read again only when the file changes."""
    try:
        stamp = (str(path), path.stat().st_mtime_ns)
        if _READ.get("stamp") == stamp:
            return dict(_READ["table"])
        table = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(table, dict):
        return {}
    ok = {k: e for k, e in ((k, _entry(v)) for k, v in table.items()) if e is not None}
    _READ.update(stamp=stamp, table=ok)
    return dict(ok)


def _entry(v) -> dict | None:
    """One cached choice, checked and converted (``lanes`` a whole number >= 1, throughputs by
    width), or None if anything in it is malformed."""
    try:
        lanes, rates, when = v["lanes"], v["backups_per_s"], v["measured"]
        if type(lanes) is not int or lanes < 1 or not isinstance(when, str):
            return None
        rates = {int(k): float(r) for k, r in rates.items()}
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    return {"lanes": lanes, "backups_per_s": rates, "measured": when}


def _write(path: Path, table: dict) -> bool:
    """Write the choices atomically (:mod:`expertise_irl.atomic`); False if the cache cannot be written."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, json.dumps(table, indent=1, sort_keys=True) + "\n")
        return True
    except OSError:
        return False


def _measure(dtype: str) -> LaneChoice:
    """Time each candidate width on the bundled ``zones30`` map: a pool of hypotheses per
    width, each swept :data:`_SWEEPS` times, after one untimed run that compiles it; the
    faster of two timed runs counts."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from ..hypotheses import THETA_PRESETS, theta_grid
    from ..numerics import enable_float64
    from ..worlds.maps import resolve_world
    from . import kernels

    enable_float64()
    candidates = CANDIDATES.get(jax.default_backend(), ())
    if not candidates:
        return LaneChoice(kernels.LANES, "default", {})
    mdp = resolve_world("zones30").to_mdp()
    prep = kernels.prepared(mdp, dtype)
    jdtype = jnp.float64 if dtype == "float64" else jnp.float32
    thetas = theta_grid(THETA_PRESETS["paper-sim"], mdp.n_features)
    consts = (jnp.asarray(mdp.gamma, jdtype), jnp.asarray(1e-300, jdtype), jnp.asarray(_SWEEPS))
    rates: dict[int, float] = {}
    for lanes in candidates:
        slots = kernels.default_chunk_size(mdp, np.dtype(dtype), lanes=lanes)
        H = _POOLS * slots
        weights = jnp.asarray(thetas[np.arange(H) % len(thetas)])
        v0 = jnp.zeros((H, prep.n_rows))
        best = np.inf
        for i in range(3):
            t = time.perf_counter()
            _, it, _, _ = kernels.solve_pool(prep, weights, v0, *consts, groups=slots // lanes, lanes=lanes)
            sweeps = int(np.asarray(it).sum())  # blocks until done
            if i:
                best = min(best, time.perf_counter() - t)
        rates[lanes] = sweeps * mdp.n_states * mdp.n_actions / best
    lanes = max(rates, key=rates.get)
    return LaneChoice(lanes, "measured", rates, datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"))
