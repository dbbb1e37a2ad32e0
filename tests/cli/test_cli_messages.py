"""The wording of what the command line tells a user: one error line and nothing above it, the
package's own words for a missing file, counts in agreement with their nouns."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from cli_helpers import invoke, ok


def _cli(*args, cwd) -> subprocess.CompletedProcess:
    """The installed command as a user runs it (stderr exactly as a terminal would get it)."""
    exe = Path(sys.executable).with_name("expertise-irl")
    return subprocess.run([str(exe), *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_a_missing_file_is_named_in_the_package_s_words(tmp_path):
    run = _cli("plot", "missing.json", "--out", "x.png", cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr == "error: missing.json: no such file\n"


@pytest.mark.slow
def test_an_error_before_any_work_leaves_no_empty_line_above_it(tmp_path):
    """A sweep whose output cannot be made fails before its progress bar has a task: the error is the
    whole of stderr (a progress display started on entry used to print an empty line first)."""
    (tmp_path / "afile").write_text("x")
    run = _cli("experiment", "run", "conditions", "--scale", "smoke", "--out", "afile/sub", cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr.splitlines() == ["error: afile/sub/rows: not a directory"], run.stderr


def test_one_episode_is_one_episode(tmp_path):
    out = tmp_path / "d.csv"
    res = invoke("simulate", "corridor", "--theta", "1,0,0,0,0", "--beta", "0.05", "--episodes", "1",
                 "--seed", "0", "--out", out)
    ok(res)
    assert ": 1 episode, " in res.stdout and "1 episodes" not in res.stdout, res.stdout


def test_counts_agree_with_their_nouns():
    from expertise_irl.errors import plural

    assert [plural(n, "move") for n in (0, 1, 2)] == ["0 moves", "1 move", "2 moves"]


def test_system_reasons_in_the_package_s_words():
    import errno

    from expertise_irl.errors import os_reason

    assert os_reason(FileNotFoundError(errno.ENOENT, "No such file or directory", "x")) == "no such file"
    assert os_reason(PermissionError(errno.EACCES, "Permission denied", "x")) == "permission denied"


@pytest.mark.parametrize(("given", "flag"), [(("--max-seconds", "5"), "--max-seconds"),
                                             (("--max-hypotheses", "500"), "--max-hypotheses")])
@pytest.mark.parametrize("unrefined", [("--thetas", "paper-real"), ("--no-refine",)])
def test_refinement_caps_are_refused_for_a_set_that_is_not_refined(tmp_path, given, flag, unrefined):
    """A cap on the refinement given for a named set (or with --no-refine) would do nothing: one line
    says so, before any work, and nothing is written."""
    from cli_helpers import assert_input_error

    demos = tmp_path / "d.csv"
    ok(invoke("simulate", "corridor", "--theta", "1,0,0,0,0", "--beta", "0.5", "--episodes", "1",
              "--seed", "0", "--out", demos))
    out = tmp_path / "r.json"
    res = invoke("infer", "corridor", "--demos", demos, "--out", out, *unrefined, *given)
    assert_input_error(res, flag, "not refined", "--refine")
    assert not out.exists()
