"""``expertise-irl tune``: the solver's lane width on this machine, and how it was chosen."""

from __future__ import annotations

from typing import Annotated

import typer

from ..errors import InputError
from ._app import _note, _say, app, handles_errors

_SOURCES = {
    "environment": "set by {env}",
    "cache": "measured on {when}, read from the cache",
    "measured": "measured just now, cached",
    "uncached": "measured just now, but {file} could not be written, so every process measures again; "
                "set {env}=N to skip that",
    "default": "the built-in default: this backend has no candidates to measure",
}


@app.command()
@handles_errors
def tune(
    again: Annotated[bool, typer.Option(
        "--again", help="Measure again, replacing the cached choice.")] = False,
    dtype: Annotated[str, typer.Option(
        "--dtype", help="float64 (what every command solves in) or float32.")] = "float64",
) -> None:
    """The solver's lane width on this machine: each candidate's measured throughput and the choice.

    It is measured at first use (a few seconds) and cached per machine and JAX version;
    EXPERTISE_IRL_LANES=N overrides it.
    """
    from ..planning.tuning import LANES_ENV, lane_choice, machine_key, tuning_file

    if dtype not in ("float64", "float32"):
        raise InputError(f"--dtype must be float64 or float32, got {dtype!r}")
    choice = lane_choice(dtype, again=again)
    if again and choice.source == "environment":
        _note(f"{LANES_ENV} is set, so nothing was measured")
    _say(f"machine: {machine_key(dtype)}")
    how = _SOURCES[choice.source].format(env=LANES_ENV, when=choice.measured, file=tuning_file())
    _say(f"lane width: {choice.lanes} ({how})")
    for lanes, rate in sorted(choice.backups_per_s.items()):
        mark = "  <- chosen" if lanes == choice.lanes else ""
        _say(f"  {lanes:>4} lanes: {rate / 1e6:,.0f} M backups/s{mark}")
    _say(f"cache: {tuning_file()}")
