"""What the command line says about itself: usage lines, flags, unknown options, which option."""

from __future__ import annotations

import json
import re
import sys

import numpy as np
import pandas as pd
import pytest
import typer
from cli_helpers import assert_input_error, invoke

from expertise_irl import __version__, cli
from expertise_irl.cli import app


def _commands():
    """Every command path (``["infer"]``, ``["experiment", "run"]``, ...)."""
    root = typer.main.get_command(app)
    out = []

    def walk(cmd, path):
        if hasattr(cmd, "commands"):  # a group (typer ships its own click: no isinstance)
            for name, sub in cmd.commands.items():
                walk(sub, [*path, name])
        else:
            out.append(path)

    walk(root, [])
    return out


@pytest.mark.parametrize("path", _commands(), ids=" ".join)
def test_usage_lines_write_arguments_one_way_and_flags_without_a_negation(path):
    # Required arguments plain (MAP), optional ones in one pair of brackets ([MAP]), names in capitals;
    # a flag shows as itself (--force), never as --force/--no-force.
    result = invoke(*path, "--help")
    assert result.exit_code == 0, result.output
    (usage,) = [ln for ln in result.output.splitlines() if "Usage:" in ln]
    args = usage.split("[OPTIONS]", 1)[1].split()
    for a in args:
        assert "{" not in a and "[[" not in a, usage
        assert re.fullmatch(r"\[?[A-Z][A-Z0-9_.a-z]*\]?(\.\.\.)?", a) and a.lstrip("[")[:1].isupper(), usage
        assert not re.fullmatch(r"\[?[a-z]+\]?", a), usage
    # A --x/--no-x pair only where both say something: an option with no default (None = decide).
    cmd = typer.main.get_command(app)
    for name in path:
        cmd = cmd.commands[name]
    for param in cmd.params:
        if getattr(param, "secondary_opts", None):
            assert param.default is None, f"{' '.join(path)}: {param.opts[0]}/{param.secondary_opts[0]}"
    if any(p.name == "force" for p in cmd.params):
        assert "--no-force" not in result.output


def test_an_unknown_option_suggests_only_a_close_one():
    line = assert_input_error(invoke("infer", "--bogus"), "--bogus")
    assert "--out" not in line
    assert_input_error(invoke("infer", "--seeed", "1"), "--seeed", "did you mean --seed?")


def test_plot_names_its_map_option(tmp_path):
    names = ["length", "road", "avoid", "slow", "traffic"]
    doc = {"method": "discrete", "feature_names": names, "beta_hat": 0.5, "theta_hat": [0.2] * 5,
           "marginals": {"beta": {"values": [0.5], "probabilities": [1.0]},
                         "theta": {"values": [[0.2] * 5], "probabilities": [1.0]}}}
    (tmp_path / "r.json").write_text(json.dumps(doc))
    line = assert_input_error(invoke("plot", tmp_path / "r.json", "--map", "crossroads", "--mdp",
                                     tmp_path / "m.npz", "--out", tmp_path / "p.png"),
                              "give exactly one of --map")
    assert " MAP " not in line


def test_fig7_ticks_whole_numbers_of_episodes():
    # Episodes 1..3: matplotlib's default locator would put ticks at 1.5 and 2.5.
    from expertise_irl.experiments.report.fixed_vs_joint import fig7

    rng = np.random.default_rng(0)
    rows = [{"environment": 0, "run": r, "k": 5, "group": g, "truth": "in_set", "group_true": g,
             "episodes": e, "policy_regret": rng.random(), "cosine_similarity": rng.random(),
             "expertise_distance": rng.random()}
            for g in ("high", "low") for r in range(3) for e in (1, 2, 3)]
    fig = fig7(pd.DataFrame(rows), 3).fig
    fig.canvas.draw()
    for ax in fig.get_axes():
        lo, hi = ax.get_xlim()
        ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
        assert ticks and all(float(t).is_integer() for t in ticks), ticks


def test_the_console_script_runs_the_app(monkeypatch, capsys):
    """``expertise-irl`` is ``cli.main`` (pyproject.toml's script): the app the tests above drive."""
    monkeypatch.setattr(sys, "argv", ["expertise-irl", "--version"])
    with pytest.raises(SystemExit) as stop:
        cli.main()
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"expertise-irl {__version__}"
