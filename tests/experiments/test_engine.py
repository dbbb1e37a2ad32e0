"""The experiment engine: same rows for any workers / engine / interruption; resume; failures; schema."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from expertise_irl.errors import InputError
from expertise_irl.experiments import load
from expertise_irl.experiments.engine import FAULTS_ENV, execute_task, run, seed_sequence, status
from expertise_irl.experiments.studies import get_study
from expertise_irl.experiments.studies.fixed_vs_joint import SCALES, person

STUDY = get_study("conditions")
SMOKE = SCALES["smoke"]
DOCS = Path(__file__).resolve().parents[2] / "docs" / "experiments.md"
IDENTITY = ["environment", "run", "k", "group", "truth", "condition", "method", "episodes"]


def deterministic(df: pd.DataFrame) -> pd.DataFrame:
    """Rows without measured columns, in identity order."""
    keep = [c for c in df.columns if not c.endswith("_time_s")]
    return df[keep].sort_values(IDENTITY, kind="stable").reset_index(drop=True)


def assert_same_rows(a: pd.DataFrame, b: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(deterministic(a), deterministic(b), check_exact=True)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, pd.DataFrame]:
    out = tmp_path_factory.mktemp("sweep") / "ref"
    summary = run(STUDY, out, scale="smoke", seed=0, workers=1)
    assert summary.ran == summary.total == len(STUDY.tasks(SMOKE)) and summary.failed == 0
    return out, load(out)


def copy_sweep(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


@pytest.mark.slow
def test_reference_is_complete(reference):
    out, df = reference
    counts = STUDY.counts(SMOKE)
    assert len(df) == counts["rows"]
    assert not df.duplicated(IDENTITY).any()
    st = status(out)
    assert (st.done, st.total, st.failed, st.rows) == (counts["tasks"], counts["tasks"], 0, counts["rows"])
    # Every person has rows for each episode count 1..N of each of its conditions.
    per = df.groupby(["environment", "run", "k", "group", "truth", "condition"])["episodes"]
    assert (per.min() == 1).all() and (per.max() == per.count()).all()


@pytest.mark.slow
def test_one_and_two_workers_give_identical_rows(reference, tmp_path):
    run(STUDY, tmp_path / "two", scale="smoke", seed=0, workers=2)
    assert_same_rows(load(tmp_path / "two"), reference[1])


@pytest.mark.slow
def test_dask_local_cluster_gives_identical_rows(reference, tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")
    # One worker process dies in the middle of a task; Dask runs the task again elsewhere.
    marker = tmp_path / "died-once"
    monkeypatch.setenv(FAULTS_ENV, f"die:{STUDY.tasks(SMOKE)[2].key}:{marker}")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        summary = run(STUDY, tmp_path / "dask", scale="smoke", seed=0, scheduler=cluster.scheduler_address)
    assert summary.failed == 0 and marker.exists()
    timings = load(tmp_path / "dask", "timings")
    assert timings["pid"].nunique() >= 1 and (timings["wall_time_s"] > 0).all()
    assert_same_rows(load(tmp_path / "dask"), reference[1])


def _cli(args: list[str], env_extra: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, **(env_extra or {})}
    code = ("import sys; from expertise_irl.cli import main; "
            "sys.argv = ['expertise-irl', *sys.argv[1:]]; main()")
    return subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("fault", "shards_left"),
    [("kill-at-start", 0), ("kill-after:2", 2), ("kill-in-write:1", 1)],
    ids=["at-start", "middle", "during-shard-write"],
)
def test_sigkill_then_resume_gives_identical_rows(reference, tmp_path, fault, shards_left):
    out = tmp_path / "killed"
    args = ["experiment", "run", "conditions", "--out", str(out), "--scale", "smoke", "--workers", "1"]
    killed = _cli(args, {FAULTS_ENV: fault})
    assert killed.returncode == -9, killed.stderr
    assert len(list((out / "rows").glob("*.parquet"))) == shards_left
    if fault.startswith("kill-in-write"):
        assert list((out / "tmp").glob("*.part"))  # the half-written shard never reached rows/
    resumed = _cli(args)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{shards_left} already done" in resumed.stdout
    assert not list((out / "tmp").glob("*.part"))
    assert_same_rows(load(out), reference[1])


def test_other_seed_or_config_is_refused(reference, tmp_path):
    out = copy_sweep(reference[0], tmp_path / "copy")
    before = sorted(p.name for p in (out / "rows").iterdir())
    with pytest.raises(InputError, match="refusing to mix"):
        run(STUDY, out, scale="smoke", seed=1, workers=1)
    named = r"scale smoke; this command has scale custom and another config \(episodes = 3 there, 4 here\); "
    with pytest.raises(InputError, match=named):
        run(STUDY, out, config=dataclasses.replace(SMOKE, episodes=4), seed=0, workers=1)
    with pytest.raises(InputError, match="refusing to mix"):
        run(STUDY, out, scale="small", seed=0, workers=1)
    assert sorted(p.name for p in (out / "rows").iterdir()) == before


def test_second_run_on_a_directory_being_written_is_refused(reference, tmp_path):
    from expertise_irl.experiments.store import Store

    out = copy_sweep(reference[0], tmp_path / "copy")
    with Store(out).lock(), pytest.raises(InputError, match="another `experiment run`"):
        run(STUDY, out, scale="smoke", workers=1)
    assert run(STUDY, out, scale="smoke", workers=1).skipped == len(STUDY.tasks(SMOKE))  # released


def test_directory_of_something_else_is_refused(tmp_path):
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        run(STUDY, tmp_path / "other", scale="smoke", workers=1)
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="not a directory"):
        run(STUDY, tmp_path / "file", scale="smoke", workers=1)


@pytest.mark.slow
def test_failing_task_is_recorded_and_retried(reference, tmp_path, monkeypatch):
    out = copy_sweep(reference[0], tmp_path / "copy")
    key = STUDY.tasks(SMOKE)[1].key
    (out / "rows" / f"{key}.parquet").unlink()
    (out / "timings" / f"{key}.parquet").unlink()
    monkeypatch.setenv(FAULTS_ENV, f"raise:{key}")
    summary = run(STUDY, out, scale="smoke", workers=1)
    assert (summary.ran, summary.failed) == (0, 1)
    failures = load(out, "failures")
    assert failures["task"].tolist() == [key]
    assert "injected failure" in failures["message"].iloc[0]
    assert json.loads(failures["params"].iloc[0]) == STUDY.tasks(SMOKE)[1].params
    st = status(out)
    assert (st.failed, st.done) == (1, st.total - 1) and st.failures[0][0] == key
    assert len(load(out)) < len(reference[1])  # failures never among the rows
    monkeypatch.delenv(FAULTS_ENV)
    assert run(STUDY, out, scale="smoke", workers=1).ran == 0  # a plain re-run leaves it failed
    summary = run(STUDY, out, scale="smoke", workers=1, retry_failed=True)
    assert (summary.ran, summary.failed) == (1, 0)
    assert load(out, "failures").empty
    assert_same_rows(load(out), reference[1])


@pytest.mark.slow
def test_worker_that_dies_is_rerun(reference, tmp_path, monkeypatch):
    key = STUDY.tasks(SMOKE)[0].key
    marker = tmp_path / "died-once"
    monkeypatch.setenv(FAULTS_ENV, f"die:{key}:{marker}")
    summary = run(STUDY, tmp_path / "sweep", scale="smoke", workers=2)
    assert marker.exists() and summary.failed == 0
    assert_same_rows(load(tmp_path / "sweep"), reference[1])


def _person_rows(df: pd.DataFrame, e: int, r: int, k: int, group: str, truth: str) -> pd.DataFrame:
    sel = df[(df.environment == e) & (df.run == r) & (df.k == k) & (df.group == group) & (df.truth == truth)]
    return deterministic(sel)


def _task_rows(cfg, seed: int, e: int, r: int, k: int) -> pd.DataFrame:
    res = execute_task("conditions", json.loads(json.dumps(dataclasses.asdict(cfg))), seed, "t",
                       {"environment": e, "run": r, "k": k})
    table = STUDY.arrow_schema().empty_table()
    import pyarrow as pa

    table = pa.table({n: pa.array(np.asarray(res.columns[n]), type=table.schema.field(n).type)
                      for n in table.schema.names})
    return table.to_pandas()


@pytest.mark.slow
def test_person_rows_do_not_depend_on_grouping_or_study(reference):
    df = reference[1]
    e, r, k = 1, 0, 5
    expected = _person_rows(df, e, r, k, "low", "in_set")
    assert len(expected) == 3 * SMOKE.low_episodes
    alone = dataclasses.replace(SMOKE, groups=("low",), out_of_set=False)
    assert len(_task_rows(alone, 0, e, r, k)) == len(expected)
    pd.testing.assert_frame_equal(_person_rows(_task_rows(alone, 0, e, r, k), e, r, k, "low", "in_set"),
                                  expected, check_exact=True)
    # Another sweep that names the same identity among other factors.
    other = dataclasses.replace(SMOKE, environments=3, ks=(5, 9), groups=("low", "high"))
    pd.testing.assert_frame_equal(_person_rows(_task_rows(other, 0, e, r, k), e, r, k, "low", "in_set"),
                                  expected, check_exact=True)
    # Fewer episodes: the first n episodes, hence the rows for n, are the same.
    shorter = dataclasses.replace(alone, low_episodes=2)
    got = _person_rows(_task_rows(shorter, 0, e, r, k), e, r, k, "low", "in_set")
    pd.testing.assert_frame_equal(got, expected[expected.episodes <= 2].reset_index(drop=True),
                                  check_exact=True)
    # And another seed gives another person.
    other_seed = _person_rows(_task_rows(alone, 1, e, r, k), e, r, k, "low", "in_set")
    assert not np.array_equal(other_seed["beta_hat"].to_numpy(), expected["beta_hat"].to_numpy())


def test_seeds_follow_identity_not_position():
    a = person(SMOKE, 0, 1, 0, 5, "medium", "out_of_set")
    b = person(dataclasses.replace(SMOKE, environments=4, ks=(5,), groups=("medium",)), 0, 1, 0, 5,
               "medium", "out_of_set")
    assert np.array_equal(a.trajectories.state, b.trajectories.state) and a.beta == b.beta
    assert np.array_equal(seed_sequence(7, (1, 2)).generate_state(4),
                          np.random.SeedSequence(entropy=7, spawn_key=(1, 2)).generate_state(4))


def test_condition_rows_obey_their_definitions(reference):
    df = reference[1]
    fb = df[df.condition == "fixed_beta"]
    groups = fb["fixed_beta"].map(lambda b: "high" if b < 0.2121 else "medium" if b < 2.2361 else "low")
    assert (groups != fb["group_true"]).all()
    ft = df[df.condition == "fixed_theta"]
    feats = ["length", "road", "avoid", "slow", "traffic"]
    same = np.isclose(ft[[f"fixed_theta_{f}" for f in feats]].to_numpy(),
                      ft[[f"theta_true_{f}" for f in feats]].to_numpy()).all(axis=1)
    assert not same.any()
    assert df[df.truth == "out_of_set"]["condition"].eq("full").all()
    ins = df[(df.truth == "in_set")]
    assert (ins["group"] == ins["group_true"]).all()
    assert df[(df.truth == "in_set") & (df.condition == "full")]["truth_probability"].notna().all()
    # Table I's factors: in-set truths sit on the set (β distance 0, θ* among Θ_k's members).
    assert (ins["beta_set_distance"] == 0).all()
    out = df[df.truth == "out_of_set"]
    assert (out["beta_set_distance"] > 0).all()
    assert ((df["theta_k_truth_similarity"] > 0) & (df["theta_k_truth_similarity"] <= 1)).all()
    assert ((df["theta_k_diversity"] > 0) & (df["theta_k_diversity"] < 1)).all()


def _documented_columns(study: str = "conditions") -> list[tuple[str, str]]:
    text = DOCS.read_text()
    section = text.split(f"### `{study}` rows", 1)[1].split("\n### ", 1)[0].split("\n## ", 1)[0]
    return re.findall(r"^\| `([a-z_0-9]+)` \| `([a-z0-9]+)` \|", section, flags=re.M)


@pytest.mark.parametrize("name", ["optimisation", "fullset"])
def test_other_schemas_match_the_documentation(name):
    """The engine refuses rows that break a study's schema; the docs must list that schema."""
    assert _documented_columns(name) == [(c.name, c.type) for c in get_study(name).columns]
    # cardinality's rows are exactly conditions' (documented once).
    assert get_study("cardinality").columns == STUDY.columns


def test_schema_matches_the_documentation(reference):
    out, df = reference
    documented = _documented_columns()
    assert documented, "no column table found in docs/experiments.md"
    for shard in sorted((out / "rows").glob("*.parquet")):
        schema = pq.read_schema(shard)
        assert [(f.name, str(f.type).replace("large_", "")) for f in schema] == [
            (n, {"float64": "double", "string": "string", "bool": "bool"}.get(t, t)) for n, t in documented]
    pandas_dtype = {"int32": "int32", "int64": "int64", "float64": "float64"}
    for name, arrow_type in documented:
        assert name in df.columns
        if arrow_type in pandas_dtype:
            assert str(df[name].dtype) == pandas_dtype[arrow_type], name
        else:
            assert pd.api.types.is_string_dtype(df[name]), name
    # The shards alone, read as one data set by another tool, hold exactly the rows.
    assert len(pd.read_parquet(out / "rows")) == len(df)
    measured = [c for c in load(out, "timings").columns if c not in ("task", "host", "pid")]
    counters = ("set_solves", "hypotheses_solved")
    assert measured and all(c.endswith("_time_s") or c in counters for c in measured)


def test_manifest_records_the_sweep(reference):
    out, _ = reference
    m = json.loads((out / "manifest.json").read_text())
    assert (m["study"], m["scale"], m["seed"]) == ("conditions", "smoke", 0)
    assert m["config"] == json.loads(json.dumps(dataclasses.asdict(SMOKE)))
    assert {"numpy", "jax", "pyarrow", "pandas", "expertise-irl"} <= set(m["versions"])
    assert m["machine"]["cpus"] >= 1
    assert m["task_keys"] == [t.key for t in STUDY.tasks(SMOKE)]
    toml = tomllib.loads((out / "config.toml").read_text())["conditions"]
    assert toml == m["config"]
    runs = [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*.json"))]
    assert runs and runs[0]["engine"] == "local" and runs[0]["workers"] == 1
    assert runs[0]["tasks_to_run"] == len(m["task_keys"]) and "numpy" in runs[0]["versions"]


def test_the_config_model_reaches_the_people_and_the_inference():
    """``model`` drives both the simulated person and the solve: under maxent-relative a person's
    episodes follow that model's policy (the same seeds give other actions), and a bad name is refused."""
    from expertise_irl.planning.soft_vi import solve

    rel = dataclasses.replace(SMOKE, model="maxent-relative")
    p_rel = person(rel, 0, 1, 0, 5, "low", "in_set")
    p_ment = person(SMOKE, 0, 1, 0, 5, "low", "in_set")
    assert np.array_equal(p_rel.theta, p_ment.theta) and p_rel.beta == p_ment.beta  # same truth
    assert not np.array_equal(p_rel.trajectories.action, p_ment.trajectories.action)
    from expertise_irl.experiments.studies.fixed_vs_joint import environment

    _, mdp = environment(rel, 0, 1)
    v = solve(mdp, p_rel.theta, p_rel.beta, model="maxent-relative").value[0]
    np.testing.assert_allclose(p_rel.value, v, atol=1e-9)
    with pytest.raises(InputError, match="model must be one of"):
        dataclasses.replace(SMOKE, model="softmax")


class _BrokenEntryPoint:
    name, value = "mine", "my_package.studies:STUDY"

    def load(self):
        raise ModuleNotFoundError("No module named 'my_package'")


@pytest.mark.parametrize(("found", "message"), [
    ([], "no study is registered (entry-point group 'expertise_irl.studies'): the installed metadata is "
         "missing or stale; reinstall the package (pip install -e .)"),
    ([_BrokenEntryPoint()], "the study entry point 'mine' (my_package.studies:STUDY) cannot be loaded: "
                            "ModuleNotFoundError: No module named 'my_package'"),
])
def test_study_registry_names_what_is_wrong_with_its_entry_points(monkeypatch, found, message):
    from expertise_irl.experiments import studies

    monkeypatch.setattr(studies, "entry_points", lambda group: found)
    studies._registered.cache_clear()
    try:
        with pytest.raises(InputError) as exc:
            studies.get_study("conditions")
        assert str(exc.value) == message
    finally:
        studies._registered.cache_clear()
    monkeypatch.undo()
    assert studies.get_study("conditions").name == "conditions"
