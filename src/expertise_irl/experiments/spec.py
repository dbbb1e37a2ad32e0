"""What a study is: :class:`Study`, its :class:`Column` schema, its :class:`TaskSpec` tasks, seeds
and configs as plain values.

A leaf of :mod:`expertise_irl.experiments`: it imports nothing from the package above
:mod:`~expertise_irl.errors`, so studies, workers, the engine and the reports all build on it.
The randomness of a study's instance comes from :func:`seed_sequence`: ``SeedSequence(entropy=seed,
spawn_key=identity)``, never from the instance's position in a sweep. A config travels to workers
and into ``manifest.json`` as plain JSON values (:func:`config_dict`) and comes back with
:func:`config_from_dict`; a person's edits arrive as TOML (:func:`config_from_toml`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError


def seed_sequence(seed: int, identity) -> np.random.SeedSequence:
    """The seed of the thing named by ``identity`` (a tuple of non-negative ints) in sweep ``seed``."""
    return np.random.SeedSequence(entropy=int(seed), spawn_key=tuple(int(i) for i in identity))


@dataclass(frozen=True)
class Column:
    """One documented column: name, Arrow type (as pyarrow names it) and meaning."""

    name: str
    type: str
    doc: str


@dataclass(frozen=True)
class TaskSpec:
    """A task: its key (file name of its shard), its parameters and a cost estimate (seconds)."""

    key: str
    params: dict[str, Any]
    estimate_s: float = 1.0


@dataclass(frozen=True)
class Study:
    """A named, versioned sweep definition.

    Attributes:
        name: the CLI name.
        version: bump when a change alters the rows for the same config and seed.
        description: one line for ``experiment list``.
        config_type: a frozen dataclass; its fields are the study's factors.
        scales: scale name -> config.
        tasks: config -> task specs (each task's key unique within the study), in the order
            they should be handed out (e.g. long ones first, maps interleaved so that workers
            compile different maps' kernels at the start).
        run_task: (config, seed, params) -> (columns dict of 1-D arrays, stats dict).
        columns: the documented schema of the rows.
        sort_by: columns that order the rows (``load`` and the report read them in this order).
        counts: config -> dict of totals (instances, rows, solves grouped and not) for ``list``.
        report: the builder of ``experiment report``, as ``module:function`` (the function takes the
            report's ``Sweep`` and returns its ``Report``); empty for a study without a report.
    """

    name: str
    version: int
    description: str
    config_type: type
    scales: dict[str, Any]
    tasks: Callable[[Any], list[TaskSpec]]
    run_task: Callable[[Any, int, dict[str, Any]], tuple[dict[str, np.ndarray], dict[str, Any]]]
    columns: tuple[Column, ...]
    sort_by: tuple[str, ...]
    counts: Callable[[Any], dict[str, int]] = field(default=lambda cfg: {})
    report: str = ""

    def config(self, scale: str):
        if scale not in self.scales:
            raise InputError(f"study {self.name!r} has no scale {scale!r} (scales: {', '.join(self.scales)})")
        return self.scales[scale]

    def arrow_schema(self):
        import pyarrow as pa

        return pa.schema([(c.name, _arrow_type(c.type)) for c in self.columns])


def _arrow_type(name: str):
    import pyarrow as pa

    types = {"int32": pa.int32(), "int64": pa.int64(), "float64": pa.float64(), "string": pa.string(),
             "bool": pa.bool_()}
    return types[name]


# ----------------------------------------------------------------------------- configs
#: Metadata key of a config field added after sweeps were written without it: while it keeps its
#: default it is left out of :func:`config_dict` (and so of the config's hash), so those sweeps
#: still resume; :func:`config_from_dict` gives it back its default.
ADDED_FIELD = "added_field"


def config_dict(config) -> dict[str, Any]:
    """A config as plain JSON/TOML values (tuples become lists); :func:`config_from_dict` inverts it.
    A field marked :data:`ADDED_FIELD` is left out while it has its default."""
    out = json.loads(json.dumps(dataclasses.asdict(config)))
    for f in dataclasses.fields(config):
        if f.metadata.get(ADDED_FIELD) and out[f.name] == json.loads(json.dumps(f.default)):
            del out[f.name]
    return out


def config_from_dict(study: Study, values: dict[str, Any]):
    """The study's config from plain values (lists become tuples); fields not given keep their default."""
    kwargs = {}
    for f in dataclasses.fields(study.config_type):
        if f.name in values:
            v = values[f.name]
            kwargs[f.name] = tuple(v) if isinstance(v, list) else v
    return study.config_type(**kwargs)


def config_from_toml(study: Study, path, base):
    """``base`` (a scale's config) with the fields set in the TOML file ``path`` replaced.

    The file holds the fields either at the top level or in a table named after the study
    (the form ``DIR/config.toml`` is written in, so a sweep's config can be edited and reused).
    Every key must be a field of the study's config with a value of the field's type; the
    config then checks its own values. Errors are one line naming the file and the field.
    """
    import tomllib

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {'is a directory' if path.is_dir() else 'no such file'} (--config)")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a TOML file: {exc}") from None
    if set(data) == {study.name} and isinstance(data[study.name], dict):
        data = data[study.name]
    elif len(data) == 1 and isinstance(next(iter(data.values())), dict):
        raise InputError(f"{path}: holds a [{next(iter(data))}] table, but the study is {study.name!r} "
                         f"(write its fields at the top level or in a [{study.name}] table)")
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    changes = {}
    for key, value in data.items():
        if key not in fields:
            raise InputError(f"{path}: {key!r} is not a field of study {study.name!r} "
                             f"(fields: {', '.join(fields)})")
        changes[key] = _typed(path, key, value, fields[key])
    try:
        return dataclasses.replace(base, **changes)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def _typed(path, key: str, value, default):
    """``value`` as the type of ``default`` (lists become tuples), or a one-line InputError."""
    def kind(x) -> str:
        return "a boolean" if isinstance(x, bool) else "a whole number" if isinstance(x, int) else \
            "a number" if isinstance(x, float) else "a string" if isinstance(x, str) else "a list"

    if isinstance(default, tuple):
        if not isinstance(value, list) or not value:
            raise InputError(f"{path}: {key} must be a non-empty list, got {value!r}")
        like = default[0] if default else value[0]
        return tuple(_typed(path, f"{key}[{i}]", v, like) for i, v in enumerate(value))
    ok = (isinstance(value, bool) if isinstance(default, bool)
          else isinstance(value, int) and not isinstance(value, bool) if isinstance(default, int)
          else isinstance(value, int | float) and not isinstance(value, bool) if isinstance(default, float)
          else isinstance(value, str))
    if not ok:
        raise InputError(f"{path}: {key} must be {kind(default)}, got {value!r}")
    return float(value) if isinstance(default, float) else value
