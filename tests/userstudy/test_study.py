"""``expertise-irl study``: manifests and their errors, Table V counts, resume, the bundled example."""

from __future__ import annotations

import csv
import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from scipy.stats import spearmanr

from expertise_irl.demos.csv_io import write_demos_csv
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.userstudy.paths import greedy_path, path_counts
from expertise_irl.worlds.warehouse import parse_floor_plan

UP, DOWN, LEFT, RIGHT = range(4)
TOML = 'world = "warehouse"\ncell_size = 1.0\n'
# 0 1 2 3 4
PLAN = "S>>>v\n..xxv\n....G\n"
EXAMPLE = Path(str(resources.files("expertise_irl.userstudy") / "example"))


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def recording(path: Path, cells, episode: int = 1) -> Path:
    """A recording that sits 2 s at each cell centre (sampled at 1 Hz, cell size 1 m)."""
    rows = ["episode,t,x,y"]
    t = 0
    for col, row in cells:
        for _ in range(2):
            rows.append(f"{episode},{t},{col + 0.5},{row + 0.5}")
            t += 1
    return write(path, "\n".join(rows) + "\n")


@pytest.fixture
def study_dir(tmp_path):
    """Two floor plans, three participants, one of them on both plans; one row via demos."""
    write(tmp_path / "a.txt", PLAN)
    write(tmp_path / "a.toml", TOML)
    write(tmp_path / "b.txt", "S...v\n.#..v\n....G\n")
    write(tmp_path / "b.toml", TOML)
    top = [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (4, 1), (4, 2)]
    low = [(0, 0), (0, 1), (0, 2), (1, 2), (2, 2), (3, 2), (4, 2)]
    recording(tmp_path / "p1.csv", top)
    recording(tmp_path / "p2.csv", low)
    recording(tmp_path / "p3b.csv", top)
    plan = parse_floor_plan(PLAN)
    idx = plan.state_index()
    s = [int(idx[1 if i and low[i][0] == low[i - 1][0] else 0, r, c]) for i, (c, r) in enumerate(low[:-1])]
    s[0] = int(idx[1, 0, 0])
    a = [DOWN, DOWN, RIGHT, RIGHT, RIGHT, RIGHT]
    write_demos_csv(
        tmp_path / "p3a.csv",
        Trajectories(np.zeros(6, int), np.arange(6), np.array(s), np.array(a)),
        plan.to_mdp(),
        fmt="grid",
    )
    write(
        tmp_path / "manifest.csv",
        "participant,map,recording,demos\nP1,a.txt,p1.csv,\nP2,a.txt,p2.csv,\n"
        "P3,a.txt,,p3a.csv\nP3,b.txt,p3b.csv,\n",
    )
    return tmp_path


# ------------------------------------------------------------------------------ counts
def test_table_v_counts_by_hand():
    plan = parse_floor_plan(PLAN)
    mdp = plan.to_mdp()
    idx = plan.state_index()
    # Along the road (right ×4, then down ×2 into the goal): one turn, every move on a road
    # but the last (the goal is not a road), none against it.
    s = [idx[0, 0, c] for c in range(5)] + [idx[1, 1, 4]]
    a = [RIGHT] * 4 + [DOWN, DOWN]
    c = path_counts(plan, mdp, s, a)
    assert c == {
        "path_length": 6,
        "path_cost": 7,
        "wrong_road_direction": 0,
        "restricted_moves": 0,
        "road_cells": 5,
        "direction_changes": 1,
    }
    # From (4,1) heading v: left into restricted (3,1), left inside it, up onto the road (2,0)
    # across its direction, left onto (1,0) against the road's '>' direction.
    s = [idx[1, 1, 4], idx[0, 1, 3], idx[0, 1, 2], idx[1, 0, 2]]
    a = [LEFT, LEFT, UP, LEFT]
    c = path_counts(plan, mdp, s, a)
    assert c == {
        "path_length": 4,
        "path_cost": 7,
        "wrong_road_direction": 1,
        "restricted_moves": 2,
        "road_cells": 2,
        "direction_changes": 3,
    }


def test_greedy_path_stops_at_a_goal_or_before_a_loop():
    mdp = parse_floor_plan("S.G\n").to_mdp()
    lp = np.full((mdp.n_states, 4), -np.inf)
    lp[:, RIGHT] = 0.0
    s, a, done = greedy_path(mdp, lp, 0)
    assert done and a.tolist() == [RIGHT, RIGHT] and len(s) == 2
    lp[:, RIGHT], lp[:, LEFT] = -1.0, -0.5  # left everywhere it can: bounces at the wall
    lp[0, LEFT] = lp[1, LEFT] = -np.inf  # not available in the first column
    s, a, done = greedy_path(mdp, lp, 0)
    assert not done and len(s) == len(set(s.tolist()))


# ---------------------------------------------------------------------- manifest errors
@pytest.mark.parametrize(
    "text, fragments",
    [
        ("participant,map\nP1,a.txt\n", ["manifest.csv:1:", "recording or demos"]),
        ("participant,map,recording\n,a.txt,p1.csv\n", ["manifest.csv:2:", "empty participant"]),
        ("participant,map,recording\nP1,a.txt,p1.csv\n../x,a.txt,p1.csv\n", ["manifest.csv:3:", "'../x'"]),
        (
            "participant,map,recording\nP1,a.txt,missing.csv\n",
            ["manifest.csv:2:", "missing.csv: no such file"],
        ),
        ("participant,map,recording\nP1,nomap.txt,p1.csv\n", ["manifest.csv:2:", "nomap.txt: no such file"]),
        ("participant,map,recording,demos\nP1,a.txt,p1.csv,p3a.csv\n", ["manifest.csv:2:", "exactly one"]),
        ("participant,map,recording\nP1,a.txt,p1.csv,extra\n", ["manifest.csv:2:", "4 fields"]),
        ("participant,map,recording\nP1,a.txt,bad.csv\n", ["manifest.csv:2:", "bad.csv:2"]),
    ],
)
def test_manifest_errors_name_the_file_and_line(study_dir, text, fragments):
    write(study_dir / "bad.csv", "episode,t,x,y\n1,0,oops,0.5\n")
    write(study_dir / "manifest.csv", text)
    res = invoke("study", study_dir / "manifest.csv", "--out", study_dir / "out")
    line = assert_input_error(res, *fragments)
    assert str(study_dir / "manifest.csv") in line
    assert not (study_dir / "out").exists()  # nothing is started before the inputs are known good


@pytest.mark.slow
def test_missing_manifest_and_a_foreign_out_dir(study_dir):
    assert_input_error(
        invoke("study", study_dir / "nope.csv", "--out", study_dir / "o"), "nope.csv", "no such manifest"
    )
    (study_dir / "busy").mkdir()
    write(study_dir / "busy" / "mine.txt", "keep me")
    assert_input_error(
        invoke("study", study_dir / "manifest.csv", "--out", study_dir / "busy"),
        "not empty and holds no study",
    )
    assert (study_dir / "busy" / "mine.txt").read_text() == "keep me"


# ----------------------------------------------------------------------------- running
def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_one_participant_on_one_floor_plan_is_a_study(study_dir):
    """The smallest study, once through: the table, the documents and the participant's estimate."""
    write(study_dir / "one.csv", "participant,map,recording,demos\nP1,a.txt,p1.csv,\n")
    out = study_dir / "out"
    ok(invoke("study", study_dir / "one.csv", "--out", out, "--workers", "1", "--thetas", "0,0.5,1",
              "--betas", "0.1,1,10", "--figures", "none"))
    (row,) = read_csv(out / "study.csv")
    assert row["participant"] == "P1" and row["tasks"] == "1"
    assert float(row["beta_q05"]) <= float(row["beta_hat"]) and 0 < float(row["beta_hat"])
    assert abs(sum(float(row[f"p_{g}"]) for g in ("high", "medium", "low")) - 1) < 1e-9
    assert "P1" in (out / "study.md").read_text(encoding="utf-8")


@pytest.mark.slow
def test_study_outputs_resume_and_multi_task_product(study_dir, monkeypatch):
    """On the study's fixed set (--no-refine; tests/userstudy/test_study_refine.py refines it)."""
    out = study_dir / "out"
    key_b = None
    from expertise_irl.userstudy.run import map_key

    key_b = map_key(parse_floor_plan("S...v\n.#..v\n....G\n", name="b.txt"))
    # First run: the task of floor plan b fails (injected), so the study stops with exit 1.
    monkeypatch.setenv("EXPERTISE_IRL_FAULTS", f"raise:{key_b}")
    res = invoke("study", study_dir / "manifest.csv", "--out", out, "--workers", "1", "--no-refine")
    assert res.exit_code == 1, res.output
    assert f"inference task {key_b} failed" in res.stderr
    assert not (out / "study.csv").exists()
    monkeypatch.delenv("EXPERTISE_IRL_FAULTS")
    # The rerun runs only what is missing: b's inference task, then the two optimal tasks.
    res = invoke("study", study_dir / "manifest.csv", "--out", out, "--workers", "1", "--no-refine")
    assert res.exit_code == 0, res.output
    assert "3 engine task(s) run, 1 already done" in res.stdout
    rows = read_csv(out / "study.csv")
    assert [r["participant"] for r in rows] == ["P1", "P2", "P3"]
    assert list(rows[0]) == [
        "participant",
        "tasks",
        "episodes",
        "beta_hat",
        "theta_length",
        "theta_restricted",
        "theta_road",
        "p_high",
        "p_medium",
        "p_low",
        "path_length",
        "path_cost",
        "wrong_road_direction",
        "restricted_moves",
        "road_cells",
        "direction_changes",
        "optimal_path_length",
        "optimal_path_cost",
        "optimal_wrong_road_direction",
        "optimal_restricted_moves",
        "optimal_road_cells",
        "optimal_direction_changes",
        "optimal_reached_goal",
        "filled_gaps",
        "snapped_samples",
        "beta_mean",
        "beta_median",
        "beta_geomean",
        "beta_q05",
        "beta_q95",
        "share",
        "goal_reached",
        "steps_to_goal",
        "cost_theta_hat",
        "feature_length",
        "feature_restricted",
        "feature_road",
        "optimal_steps_to_goal",
        "optimal_cost_theta_hat",
        "optimal_feature_length",
        "optimal_feature_restricted",
        "optimal_feature_road",
        "heldout_split",
        "heldout_actions",
        "heldout_log_likelihood_per_action",
        "warnings",
        "misspecification",
    ]
    p1, p3 = rows[0], rows[2]
    assert (p1["path_length"], p1["path_cost"], p1["road_cells"], p1["direction_changes"]) == (
        "6",
        "7",
        "5",
        "1",
    )
    assert p3["tasks"] == "2" and p3["path_length"] == "12"
    tasks = read_csv(out / "tasks.csv")
    assert [(t["participant"], t["line"]) for t in tasks] == [
        ("P1", "2"),
        ("P2", "3"),
        ("P3", "4"),
        ("P3", "5"),
    ]
    assert tasks[2]["demos"].endswith("p3a.csv") and tasks[2]["recording"] == ""
    # On the study's set (--no-refine), P3's joint posterior is the normalised product of its two
    # tasks' (uniform prior).
    doc = json.loads((out / "participants" / "P3" / "result.json").read_text())
    ll = np.array([h["log_likelihood"] for h in doc["hypotheses"]], dtype=float)
    per_task = [np.array(doc["tasks"][i]["beta_hat"]) for i in range(2)]
    assert doc["method"] == "discrete" and len(doc["hypotheses"]) == 19 * len(doc["settings"]["beta_grid"])
    p = np.array([h["probability"] for h in doc["hypotheses"]])
    np.testing.assert_allclose(p, np.exp(ll - ll.max()) / np.exp(ll - ll.max()).sum(), rtol=1e-9)
    assert doc["beta_hat"] != pytest.approx(per_task[0]) and doc["beta_hat"] != pytest.approx(per_task[1])
    assert (out / "participants" / "P3" / "P3.png").read_bytes()[:4] == b"\x89PNG"
    md = (out / "study.md").read_text().splitlines()
    # Estimates, every world's path counts, Tables V and VI: a row each per participant.
    assert sum(ln.startswith(("| P1 |", "| P2 |", "| P3 |")) for ln in md) == 12
    before = (out / "study.csv").read_bytes()
    # A third run finds everything done and writes the same tables.
    res = invoke("study", study_dir / "manifest.csv", "--out", out, "--workers", "1", "--no-refine")
    assert res.exit_code == 0 and "0 engine task(s) run, 4 already done" in res.stdout
    assert (out / "study.csv").read_bytes() == before
    # Other options or inputs on the same DIR are refused, naming what differs; nothing changes.
    assert_refused_by_name(study_dir, out, monkeypatch)


def snapshot(d: Path) -> dict[str, tuple[int, bytes]]:
    return {str(p): (p.stat().st_mtime_ns, p.read_bytes()) for p in sorted(d.rglob("*")) if p.is_file()}


def assert_refused_by_name(study_dir: Path, out: Path, monkeypatch) -> None:
    before = snapshot(out)
    m = study_dir / "manifest.csv"
    fresh = f"use another --out, or delete {out} to start again"
    assert_input_error(invoke("study", m, "--out", out, "--betas", "0.1,1", "--fill-gaps"),
                       "holds a study run with --betas auto, no --fill-gaps; this command has "
                       "--betas 0.1,1, --fill-gaps;", fresh)
    text = (study_dir / "p2.csv").read_text()
    write(study_dir / "p2.csv", text.replace(",0.5,0.5\n", ",0.55,0.5\n", 1))
    assert_input_error(invoke("study", m, "--out", out),
                       "holds a study of other inputs (the recording of manifest line 3 (p2.csv) changed);",
                       fresh)
    assert_input_error(invoke("study", m, "--out", out, "--model", "boltzmann"),
                       "run with --model maxent; this command has --model boltzmann (and the recording of "
                       "manifest line 3 (p2.csv) changed);")
    write(study_dir / "p2.csv", text)
    assert snapshot(out) == before
    # The same study named from its own folder (other paths, same files) resumes.
    monkeypatch.chdir(study_dir)
    res = invoke("study", "manifest.csv", "--out", "out", "--workers", "1", "--no-refine")
    assert res.exit_code == 0 and "0 engine task(s) run, 4 already done" in res.stdout, res.output
    # A study.json without the options and inputs: the difference cannot be named, only that there is one.
    doc = json.loads((out / "study.json").read_text())
    write(out / "study.json", json.dumps({"hash": "0" * 64, "version": doc["version"]}))
    version = doc["version"]
    assert_input_error(invoke("study", m, "--out", out), fresh,
                       f"holds a study of other inputs or options (written by expertise-irl {version})")


# ----------------------------------------------------------------------- bundled study
def test_bundled_recording_is_what_its_generator_command_writes(tmp_path):
    """The first line of generate.sh, run again, gives the bundled P01 recording byte for byte."""
    line = next(ln for ln in (EXAMPLE / "generate.sh").read_text().splitlines() if ln.startswith("rec "))
    args = line.split()[1:]
    args[args.index("--out") + 1] = str(tmp_path / "P01.csv")
    args[0] = str(EXAMPLE / args[0])
    res = invoke("simulate-recordings", *args, "--model", "maxent-relative", "--max-steps", "3000")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "P01.csv").read_bytes() == (EXAMPLE / "recordings" / "P01.csv").read_bytes()


@pytest.mark.slow
def test_bundled_study_recovers_the_ordering_of_expertise(tmp_path):
    # --check off: the ordering does not depend on the checks, which would double the run (one
    # episode each gives "not enough data to tell" anyway); the other studies here run the default.
    res = invoke("study", "example", "--out", tmp_path / "s", "--fill-gaps", "--model", "maxent-relative",
                 "--betas", "paper-real", "--check", "off")
    assert res.exit_code == 0, res.output
    est = {r["participant"]: r for r in read_csv(tmp_path / "s" / "study.csv")}
    truth = {r["participant"]: float(r["beta"]) for r in read_csv(EXAMPLE / "truth.csv")}
    ids = sorted(truth)
    rho = spearmanr([truth[i] for i in ids], [float(est[i]["beta_hat"]) for i in ids]).statistic
    # Eight people, one episode each (two for P07), seeded. The β grid (0.1, 0.3, 1, 3, 10) has
    # no value between 0.1 and 0.3, nor between 1 and 3, so neighbouring truths inside those
    # intervals (0.1/0.2/0.3 and 2.0/2.5) can trade places: those swaps cost at most
    # 1 − 6·(8 + 2)/(8·63) ≈ 0.88. ρ ≥ 0.85 means Σd² ≤ 12: beyond those swaps, no participant
    # may move four or more places (that alone gives Σd² ≥ 4² + 4 = 20).
    assert rho >= 0.85, rho
    assert int(est["P04"]["filled_gaps"]) == 1
    assert all(int(r["optimal_reached_goal"]) == int(r["episodes"]) for r in est.values())


@pytest.mark.slow
def test_map_and_nuts_studies_fit_each_participant_on_all_their_tasks(study_dir):
    from expertise_irl.demos.csv_io import read_demos_csv
    from expertise_irl.demos.recordings import discretise_recording
    from expertise_irl.inference.gradient import map_estimate
    from expertise_irl.userstudy.study import participant_seed

    out = study_dir / "out_map"
    res = invoke("study", study_dir / "manifest.csv", "--out", out, "--method", "map", "--workers", "1")
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "participants" / "P3" / "result.json").read_text())
    assert doc["method"] == "map" and doc["data"]["tasks"] == 2
    # The same MAP as the library's on P3's two tasks (same seed: the participant's).
    plan_a, plan_b = (parse_floor_plan((study_dir / n).read_text(), name=n) for n in ("a.txt", "b.txt"))
    a = read_demos_csv(study_dir / "p3a.csv", plan_a.to_mdp())
    b = discretise_recording(study_dir / "p3b.csv", plan_b).trajectories
    direct = map_estimate([plan_a.to_mdp(), plan_b.to_mdp()], [a, b], n_starts=4,
                          rng=np.random.default_rng(participant_seed("P3")))
    assert doc["map"]["log_posterior"] == pytest.approx(direct.log_posterior, abs=1e-6)
    np.testing.assert_allclose(doc["theta_hat"], direct.theta, atol=1e-4)

    out = study_dir / "out_nuts"
    res = invoke("study", study_dir / "manifest.csv", "--out", out, "--method", "nuts", "--workers", "1")
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "participants" / "P3" / "result.json").read_text())
    assert doc["method"] == "nuts" and doc["diagnostics"]["chains"] == 4
    rows = read_csv(out / "study.csv")
    # NUTS's group probabilities are fractions of its draws: they sum to 1.
    assert sum(float(rows[2][f"p_{g}"]) for g in ("high", "medium", "low")) == pytest.approx(1.0)


# ---------------------------------------------------------------------- model evidence
MODELS = ("maxent", "maxent-relative")


def low_path(plan):
    """The fixture's P2/P3a path (down the left edge, then right along the bottom) as pairs."""
    idx = plan.state_index()
    low = [(0, 0), (0, 1), (0, 2), (1, 2), (2, 2), (3, 2), (4, 2)]
    s = [int(idx[1 if i and low[i][0] == low[i - 1][0] else 0, r, c]) for i, (c, r) in enumerate(low[:-1])]
    s[0] = int(idx[1, 0, 0])
    return s, [DOWN, DOWN, RIGHT, RIGHT, RIGHT, RIGHT]


def add_three_episode_participant(study_dir) -> None:
    """P4 on floor plan a: along the road, along the bottom, along the road again."""
    plan = parse_floor_plan(PLAN)
    idx = plan.state_index()
    top_s, top_a = [int(idx[0, 0, c]) for c in range(5)] + [int(idx[1, 1, 4])], [RIGHT] * 4 + [DOWN, DOWN]
    low_s, low_a = low_path(plan)
    s, a = top_s + low_s + top_s, top_a + low_a + top_a
    ep = np.repeat([0, 1, 2], 6)
    steps = np.tile(np.arange(6), 3)
    write_demos_csv(study_dir / "p4.csv", Trajectories(ep, steps, np.array(s), np.array(a)), plan.to_mdp(),
                    fmt="grid")
    with open(study_dir / "manifest.csv", "a", encoding="utf-8") as fh:
        fh.write("P4,a.txt,,p4.csv\n")


def manifest_trajectories(study_dir):
    """``(participant, map name, trajectories)`` of every manifest row, read without the study."""
    from expertise_irl.demos.csv_io import read_demos_csv
    from expertise_irl.demos.recordings import discretise_recording

    out = []
    for r in read_csv(study_dir / "manifest.csv"):
        plan = parse_floor_plan((study_dir / r["map"]).read_text(), name=r["map"])
        if r["recording"]:
            tr = discretise_recording(study_dir / r["recording"], plan).trajectories
        else:
            tr = read_demos_csv(study_dir / r["demos"], plan.to_mdp())
        out.append((r["participant"], r["map"], tr))
    return out


@pytest.mark.slow
def test_study_models_evidence_is_the_brute_force_sum_over_tasks_and_resumes(study_dir):
    from scipy.special import logsumexp

    from expertise_irl.hypotheses import HypothesisSet, resolve_betas, resolve_thetas
    from expertise_irl.inference.belief import DiscreteBelief

    add_three_episode_participant(study_dir)
    out = study_dir / "out_models"
    args = ("study", study_dir / "manifest.csv", "--out", out, "--models", ",".join(MODELS), "--workers", "1",
            "--betas", "paper-real")
    res = invoke(*args)
    assert res.exit_code == 0, res.output
    # Brute force: per row, each hypothesis's log-likelihood from a fresh solve of its floor plan
    # under each model; summed over the participant's rows; logsumexp − log H.
    hyp = HypothesisSet(resolve_thetas("paper-real", 3), resolve_betas("paper-real"))
    H = len(hyp)
    rows = manifest_trajectories(study_dir)
    start = {
        (name, m): DiscreteBelief.from_mdp(parse_floor_plan((study_dir / name).read_text()).to_mdp(), hyp,
                                           model=m)
        for name in ("a.txt", "b.txt")
        for m in MODELS
    }
    ll: dict = {}
    for pid, name, tr in rows:
        for m in MODELS:
            ll[pid, m] = ll.get((pid, m), 0.0) + start[name, m].update(tr).log_likelihood
    evidence = {key: float(logsumexp(v)) - np.log(H) for key, v in ll.items()}
    got = read_csv(out / "models.csv")
    assert list(got[0]) == [
        "participant",
        "log_evidence_maxent",
        "log_evidence_maxent-relative",
        "best_model",
        "log_bf_maxent",
        "log_bf_maxent-relative",
        "heldout_split",
        "heldout_episodes",
        "heldout_actions",
        "heldout_per_action_maxent",
        "heldout_per_action_maxent-relative",
    ]
    assert [r["participant"] for r in got] == ["P1", "P2", "P3", "P4"]
    for r in got:
        ev = {m: evidence[r["participant"], m] for m in MODELS}
        assert abs(ev["maxent"] - ev["maxent-relative"]) > 1e-3  # the two models do differ here
        best = max(ev, key=ev.get)
        assert r["best_model"] == best
        for m in MODELS:
            assert float(r[f"log_evidence_{m}"]) == pytest.approx(ev[m], abs=1e-8)
            assert float(r[f"log_bf_{m}"]) == pytest.approx(ev[m] - ev[best], abs=1e-8)
    # Held out, P4 (one task of 3 episodes): each episode in turn, predicted from the other two.
    (tr4,) = [tr for pid, _, tr in rows if pid == "P4"]
    episodes = [Trajectories(tr4.episode[k:k + 6], tr4.step[k:k + 6], tr4.state[k:k + 6], tr4.action[k:k + 6])
                for k in (0, 6, 12)]
    p4 = got[3]
    assert (p4["heldout_split"], p4["heldout_episodes"], p4["heldout_actions"]) == ("episode", "3", "18")
    for m in MODELS:
        b = start["a.txt", m]
        ell = [b.update(e).log_likelihood for e in episodes]
        total = 0.0
        for k in range(3):
            rest = sum(ell[u] for u in range(3) if u != k)
            total += float(logsumexp(ell[k], b=np.exp(rest - logsumexp(rest))))
        assert float(p4[f"heldout_per_action_{m}"]) == pytest.approx(total / 18, abs=1e-8)
    # P3 (two tasks of one episode each): each task in turn, predicted from the other.
    p3 = got[2]
    assert (p3["heldout_split"], p3["heldout_episodes"], p3["heldout_actions"]) == ("task", "2", "12")
    for m in MODELS:
        ell = [start[name, m].update(tr).log_likelihood for pid, name, tr in rows if pid == "P3"]
        total = sum(float(logsumexp(ell[k], b=np.exp(ell[1 - k] - logsumexp(ell[1 - k])))) for k in range(2))
        assert float(p3[f"heldout_per_action_{m}"]) == pytest.approx(total / 12, abs=1e-8)
    # One task of one episode has nothing to hold out.
    for r in got[:2]:
        assert r["heldout_split"] == "none" and r["heldout_per_action_maxent"] == ""
    # result.json: the main result is --model's default (maxent); model_evidence beside it.
    doc = json.loads((out / "participants" / "P3" / "result.json").read_text())
    assert doc["settings"]["model"] == "maxent"
    assert doc["log_evidence"] == pytest.approx(evidence["P3", "maxent"], abs=1e-8)
    me = doc["model_evidence"]
    assert [f["model"] for f in me["models"]] == list(MODELS) and me["n_hypotheses"] == H
    assert me["heldout"]["split"] == "task" and not me["unavailable"]
    me1 = json.loads((out / "participants" / "P1" / "result.json").read_text())["model_evidence"]
    assert "needs a task with 2 episodes" in me1["unavailable"]["heldout_log_likelihood_per_action"]
    md = (out / "study.md").read_text()
    assert "## Model evidence" in md and sum(ln.startswith("| P") for ln in md.splitlines()) == 4 * 5
    # The extra phase is its own sweep; a rerun runs nothing and writes the same table.
    assert (out / "engine" / "inference-maxent-relative").is_dir()
    assert not (out / "engine" / "inference-maxent").exists()  # --model's sweep serves maxent
    before = (out / "models.csv").read_bytes()
    res = invoke(*args)
    assert res.exit_code == 0 and "0 engine task(s) run, 6 already done" in res.stdout, res.output
    assert (out / "models.csv").read_bytes() == before


@pytest.mark.parametrize("method", ["map", "nuts"])
def test_models_need_the_discrete_method(study_dir, method):
    out = study_dir / "out"
    res = invoke("study", study_dir / "manifest.csv", "--out", out, "--method", method, "--models", "maxent")
    assert_input_error(res, "--models needs --method discrete")
    assert not out.exists()


@pytest.mark.parametrize(
    "spec, fragment",
    [
        ("maxent,nope", "--models must be one of"),
        ("maxent,maxent", "names a model twice"),
        (",", "at least one"),
    ],
)
def test_bad_models_are_refused(study_dir, spec, fragment):
    out = study_dir / "out"
    assert_input_error(invoke("study", study_dir / "manifest.csv", "--out", out, "--models", spec), fragment)
    assert not out.exists()
