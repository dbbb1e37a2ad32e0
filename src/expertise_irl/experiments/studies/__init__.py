"""The registry of studies (``expertise-irl experiment list``), filled from entry points.

Every study, the built-in ones included, is registered as a Python entry point in the group
``expertise_irl.studies`` that names a :class:`~expertise_irl.experiments.spec.Study` or a
list or tuple of them, e.g. in a package's ``pyproject.toml``::

    [project.entry-points."expertise_irl.studies"]
    my-study = "my_package.my_study:STUDY"

so the engine never imports the packages that define studies (``userstudy`` registers its own),
and another installed package can add a study without touching this one. Workers (local
processes, Dask workers) find a study by name the same way, from the installed metadata.
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import entry_points

from ...errors import InputError

__all__ = ["GROUP", "get_study", "studies"]

#: The entry-point group that registers studies.
GROUP = "expertise_irl.studies"


@cache
def _registered() -> tuple:
    found = []
    for ep in entry_points(group=GROUP):
        try:
            value = ep.load()
        except Exception as exc:  # a broken provider is named, not a traceback
            raise InputError(f"the study entry point {ep.name!r} ({ep.value}) cannot be loaded: "
                             f"{type(exc).__name__}: {exc}") from None
        found += list(value) if isinstance(value, list | tuple) else [value]
    if not found:
        raise InputError(f"no study is registered (entry-point group {GROUP!r}): the installed "
                         "metadata is missing or stale; reinstall the package (pip install -e .)")
    names = [s.name for s in found]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"study {twice[0]!r} is registered twice (entry points {GROUP!r})")
    return tuple(found)


def studies() -> dict:
    """Every registered study, by name, in the order registered.

    Returns:
        Study name -> :class:`~expertise_irl.experiments.spec.Study`.

    Raises:
        InputError: an entry point cannot be loaded, none is registered, or two register the
            same name.
    """
    return {s.name: s for s in _registered()}


def get_study(name: str):
    """The registered study called ``name``.

    Args:
        name: the study's name (``expertise-irl experiment list``).

    Returns:
        Its :class:`~expertise_irl.experiments.spec.Study`.

    Raises:
        InputError: no study of that name is registered (the message lists those that are), or
            the registry cannot be read (see :func:`studies`).
    """
    known = studies()
    if name not in known:
        raise InputError(f"unknown study {name!r} (studies: {', '.join(sorted(known))})")
    return known[name]
