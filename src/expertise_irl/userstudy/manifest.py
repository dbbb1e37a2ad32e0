"""A study's manifest: who did which task, on which floor plan, recorded where.

A manifest is a CSV with a header and the columns ``participant``, ``map`` and
``recording`` (a Cartesian recording ``episode,t,x,y``) or ``demos`` (the project's
demonstration CSV, ``episode,step,x,y[,heading]`` or ``episode,step,state,action``); a
manifest may hold both columns, and each row then fills exactly one. Paths are relative to
the manifest's folder. Several rows of one participant are several tasks (maps,
specifications or start points); participants keep the order of their first row. Other
columns are ignored.

Every problem is an :class:`~expertise_irl.errors.InputError` naming the manifest and
line (``study.csv:4: ...``), including those found in the files a row names.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

from ..demos.csv_io import read_demos_csv
from ..demos.recordings import Discretised, discretise_recording
from ..demos.trajectories import Trajectories
from ..errors import InputError, read_text
from ..worlds.warehouse import WarehouseMap, load_floor_plan

REQUIRED = ("participant", "map")
SOURCES = ("recording", "demos")
#: A participant ID names a folder: letters, digits, ``.``, ``_``, ``-``; not starting with ``.``.
PARTICIPANT_ID = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}")


@dataclass(frozen=True, eq=False)
class StudyTask:
    """One manifest row, loaded.

    Attributes:
        index: the row's position among the manifest's rows (0-based).
        line: its line in the manifest (the header is line 1).
        participant: the participant ID.
        map_path, plan: the floor plan.
        kind: ``"recording"`` or ``"demos"``.
        source: the recording or demonstrations file.
        trajectories: the demonstrations on ``plan.to_mdp()``.
        discretised: how a recording became demonstrations (``None`` for demos).
    """

    index: int
    line: int
    participant: str
    map_path: Path
    plan: WarehouseMap
    kind: str
    source: Path
    trajectories: Trajectories
    discretised: Discretised | None

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

    @property
    def participants(self) -> list[str]:
        """Participant IDs in the order of their first row."""
        return list(dict.fromkeys(t.participant for t in self.tasks))

    def tasks_of(self, participant: str) -> list[StudyTask]:
        return [t for t in self.tasks if t.participant == participant]


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
    plans: dict[Path, WarehouseMap] = {}
    tasks: list[StudyTask] = []
    for line, row in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in row):
            continue  # blank line
        at = f"{path}:{line}"
        if len(row) > len(header):
            raise InputError(f"{at}: {len(row)} fields but the header has {len(header)}")
        cell = {c: (row[i].strip() if i < len(row) else "") for c, i in col.items()}
        kind = _source_kind(at, cell)
        map_path = base / cell["map"]
        source = base / cell[kind]
        if not map_path.is_file():
            raise InputError(f"{at}: map {cell['map']}: no such file ({map_path})")
        if not source.is_file():
            raise InputError(f"{at}: {kind} {cell[kind]}: no such file ({source})")
        try:
            key = map_path.resolve()
            if key not in plans:
                plans[key] = load_floor_plan(map_path)
            plan = plans[key]
            if kind == "recording":
                disc = discretise_recording(
                    source, plan, rate=rate, max_dt=max_dt, fill_gaps=fill_gaps, snap=snap
                )
                trajs = disc.trajectories
            else:
                disc = None
                trajs = read_demos_csv(source, plan.to_mdp())
        except InputError as exc:
            raise InputError(f"{at}: {exc}") from None
        if len(trajs) == 0:
            raise InputError(f"{at}: {kind} {cell[kind]} holds no moves")
        tasks.append(StudyTask(len(tasks), line, cell["participant"], map_path, plan, kind, source, trajs,
                               disc))
    if not tasks:
        raise InputError(f"{path}: the manifest has a header but no rows")
    return Manifest(path, tuple(tasks))


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
    for c in (*REQUIRED, *SOURCES):
        if header.count(c) > 1:
            raise InputError(f"{path}:1: column {c!r} appears twice")
    return header, {c: header.index(c) for c in (*REQUIRED, *SOURCES) if c in header}


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
