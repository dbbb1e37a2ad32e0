"""The solver's lane width: measured at first use, cached per machine, overridable."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok

from expertise_irl.errors import InputError
from expertise_irl.planning import tuning
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.maps import resolve_world


@pytest.fixture
def fresh(tmp_path, monkeypatch):
    """No override, no choice made in this process, and a cache file of the test's own."""
    monkeypatch.delenv(tuning.LANES_ENV, raising=False)
    monkeypatch.setenv(tuning.TUNING_FILE_ENV, str(tmp_path / "tuning.json"))
    monkeypatch.setattr(tuning, "_CHOSEN", {})
    return tmp_path / "tuning.json"


def _fake_measure(calls):
    def measure(dtype):
        calls.append(dtype)
        return tuning.LaneChoice(16, "measured", {4: 1.0e8, 8: 2.0e8, 16: 3.0e8}, "2026-01-01 00:00 UTC")
    return measure


def test_first_use_measures_and_caches_then_later_processes_read_it(fresh, monkeypatch):
    calls = []
    monkeypatch.setattr(tuning, "_measure", _fake_measure(calls))
    assert not tuning.is_settled()
    first = tuning.lane_choice()
    assert (first.lanes, first.source) == (16, "measured") and calls == ["float64"]
    table = json.loads(fresh.read_text())
    assert list(table) == [tuning.machine_key("float64")]
    assert table[tuning.machine_key("float64")]["lanes"] == 16
    # A new process (nothing chosen in memory) reads the file and measures nothing.
    monkeypatch.setattr(tuning, "_CHOSEN", {})
    assert tuning.is_settled()
    again = tuning.lane_choice()
    assert (again.lanes, again.source, again.backups_per_s) == (16, "cache", first.backups_per_s)
    assert calls == ["float64"]
    # Each dtype is its own entry; --again measures anew.
    tuning.lane_choice("float32")
    tuning.lane_choice(again=True)
    assert calls == ["float64", "float32", "float64"]
    assert len(json.loads(fresh.read_text())) == 2


def test_the_key_names_what_the_choice_depends_on(monkeypatch):
    import jax

    key = tuning.machine_key("float64")
    for part in (f"jax={jax.__version__}", f"backend={jax.default_backend()}", "dtype=float64", "cores="):
        assert part in key
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_max_isa=AVX2")
    assert tuning.machine_key("float64") != key  # other compiler flags: measured anew


def test_a_damaged_cache_is_measured_again_and_rewritten(fresh, monkeypatch):
    calls = []
    monkeypatch.setattr(tuning, "_measure", _fake_measure(calls))
    fresh.write_text("{not json")
    assert tuning.lane_width() == 16 and calls == ["float64"]
    assert json.loads(fresh.read_text())[tuning.machine_key("float64")]["lanes"] == 16
    # entries that are malformed inside are dropped and measured again, never a crash
    key = tuning.machine_key("float64")
    for n, entry in enumerate([{"lanes": "many"}, {"lanes": True, "backups_per_s": {}, "measured": ""},
                               {"lanes": 8, "backups_per_s": {"x": 1}, "measured": ""},
                               {"lanes": 8, "backups_per_s": [1], "measured": ""}], start=2):
        monkeypatch.setattr(tuning, "_CHOSEN", {})
        fresh.write_text(json.dumps({key: entry}))
        assert tuning.lane_width() == 16 and len(calls) == n


def test_an_unwritable_cache_still_gives_a_width(fresh, tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(tuning, "_measure", _fake_measure(calls))
    (tmp_path / "a-file").write_text("")
    monkeypatch.setenv(tuning.TUNING_FILE_ENV, str(tmp_path / "a-file" / "tuning.json"))
    choice = tuning.lane_choice()
    assert (choice.lanes, choice.source) == (16, "uncached")
    assert not list((tmp_path).glob(".*.tmp")) and not list(tmp_path.glob("a-file*/*"))
    r = invoke("tune")
    ok(r)
    assert "lane width: 16 (measured just now, but" in r.stdout and "EXPERTISE_IRL_LANES=N" in r.stdout


def test_the_environment_overrides_and_a_bad_value_is_named(fresh, monkeypatch):
    monkeypatch.setattr(tuning, "_measure", lambda dtype: pytest.fail("measured despite the override"))
    monkeypatch.setenv(tuning.LANES_ENV, "4")
    assert tuning.lane_choice() == tuning.LaneChoice(4, "environment", {})
    for bad in ("0", "four", "-8", "2.5"):
        monkeypatch.setenv(tuning.LANES_ENV, bad)
        with pytest.raises(InputError, match=f"{tuning.LANES_ENV} must be a whole number >= 1, got '{bad}'"):
            tuning.lane_width()
    assert not fresh.exists()


@pytest.mark.slow
def test_a_real_measurement_picks_the_fastest_candidate(fresh):
    """The timing run itself (a few seconds): every CPU candidate is measured, the choice is the
    fastest of them, and it is written to the cache."""
    choice = tuning.lane_choice()
    assert choice.source == "measured"
    assert set(choice.backups_per_s) == set(tuning.CANDIDATES["cpu"])
    assert all(r > 0 and np.isfinite(r) for r in choice.backups_per_s.values())
    assert choice.lanes == max(choice.backups_per_s, key=choice.backups_per_s.get)
    assert json.loads(fresh.read_text())[tuning.machine_key("float64")]["lanes"] == choice.lanes


@pytest.mark.slow
def test_solutions_agree_within_the_tolerance_whatever_the_width():
    mdp = resolve_world("corridor").to_mdp()
    rng = np.random.default_rng(3)
    theta = rng.dirichlet(np.ones(mdp.n_features), size=40)
    beta = rng.choice([0.05, 0.5, 5.0], size=40)
    sols = {lanes: solve(mdp, theta, beta, lanes=lanes) for lanes in (1, 4, 8, 16)}
    ref = sols[8]
    fin = np.isfinite(ref.log_policy)
    for lanes, sol in sols.items():
        # each within 1e-8 nats of the fixed point on V/β, so within 2e-8 of each other
        assert np.max(np.abs(sol.value - ref.value) / beta[:, None]) <= 2e-8, lanes
        np.testing.assert_array_equal(np.isfinite(sol.log_policy), fin)
        assert np.max(np.abs(sol.log_policy[fin] - ref.log_policy[fin])) <= 4e-8, lanes
    with pytest.raises(InputError, match="lanes must be a whole number >= 1"):
        solve(mdp, theta, beta, lanes=0)


def test_tune_command_shows_the_choice_and_its_measurements(fresh, monkeypatch):
    calls = []
    monkeypatch.setattr(tuning, "_measure", _fake_measure(calls))
    r = invoke("tune")
    ok(r)
    assert "lane width: 16 (measured just now, cached)" in r.stdout
    assert "16 lanes: 300 M backups/s  <- chosen" in r.stdout and "4 lanes: 100 M backups/s" in r.stdout
    assert str(fresh) in r.stdout
    monkeypatch.setattr(tuning, "_CHOSEN", {})
    r = invoke("tune")
    ok(r)
    assert "read from the cache" in r.stdout and calls == ["float64"]
    monkeypatch.setenv(tuning.LANES_ENV, "4")
    r = invoke("tune", "--again")
    ok(r)
    assert "lane width: 4 (set by EXPERTISE_IRL_LANES)" in r.stdout and "nothing was measured" in r.stderr
    assert_input_error(invoke("tune", "--dtype", "f16"), "--dtype must be float64 or float32")
    monkeypatch.setenv(tuning.LANES_ENV, "x")
    assert_input_error(invoke("tune"), "EXPERTISE_IRL_LANES must be a whole number >= 1, got 'x'")


@pytest.mark.slow
def test_a_command_says_why_it_pauses_on_first_use(fresh, monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(tuning, "_measure", _fake_measure(calls))
    r = invoke("demo", "--out", tmp_path / "demo", "--seed", "1")
    ok(r)
    assert "measuring the solver's lane width for this machine" in r.stderr and calls == ["float64"]
    monkeypatch.setattr(tuning, "_CHOSEN", {})
    r = invoke("demo", "--out", tmp_path / "demo", "--seed", "1", "--force")
    ok(r)
    assert "measuring" not in r.stderr and calls == ["float64"]


def test_small_sets_do_not_pause_to_measure(fresh, monkeypatch):
    from expertise_irl.planning.soft_vi import TUNE_MIN

    monkeypatch.setattr(tuning, "_measure", lambda dtype: pytest.fail("measured for a small set"))
    mdp = resolve_world("corridor").to_mdp()
    theta = np.eye(mdp.n_features)[np.arange(TUNE_MIN - 1) % mdp.n_features]
    solve(mdp, theta, 1.0)
    assert not fresh.exists()
