"""The user's cache directory for expertise-irl (compiled programs, measured settings)."""

from __future__ import annotations

import os
from pathlib import Path


def user_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/expertise-irl``, else ``~/.cache/expertise-irl`` (not created here)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "expertise-irl"
