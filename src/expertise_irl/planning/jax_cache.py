"""JAX's persistent compilation cache, shared by the command line and the engine's workers.

Compiling the solver, likelihood and sampler programs takes seconds per map; JAX can keep the
compiled programs on disk and serve them to later processes. ``EXPERTISE_IRL_JAX_CACHE``
names the directory (default ``$XDG_CACHE_HOME/expertise-irl/jax``, else
``~/.cache/expertise-irl/jax``); ``off`` disables it. Programs are keyed by JAX on their
computation, options and JAX version, so a stale entry is never used. That key leaves out the
host CPU, though, and a program compiled for one CPU's instructions (AVX-512, say) would be
offered to a CPU without them; so each CPU (model and SIMD flags,
:func:`.tuning.cpu_description`) has a folder of its own below the directory, and machines that
share a home folder (a Dask cluster of unlike nodes) never load each other's programs.
"""

from __future__ import annotations

import os

from ..cache import user_cache_dir

JAX_CACHE_ENV = "EXPERTISE_IRL_JAX_CACHE"

_READY = False


def cpu_folder() -> str:
    """The cache's folder for this CPU: ``cpu-`` and 12 hex digits of its model and SIMD flags."""
    import hashlib

    from .tuning import cpu_description

    cpu, flags = cpu_description()
    return "cpu-" + hashlib.sha256(f"{cpu}|{flags}".encode()).hexdigest()[:12]


def enable_jax_cache() -> None:
    """Turn the persistent cache on for this process (once; a directory that cannot be
    created leaves it off)."""
    global _READY
    if _READY:
        return
    _READY = True
    where = os.environ.get(JAX_CACHE_ENV, "")
    if where.lower() == "off":
        return
    if not where:
        where = str(user_cache_dir() / "jax")
    where = os.path.join(where, cpu_folder())
    try:
        os.makedirs(where, exist_ok=True)
    except OSError:
        return
    import jax

    jax.config.update("jax_compilation_cache_dir", where)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
