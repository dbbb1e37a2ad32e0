"""The package's exceptions share one base; the command line tells the user's mistakes (exit 2)
from the package's own bugs (a traceback)."""

from __future__ import annotations

import pytest
import typer

from expertise_irl.cli._app import handles_errors
from expertise_irl.errors import ArgumentError, ConvergenceError, ExpertiseIRLError, InputError


def test_every_error_of_the_package_has_one_base():
    for cls in (InputError, ConvergenceError, ArgumentError):
        assert issubclass(cls, ExpertiseIRLError)
    assert issubclass(InputError, ValueError) and issubclass(ArgumentError, ValueError)
    assert issubclass(ConvergenceError, RuntimeError)
    assert not issubclass(ArgumentError, InputError)  # a bug is not the user's input


def _raising(exc):
    @handles_errors
    def command():
        raise exc

    return command


@pytest.mark.parametrize(("exc", "code"), [(InputError("a.csv:3: bad"), 2), (ConvergenceError("slow"), 1)])
def test_the_command_line_shows_the_users_problems_as_one_line(exc, code, capsys):
    with pytest.raises(typer.Exit) as done:
        _raising(exc)()
    assert done.value.exit_code == code
    assert str(exc) in capsys.readouterr().err


def test_a_programming_error_reaches_the_command_line_as_a_bug():
    with pytest.raises(ArgumentError, match="shape"):
        _raising(ArgumentError("counts must have shape [S, A]"))()
