"""Runners that put the pieces together: the demo job and the paper's experiments."""

__all__ = ["load"]


def load(out, table: str = "rows"):
    """A sweep's rows (or ``timings`` / ``failures``) as a pandas DataFrame; see :func:`.engine.load`.

    Rows are sorted by the study's identity columns (its ``sort_by``), so two runs of the same
    sweep give equal frames whatever the order their tasks finished in.

    Args:
        out: the sweep directory (``expertise-irl experiment run --out``).
        table: ``"rows"`` (one per result), ``"timings"`` or ``"failures"``.

    Returns:
        A :class:`pandas.DataFrame`, empty (with the study's columns for ``rows``) when no task
        has written the table yet.

    Raises:
        InputError: ``table`` is not one of the three, or ``out`` holds no sweep.
    """
    from .engine import load as _load

    return _load(out, table)
