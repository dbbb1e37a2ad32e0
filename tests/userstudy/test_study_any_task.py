"""``expertise-irl study`` on any task: MDP archives and zone maps in a manifest, ``--share beta``,
the held-out check, study diagnostics and β summaries, extra manifest columns and ``--group-by``."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from scipy.special import logsumexp

from expertise_irl.demos.csv_io import write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import HypothesisSet
from expertise_irl.inference.methods import DiscreteOptions
from expertise_irl.planning.soft_vi import solve
from expertise_irl.planning.table_likelihood import log_likelihood
from expertise_irl.userstudy import posteriors
from expertise_irl.worlds.warehouse import parse_floor_plan
from expertise_irl.worlds.zones import load_bundled, parse_map

TOML = 'world = "warehouse"\ncell_size = 1.0\n'
PLAN = "S>>>v\n..xxv\n....G\n"
BETAS = "0.03,0.1,0.3,1,3"


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def demos(path: Path, mdp, theta, beta, n, seed, fmt="state") -> Path:
    trajs = simulate(mdp, np.asarray(theta, float), beta, n, np.random.default_rng(seed))
    write_demos_csv(path, trajs, mdp, fmt=fmt)
    return path


def cosine(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))


def task_ll(mdp, hyp, path) -> np.ndarray:
    """``[H]`` log-likelihood of a demonstrations file under every hypothesis (a fresh solve)."""
    from expertise_irl.demos.csv_io import read_demos_csv

    tr = read_demos_csv(path, mdp)
    sol = solve(mdp, hyp.theta, hyp.beta)
    return log_likelihood(sol.log_policy, tr.state, tr.action)


# --------------------------------------------------------------------------- any map
@pytest.fixture
def mixed(tmp_path):
    """A floor plan, a bundled zone map and an MDP archive (the zone map's MDP exported)."""
    write(tmp_path / "plan.txt", PLAN)
    write(tmp_path / "plan.toml", TOML)
    plan = parse_floor_plan(PLAN)
    corridor = load_bundled("corridor").to_mdp()
    corridor.save(tmp_path / "corridor.npz")
    demos(tmp_path / "p1.csv", plan.to_mdp(), [0.6, 0.2, 0.2], 0.1, 2, seed=1, fmt="grid")
    demos(tmp_path / "p2.csv", corridor, [0.5, 0.2, 0.1, 0.1, 0.1], 0.3, 2, seed=2, fmt="grid")
    demos(tmp_path / "p3a.csv", corridor, [0.5, 0.2, 0.1, 0.1, 0.1], 0.3, 1, seed=3)
    demos(tmp_path / "p3b.csv", corridor, [0.5, 0.2, 0.1, 0.1, 0.1], 0.3, 1, seed=4)
    write(tmp_path / "manifest.csv",
          "participant,map,demos,condition\n"
          "P1,plan.txt,p1.csv,do\nP2,corridor,p2.csv,show\nP3,corridor.npz,p3a.csv,show\n"
          "P3,corridor.npz,p3b.csv,show\n")
    return tmp_path


@pytest.mark.slow
def test_a_manifest_mixing_a_floor_plan_a_zone_map_and_an_archive_runs(mixed):
    out = mixed / "out"
    res = invoke("study", mixed / "manifest.csv", "--out", out, "--workers", "1", "--figures", "1",
                 "--group-by", "condition")
    ok(res)
    rows = {r["participant"]: r for r in read_csv(out / "study.csv")}
    # θ columns: the union of the features, empty where a participant's tasks lack one.
    assert rows["P1"]["theta_restricted"] != "" and rows["P1"]["theta_avoid"] == ""
    assert rows["P2"]["theta_avoid"] != "" and rows["P2"]["theta_restricted"] == ""
    # Table V's counts only on the floor plan; every world's counts everywhere.
    assert rows["P1"]["wrong_road_direction"] != "" and rows["P2"]["wrong_road_direction"] == ""
    for r in rows.values():
        assert int(r["path_length"]) > 0 and r["cost_theta_hat"] != "" and r["steps_to_goal"] != ""
        assert int(r["goal_reached"]) == int(r["episodes"])  # simulated to the goal
    assert float(rows["P2"]["feature_length"]) != 0
    # The held-out split: P1, P2 have a task of 2 episodes; P3 two single-episode tasks.
    assert [rows[p]["heldout_split"] for p in ("P1", "P2", "P3")] == ["episode", "episode", "task"]
    assert all(float(rows[p]["heldout_log_likelihood_per_action"]) < 0 for p in rows)
    # Extra columns verbatim, and --group-by's section.
    assert [rows[p]["condition"] for p in ("P1", "P2", "P3")] == ["do", "show", "show"]
    assert [t["condition"] for t in read_csv(out / "tasks.csv")] == ["do", "show", "show", "show"]
    md = (out / "study.md").read_text()
    assert "## β by condition" in md and "Table V" in md
    # --figures 1: only the first participant's figure, and the study's.
    assert (out / "participants" / "P1" / "P1.png").is_file()
    assert not (out / "participants" / "P2" / "P2.png").exists()
    assert (out / "study.png").read_bytes()[:4] == b"\x89PNG"
    # The β grid came from the maps and the result says so.
    doc = json.loads((out / "participants" / "P3" / "result.json").read_text())
    assert doc["settings"]["betas"] == "auto" and "q_gap_median" in doc["settings"]["beta_grid_source"]
    assert min(doc["settings"]["beta_grid"]) < 0.01
    # A rerun with other report options redraws the reports without running the engine again.
    res = invoke("study", mixed / "manifest.csv", "--out", out, "--workers", "1", "--figures", "none")
    ok(res)
    assert "0 engine task(s) run" in res.stdout


@pytest.mark.slow
def test_an_archive_study_is_infer_mdp_on_each_task_multiplied(mixed, tmp_path):
    out = tmp_path / "npz"
    write(tmp_path / "m.csv", "participant,map,demos\nP3,corridor.npz,p3a.csv\nP3,corridor.npz,p3b.csv\n")
    ok(invoke("study", tmp_path / "m.csv", "--out", out, "--workers", "1", "--betas", BETAS,
              "--figures", "none"))
    lls = []
    for name in ("p3a", "p3b"):
        ok(invoke("infer", "--mdp", mixed / "corridor.npz", "--demos", mixed / f"{name}.csv",
                  "--betas", BETAS, "--out", tmp_path / f"{name}.json"))
        doc = json.loads((tmp_path / f"{name}.json").read_text())
        lls.append(np.array([h["log_likelihood"] for h in doc["hypotheses"]], float))
    joint = lls[0] + lls[1]
    want = np.exp(joint - logsumexp(joint))
    got = json.loads((out / "participants" / "P3" / "result.json").read_text())
    p = np.array([h["probability"] for h in got["hypotheses"]])
    np.testing.assert_allclose(p, want, rtol=1e-6, atol=1e-12)
    assert got["share"] == "both"


def test_recordings_need_a_floor_plan_and_bad_maps_are_named(mixed):
    write(mixed / "rec.csv", "episode,t,x,y\n1,0,0.5,0.5\n1,1,1.5,0.5\n")
    write(mixed / "bad.csv", "participant,map,recording\nP1,corridor.npz,rec.csv\n")
    assert_input_error(invoke("study", mixed / "bad.csv", "--out", mixed / "o"),
                       "bad.csv:2:", "is an MDP archive", "needs a floor plan")
    write(mixed / "bad2.csv", "participant,map,demos\nP1,nowhere.npz,p1.csv\n")
    assert_input_error(invoke("study", mixed / "bad2.csv", "--out", mixed / "o"),
                       "bad2.csv:2:", "nowhere.npz", "no such file")
    write(mixed / "bad3.csv", "participant,map,demos\nP1,plan.txt,p1.csv\nP1,corridor,p2.csv\n")
    assert_input_error(invoke("study", mixed / "bad3.csv", "--out", mixed / "o"),
                       "bad3.csv:3:", "a participant's tasks must have the same features")
    write(mixed / "bad4.csv", "participant,map,demos,beta_hat\nP1,plan.txt,p1.csv,x\n")
    assert_input_error(invoke("study", mixed / "bad4.csv", "--out", mixed / "o"),
                       "column 'beta_hat' is a column the study writes")
    assert_input_error(invoke("study", mixed / "manifest.csv", "--out", mixed / "o", "--group-by", "nope"),
                       "--group-by nope: no such manifest column", "condition")
    assert_input_error(invoke("study", mixed / "manifest.csv", "--out", mixed / "o", "--share", "theta"),
                       "--share must be one of both, beta")
    assert_input_error(invoke("study", mixed / "manifest.csv", "--out", mixed / "o", "--figures", "x"),
                       "--figures must be all, none or a positive number")
    assert not (mixed / "o").exists()


# ------------------------------------------------------------------------ --share beta
@pytest.mark.slow
def test_share_beta_recovers_each_tasks_theta_and_is_the_product_over_tasks(tmp_path):
    mdp = load_bundled("corridor").to_mdp()
    mdp.save(tmp_path / "c.npz")
    # Length and road on one task, length and traffic on the other; one β. With 20 episodes each
    # the per-task θ̂ beat the pooled one on both tasks for 5 of 5 seeds tried (θ_avoid's cells
    # lie off the corridor's paths, so a truth with avoid in it would not be identified).
    truths = ([0.5, 0.5, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0, 0.5])
    beta = 0.1
    for j, th in enumerate(truths):
        demos(tmp_path / f"t{j}.csv", mdp, th, beta, 20, seed=j)
    write(tmp_path / "m.csv", "participant,map,demos\nP,c.npz,t0.csv\nP,c.npz,t1.csv\n")
    cos = {}
    for share in ("both", "beta"):
        out = tmp_path / share
        ok(invoke("study", tmp_path / "m.csv", "--out", out, "--workers", "1", "--betas", BETAS,
                  "--share", share, "--figures", "none"))
        tasks = read_csv(out / "tasks.csv")
        names = mdp.feature_names
        est = [[float(t[f"theta_{f}"]) for f in names] for t in tasks]
        if share == "both":  # every task's θ̂ is the participant's
            doc = json.loads((out / "participants" / "P" / "result.json").read_text())
            est = [doc["theta_hat"]] * 2
        cos[share] = [cosine(e, t) for e, t in zip(est, truths, strict=True)]
    assert all(b > a for a, b in zip(cos["both"], cos["beta"], strict=True)), cos
    # The share-beta posterior equals the brute-force product over tasks of each θ-marginal.
    hyp = DiscreteOptions(thetas="paper-real", betas=BETAS).hypotheses(5)
    lls = [task_ll(mdp, hyp, tmp_path / f"t{j}.csv").reshape(hyp.n_theta, hyp.n_beta) for j in range(2)]
    m = [logsumexp(ll, axis=0) - math.log(hyp.n_theta) for ll in lls]
    log_pb = m[0] + m[1]
    pb = np.exp(log_pb - logsumexp(log_pb))
    doc = json.loads((tmp_path / "beta" / "participants" / "P" / "result.json").read_text())
    assert doc["share"] == "beta" and doc["theta_hat"] is None
    np.testing.assert_allclose(doc["marginals"]["beta"]["probabilities"], pb, rtol=1e-6, atol=1e-12)
    for j in range(2):
        cond = np.exp(lls[j] - logsumexp(lls[j], axis=0))  # P(θ | β, Ξ_j)
        pt = cond @ pb
        np.testing.assert_allclose(doc["tasks"][j]["marginals"]["theta"]["probabilities"], pt,
                                   rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(doc["theta_hat_by_task"][j], pt @ hyp.thetas, rtol=1e-6, atol=1e-12)


# --------------------------------------------------------------------------- held out
def _hyp():
    return HypothesisSet(np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]), np.array([0.1, 1.0]))


def test_leave_one_task_out_is_the_explicit_posterior_predictive():
    rng = np.random.default_rng(0)
    hyp = _hyp()
    H = len(hyp)
    episode_ll = [rng.normal(-5, 2, size=(1, H)) for _ in range(3)]  # three single-episode tasks
    actions = [[4], [6], [5]]
    got = posteriors.heldout_check(episode_ll, actions, hyp, "both")
    assert got["split"] == "task" and got["units"] == 3 and got["actions"] == 15
    total = 0.0
    for t in range(3):
        rest = sum(episode_ll[u][0] for u in range(3) if u != t)
        post = np.exp(rest - logsumexp(rest))  # P(h | the other tasks), uniform prior
        total += math.log(post @ np.exp(episode_ll[t][0]))  # Σ_h P(h | rest) P(ξ_t | h)
    assert got["per_action"] == pytest.approx(total / 15, rel=1e-12)
    # Within tasks of 2 episodes: leave-one-episode-out, the rest of the participant kept.
    episode_ll = [rng.normal(-5, 2, size=(2, H)), rng.normal(-5, 2, size=(1, H))]
    got = posteriors.heldout_check(episode_ll, [[3, 4], [2]], hyp, "both")
    assert got["split"] == "episode" and got["units"] == 2 and got["actions"] == 7
    every = episode_ll[0].sum(0) + episode_ll[1][0]
    total = 0.0
    for e in range(2):
        rest = every - episode_ll[0][e]
        post = np.exp(rest - logsumexp(rest))
        total += math.log(post @ np.exp(episode_ll[0][e]))
    assert got["per_action"] == pytest.approx(total / 7, rel=1e-12)
    # With --share beta single-episode tasks are not held out, and the reason is given.
    single = [rng.normal(size=(1, H)), rng.normal(size=(1, H))]
    got = posteriors.heldout_check(single, [[3], [3]], hyp, "beta")
    assert got["split"] == "none" and got["per_action"] is None and "--share beta" in got["unavailable"]


def test_share_beta_leave_one_episode_out_is_the_explicit_predictive():
    rng = np.random.default_rng(1)
    hyp = _hyp()
    episode_ll = [rng.normal(-5, 2, size=(2, len(hyp))), rng.normal(-5, 2, size=(1, len(hyp)))]
    got = posteriors.heldout_check(episode_ll, [[3, 4], [2]], hyp, "beta")

    def evidence(task_lls):  # brute force over (β, θ_1, θ_2): uniform priors
        total = []
        for j in range(hyp.n_beta):
            for i1 in range(hyp.n_theta):
                for i2 in range(hyp.n_theta):
                    total.append(task_lls[0].reshape(3, 2)[i1, j] + task_lls[1].reshape(3, 2)[i2, j])
        return logsumexp(total) - math.log(hyp.n_beta * hyp.n_theta ** 2)

    full = [episode_ll[0].sum(0), episode_ll[1][0]]
    want = sum(evidence(full) - evidence([episode_ll[0][1 - e], episode_ll[1][0]]) for e in range(2))
    assert got["split"] == "episode" and got["per_action"] == pytest.approx(want / 7, rel=1e-12)


# ------------------------------------------------------------------------ diagnostics
@pytest.mark.slow
def test_an_expert_below_the_grid_and_a_constant_feature_are_warned(tmp_path):
    zone = parse_map("S....\n.###.\n.....\n....G\n", name="open")  # no road, avoid, slow, traffic cells
    write(tmp_path / "open.txt", zone.to_text())
    mdp = zone.to_mdp()
    demos(tmp_path / "e.csv", mdp, [1, 0, 0, 0, 0], 0.005, 3, seed=5, fmt="grid")
    corridor = load_bundled("corridor").to_mdp()
    demos(tmp_path / "c.csv", corridor, [0.5, 0.5, 0, 0, 0], 0.005, 3, seed=6, fmt="grid")
    write(tmp_path / "m.csv", "participant,map,demos\nE,open.txt,e.csv\nC,corridor,c.csv\n")
    out = tmp_path / "out"
    res = invoke("study", tmp_path / "m.csv", "--out", out, "--workers", "1", "--betas", "1,3,10",
                 "--figures", "none")
    ok(res)
    assert "warning(s)" in res.stderr
    md = (out / "study.md").read_text()
    doc = json.loads((out / "participants" / "C" / "result.json").read_text())
    edge = [w for w in doc["diagnostics"]["warnings"] if "smallest β of the grid" in w]
    assert edge and any(ln.startswith("- C: ") and "smallest β of the grid" in ln for ln in md.splitlines())
    doc = json.loads((out / "participants" / "E" / "result.json").read_text())
    named = {f for f in ("road", "avoid", "slow", "traffic")
             if any(f"feature {f} is 0 on every task" in w for w in doc["diagnostics"]["warnings"])}
    assert named == {"road", "avoid", "slow", "traffic"}, doc["diagnostics"]["warnings"]
    assert doc["diagnostics"]["kept_at_zero"] == ["road", "avoid", "slow", "traffic"]
    assert doc["theta_hat"][1:] == [0.0, 0.0, 0.0, 0.0]
    assert "**Warnings: " in md
    rows = {r["participant"]: r for r in read_csv(out / "study.csv")}
    assert int(rows["E"]["warnings"]) >= 4 and int(rows["C"]["warnings"]) >= 1
    # β summaries: the interval holds the median, the geometric mean lies below the mean.
    for r in rows.values():
        q05, med, q95 = float(r["beta_q05"]), float(r["beta_median"]), float(r["beta_q95"])
        assert q05 <= med <= q95 and float(r["beta_geomean"]) <= float(r["beta_mean"]) + 1e-12
        assert float(r["beta_mean"]) == pytest.approx(float(r["beta_hat"]))


@pytest.mark.slow
def test_share_beta_with_map_is_the_libraries_shared_beta_fit(mixed):
    from expertise_irl.demos.csv_io import read_demos_csv
    from expertise_irl.inference.shared_beta import map_shared_beta
    from expertise_irl.userstudy.study import participant_seed

    write(mixed / "m.csv", "participant,map,demos\nP3,corridor.npz,p3a.csv\nP3,corridor,p2.csv\n")
    out = mixed / "map"
    ok(invoke("study", mixed / "m.csv", "--out", out, "--workers", "1", "--method", "map", "--share", "beta",
              "--figures", "none"))
    doc = json.loads((out / "participants" / "P3" / "result.json").read_text())
    mdp = load_bundled("corridor").to_mdp()
    trajs = [read_demos_csv(mixed / n, mdp) for n in ("p3a.csv", "p2.csv")]
    direct = map_shared_beta([mdp, mdp], trajs, n_starts=4, rng=np.random.default_rng(participant_seed("P3")))
    assert doc["share"] == "beta" and doc["theta_hat"] is None and doc["settings"]["share"] == "beta"
    np.testing.assert_allclose(doc["theta_hat_by_task"], direct.thetas, atol=1e-6)
    assert doc["beta_hat"] == pytest.approx(direct.beta, rel=1e-6)
    tasks = read_csv(out / "tasks.csv")
    np.testing.assert_allclose([[float(t[f"theta_{f}"]) for f in mdp.feature_names] for t in tasks],
                               direct.thetas, atol=1e-6)
    row = read_csv(out / "study.csv")[0]
    assert row["share"] == "beta" and row["theta_length"] == "" and row["heldout_split"] == "none"
    assert "needs --method discrete" in doc["heldout"]["unavailable"]


def test_a_bump_into_a_wall_is_written_in_the_state_form_and_read_back(tmp_path):
    """On a grid with a layout, a move that stays in its cell cannot be an x,y row: ``auto`` writes
    the state,action form (which a study reads on the same archive), ``grid`` refuses, naming it."""
    from expertise_irl.demos.csv_io import read_demos_csv
    from expertise_irl.demos.trajectories import Trajectories
    from expertise_irl.errors import InputError
    from expertise_irl.mdp import TabularMDP

    # A corridor of 3 cells, goal on the right; up and down bump into the walls.
    nxt = np.array([[0, 0, 0, 1], [1, 1, 0, 2], [2, 2, 2, 2]])
    mdp = TabularMDP(next_state=nxt, features=-np.ones((3, 4, 1)), terminal=np.array([False, False, True]),
                     feature_names=("length",), state_xy=np.array([[0, 0], [1, 0], [2, 0]]))
    tr = Trajectories(np.zeros(3, int), np.arange(3), np.array([0, 0, 1]), np.array([0, 3, 3]))
    write_demos_csv(tmp_path / "d.csv", tr, mdp)
    assert (tmp_path / "d.csv").read_text().startswith("episode,step,state,action\n")
    back = read_demos_csv(tmp_path / "d.csv", mdp)
    assert back.state.tolist() == [0, 0, 1] and back.action.tolist() == [0, 3, 3]
    with pytest.raises(InputError, match="episode 0 step 0: the move stays in its cell"):
        write_demos_csv(tmp_path / "g.csv", tr, mdp, fmt="grid")
    # Without a bump, auto still writes cells.
    write_demos_csv(tmp_path / "c.csv", Trajectories(np.zeros(2, int), np.arange(2), np.array([0, 1]),
                                                     np.array([3, 3])), mdp)
    assert (tmp_path / "c.csv").read_text().startswith("episode,step,x,y\n")
