"""The ``plot`` command: a figure of any result JSON (and of the demonstrations behind it)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ._app import _load_mdp, _say, app, handles_errors


@app.command()
@handles_errors
def plot(
    result: Annotated[Path, typer.Argument(metavar="RESULT.json", help="Result JSON of infer or demo.")],
    out_path: Annotated[Path, typer.Option("--out", help="Output figure (.png, .pdf, .svg, ...).")],
    map_spec: Annotated[str | None, typer.Option(
        "--map", help="Map file or bundled name: draw it (with --demos) beside the posterior.")] = None,
    mdp_path: Annotated[Path | None, typer.Option(
        "--mdp", help="MDP archive (.npz) instead of --map; drawn from its state_xy.")] = None,
    demos: Annotated[Path | None, typer.Option(help="Demonstrations CSV to draw on the map.")] = None,
    check: Annotated[bool, typer.Option(
        "--check", help="Draw the result's misspecification checks instead: each predictive statistic's "
        "replicated values against the demonstrations', and (--check full results, with --map or --mdp) "
        "the map of where a per-state reward departs from θ̂·φ.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output if it exists.")] = False,
) -> None:
    """Draw a result: posterior of β and of each θ_i, the map with the demonstrations, and the belief after each action for --per-action results.

    Discrete results show the marginal probabilities as bars; birl and nuts show histograms of the draws with the 90% credible interval; map shows its point estimate.
    """  # noqa: E501  (one line per paragraph: the help text wraps it)
    from ..plots.results import render_result_png
    from ..results import check_features, check_writable, read_result

    inputs = [p for p in (result, mdp_path, demos) if p is not None]
    if map_spec is not None and Path(map_spec).exists():
        inputs.append(Path(map_spec))
    target = out_path.resolve()
    for p in inputs:
        if p.resolve() == target:
            raise InputError(f"{out_path}: is one of the inputs of this command; choose another --out")
    check_writable(out_path, force=force)
    _check_format(out_path)
    if demos is not None and map_spec is None and mdp_path is None:
        raise InputError(f"{demos}: --demos needs the task it was recorded on (--map or --mdp)")
    typed = read_result(result)
    mdp = zone_map = trajs = None
    if map_spec is not None or mdp_path is not None:
        mdp, zone_map = _load_mdp(map_spec, mdp_path, map_name="--map")
        check_features(typed, result, mdp, mdp_path if mdp_path is not None else map_spec)
        if zone_map is None and mdp.state_xy is None:
            raise InputError(f"{mdp_path}: the MDP has no grid coordinates (state_xy), so it cannot "
                             "be drawn; plot without --mdp/--demos")
        if demos is not None:
            from ..demos.csv_io import read_demos_csv

            trajs = read_demos_csv(demos, mdp)
    if check:
        from ..plots.check import render_check_png

        render_check_png(out_path, typed, mdp=mdp, trajs=trajs, source=result)
        _say(f"wrote {out_path}")
        return
    render_result_png(out_path, typed, source=result, mdp=mdp, zone_map=zone_map, trajs=trajs)
    _say(f"wrote {out_path}")


def _check_format(path: Path) -> None:
    from matplotlib.figure import Figure

    supported = Figure().canvas.get_supported_filetypes()
    ext = path.suffix.lower().lstrip(".")
    if not ext or ext not in supported:
        what = f".{ext}" if ext else "a file without a suffix"
        raise InputError(f"{path}: cannot write a figure as {what} "
                         f"(use one of: {', '.join(sorted(supported))})")
