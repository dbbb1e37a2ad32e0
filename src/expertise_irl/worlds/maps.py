"""Load a text map of either world, chosen by the ``world`` key of the TOML beside it.

``world = "warehouse"`` gives a :class:`~expertise_irl.worlds.warehouse.WarehouseMap`
(floor plan with headings); no TOML, no ``world`` key or ``world = "zones"`` gives a
:class:`~expertise_irl.worlds.zones.ZoneMap`. Bundled maps follow the same rule.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import InputError
from . import warehouse, zones
from .files import read_toml

WORLDS = ("zones", warehouse.WORLD)
Map = zones.ZoneMap | warehouse.WarehouseMap


def world_of(toml_path: Path, text: str | None = None) -> str:
    """The ``world`` named by a map's TOML (``"zones"`` when the file or the key is absent)."""
    if text is None and not toml_path.is_file():
        return "zones"
    world = read_toml(toml_path, text).get("world", "zones")
    if world not in WORLDS:
        raise InputError(f"{toml_path}: unknown world {world!r} (known: {', '.join(WORLDS)})")
    return world


def load_world(path: str | Path) -> Map:
    """Read a map file of either world (see the module docstring)."""
    path = Path(path)
    if path.is_file() and world_of(path.with_suffix(".toml")) == warehouse.WORLD:
        return warehouse.load_floor_plan(path)
    return zones.load_map(path)


def load_bundled_world(name: str) -> Map:
    """A bundled map of either world by name (see :func:`expertise_irl.worlds.zones.bundled_maps`)."""
    if name not in zones.bundled_maps():
        raise InputError(f"no bundled map {name!r} (available: {', '.join(zones.bundled_maps())})")
    base = resources.files("expertise_irl") / "maps"
    toml = base / f"{name}.toml"
    toml_text = toml.read_text(encoding="utf-8") if toml.is_file() else None
    if toml_text is None or world_of(Path(f"bundled:{name}.toml"), toml_text) != warehouse.WORLD:
        return zones.load_bundled(name)
    settings = warehouse.read_floor_plan_settings(Path(f"bundled:{name}.toml"), toml_text)
    return warehouse.parse_floor_plan((base / f"{name}.txt").read_text(encoding="utf-8"),
                                      name=f"bundled:{name}", **settings)


def resolve_world(spec: str | Path) -> Map:
    """A map of either world from a file path, or a bundled map by name if no such file exists."""
    p = Path(spec)
    if p.is_file():
        return load_world(p)
    if str(spec) in zones.bundled_maps():
        return load_bundled_world(str(spec))
    return zones.resolve_map(spec)  # raises the usual "no such map file" message
