"""Shared test configuration: a headless matplotlib backend and small fixtures."""

import os

import matplotlib

matplotlib.use("Agg")
# The solver's lane width is fixed for the suite (results agree within the tolerance whatever the
# width, but one width keeps them identical from machine to machine); tests/planning/test_tuning.py
# measures and caches it in a folder of its own.
os.environ.setdefault("EXPERTISE_IRL_LANES", "8")
# No persistent compilation cache in the suite's processes: late in a whole-suite process, XLA's
# (de)serialisation of a cached program crashed it (an abort reading an entry, a segfault writing
# one; each test passes alone). The cache's own behaviour is tested with a folder of its own
# (tests/planning/test_jax_cache.py).
os.environ.setdefault("EXPERTISE_IRL_JAX_CACHE", "off")

# The quick tier's record of the modules its tests call (tests/quick_tier.py).
from quick_tier import (
    pytest_collection_finish,
    pytest_collection_modifyitems,
    pytest_runtest_protocol,
)

__all__ = ["pytest_collection_finish", "pytest_collection_modifyitems", "pytest_runtest_protocol"]
