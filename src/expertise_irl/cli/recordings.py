"""The ``discretise`` command: a Cartesian recording → demonstrations CSV and a PNG to inspect."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ._app import _map_files, _note, _say, app, handles_errors

#: Options shared with the commands that ingest recordings.
RateOption = Annotated[float, typer.Option(
    "--rate", help="Ticks per second: at each tick t0 + k/rate the last sample at or before it is "
    "kept (the paper's 1 Hz).")]
MaxDtOption = Annotated[float | None, typer.Option(
    "--max-dt", help="Seconds between two consecutive kept samples beyond which they are a gap "
    "(default: 2/rate).")]
FillGapsOption = Annotated[bool, typer.Option(
    "--fill-gaps", help="Fill gaps with a shortest free path (counted) instead of stopping with an error.")]
SnapOption = Annotated[bool, typer.Option(
    "--snap", help="Move samples outside the map or inside obstacles to the nearest free cell "
    "(counted) instead of stopping with an error.")]


def load_floor_plan_arg(map_spec: str):
    """The floor plan a MAP argument names; a zone map is refused with the reason."""
    from ..worlds.maps import resolve_world
    from ..worlds.warehouse import WarehouseMap

    plan = resolve_world(map_spec)
    if not isinstance(plan, WarehouseMap):
        raise InputError(f"{map_spec}: is a zone map; recordings need a warehouse floor plan "
                         "(a TOML beside it with world = \"warehouse\" and cell_size)")
    return plan


@app.command()
@handles_errors
def discretise(
    map_spec: Annotated[str, typer.Argument(
        metavar="MAP", help="Warehouse floor plan (.txt with its TOML).")],
    recording: Annotated[Path, typer.Option(help="Recording CSV: episode,t,x,y (seconds, metres).")],
    out_path: Annotated[Path, typer.Option(
        "--out", help="Output demonstrations CSV (episode,step,x,y,heading).")],
    png: Annotated[Path | None, typer.Option(
        help="Figure of the samples against the cells (default: --out with .png).")] = None,
    rate: RateOption = 1.0,
    max_dt: MaxDtOption = None,
    fill_gaps: FillGapsOption = False,
    snap: SnapOption = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the outputs if they exist.")] = False,
) -> None:
    """Turn a Cartesian recording into demonstrations on a floor plan, and draw what was done.

    Samples are mapped to cells, resampled at --rate, repeats dropped, diagonal steps split,
    and each state's heading set from the move into it (docs/user-studies.md). Gaps and
    samples off the free cells stop with an error unless --fill-gaps / --snap; what they
    changed is counted and printed.
    """
    from ..demos import write_demos_csv
    from ..recordings import discretise_recording
    from ..results import check_writable
    from ..worlds.warehouse_render import render_discretised_png
    from .core import _check_figure_format

    png = png if png is not None else out_path.with_suffix(".png")
    inputs = [*_map_files(map_spec), recording]
    for p in (out_path, png):
        check_writable(p, force=force, inputs=inputs)
    if png.resolve() == out_path.resolve():
        raise InputError(f"{png}: the figure and the demonstrations would be the same file")
    _check_figure_format(png)
    plan = load_floor_plan_arg(map_spec)
    result = discretise_recording(recording, plan, rate=rate, max_dt=max_dt, fill_gaps=fill_gaps,
                                  snap=snap)
    write_demos_csv(out_path, result.trajectories, plan.to_mdp(), fmt="grid")
    render_discretised_png(png, plan, result, title=f"{recording} on {plan.name}")
    for ep in result.episodes:
        end = "reached a goal" if ep.reached_goal else "ended before a goal"
        _say(f"episode {ep.episode}: {len(ep.samples_xy)} samples, {len(ep.kept)} kept at "
             f"{result.rate:g} Hz, {ep.moves} moves, {end}; filled gaps {ep.filled_gaps}, "
             f"snapped samples {ep.snapped_samples}")
        if ep.after_goal:
            _note(f"episode {ep.episode}: the robot drove on after entering a goal; "
                  f"{ep.after_goal} kept samples after it ignored (a goal ends the episode)")
    _say(f"wrote {out_path} and {png}: {len(result.episodes)} episodes, {len(result.trajectories)} moves; "
         f"filled gaps {result.filled_gaps}, snapped samples {result.snapped_samples}")
