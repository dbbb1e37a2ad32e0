"""Cartesian recordings → cells → demonstrations in a warehouse floor plan (paper Sec. VIII-A).

A recording is a CSV with columns ``episode,t,x,y`` (integer episode label, seconds,
metres; other columns are ignored; the samples of an episode are contiguous and in time
order), or a ROS bag whose positions on one topic give the same samples
(:mod:`.rosbag`). Coordinates follow the floor plan (:mod:`expertise_irl.worlds.warehouse`): x to
the right from the left edge, y down from the top edge (up from the bottom with
``y_up = true``).

:func:`discretise` applies these rules to each episode, in this order:

1. **Cells.** Every sample is mapped to the cell holding it. A sample outside the map or
   inside an obstacle is an error naming its row, or with ``snap`` is moved to the free
   cell whose centre is nearest (ties: the first in row-major order) and counted.
2. **Resampling.** Ticks ``t0 + k / rate`` for k = 0, 1, ..., K, where t0 is the episode's
   first sample and tick K the first at or after its last sample; at each tick the last
   sample at or before it is kept. A sample kept by several ticks counts once.
3. **Gaps.** Two consecutive kept samples whose cells are more than one cell apart (in
   either axis) or whose times are more than ``max_dt`` seconds apart (default two ticks,
   ``2 / rate``) are a gap: an error naming the file, episode and time, or with
   ``fill_gaps`` a shortest free path between the two cells (fewest turns among the
   shortest, never through a goal) is inserted, and the gap is counted.
4. **Moves.** Repeats of the same cell are dropped; a diagonal step is split into two moves,
   the first along the current heading (horizontal first when there is no heading yet),
   the other order when that corner cell is an obstacle or a goal, and a gap when both are.
5. **Headings.** Each state's heading is the axis of the move that entered it; the first
   state takes the axis of the episode's first move, so that move costs 1.
6. **Goals.** Entering a goal ends the episode (goals are terminal); the samples after it
   are ignored, and the kept ones outside the goal cell counted. An episode that starts in
   a goal or never leaves its first cell is an error.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, where
from ..mdp import ACTION_DELTAS
from ..worlds.grid import GOAL
from ..worlds.warehouse import ACTION_AXIS, HORIZONTAL, VERTICAL, WarehouseMap
from .csv_rows import parse_float, parse_int, read_rows
from .rosbag import BagOptions, is_bag, read_bag
from .trajectories import Trajectories, validate

RECORDING_COLUMNS = ("episode", "t", "x", "y")
DEFAULT_RATE = 1.0
#: Default ``max_dt``, in ticks: ``MAX_DT_TICKS / rate`` seconds.
MAX_DT_TICKS = 2.0
_EPS = 1e-9
#: Most ticks one episode may have (a day at 10 Hz), against a wrong time unit.
MAX_TICKS = 864_000


# --------------------------------------------------------------------------- reading
@dataclass(frozen=True, eq=False)
class Recording:
    """The samples of a recording, flat and in file order (all arrays ``[N]``).

    Attributes:
        episode: int64 episode label of each sample (samples of one episode contiguous).
        t: float64 time in seconds (non-decreasing within an episode).
        x, y: float64 position in metres.
        line: int64 file line of each sample (1 = header), for messages; in a bag, the
            number of its message on the topic (1 = first).
        source: file name (a bag's with ``:topic``), for messages.
    """

    episode: np.ndarray
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    line: np.ndarray
    source: str = "<recording>"

    @property
    def episode_ids(self) -> np.ndarray:
        """Episode labels in file order."""
        _, first = np.unique(self.episode, return_index=True)
        return self.episode[np.sort(first)]

    def rows_of(self, episode: int) -> np.ndarray:
        """Indices of the samples of one episode."""
        return np.flatnonzero(self.episode == episode)


def read_recording(path: str | Path, bag: BagOptions | None = None) -> Recording:
    """Read a recording: a ROS bag (``.bag``, ``.db3``, ``.mcap`` or a folder) with ``bag``'s
    options (:func:`.rosbag.read_bag`), or else a CSV (:func:`read_recording_csv`; ``bag``'s
    options, if any are set, are an error there)."""
    path = Path(path)
    bag = bag if bag is not None else BagOptions()
    if is_bag(path):
        s = read_bag(path, bag)
        return Recording(s.episode, s.t, s.x, s.y, s.message, source=f"{path}:{s.topic}")
    if bag.given():
        raise InputError(f"{path}: {', '.join(bag.given())} apply to a ROS bag (.bag, .db3, .mcap or a "
                         "ROS 2 bag folder), not to a CSV recording")
    return read_recording_csv(path)


def read_recording_csv(path: str | Path) -> Recording:
    """Read a recording CSV ``episode,t,x,y`` (columns by name, in any order; others ignored).

    Blank lines, whitespace around fields, a UTF-8 BOM and CRLF line ends are accepted.

    Raises
    ------
    InputError
        One line ``"<path>:<line>: [episode E t=T: ]<reason>"`` for a missing file or
        header column, a row with the wrong number of fields, an empty or non-numeric
        value, a time that goes backwards within an episode, or an episode whose samples
        are not contiguous.
    """
    path = Path(path)
    records = read_rows(path, kind="a recording CSV file", nothing="no samples")
    line, header = records[0]
    names = [h.lower() for h in header]
    missing = [c for c in RECORDING_COLUMNS if c not in names]
    if missing:
        raise InputError(f"{where(path, line)}expected a header with columns episode,t,x,y, got "
                         f"{','.join(header)!r} (missing column(s) {', '.join(missing)})")
    dup = [c for c in RECORDING_COLUMNS if names.count(c) > 1]
    if dup:
        raise InputError(f"{where(path, line)}column {dup[0]!r} appears more than once in the header")
    if len(records) == 1:
        raise InputError(f"{where(path, line)}no samples: the file has a header but no rows")
    pos = [names.index(c) for c in RECORDING_COLUMNS]
    n = len(records) - 1
    episode = np.empty(n, dtype=np.int64)
    values = np.empty((n, 3))
    lines = np.empty(n, dtype=np.int64)
    seen: set[int] = set()
    for r, (line, fields) in enumerate(records[1:]):
        prefix = where(path, line)
        if len(fields) != len(header):
            raise InputError(f"{prefix}row has {len(fields)} fields, expected {len(header)} "
                             f"({','.join(header)})")
        e = parse_int(fields[pos[0]], "episode", prefix, strict=True)
        prefix += f"episode {e}: "
        t, x, y = (parse_float(fields[i], c, prefix)
                   for i, c in zip(pos[1:], RECORDING_COLUMNS[1:], strict=True))
        if r > 0 and e == episode[r - 1]:
            if t < values[r - 1, 0]:
                raise InputError(f"{where(path, line)}episode {e} t={t:g}: time goes backwards (the "
                                 f"previous sample is at t={values[r - 1, 0]:g}); sort each "
                                 "episode's samples by t")
        elif e in seen:
            raise InputError(f"{where(path, line)}episode {e} appears again after other episodes; "
                             "the samples of one episode must be contiguous")
        seen.add(e)
        episode[r], values[r], lines[r] = e, (t, x, y), line
    return Recording(episode, values[:, 0], values[:, 1], values[:, 2], lines, source=str(path))


# ------------------------------------------------------------------------ discretising
@dataclass(frozen=True, eq=False)
class EpisodeCells:
    """How one episode of a recording became a path of cells.

    Attributes:
        episode: the episode label.
        samples_xy: ``[n, 2]`` float, every sample (metres), in time order.
        sample_cells: ``[n, 2]`` int (col, row) of each sample, after snapping.
        snapped: ``[n]`` bool, the sample was outside the map or in an obstacle and snapped.
        kept: ``[k]`` int, indices (into the samples) of the samples kept by the ticks.
        cells: ``[T, 2]`` int (col, row) of the visited cells, T >= 2.
        headings: ``[T]`` int heading of each visited state (0 = horizontal, 1 = vertical).
        filled: ``[T]`` bool, the cell was inserted to fill a gap.
        filled_gaps: number of gaps filled.
        reached_goal: the path ends in a goal.
        after_goal: kept samples ignored because they come after entering a goal and lie
            outside it (the robot drove on).
    """

    episode: int
    samples_xy: np.ndarray
    sample_cells: np.ndarray
    snapped: np.ndarray
    kept: np.ndarray
    cells: np.ndarray
    headings: np.ndarray
    filled: np.ndarray
    filled_gaps: int
    reached_goal: bool
    after_goal: int

    @property
    def snapped_samples(self) -> int:
        return int(self.snapped.sum())

    @property
    def moves(self) -> int:
        return int(len(self.cells) - 1)


@dataclass(frozen=True, eq=False)
class Discretised:
    """The demonstrations made from a recording, and what was done to make them.

    Attributes:
        trajectories: the (state, action) pairs, in the floor plan's MDP.
        episodes: one :class:`EpisodeCells` per episode, in file order.
        rate, max_dt, fill_gaps, snap: the settings used.
    """

    trajectories: Trajectories
    episodes: tuple[EpisodeCells, ...]
    rate: float
    max_dt: float
    fill_gaps: bool
    snap: bool

    @property
    def filled_gaps(self) -> int:
        return sum(e.filled_gaps for e in self.episodes)

    @property
    def snapped_samples(self) -> int:
        return sum(e.snapped_samples for e in self.episodes)

    def summary(self) -> dict:
        """Counts and settings, ready for a result file."""
        return {"episodes": len(self.episodes), "moves": len(self.trajectories),
                "filled_gaps": self.filled_gaps, "snapped_samples": self.snapped_samples,
                "samples_after_goal": sum(e.after_goal for e in self.episodes),
                "episodes_reaching_goal": sum(e.reached_goal for e in self.episodes),
                "rate": self.rate, "max_dt": self.max_dt, "fill_gaps": self.fill_gaps,
                "snap": self.snap}


def _snap(plan: WarehouseMap, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(col, row) of the free cell whose centre is nearest each point (ties: row-major first)."""
    free = plan.cells  # [C, 2] row-major
    cx, cy = plan.centre_of(free[:, 0], free[:, 1])
    d2 = (x[:, None] - cx[None, :]) ** 2 + (y[:, None] - cy[None, :]) ** 2
    best = np.argmin(d2, axis=1)  # first minimum = row-major first
    return free[best, 0], free[best, 1]


def shortest_free_path(plan: WarehouseMap, start: tuple[int, int], end: tuple[int, int],
                       heading: int | None) -> list[tuple[int, int]] | None:
    """Cells after ``start`` up to ``end`` on a shortest 4-connected path through passable cells
    that are not goals (``end`` may be one); among the shortest, the fewest turns given the
    current ``heading`` (None: none yet). None when ``end`` cannot be reached."""
    g = plan.grid
    H, W = g.shape
    # state (col, row, heading 0/1/2 = none); cost (moves, turns), then insertion order.
    best: dict[tuple[int, int, int], tuple[int, int]] = {}
    prev: dict[tuple[int, int, int], tuple[int, int, int] | None] = {}
    s0 = (start[0], start[1], 2 if heading is None else heading)
    heap = [(0, 0, 0, s0)]
    best[s0], prev[s0] = (0, 0), None
    counter = 1
    while heap:
        moves, turns, _, s = heapq.heappop(heap)
        if best.get(s) != (moves, turns):
            continue
        col, row, h = s
        if (col, row) == tuple(end):
            out = []
            while prev[s] is not None:
                out.append((s[0], s[1]))
                s = prev[s]
            return out[::-1]
        if (col, row) != tuple(start) and g[row, col] == GOAL:
            continue
        for a, (dx, dy) in enumerate(ACTION_DELTAS.tolist()):
            c2, r2 = col + dx, row + dy
            if not (0 <= c2 < W and 0 <= r2 < H) or not plan.passable[r2, c2]:
                continue
            axis = int(ACTION_AXIS[a])
            nxt = (c2, r2, axis)
            cost = (moves + 1, turns + int(h != 2 and h != axis))
            if nxt not in best or cost < best[nxt]:
                best[nxt], prev[nxt] = cost, s
                heapq.heappush(heap, (*cost, counter, nxt))
                counter += 1
    return None


class _Episode:
    """Builds the path of one episode (rules 4-6 of the module docstring)."""

    def __init__(self, plan: WarehouseMap, fill_gaps: bool):
        self.plan, self.fill_gaps = plan, fill_gaps
        self.cells: list[tuple[int, int]] = []
        self.filled: list[bool] = []
        self.heading: int | None = None
        self.filled_gaps = 0

    @property
    def done(self) -> bool:
        return bool(self.cells) and self.plan.grid[self.cells[-1][1], self.cells[-1][0]] == GOAL

    def add(self, cell: tuple[int, int], filled: bool = False) -> None:
        if self.cells:
            self.heading = HORIZONTAL if cell[0] != self.cells[-1][0] else VERTICAL
        self.cells.append(cell)
        self.filled.append(filled)

    def gap(self, reason: str, at: str) -> None:
        """Count a gap, or raise when gaps are not to be filled."""
        if not self.fill_gaps:
            raise InputError(f"{at}{reason} (fill_gaps / --fill-gaps fills it with a shortest free path)")
        self.filled_gaps += 1

    def fill(self, cell: tuple[int, int], reason: str, at: str) -> None:
        self.gap(reason, at)
        path = shortest_free_path(self.plan, self.cells[-1], cell, self.heading)
        if path is None:
            raise InputError(f"{at}{reason}, and no free path joins the two cells")
        for i, c in enumerate(path):
            self.add(c, filled=i < len(path) - 1)
            if self.done:
                break

    def step(self, cell: tuple[int, int], at: str) -> None:
        """Move to ``cell``, at most one cell away in each axis from the end of the path."""
        here = self.cells[-1]
        dx, dy = cell[0] - here[0], cell[1] - here[1]
        if dx == 0 and dy == 0:
            return
        if dx == 0 or dy == 0:
            self.add(cell)
            return
        horizontal_first = self.heading in (None, HORIZONTAL)
        corners = [(cell[0], here[1]), (here[0], cell[1])]  # horizontal first, vertical first
        if not horizontal_first:
            corners.reverse()
        g = self.plan.grid
        for corner in corners:
            if self.plan.passable[corner[1], corner[0]] and g[corner[1], corner[0]] != GOAL:
                self.add(corner)
                self.add(cell)
                return
        self.fill(cell, f"diagonal step from cell {here} to {cell} cuts a corner: both cells "
                  "between are obstacles or goals", at)


def _discretise_episode(rec: Recording, rows: np.ndarray, plan: WarehouseMap, rate: float,
                        max_dt: float, fill_gaps: bool, snap: bool) -> EpisodeCells:
    e = int(rec.episode[rows[0]])
    t, x, y, line = rec.t[rows], rec.x[rows], rec.y[rows], rec.line[rows]
    col, row = plan.cell_of(x, y)
    inside = (col >= 0) & (col < plan.width) & (row >= 0) & (row < plan.height)
    ok = inside.copy()
    ok[inside] = plan.passable[row[inside], col[inside]]
    if not ok.all() and not snap:
        i = int(np.flatnonzero(~ok)[0])
        what = (f"is outside the map (x 0..{plan.width * plan.cell_size:g} m, "
                f"y 0..{plan.height * plan.cell_size:g} m)" if not inside[i]
                else f"is inside an obstacle (cell {int(col[i])}, {int(row[i])})")
        raise InputError(f"{where(rec.source, int(line[i]))}episode {e} t={t[i]:g}: sample "
                         f"(x={x[i]:g}, y={y[i]:g}) {what} (snap / --snap moves it to the nearest "
                         "free cell)")
    if not ok.all():
        col, row = col.copy(), row.copy()
        col[~ok], row[~ok] = _snap(plan, x[~ok], y[~ok])

    def at(i: int) -> str:
        return f"{where(rec.source, int(line[i]))}episode {e} t={t[i]:g}: "

    tau = t - t[0]  # times from the episode's first sample: ticks are k / rate
    n_ticks = math.ceil(tau[-1] * rate - _EPS) + 1
    if n_ticks > MAX_TICKS:
        raise InputError(f"{at(len(t) - 1)}the episode lasts {tau[-1]:g} s, {n_ticks} ticks at "
                         f"{rate:g} Hz (more than {MAX_TICKS}); check the time unit (seconds)")
    ticks = np.arange(n_ticks) / rate
    picked = np.searchsorted(tau, ticks + _EPS * np.maximum(1.0, ticks), side="right") - 1
    kept = np.unique(picked)  # ticks are increasing, so this is their order

    first = int(kept[0])
    if plan.grid[row[first], col[first]] == GOAL:
        raise InputError(f"{at(first)}episode starts in a goal cell ({int(col[first])}, "
                         f"{int(row[first])}); an episode must start outside every goal")
    path = _Episode(plan, fill_gaps)
    path.add((int(col[first]), int(row[first])))
    after_goal = 0
    for j, (a, b) in enumerate(zip(kept[:-1].tolist(), kept[1:].tolist(), strict=True)):
        if path.done:
            later = kept[j + 1:]
            goal = path.cells[-1]
            after_goal = int(np.sum((col[later] != goal[0]) | (row[later] != goal[1])))
            break
        ca, cb = (int(col[a]), int(row[a])), (int(col[b]), int(row[b]))
        apart = max(abs(cb[0] - ca[0]), abs(cb[1] - ca[1]))
        dt = float(t[b] - t[a])
        if apart > 1:
            path.fill(cb, f"gap from cell {ca} at t={t[a]:g} to cell {cb}: {apart} cells apart "
                      f"after resampling at {rate:g} Hz", at(b))
            continue
        if dt > max_dt + _EPS:
            path.gap(f"gap of {dt:g} s since the previous kept sample at t={t[a]:g} "
                     f"(max_dt {max_dt:g} s)", at(b))
        path.step(cb, at(b))
    if len(path.cells) < 2:
        raise InputError(f"{where(rec.source, int(line[0]))}episode {e} t={t[0]:g}: the episode never "
                         f"leaves cell {path.cells[0]}; there is no move to learn from")
    cells = np.array(path.cells, dtype=np.int64)
    step = np.diff(cells, axis=0)
    axis = np.where(step[:, 0] != 0, HORIZONTAL, VERTICAL)
    return EpisodeCells(
        episode=e, samples_xy=np.stack([x, y], axis=1), sample_cells=np.stack([col, row], axis=1),
        snapped=~ok, kept=kept, cells=cells, headings=np.append(axis[:1], axis).astype(np.int64),
        filled=np.array(path.filled), filled_gaps=path.filled_gaps, reached_goal=path.done,
        after_goal=after_goal)


def discretise(recording: Recording, plan: WarehouseMap, *, rate: float = DEFAULT_RATE,
               max_dt: float | None = None, fill_gaps: bool = False, snap: bool = False) -> Discretised:
    """Turn a recording into demonstrations in ``plan`` (rules in the module docstring).

    Parameters
    ----------
    recording : Recording
        From :func:`read_recording`.
    plan : WarehouseMap
        The floor plan the recording was made in.
    rate : float
        Ticks per second (the paper's 1 Hz by default).
    max_dt : float, optional
        Longest time in seconds between two consecutive kept samples that is not a gap;
        default ``2 / rate``.
    fill_gaps : bool
        Fill gaps with a shortest free path (counted) instead of raising.
    snap : bool
        Move samples outside the map or inside obstacles to the nearest free cell (counted)
        instead of raising.

    Returns
    -------
    Discretised
        ``trajectories`` (valid in ``plan.to_mdp()``), per-episode details and the counts
        ``filled_gaps`` and ``snapped_samples``.
    """
    if isinstance(rate, bool) or not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
        raise InputError(f"rate must be a number of ticks per second > 0, got {rate!r}")
    if max_dt is None:
        max_dt = MAX_DT_TICKS / rate
    if isinstance(max_dt, bool) or not (isinstance(max_dt, int | float) and math.isfinite(max_dt)
                                        and max_dt > 0):
        raise InputError(f"max_dt must be a number of seconds > 0, got {max_dt!r}")
    mdp = plan.to_mdp()
    index = plan.state_index()
    episodes, parts = [], []
    for e in recording.episode_ids.tolist():
        ep = _discretise_episode(recording, recording.rows_of(e), plan, float(rate), float(max_dt),
                                 fill_gaps, snap)
        episodes.append(ep)
        c, h = ep.cells, ep.headings
        step = np.diff(c, axis=0)
        action = np.array([int(np.flatnonzero((ACTION_DELTAS == d).all(axis=1))[0]) for d in step])
        n = len(step)
        parts.append((np.full(n, e), np.arange(n), index[h[:-1], c[:-1, 1], c[:-1, 0]], action))
    ep_, st_, s_, a_ = (np.concatenate(p) for p in zip(*parts, strict=True))
    trajs = Trajectories(ep_, st_, s_, a_)
    validate(trajs, mdp, recording.source)
    return Discretised(trajs, tuple(episodes), float(rate), float(max_dt), bool(fill_gaps), bool(snap))


def discretise_recording(path: str | Path, plan: WarehouseMap, *, bag: BagOptions | None = None,
                         **options) -> Discretised:
    """:func:`read_recording` (a CSV, or a ROS bag read with ``bag``) then :func:`discretise`
    (same keyword options)."""
    return discretise(read_recording(path, bag), plan, **options)
