"""Runners that put the pieces together: the demo job and the paper's experiments."""


def load(out, table: str = "rows"):
    """A sweep's rows (or ``timings`` / ``failures``) as a pandas DataFrame; see :func:`.engine.load`."""
    from .engine import load as _load

    return _load(out, table)
