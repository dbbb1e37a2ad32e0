"""Output files are written atomically: a temporary file beside the output, fsynced, renamed."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import invoke, ok

import expertise_irl
from expertise_irl import atomic
from expertise_irl.demos import simulation
from expertise_irl.demos.csv_io import demos_csv_stream, read_demos_csv, write_demos_csv
from expertise_irl.worlds.maps import load_bundled_world

SRC = Path(expertise_irl.__file__).parent


def test_a_write_that_fails_leaves_the_old_file_and_no_temporary_one(tmp_path):
    path = tmp_path / "out.json"
    path.write_text("old\n")
    with pytest.raises(KeyboardInterrupt), atomic.atomic_open(path, "w") as fh:
        fh.write("half of the new")
        raise KeyboardInterrupt
    assert path.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_a_new_file_appears_whole_with_the_mode_open_would_give(tmp_path):
    path = tmp_path / "new.csv"
    atomic.write_atomic(path, "a,b\n1,2\n")
    assert path.read_text() == "a,b\n1,2\n"
    umask = os.umask(0o022)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new.csv"]


def test_figures_keep_the_format_of_their_suffix(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure()
    fig.subplots().plot([0, 1])
    atomic.save_figure_atomic(fig, tmp_path / "f.pdf")
    atomic.save_figure_atomic(fig, tmp_path / "f.png")
    assert (tmp_path / "f.pdf").read_bytes()[:4] == b"%PDF"
    assert (tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.pdf", "f.png"]


def test_one_home_for_atomic_writes_and_no_plain_writes_left():
    # Every module writes through expertise_irl.atomic; the live page's demonstrations log is the one
    # file appended to (row by row, fsynced), by design.
    from expertise_irl.experiments import store
    from expertise_irl.plots import userstudy

    assert store.write_atomic is atomic.write_atomic
    assert userstudy.write_atomic is atomic.write_atomic
    plain = re.compile(r"\.write_text\(|\.write_bytes\(|\bopen\([^)]*[\"'][wa]b?[\"']"
                       r"|savefig\((?!buf\b|tmp\b)|\.to_csv\([a-z_]+[,)]|np\.savez\w*\((?!fh\b)")
    found = [f"{p.relative_to(SRC)}:{i}: {line.strip()}"
             for p in SRC.rglob("*.py") if p.name != "atomic.py"
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if plain.search(line) and "self.demos_path" not in line]
    assert found == []


def test_batches_number_episodes_on_and_one_batch_is_simulate(tmp_path):
    mdp = load_bundled_world("crossroads").to_mdp()
    theta = np.array([0.5, 0.5, 0, 0, 0])
    one = simulation.simulate(mdp, theta, 0.5, 7, 3, max_steps=50)
    (same,) = simulation.simulate_batches(mdp, theta, 0.5, 7, 3, max_steps=50, batch=7)
    for k in ("episode", "step", "state", "action"):
        assert np.array_equal(getattr(one, k), getattr(same, k))
    parts = list(simulation.simulate_batches(mdp, theta, 0.5, 7, 3, max_steps=50, batch=3))
    assert [p.n_episodes for p in parts] == [3, 3, 1]
    assert np.concatenate([np.unique(p.episode) for p in parts]).tolist() == list(range(7))
    write_demos_csv(tmp_path / "a.csv", one, mdp)
    with demos_csv_stream(tmp_path / "b.csv", mdp) as write:
        write(one)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    with demos_csv_stream(tmp_path / "c.csv", mdp, fmt="grid") as write:
        for p in parts:
            write(p)
    assert read_demos_csv(tmp_path / "c.csv", mdp).n_episodes == 7


def test_many_episodes_get_a_size_estimate_and_are_written_in_batches(tmp_path, monkeypatch):
    monkeypatch.setattr(simulation, "BATCH_EPISODES", 5)
    out = tmp_path / "d.csv"
    r = invoke("simulate", "crossroads", "--theta", "0.5,0.5,0,0,0", "--beta", "0.5", "--episodes", "12",
               "--out", out)
    ok(r)
    assert re.search(r"note: 12 episodes: about [\d.]+ (bytes|kB) and [\d,]+ actions to write", r.stderr)
    mdp = load_bundled_world("crossroads").to_mdp()
    assert read_demos_csv(out, mdp).n_episodes == 12
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.csv"]


@pytest.mark.slow
@pytest.mark.parametrize(("sig", "code", "word"), [(signal.SIGTERM, 143, "terminated"),
                                                   (signal.SIGINT, 130, "interrupted")])
def test_a_stopped_simulate_leaves_nothing_at_its_output(tmp_path, sig, code, word):
    # A run far too long to finish, stopped once its temporary file exists: exit 128 + signal, one
    # line on stderr, no traceback, no file at --out and no temporary file left beside it.
    # Python's own SIGINT handler, as at the start of a foreground command: a suite started in the
    # background of a non-interactive shell runs with SIGINT ignored, which a child inherits
    start = ("import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
             "from expertise_irl.cli import app; app()")
    cmd = [sys.executable, "-c", start, "simulate", "crossroads",
           "--theta", "0.5,0.5,0,0,0", "--beta", "1", "--episodes", "100000000", "--max-steps", "1",
           "--out", str(tmp_path / "big.csv")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while not list(tmp_path.glob(".big.csv.*.tmp")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "Traceback" not in err
    assert f"error: {word}" in err.splitlines()[-1]
    assert list(tmp_path.iterdir()) == []
