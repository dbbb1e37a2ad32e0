"""A study's manifest: who did which task, on which map, recorded where.

A manifest is a CSV with a header and the columns ``participant``, ``map`` and
``recording`` (a Cartesian recording ``episode,t,x,y``) or ``demos`` (the project's
demonstration CSV, ``episode,step,x,y[,heading]`` or ``episode,step,state,action``); a
manifest may hold both columns, and each row then fills exactly one. ``map`` is any task
the project reads: a floor plan (a text map whose TOML says ``world = "warehouse"``), a
zone map, a bundled map's name, or an ``.npz`` MDP archive (the format ``infer --mdp``
reads). A recording needs a floor plan (its metres become cells); demonstrations fit every
world. Paths are relative to the manifest's folder. Several rows of one participant are
several tasks (maps, specifications or start points); participants keep the order of their
first row. A participant's tasks must have the same features, in the same order (their θ means
one thing on all of them); participants may differ (a study's θ columns are the union of its
features, empty where a participant's tasks lack one).

A recording may be a ROS bag (``.bag``, ``.db3``, ``.mcap`` or a ROS 2 bag folder,
:mod:`..demos.rosbag`); the optional columns ``bag_topic``, ``bag_child``, ``bag_parent``,
``bag_frame``, ``bag_clock``, ``bag_episode_topic`` and ``bag_episode_gap`` (:data:`BAG_COLUMNS`)
give that row's ``discretise`` options ``--topic`` ... ``--episode-gap``; ``bag_topic`` is
required for a bag, and a bag column filled on another row is an error.

Other columns (a condition, a group, an instruction) are carried verbatim into ``tasks.csv``
and ``study.csv`` (:attr:`StudyTask.extra`), and ``study --group-by`` can compare by one. An
extra column may not take the name of a column the study writes.

Every problem is an :class:`~expertise_irl.errors.InputError` naming the manifest and
line (``study.csv:4: ...``), including those found in the files a row names.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..demos.csv_io import read_demos_csv
from ..demos.recordings import Discretised, discretise_recording
from ..demos.rosbag import BagOptions, is_bag
from ..demos.trajectories import Trajectories
from ..errors import InputError, read_text
from ..mdp import TabularMDP
from ..worlds.maps import Map, load_bundled_world, load_world
from ..worlds.warehouse import WarehouseMap
from ..worlds.zones import bundled_maps

REQUIRED = ("participant", "map")
SOURCES = ("recording", "demos")
#: The optional columns of a ROS bag's options (``bag_<option>``, :class:`BagOptions`' fields).
BAG_COLUMNS = tuple(f"bag_{o}" for o in ("topic", "child", "parent", "frame", "clock", "episode_topic",
                                          "episode_gap"))
#: A participant ID names a folder: letters, digits, ``.``, ``_``, ``-``; not starting with ``.``.
PARTICIPANT_ID = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}")


@dataclass(frozen=True, eq=False)
class StudyTask:
    """One manifest row, loaded.

    Attributes:
        index: the row's position among the manifest's rows (0-based).
        line: its line in the manifest (the header is line 1).
        participant: the participant ID.
        map_path: the map's file (``bundled:NAME`` for a bundled map).
        world: the map (a floor plan or a zone map), or ``None`` for an MDP archive.
        mdp: the task's MDP (``world.to_mdp()``, or the archive's).
        kind: ``"recording"`` or ``"demos"``.
        source: the recording or demonstrations file.
        trajectories: the demonstrations on ``mdp``.
        discretised: how a recording became demonstrations (``None`` for demos).
        extra: the row's other manifest columns, verbatim (``{column: value}``).
    """

    index: int
    line: int
    participant: str
    map_path: Path
    world: Map | None
    mdp: TabularMDP
    kind: str
    source: Path
    trajectories: Trajectories
    discretised: Discretised | None
    extra: dict[str, str] = field(default_factory=dict)

    @property
    def plan(self) -> WarehouseMap | None:
        """The floor plan of the task, or ``None`` in another world."""
        return self.world if isinstance(self.world, WarehouseMap) else None

    @property
    def map_label(self) -> str:
        """The map as the manifest names it (a path relative to the manifest, or ``bundled:NAME``)."""
        return self.map_path.name

    @property
    def filled_gaps(self) -> int:
        return self.discretised.filled_gaps if self.discretised is not None else 0

    @property
    def snapped_samples(self) -> int:
        return self.discretised.snapped_samples if self.discretised is not None else 0


@dataclass(frozen=True, eq=False)
class Manifest:
    path: Path
    tasks: tuple[StudyTask, ...]
    extra_columns: tuple[str, ...] = ()

    @property
    def participants(self) -> list[str]:
        """Participant IDs in the order of their first row."""
        return list(dict.fromkeys(t.participant for t in self.tasks))

    def tasks_of(self, participant: str) -> list[StudyTask]:
        return [t for t in self.tasks if t.participant == participant]

    @property
    def feature_names(self) -> tuple[str, ...]:
        """Every task's features, in the order first seen."""
        return tuple(dict.fromkeys(f for t in self.tasks for f in t.mdp.feature_names))


def read_manifest(
    path: str | Path,
    *,
    rate: float = 1.0,
    max_dt: float | None = None,
    fill_gaps: bool = False,
    snap: bool = False,
) -> Manifest:
    """Read a manifest and load every row's floor plan and demonstrations (recordings are
    discretised with ``rate``, ``max_dt``, ``fill_gaps``, ``snap``; see :mod:`..demos.recordings`)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such manifest file")
    text = read_text(path, encoding="utf-8-sig")
    rows = list(csv.reader(text.splitlines()))
    header, col = _columns(path, rows)
    base = path.parent
    worlds: dict[str, tuple[Map | None, TabularMDP]] = {}
    tasks: list[StudyTask] = []
    extra = tuple(c for c in header if c not in col and c)
    for line, row in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in row):
            continue  # blank line
        at = f"{path}:{line}"
        if len(row) > len(header):
            raise InputError(f"{at}: {len(row)} fields but the header has {len(header)}")
        cell = {c: (row[i].strip() if i < len(row) else "") for c, i in col.items()}
        kind = _source_kind(at, cell)
        source = base / cell[kind]
        map_path, key = _map_path(at, base, cell["map"])
        if not (source.is_file() or (kind == "recording" and source.is_dir())):
            raise InputError(f"{at}: {kind} {cell[kind]}: no such file ({source})")
        bag = _bag_options(at, cell, kind, source)
        try:
            if key not in worlds:
                worlds[key] = _load_task_map(map_path, cell["map"])
            world, mdp = worlds[key]
            if kind == "recording":
                if not isinstance(world, WarehouseMap):
                    what = "an MDP archive" if world is None else "a zone map"
                    raise InputError(f"map {cell['map']} is {what}: a recording (episode,t,x,y in metres) "
                                     "needs a floor plan (world = \"warehouse\"); give the moves as demos "
                                     "(episode,step,x,y or episode,step,state,action)")
                disc = discretise_recording(
                    source, world, rate=rate, max_dt=max_dt, fill_gaps=fill_gaps, snap=snap, bag=bag
                )
                trajs = disc.trajectories
            else:
                disc = None
                trajs = read_demos_csv(source, mdp)
        except InputError as exc:
            raise InputError(f"{at}: {exc}") from None
        if len(trajs) == 0:
            raise InputError(f"{at}: {kind} {cell[kind]} holds no moves")
        first = next((t for t in tasks if t.participant == cell["participant"]), None)
        if first is not None and tuple(mdp.feature_names) != tuple(first.mdp.feature_names):
            raise InputError(
                f"{at}: map {cell['map']} has features {', '.join(mdp.feature_names)}, but "
                f"{cell['participant']}'s task on line {first.line} has "
                f"{', '.join(first.mdp.feature_names)}: "
                "a participant's tasks must have the same features in the same order"
            )
        values = {c: (row[header.index(c)].strip() if header.index(c) < len(row) else "") for c in extra}
        tasks.append(StudyTask(len(tasks), line, cell["participant"], map_path, world, mdp, kind, source,
                               trajs, disc, values))
    if not tasks:
        raise InputError(f"{path}: the manifest has a header but no rows")
    return Manifest(path, tuple(tasks), extra)


def _map_path(at: str, base: Path, spec: str) -> tuple[Path, str]:
    """The map's path (``bundled:NAME`` for a bundled map) and the key it is loaded once under."""
    p = base / spec
    if p.is_file():
        return p, str(p.resolve())
    if spec in bundled_maps():
        return Path(f"bundled:{spec}"), f"bundled:{spec}"
    raise InputError(f"{at}: map {spec}: no such file ({p}) and no bundled map of that name "
                     f"(bundled: {', '.join(bundled_maps())})")


def _load_task_map(map_path: Path, spec: str) -> tuple[Map | None, TabularMDP]:
    """(map or None, MDP) of a manifest's ``map`` cell."""
    if str(map_path).startswith("bundled:"):
        world = load_bundled_world(spec)
        return world, world.to_mdp()
    if map_path.suffix == ".npz":
        return None, TabularMDP.load(map_path)
    world = load_world(map_path)
    return world, world.to_mdp()


def _columns(path: Path, rows: list[list[str]]) -> tuple[list[str], dict[str, int]]:
    """The header's names and the position of each known column; raises for a bad header."""
    if not rows or not any(c.strip() for c in rows[0]):
        raise InputError(
            f"{path}:1: empty manifest; expected a header participant,map,recording "
            "(or participant,map,demos)"
        )
    header = [c.strip() for c in rows[0]]
    missing = [c for c in REQUIRED if c not in header]
    if missing or not any(s in header for s in SOURCES):
        need = ", ".join(missing + ([] if any(s in header for s in SOURCES) else ["recording or demos"]))
        raise InputError(
            f"{path}:1: header lacks {need} (expected participant,map,recording or "
            f"participant,map,demos; got {','.join(header)})"
        )
    for c in header:
        if c and header.count(c) > 1:
            raise InputError(f"{path}:1: column {c!r} appears twice")
    return header, {c: header.index(c) for c in (*REQUIRED, *SOURCES, *BAG_COLUMNS) if c in header}


def _bag_options(at: str, cell: dict[str, str], kind: str, source: Path) -> BagOptions | None:
    """The row's bag options (None for a row that is not a bag and fills no bag column)."""
    given = {c[len("bag_"):]: cell[c] for c in BAG_COLUMNS if cell.get(c)}
    if kind != "recording" or not is_bag(source):
        if given:
            what = "demos" if kind == "demos" else "a CSV recording"
            raise InputError(f"{at}: {', '.join('bag_' + c for c in given)} apply to a recording that is "
                             f"a ROS bag (.bag, .db3, .mcap or a ROS 2 bag folder), not to {what}")
        return None
    if "episode_gap" in given:
        try:
            given["episode_gap"] = float(given["episode_gap"])
        except ValueError:
            raise InputError(f"{at}: bag_episode_gap {given['episode_gap']!r} is not a number of "
                             "seconds") from None
    return BagOptions(**given, spelling="column")


def _source_kind(at: str, cell: dict[str, str]) -> str:
    """Which source the row gives (``recording`` or ``demos``), after checking its participant
    and map; messages start with ``at``."""
    pid = cell["participant"]
    if not pid:
        raise InputError(f"{at}: empty participant")
    if not PARTICIPANT_ID.fullmatch(pid):
        raise InputError(
            f"{at}: participant {pid!r} is not a valid ID (letters, digits, '.', '_', '-'; "
            "up to 64 characters, not starting with '.'; it names a folder)"
        )
    if not cell["map"]:
        raise InputError(f"{at}: empty map")
    given = [s for s in SOURCES if cell.get(s)]
    if len(given) != 1:
        raise InputError(
            f"{at}: give exactly one of recording or demos (got "
            f"{' and '.join(given) if given else 'neither'})"
        )
    return given[0]
