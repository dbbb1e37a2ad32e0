"""The registry of studies (``expertise-irl experiment list``)."""

from __future__ import annotations

from ...errors import InputError


def studies() -> dict:
    """Study name -> :class:`~expertise_irl.experiments.engine.Study`."""
    from ...userstudy.study import STUDIES as user_studies
    from .cardinality import STUDY as cardinality
    from .fixed_vs_joint import STUDY as conditions
    from .fullset import STUDY as fullset
    from .optimisation import STUDY as optimisation

    return {s.name: s for s in (conditions, cardinality, optimisation, fullset, *user_studies)}


def get_study(name: str):
    known = studies()
    if name not in known:
        raise InputError(f"unknown study {name!r} (studies: {', '.join(sorted(known))})")
    return known[name]
