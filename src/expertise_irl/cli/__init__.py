"""Command-line interface ``expertise-irl``.

``_app`` holds the typer application and what every command shares (one-line errors,
exit code 2, progress bars); each command group lives in its own module and registers
itself on import: ``core`` (demo, simulate, infer, export-mdp, render, maps), ``recordings``
(discretise, simulate-recordings), ``study`` (study), ``tune`` (tune).
"""

from __future__ import annotations

from . import core, experiment, live, models, plot, recordings, study, tune  # noqa: F401  (registers the commands)
from ._app import app, err, out


def main() -> None:
    """Console-script entry point."""
    app()


__all__ = ["app", "err", "main", "out"]
