"""``expertise-irl experiment run | status | list``: output, resume, one-line errors, fast help."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from cli_helpers import assert_input_error as one_line_error
from cli_helpers import invoke, ok


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "sweep"
    result = invoke("experiment", "run", "conditions", "--out", str(out), "--workers", "2")
    assert result.exit_code == 0, result.output
    return out, result


@pytest.mark.slow
def test_run_reports_and_status_counts(sweep):
    out, result = sweep
    assert "4 task(s) run, 0 already done or skipped, 0 failed, 168 rows" in result.output
    status = invoke("experiment", "status", str(out))
    assert status.exit_code == 0, status.output
    assert "tasks: 4 done / 4 total, 0 failed, 0 to do" in status.output
    assert "rows: 168" in status.output and "time spent:" in status.output


@pytest.mark.slow
def test_rerun_skips_finished_tasks(sweep):
    out, _ = sweep
    again = invoke("experiment", "run", "conditions", "--out", str(out), "--workers", "1")
    assert again.exit_code == 0, again.output
    assert "0 task(s) run, 4 already done" in again.output


@pytest.mark.slow
def test_other_seed_on_same_dir_is_one_line_error(sweep):
    out, _ = sweep
    one_line_error(invoke("experiment", "run", "conditions", "--out", str(out), "--seed", "5"),
                   "holds study 'conditions' run with seed 0; this command has seed 5; refusing to mix",
                   f"delete {out} to start again")
    one_line_error(invoke("experiment", "run", "conditions", "--out", str(out), "--scale", "small"),
                   "run with scale smoke; this command has scale small; refusing to mix")
    one_line_error(invoke("experiment", "run", "cardinality", "--out", str(out), "--scale", "smoke"),
                   "holds study 'conditions', not 'cardinality'; refusing to mix")


@pytest.mark.slow
def test_status_lists_failures_and_time_left(tmp_path, monkeypatch):
    from expertise_irl.experiments.engine import FAULTS_ENV

    out = tmp_path / "failing"
    monkeypatch.setenv(FAULTS_ENV, "raise:e000-r000-k003")
    result = invoke("experiment", "run", "conditions", "--out", str(out), "--workers", "1")
    assert result.exit_code == 1, result.output
    assert "1 failed" in result.output and "--retry-failed" in result.output
    status = invoke("experiment", "status", str(out))
    assert "tasks: 3 done / 4 total, 1 failed, 0 to do" in status.output
    assert "failed: e000-r000-k003: injected failure" in status.output
    monkeypatch.delenv(FAULTS_ENV)
    # Running again without --retry-failed runs nothing, and still says the sweep is not whole.
    again = invoke("experiment", "run", "conditions", "--out", str(out), "--workers", "1")
    assert again.exit_code == 1, again.output
    assert "0 task(s) run" in again.output and "1 task(s) that failed before were not retried" in again.output
    retried = invoke("experiment", "run", "conditions", "--out", str(out), "--workers", "1", "--retry-failed")
    assert retried.exit_code == 0 and "1 task(s) run" in retried.output, retried.output
    assert "0 failed" in invoke("experiment", "status", str(out)).output


def test_list_shows_every_scale_with_counts():
    result = invoke("experiment", "list")
    assert result.exit_code == 0, result.output
    for scale in ("smoke", "small", "paper"):
        assert scale in result.output
    assert "conditions" in result.output and "100 / 1200" in result.output


def test_readme_times_of_the_paper_runs_are_the_list_estimates():
    """Each ``≈`` time of README's "Reproducing the paper" commands is within 15% of what
    ``experiment list`` estimates for that study, scale and workers on the README's 2-core machine."""
    import re

    from expertise_irl.cli.experiment import estimate_s
    from expertise_irl.experiments.studies import studies

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    pattern = r"experiment run (\w+) .*--scale (\w+)(?: --workers (\d+))?\s+#.*≈ ([\d.]+) (s|min)"
    found = re.findall(pattern, readme)
    assert len(found) >= 4, found
    for name, scale, workers, value, unit in found:
        st = studies()[name]
        est = estimate_s(st.tasks(st.scales[scale]), int(workers or 2))
        quoted = float(value) * (60 if unit == "min" else 1)
        assert abs(quoted - est) <= 0.15 * est, (name, scale, quoted, est)


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["run", "nope", "--out", "{tmp}/x"], ["unknown study 'nope'", "conditions"]),
        (["run", "conditions", "--out", "{tmp}/x", "--scale", "huge"], ["no scale 'huge'", "smoke"]),
        (["run", "conditions", "--out", "{tmp}/x", "--workers", "0"], ["--workers"]),
        (["run", "conditions"], ["--out"]),
        (["status", "{tmp}"], ["not an experiment directory"]),
        (["status", "{tmp}/missing"], ["does not exist"]),
    ],
    ids=["unknown-study", "unknown-scale", "zero-workers", "no-out", "status-not-sweep", "status-missing"],
)
def test_bad_input_is_one_line_error(tmp_path, args, needles):
    one_line_error(invoke("experiment", *[a.format(tmp=tmp_path) for a in args]), *needles)


def test_run_into_a_file_or_foreign_directory_is_refused(tmp_path):
    (tmp_path / "file").write_text("x")
    one_line_error(invoke("experiment", "run", "conditions", "--out", str(tmp_path / "file")),
                   "not a directory")
    (tmp_path / "dir").mkdir()
    (tmp_path / "dir" / "mine.txt").write_text("x")
    one_line_error(invoke("experiment", "run", "conditions", "--out", str(tmp_path / "dir")), "not empty")


def test_help_does_not_import_heavy_modules():
    code = (
        "import sys\n"
        "from expertise_irl.cli import app\n"
        "try:\n"
        "    app(['experiment', 'run', '--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = [m for m in ('jax', 'pandas', 'pyarrow', 'dask', 'distributed') if m in sys.modules]\n"
        "print('HEAVY', heavy)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "--scheduler" in proc.stdout and "--retry-failed" in proc.stdout
    assert "HEAVY []" in proc.stdout, proc.stdout


def test_list_does_not_load_jax():
    """Listing studies reads their specs; nothing is solved, so JAX stays unloaded (seconds saved)."""
    code = (
        "import sys\n"
        "from expertise_irl.cli import app\n"
        "try:\n"
        "    app(['experiment', 'list'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print('JAX', 'jax' in sys.modules)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "conditions" in proc.stdout and "fullset" in proc.stdout, proc.stdout + proc.stderr
    assert "JAX False" in proc.stdout, proc.stdout


@pytest.mark.slow
def test_config_file_replaces_fields_and_is_recorded(tmp_path):
    import json
    import tomllib

    from expertise_irl.experiments import load

    cfg = tmp_path / "rel.toml"
    cfg.write_text('[conditions]\nmodel = "maxent-relative"\nks = [3]\nenvironments = 1\n')
    out = tmp_path / "sweep"
    result = invoke("experiment", "run", "conditions", "--out", out, "--config", cfg, "--workers", "1")
    ok(result)
    assert f"smoke with {cfg}" in result.output
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["scale"] == "custom"
    assert manifest["config"]["model"] == "maxent-relative" and manifest["config"]["ks"] == [3]
    assert manifest["config"]["episodes"] == 3  # the rest is the smoke scale's
    assert set(load(out)["k"]) == {3}
    # The sweep's own config.toml is a valid --config: the same command resumes, nothing to run.
    again = invoke("experiment", "run", "conditions", "--out", out, "--config", out / "config.toml",
                   "--workers", "1")
    ok(again)
    assert "0 task(s) run" in again.output
    assert tomllib.loads((out / "config.toml").read_text())["conditions"]["model"] == "maxent-relative"


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("episodes = 'many'\n", ["episodes must be a whole number", "'many'"]),
        ("epsiodes = 3\n", ["'epsiodes' is not a field of study 'conditions'", "episodes"]),
        ("ks = []\n", ["ks must be a non-empty list"]),
        ("ks = [3, 'x']\n", ["ks[1] must be a whole number"]),
        ("model = 'softmax'\n", ["model must be one of"]),
        ("episodes = 0\n", ["episodes must be at least 1"]),
        ("episodes = \n", ["not a TOML file"]),
    ],
    ids=["type", "unknown-field", "empty-list", "list-item", "bad-model", "bad-value", "not-toml"],
)
def test_bad_config_file_is_one_line_error_naming_it(tmp_path, text, needles):
    cfg = tmp_path / "c.toml"
    cfg.write_text(text)
    out = tmp_path / "sweep"
    line = one_line_error(invoke("experiment", "run", "conditions", "--out", out, "--config", cfg), *needles)
    assert str(cfg) in line
    assert not out.exists()  # refused before any directory is made


def test_missing_config_file_is_one_line_error(tmp_path):
    one_line_error(invoke("experiment", "run", "conditions", "--out", tmp_path / "s", "--config",
                          tmp_path / "none.toml"), "none.toml", "no such file")


@pytest.mark.slow
def test_config_table_of_another_study_and_changed_config_are_named(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[cardinality]\nruns = 2\n")
    one_line_error(invoke("experiment", "run", "conditions", "--out", tmp_path / "s", "--config", cfg),
                   "holds a [cardinality] table, but the study is 'conditions'")
    big = tmp_path / "big.toml"
    big.write_text("ks = [3031]\n")
    one_line_error(invoke("experiment", "run", "conditions", "--out", tmp_path / "s", "--config", big),
                   "k must be below 3031", str(big))
    # A DIR made with one config, resumed with another: the error names the field that changed.
    one = tmp_path / "one.toml"
    one.write_text("ks = [3]\nenvironments = 1\n")
    out = tmp_path / "sweep"
    ok(invoke("experiment", "run", "conditions", "--out", out, "--config", one, "--workers", "1"))
    two = tmp_path / "two.toml"
    two.write_text("ks = [4]\nenvironments = 1\n")
    one_line_error(invoke("experiment", "run", "conditions", "--out", out, "--config", two),
                   "another config", "ks = [3] there, [4] here", "refusing to mix")


@pytest.mark.slow
def test_run_record_has_the_elapsed_time(sweep):
    import json

    out, _ = sweep
    records = [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*.json"))]
    assert records and all(r["wall_time_s"] > 0 and r["finished"] >= r["started"] for r in records)
    assert records[0]["tasks_run"] == records[0]["tasks_to_run"] and records[0]["tasks_failed"] == 0
