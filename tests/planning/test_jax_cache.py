"""JAX's persistent cache: one folder per CPU below the cache directory."""

import os
import subprocess
import sys

from expertise_irl.planning import jax_cache, tuning


def test_each_cpu_has_a_folder_of_its_own(monkeypatch):
    here = jax_cache.cpu_folder()
    assert here.startswith("cpu-") and len(here) == len("cpu-") + 12
    monkeypatch.setattr(tuning, "cpu_description", lambda: ("Some CPU", "avx avx2 fma"))
    other = jax_cache.cpu_folder()
    monkeypatch.setattr(tuning, "cpu_description", lambda: ("Some CPU", "avx avx2 fma avx512f"))
    assert other != jax_cache.cpu_folder() and here != other


def test_the_cache_directory_is_the_cpus_folder_below_the_one_named(tmp_path):
    """In a fresh process (the cache is set once per process), as the command line does."""
    code = ("import jax; from expertise_irl.planning.jax_cache import enable_jax_cache, cpu_folder; "
            "enable_jax_cache(); print(jax.config.jax_compilation_cache_dir); print(cpu_folder())")
    env = {**os.environ, "EXPERTISE_IRL_JAX_CACHE": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    where, folder = out.stdout.split()
    assert where == str(tmp_path / folder) and (tmp_path / folder).is_dir()
