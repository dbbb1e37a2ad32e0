"""The typer application and what every command group shares.

Every problem with the user's input is reported as one line on stderr,
``error: <file>:<line>: <what is wrong>``, with exit code 2 and no traceback.
Existing output files are never overwritten unless ``--force`` is given.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from typer.core import TyperArgument, TyperGroup, TyperOption

from .. import __version__
from ..errors import ConvergenceError, InputError, os_reason, plural
from ..numerics import enable_float64
from ..options import OptionError, flag


class _OneLineErrors(TyperGroup):
    """Report command-line parsing errors (bad option values, missing options) as one line.

    Click's default is a multi-line usage panel; our contract is ``error: ...`` and exit 2.
    """

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        enable_float64()  # before JAX is imported, only the environment variable JAX reads
        try:
            with _sigterm_interrupts():
                rv = super().main(args=args, prog_name=prog_name, complete_var=complete_var,
                                  standalone_mode=False, **extra)
        except Exception as exc:
            if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):  # click's UsageError & co.
                message = _no_such_option(exc) or exc.format_message()
                if message:  # empty when help was shown for a bare command
                    _print_error(f"{message} (see --help)")
                sys.exit(exc.exit_code)
            if type(exc).__name__ == "Abort":  # click's word for Ctrl-C (and SIGTERM) outside a command
                stopped = exc.__context__
                if isinstance(stopped, KeyboardInterrupt):
                    _print_error(_stop_message(stopped))
                    sys.exit(_stop_code(stopped))
                _print_error("aborted")
                sys.exit(1)
            raise
        if not standalone_mode:
            return rv
        sys.exit(rv if isinstance(rv, int) else 0)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C's KeyboardInterrupt: the command stops the same
    way (temporary files removed, nothing partial at an output path), with exit code 143."""


def _stop_code(exc: KeyboardInterrupt) -> int:
    return 143 if isinstance(exc, Terminated) else 130


def _stop_message(exc: KeyboardInterrupt) -> str:
    return "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"


@contextlib.contextmanager
def _sigterm_interrupts():
    """While a command runs (in the main thread), SIGTERM raises :class:`Terminated`. A child process
    that inherited the handler by fork ends as SIGTERM would end it, without the exception."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pid = os.getpid()

    def handler(signum, frame):
        if os.getpid() != pid:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        raise Terminated()

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _no_such_option(exc) -> str | None:
    """An unknown option, with a suggestion only when one is close once the dashes are set aside
    (click compares with them, so ``--bogus`` is "close" to ``--out``); None for other errors."""
    import difflib

    name, possible = getattr(exc, "option_name", None), getattr(exc, "possibilities", None)
    if type(exc).__name__ != "NoSuchOption" or not name or not name.startswith("--"):
        return None
    bare = {p.lstrip("-"): p for p in possible or () if p.startswith("--")}
    close = difflib.get_close_matches(name.lstrip("-"), list(bare), n=3, cutoff=0.6)
    hint = f" (did you mean {' or '.join(bare[c] for c in close)}?)" if close else ""
    return f"no such option: {name}{hint}"


def _flag_has_no_type(self, ctx):
    """Flags take no value: show none (typer's rich help prints ``<bool>`` for them)."""
    return None if getattr(self, "is_flag", False) else _display_type_rich(self, ctx)


_display_type_rich = TyperOption.display_type_rich
TyperOption.display_type_rich = _flag_has_no_type


def _usage_name(self) -> str:
    """An argument on the usage line as click writes it: ``MAP`` when required, ``[MAP]`` when not
    (typer writes ``{MAP}`` for a required one)."""
    name = self.display_name_raw if self.metavar is not None else self.name.upper()
    name = name if self.required else f"[{name}]"
    return name + ("..." if self.nargs != 1 else "")


TyperArgument._usage_display_name = _usage_name

app = typer.Typer(
    name="expertise-irl",
    cls=_OneLineErrors,
    help="Infer what a person wants (reward weights θ) and how expert they are (temperature β) "
    "from demonstrations.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
out = Console()
err = Console(stderr=True)


def _say(message: str) -> None:
    """Print plain text (no rich markup: θ vectors in brackets must print as they are)."""
    out.print(message, markup=False, highlight=False, soft_wrap=True)


def prepare_solver(*, measure: bool = True) -> None:
    """Before a command solves: JAX's persistent cache on and, with ``measure``, on a machine's
    first use the solver's lane width measured, with a note on stderr saying why there is a
    pause (commands whose solves run elsewhere or on one hypothesis pass ``measure=False``)."""
    from ..planning.jax_cache import enable_jax_cache
    from ..planning.tuning import is_settled, lane_choice

    enable_jax_cache()
    if measure and not is_settled("float64"):
        _note("measuring the solver's lane width for this machine (once; see `expertise-irl tune`)")
        lane_choice("float64")


def _print_error(message: str) -> None:
    err.print("[bold red]error:[/] ", end="", highlight=False)
    err.print(message, markup=False, highlight=False, soft_wrap=True)


def _fail(message: str, code: int = 2) -> None:
    _print_error(message)
    raise typer.Exit(code)


def handles_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn input problems into a one-line message and exit code 2 (no traceback)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except OptionError as exc:  # the library names the field; the command line, its flag
            _fail(exc.message(flag))
        except InputError as exc:
            _fail(str(exc))
        except ConvergenceError as exc:
            _fail(str(exc), code=1)
        except OSError as exc:  # a file we were asked to read or write cannot be
            _fail(f"{exc.filename or 'file'}: {os_reason(exc)}")
        except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Terminated)
            _fail(_stop_message(exc), code=_stop_code(exc))

    return wrapper


class QuietProgress(Progress):
    """A progress display that appears with its first task: a command that fails before any work
    starts leaves nothing on stderr above its error (not even an empty line)."""

    def __enter__(self) -> QuietProgress:
        return self

    def add_task(self, *args, **kwargs):
        if not self.live.is_started:
            self.start()
        return super().add_task(*args, **kwargs)

    def __exit__(self, exc_type, exc_val, exc_tb) -> None:
        if self.live.is_started:
            self.stop()


def _progress(unit: str = "hypotheses") -> Progress:
    return QuietProgress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        TextColumn(f"{{task.completed}}/{{task.total}} {unit}"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
        console=err,
    )


def _solve_progress(bar: Progress, description: str) -> Callable[[int, int], None]:
    task = bar.add_task(description, total=None)

    def update(done: int, total: int) -> None:
        bar.update(task, completed=done, total=total)

    return update


def _map_files(map_spec: str | None) -> list[Path]:
    """The files a MAP argument reads: the map and the settings TOML beside it (none if bundled)."""
    if map_spec is None or not Path(map_spec).is_file():
        return []
    return [Path(map_spec), Path(map_spec).with_suffix(".toml")]


#: ``--model``: the observation model (see expertise_irl.models), shared by every command.
ModelOption = Annotated[str, typer.Option(
    "--model", help="Observation model: maxent (the paper's; random behaviour earns an entropy "
    "bonus, so noisy people wander), maxent-relative (entropy relative to a uniform choice: "
    "noisy people still head for the goal), boltzmann (softmax of the optimal Q-values) or "
    "pedagogical (maxent reweighted by what each action shows a literal observer of a fixed "
    "hypothesis set, with a teaching weight λ: infer, study, compare-models and live on a discrete "
    "fixed set with --lambdas, simulate with --lambda; a command that solves a model's Bellman backup "
    "refuses it).")]


def _check_model(model: str) -> str:
    from ..models import check_model

    return check_model(model)


def _report_capped(trajs, mdp, max_steps: int, model: str) -> int:
    """Say how many episodes ran to the step cap; warn when most did, and why."""
    from ..demos.simulation import capped_episodes

    return _say_capped(capped_episodes(trajs, mdp, max_steps), trajs.n_episodes, max_steps, model)


def _say_capped(n: int, total: int, max_steps: int, model: str) -> int:
    """:func:`_report_capped` from the counts: ``n`` of ``total`` episodes hit the cap."""
    if n:
        _note(f"{n} of {plural(total, 'episode')} hit the {max_steps}-step cap without reaching a goal")
    if total and n > total / 2:
        why = ("under the maxent model the entropy bonus pays a person whose β is large next to "
               "their weights to keep moving rather than finish; --model maxent-relative removes "
               "that pay" if model == "maxent" else "the person is too noisy for this map and cap")
        _warn(f"most episodes ({n} of {total}) never reached a goal: {why}")
    return n


def _warn(message: str) -> None:
    """A warning on stderr (one line per warning)."""
    err.print("[bold yellow]warning:[/] ", end="", highlight=False)
    err.print(message, markup=False, highlight=False, soft_wrap=True)


def _note(message: str) -> None:
    """A note on stderr: information about the run, not part of its result."""
    err.print(f"note: {message}", markup=False, highlight=False, soft_wrap=True)


GoalRewardOption = Annotated[str | None, typer.Option(
    "--goal-reward", metavar="MODE",
    help="How the goal pays: scaled (goal_bonus is part of the length feature, weighted by "
    "θ_length, so it vanishes with it) or fixed (goal_bonus paid outside θ·φ, the same for every "
    "θ: everyone is drawn to the goal). Default: the map TOML's goal_reward_mode, else scaled.")]


def with_goal_reward(zone_map, goal_reward: str | None):
    """``zone_map`` with ``--goal-reward`` applied when given (a copy; the map is frozen)."""
    import dataclasses

    from ..worlds.grid import check_goal_reward_mode

    if goal_reward is None:
        return zone_map
    mode = check_goal_reward_mode(goal_reward, "--goal-reward")
    return dataclasses.replace(zone_map, goal_reward_mode=mode)


def load_map(map_spec: str, goal_reward: str | None = None):
    """The map of either world named by ``map_spec``, with ``--goal-reward`` applied when given."""
    from ..worlds.maps import resolve_world

    return with_goal_reward(resolve_world(map_spec), goal_reward)


def goal_reward_mode_of(mdp, zone_map) -> str:
    """The map's goal reward mode; for an MDP archive, ``fixed`` if it holds a reward outside θ·φ."""
    if zone_map is not None:
        return zone_map.goal_reward_mode
    return "fixed" if mdp.has_offset else "scaled"


def _load_mdp(map_spec: str | None, mdp_path: Path | None, goal_reward: str | None = None, *,
              map_name: str = "MAP"):
    """(mdp, map or None) from exactly one of MAP or --mdp; MAP is a zone map or, when the TOML
    beside it says ``world = "warehouse"``, a floor plan. ``map_name``: how the command takes the map
    (an argument ``MAP``, or an option such as ``--map``), for the error."""
    from ..mdp import TabularMDP

    if (map_spec is None) == (mdp_path is None):
        raise InputError(f"give exactly one of {map_name} (a map file or bundled map name) or --mdp FILE.npz")
    if mdp_path is not None:
        if goal_reward is not None:
            raise InputError("--goal-reward applies to a MAP; an MDP archive holds its own reward "
                             "(export it with expertise-irl export-mdp MAP --goal-reward MODE)")
        return TabularMDP.load(mdp_path), None
    zone_map = load_map(map_spec, goal_reward)
    return zone_map.to_mdp(), zone_map


def _parse_theta(spec: str, n_features: int, names, *, fixed_reward: bool = False) -> np.ndarray:
    """``--theta`` scaled to unit l1 norm; on an MDP with a fixed reward (``fixed_reward``) that
    rescaling makes another person, so a θ that needed it is named in a warning."""
    from ..hypotheses import normalize_theta

    try:
        values = [float(x) for x in spec.split(",")]
    except ValueError:
        raise InputError(f"--theta: {spec!r} is not a comma-separated list of numbers") from None
    if len(values) != n_features:
        raise InputError(
            f"--theta has {len(values)} values but the MDP has {n_features} features ({', '.join(names)})"
        )
    theta = normalize_theta(values, what="--theta")
    if fixed_reward and not np.allclose(theta, values):
        _warn(f"--theta {spec} was scaled to unit l1 norm ({', '.join(f'{x:.4g}' for x in theta)}); "
              "with a fixed goal reward the scale of θ matters, so give θ with components summing to 1")
    return theta


def _check_beta(beta: float, what: str = "--beta") -> float:
    if not math.isfinite(beta) or beta <= 0:
        raise InputError(f"{what} must be a number > 0, got {beta:g}")
    return beta


def _version(value: bool) -> None:
    if value:
        _say(f"expertise-irl {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Show the version and exit.")] = False,
) -> None:
    """Joint inference of expertise and reward from demonstrations."""
