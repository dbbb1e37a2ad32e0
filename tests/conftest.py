"""Shared test configuration: a headless matplotlib backend and small fixtures."""

import os
import sys

import matplotlib
import pytest

matplotlib.use("Agg")
# The solver's lane width is fixed for the suite (results agree within the tolerance whatever the
# width, but one width keeps them identical from machine to machine); tests/planning/test_tuning.py
# measures and caches it in a folder of its own.
os.environ.setdefault("EXPERTISE_IRL_LANES", "8")

# The quick tier's record of the modules its tests call (tests/quick_tier.py).
from quick_tier import (
    pytest_collection_finish,
    pytest_collection_modifyitems,
    pytest_runtest_protocol,
)

__all__ = ["pytest_collection_finish", "pytest_collection_modifyitems", "pytest_runtest_protocol"]


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After each test module, JAX's in-memory caches are cleared: late in a whole-suite process XLA
    crashed while compiling or loading a program (at tests that pass alone), as the process's
    compiled programs piled up; the persistent cache serves them again cheaply."""
    yield
    jax = sys.modules.get("jax")
    if jax is not None:
        jax.clear_caches()
