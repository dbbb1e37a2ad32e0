"""Demonstrations as CSV (formats in the README): the generic ``episode,step,state,action`` and
the grid ``episode,step,x,y`` (with an optional ``heading`` column in heading worlds)."""

from __future__ import annotations

import contextlib
import csv
import io
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from ..atomic import atomic_open
from ..errors import InputError, where
from ..mdp import ACTION_DELTAS, TabularMDP
from .csv_rows import parse_int, read_rows
from .trajectories import Trajectories, structure_error, validate, validate_rows

#: Header of the generic format: one row per (state, action) pair.
STATE_COLUMNS = ("episode", "step", "state", "action")
#: Header of the grid format: one row per visited cell, the final cell included.
GRID_COLUMNS = ("episode", "step", "x", "y")
#: Optional column of the grid format in heading worlds: ``h`` or ``v``, the state's heading.
HEADING_COLUMN = "heading"
_HEADING_LETTERS = ("h", "v")
_HEADERS = {"state": STATE_COLUMNS, "grid": GRID_COLUMNS}
_HEADER_HELP = "'episode,step,state,action' (generic MDP) or 'episode,step,x,y' (grid map)"
# _MOVE[dx + 1, dy + 1] = the action with that (dx, dy), -1 for anything else.
_MOVE = np.full((3, 3), -1, dtype=np.int64)
_MOVE[ACTION_DELTAS[:, 0] + 1, ACTION_DELTAS[:, 1] + 1] = np.arange(len(ACTION_DELTAS))


def _cell_index(mdp: TabularMDP) -> np.ndarray | None:
    """``[L, H, W]`` state of each (heading, cell) (-1: not a state), ``L`` = 2 in a heading
    world (``mdp.state_heading``), else 1; None if ``mdp`` is not a grid of that kind."""
    xy = mdp.state_xy
    if xy is None or mdp.n_actions != len(ACTION_DELTAS) or (xy < 0).any():
        return None
    heading = mdp.state_heading if mdp.state_heading is not None else np.zeros(mdp.n_states, np.int64)
    layers = 2 if mdp.state_heading is not None else 1
    idx = np.full((layers, int(xy[:, 1].max()) + 1, int(xy[:, 0].max()) + 1), -1, dtype=np.int64)
    idx[heading, xy[:, 1], xy[:, 0]] = np.arange(mdp.n_states)
    return idx if int((idx >= 0).sum()) == mdp.n_states else None  # one state per (heading, cell)


def _require_grid(mdp: TabularMDP, source) -> np.ndarray:
    idx = _cell_index(mdp)
    if idx is None:
        raise InputError(
            f"{where(source)}the grid format (episode,step,x,y) needs a grid map: 4 actions and "
            "one state per cell (per cell and heading in a heading world); use the generic "
            "format episode,step,state,action"
        )
    return idx


def write_demos_csv(path: str | Path, trajs: Trajectories, mdp: TabularMDP, *, fmt: str = "auto") -> None:
    """Write demonstrations as CSV (formats in the README); :func:`read_demos_csv` reads them back.

    Args:
        path: file to write (overwritten).
        trajs: ``[N]`` pairs, checked with :func:`validate` first.
        mdp: the task they belong to.
        fmt: ``"auto"``, ``"state"`` or ``"grid"``. ``"state"``: header
            ``episode,step,state,action``, one row per pair. ``"grid"``: header
            ``episode,step,x,y``, one row per visited cell including the cell the last action
            leads to (needs ``mdp.state_xy``, 4 actions, one state per cell); in a heading world
            (``mdp.state_heading``) one state per cell and heading, and a ``heading`` column
            (``h``/``v``) is added. ``"auto"``: grid when the MDP is such a grid and no move stays
            in its cell (a bump into a wall: x,y rows cannot say which way it went), else state.

    Raises:
        InputError: a pair is not valid in ``mdp``, there are no pairs, ``fmt`` is unknown, or
            ``"grid"`` was asked of an MDP or demonstrations that cannot be written as cells.
    """
    validate(trajs, mdp)
    if len(trajs) == 0:
        raise InputError(f"{where(path)}no demonstrations to write")
    fmt = _resolve_format(trajs, mdp, fmt, path)
    with atomic_open(path, "w", encoding="utf-8", newline="") as fh:
        out = csv.writer(fh, lineterminator="\n")
        out.writerow(_header(mdp, fmt))
        _write_rows(out, trajs, mdp, fmt)


def _header(mdp: TabularMDP, fmt: str) -> tuple[str, ...]:
    heading = fmt == "grid" and mdp.state_heading is not None
    return _HEADERS[fmt] + ((HEADING_COLUMN,) if heading else ())


def _resolve_format(trajs: Trajectories, mdp: TabularMDP, fmt: str, path) -> str:
    """``fmt`` checked against the demonstrations (``"auto"`` decided as :func:`write_demos_csv` says)."""
    if fmt not in ("auto", "state", "grid"):
        raise InputError(f"fmt must be 'auto', 'state' or 'grid', got {fmt!r}")
    ep, step, s, a = trajs.episode, trajs.step, trajs.state, trajs.action
    stays = (mdp.next_state[s, a] == s) if mdp.state_heading is None else np.zeros(len(s), dtype=bool)
    if fmt == "auto":
        fmt = "grid" if _cell_index(mdp) is not None and not stays.any() else "state"
    if fmt == "grid":
        _require_grid(mdp, path)
        if stays.any():
            i = int(np.argmax(stays))
            raise InputError(f"{where(path)}episode {int(ep[i])} step {int(step[i])}: the move stays in its "
                             "cell, which episode,step,x,y rows cannot say; write the state,action form")
    return fmt


def _write_rows(out, trajs: Trajectories, mdp: TabularMDP, fmt: str) -> None:
    """The rows of ``trajs`` in ``fmt`` (``"state"`` or ``"grid"``), whole episodes, to a csv writer."""
    ep, step, s, a = trajs.episode, trajs.step, trajs.state, trajs.action
    if fmt == "state":
        out.writerows(np.stack([ep, step, s, a], axis=1).tolist())
        return
    heading = mdp.state_heading
    xy = mdp.state_xy

    def cell(state: int) -> list:
        extra = [_HEADING_LETTERS[int(heading[state])]] if heading is not None else []
        return [*xy[state].tolist(), *extra]

    last = np.append(ep[1:] != ep[:-1], True)
    for i in range(len(trajs)):
        out.writerow([int(ep[i]), int(step[i]), *cell(s[i])])
        if last[i]:
            out.writerow([int(ep[i]), int(step[i]) + 1, *cell(mdp.next_state[s[i], a[i]])])


def stream_format(mdp: TabularMDP) -> str:
    """The format for demonstrations not yet made: ``"grid"`` when the MDP is such a grid and no
    available move stays in its cell (so no episode can need the state form), else ``"state"``."""
    if _cell_index(mdp) is None:
        return "state"
    if mdp.state_heading is not None:
        return "grid"
    return "state" if (mdp.next_state == np.arange(mdp.n_states)[:, None]).any() else "grid"


@contextlib.contextmanager
def demos_csv_stream(path: str | Path, mdp: TabularMDP, *, fmt: str = "auto") -> Iterator[Callable]:
    """Write demonstrations batch by batch: yields ``write(trajs)``, to be called with whole episodes
    in order; the file is written atomically (nothing at ``path`` until the block ends without an
    error). ``fmt`` as in :func:`write_demos_csv` (``"auto"`` is decided on the first batch); returns
    after writing at least one pair, else raises :class:`InputError`. ``write`` returns the bytes so far."""
    state = {"fmt": fmt, "pairs": 0}
    with atomic_open(path, "w", encoding="utf-8", newline="") as fh:
        out = csv.writer(fh, lineterminator="\n")

        def write(trajs: Trajectories) -> int:
            validate(trajs, mdp)
            if len(trajs):
                first = state["pairs"] == 0
                state["fmt"] = _resolve_format(trajs, mdp, state["fmt"], path)
                if first:
                    out.writerow(_header(mdp, state["fmt"]))
                _write_rows(out, trajs, mdp, state["fmt"])
                state["pairs"] += len(trajs)
            return fh.tell()

        yield write
        if state["pairs"] == 0:
            raise InputError(f"{where(path)}no demonstrations to write")


def csv_bytes(trajs: Trajectories, mdp: TabularMDP, fmt: str) -> int:
    """The bytes the rows of ``trajs`` take in ``fmt`` (no header): to estimate a file's size."""
    buf = io.StringIO()
    _write_rows(csv.writer(buf, lineterminator="\n"), trajs, mdp, fmt)
    return len(buf.getvalue().encode("utf-8"))


def _read_rows(path: str | Path, heading: bool = False) -> tuple[str, np.ndarray, np.ndarray,
                                                                  np.ndarray | None]:
    """Format name, ``[n, 4]`` int values, ``[n]`` line numbers of the data rows, and with
    ``heading`` the ``[n]`` headings (0 = h, 1 = v) of a grid file's ``heading`` column
    (None when the file has none)."""
    records = read_rows(path, kind="a demonstrations CSV file", nothing="no demonstrations")
    line, header = records[0]
    names = [h.lower() for h in header]
    # Columns are found by name, in any order; other columns (a timestamp, say) are ignored.
    fmt = next((k for k, cols in _HEADERS.items() if set(cols) <= set(names)), None)
    if fmt is None:
        got = ",".join(header)
        if all(h.lstrip("-").isdigit() for h in header):
            raise InputError(f"{where(path, line)}missing header row: expected {_HEADER_HELP}, got {got!r}")
        cols = min(_HEADERS.values(), key=lambda c: len(set(c) - set(names)))
        missing = [c for c in cols if c not in names]
        raise InputError(
            f"{where(path, line)}expected header {_HEADER_HELP}, got {got!r} "
            f"(missing column(s) {', '.join(missing)})"
        )
    cols = _HEADERS[fmt]
    dup = [c for c in cols if names.count(c) > 1]
    if dup:
        raise InputError(f"{where(path, line)}column {dup[0]!r} appears more than once in the header")
    pos = [names.index(c) for c in cols]
    if len(records) == 1:
        raise InputError(f"{where(path, line)}no demonstrations: the file has a header but no rows")
    values = np.empty((len(records) - 1, 4), dtype=np.int64)
    lines = np.empty(len(records) - 1, dtype=np.int64)
    hpos = names.index(HEADING_COLUMN) if heading and fmt == "grid" and HEADING_COLUMN in names else None
    if hpos is not None and names.count(HEADING_COLUMN) > 1:
        raise InputError(f"{where(path, line)}column {HEADING_COLUMN!r} appears more than once in the header")
    headings = np.empty(len(records) - 1, dtype=np.int64) if hpos is not None else None
    for r, (line, fields) in enumerate(records[1:]):
        prefix = where(path, line)
        if len(fields) != len(header):
            raise InputError(
                f"{prefix}row has {len(fields)} fields, expected {len(header)} ({','.join(header)})"
            )
        values[r] = [parse_int(fields[i], c, prefix) for i, c in zip(pos, cols, strict=True)]
        lines[r] = line
        if headings is not None:
            letter = fields[hpos].lower()
            if letter not in _HEADING_LETTERS:
                raise InputError(f"{prefix}episode {values[r, 0]} step {values[r, 1]}: column "
                                 f"'{HEADING_COLUMN}': {fields[hpos]!r} is not h (horizontal) or "
                                 "v (vertical)")
            headings[r] = _HEADING_LETTERS.index(letter)
    err = structure_error(values[:, 0], values[:, 1])
    if err is not None:
        i, msg = err
        raise InputError(f"{where(path, lines[i])}episode {values[i, 0]} step {values[i, 1]}: {msg}")
    return fmt, values, lines, headings


def read_demos_csv(path: str | Path, mdp: TabularMDP) -> Trajectories:
    """Read demonstrations from CSV, detecting the format from the header (formats in the README).

    ``episode,step,state,action`` gives one (state, action) pair per row;
    ``episode,step,x,y`` gives one visited cell per row (the final cell included,
    at least 2 cells per episode) and each action is the move between consecutive
    cells. In a heading world (``mdp.state_heading``, e.g. a warehouse floor plan) an
    optional ``heading`` column (``h``/``v``) gives each state's heading; without it, a
    state's heading is the axis of the move that entered it and an episode's first state
    takes the axis of its first move. Rows of one episode must be contiguous, steps 0, 1,
    2, ...; episodes keep their labels and file order. Blank lines, whitespace around fields, a UTF-8 BOM
    and CRLF line ends are accepted.

    Args:
        path: the CSV file.
        mdp: the task; every pair is checked with the rules of :func:`validate`.

    Returns:
        ``[N]`` pairs.

    Raises:
        InputError: one line ``"<path>:<line>: [episode E step T: ]<reason>"`` (line 1 = header).
    """
    fmt, v, lines, given_heading = _read_rows(path, heading=mdp.state_heading is not None)
    ep, step = v[:, 0], v[:, 1]
    if fmt == "state":
        trajs = Trajectories(ep, step, v[:, 2], v[:, 3])
        validate_rows(trajs, mdp, path, lines)
        return trajs
    return _grid_pairs(path, mdp, v, lines, given_heading)


def _grid_pairs(path: str | Path, mdp: TabularMDP, v: np.ndarray, lines: np.ndarray,
                given_heading: np.ndarray | None) -> Trajectories:
    """The pairs of a grid file's rows ``v`` (episode, step, x, y): each row's state, checked,
    and the move to the next row of its episode."""
    ep, step = v[:, 0], v[:, 1]
    idx = _require_grid(mdp, path)
    _, H, W = idx.shape
    x, y = v[:, 2], v[:, 3]
    inside = (x >= 0) & (x < W) & (y >= 0) & (y < H)
    same = np.zeros(ep.size, dtype=bool)
    same[1:] = ep[1:] == ep[:-1]
    last = ~np.append(same[1:], False)
    dx = np.diff(x, prepend=0)
    dy = np.diff(y, prepend=0)
    dist = np.abs(dx) + np.abs(dy)
    xc, yc = np.clip(x, 0, W - 1), np.clip(y, 0, H - 1)
    wrong_heading = np.zeros(ep.size, dtype=bool)
    if mdp.state_heading is None:
        heading = np.zeros(ep.size, dtype=np.int64)
    else:  # heading of the move into each row; an episode's first row takes its first move's
        moved = np.where(dx != 0, 0, 1)
        heading = np.where(same, moved, np.append(moved[1:], 0))
        if given_heading is not None:
            wrong_heading = same & (dist == 1) & (given_heading != heading)
            heading = given_heading
    state = np.where(inside, idx[heading, yc, xc], -1)
    is_cell = inside & (idx.max(axis=0)[yc, xc] >= 0)
    checks = (
        (~inside, lambda i: f"cell (x={x[i]}, y={y[i]}) is outside the map (x 0..{W - 1}, y 0..{H - 1})"),
        (~is_cell, lambda i: f"cell (x={x[i]}, y={y[i]}) is an obstacle (not a state of the map)"),
        (is_cell & (state < 0), lambda i: (
            f"cell (x={x[i]}, y={y[i]}) with heading {_HEADING_LETTERS[heading[i]]} is not a state "
            "of the map")),
        (same & (dist == 0), lambda i: f"cell (x={x[i]}, y={y[i]}) repeats the previous cell (a zero move; "
                                       "a move that stays in place, e.g. into a wall, needs the "
                                       "episode,step,state,action form)"),
        (same & (dist > 1), lambda i: (
            f"jumps from ({x[i - 1]},{y[i - 1]}) to ({x[i]},{y[i]}); consecutive cells must be "
            "adjacent (one move up, down, left or right)")),
        (~same & last, lambda i: "episode has a single cell; the grid format needs at least 2 cells"),
        (wrong_heading, lambda i: (
            f"heading {_HEADING_LETTERS[given_heading[i]]} at cell (x={x[i]}, y={y[i]}) does not "
            f"match the {('horizontal', 'vertical')[1 - given_heading[i]]} move into it: a move "
            f"leaves the heading on its own axis ({_HEADING_LETTERS[1 - given_heading[i]]})")),
    )
    bad = np.logical_or.reduce([m for m, _ in checks])
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        msg = next(describe(i) for m, describe in checks if m[i])
        raise InputError(f"{where(path, lines[i])}episode {ep[i]} step {step[i]}: {msg}")
    j = np.flatnonzero(~last)  # rows that have a next cell: one pair each
    action = _MOVE[dx[j + 1] + 1, dy[j + 1] + 1]
    trajs = Trajectories(ep[j], step[j], state[j], action)
    # A pair is reported at the row of the cell its action moves to.
    validate_rows(trajs, mdp, path, lines[j + 1], step[j + 1], source_lines=lines[j])
    return trajs
