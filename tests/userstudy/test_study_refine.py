"""``study`` without a named set: each participant's posterior over a set refined from the study's
(inference.adaptive), the same as refining over their tasks directly; a named set stays fixed; a study
directory made without refinement resumes."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok

from expertise_irl.demos.csv_io import read_demos_csv, write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import HypothesisSet, resolve_thetas
from expertise_irl.inference.adaptive import refine_tasks
from expertise_irl.mdp import TabularMDP
from expertise_irl.worlds.zones import parse_map

A = """
S.....s...
S..xx.....
S..xx....G
S.....tt..
..>>>>>>..
"""
B = """
S....tt...
S..ss.....
S..ss..xxG
S.........
..<<<<<<..
"""
# θ* off every grid; P1 on map a, P2 on both maps (one (θ, β) for both).
PEOPLE = {"P1": ([0.5, 0.1, 0.25, 0.1, 0.05], 0.42, [("a", 12, 1)]),
          "P2": ([0.3, 0.3, 0.1, 0.2, 0.1], 0.15, [("a", 6, 2), ("b", 6, 3)])}


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def result(out: Path, pid: str) -> dict:
    return json.loads((out / "participants" / pid / "result.json").read_text())


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """Two maps as MDP archives and two simulated people (seeded), demonstrations by state."""
    d = tmp_path_factory.mktemp("study_refine")
    mdps = {}
    for name, text in (("a", A), ("b", B)):
        mdps[name] = parse_map(text.strip("\n"), name=name).to_mdp()
        mdps[name].save(d / f"{name}.npz")
    lines = ["participant,map,demos"]
    for pid, (theta, beta, tasks) in PEOPLE.items():
        for name, n, seed in tasks:
            trajs = simulate(mdps[name], np.array(theta), beta, n, np.random.default_rng(seed), max_steps=200)
            write_demos_csv(d / f"{pid}-{name}.csv", trajs, mdps[name], fmt="state")
            lines.append(f"{pid},{name}.npz,{pid}-{name}.csv")
    (d / "manifest.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    out = d / "default"
    ok(invoke("study", d / "manifest.csv", "--out", out, "--check", "off", "--figures", "none",
              "--workers", "1"))
    return d


@pytest.mark.slow
def test_no_named_set_refines_each_participant_as_refining_their_tasks_directly(study):
    out = study / "default"
    rows = {r["participant"]: r for r in read_csv(out / "study.csv")}
    for pid, (_, _, tasks) in PEOPLE.items():
        doc = result(out, pid)
        s, rec = doc["settings"], doc["refinement"]
        assert s["hypotheses"] == "adaptive"
        assert s["n_hypotheses"] == rec["n_hypotheses"] == len(doc["hypotheses"])
        assert len(rec["rounds"]) >= 2 and rec["rounds"][0]["solved"] == 0  # the sweep's start: not solved
        assert float(rows[pid]["beta_hat"]) == pytest.approx(doc["beta_hat"], rel=1e-12)
        # the same refinement run directly over the participant's tasks, solving the start itself
        mdps = {n: TabularMDP.load(study / f"{n}.npz") for n, _, _ in tasks}
        shown = [(mdps[n], read_demos_csv(study / f"{pid}-{n}.csv", mdps[n])) for n, _, _ in tasks]
        direct = refine_tasks(shown, HypothesisSet(resolve_thetas("paper-real", 5), s["beta_grid"]),
                              keep_policies=False)
        assert rec["n_hypotheses"] == len(direct.hypotheses)
        p = np.exp(direct.log_likelihood - direct.log_likelihood.max()) * direct.prior
        p /= p.sum()
        np.testing.assert_allclose([h["probability"] for h in doc["hypotheses"]], p, rtol=1e-6, atol=1e-12)
        assert doc["beta_hat"] == pytest.approx(p @ direct.hypotheses.beta, rel=1e-6)
        np.testing.assert_allclose(doc["theta_hat"], p @ direct.hypotheses.theta, atol=1e-8)
        np.testing.assert_allclose([float(rows[pid][f"theta_{f}"]) for f in doc["feature_names"]],
                                   doc["theta_hat"], rtol=1e-12)
    # P2's two tasks moved the estimate away from either task's own (kept on the study's set)
    p2 = result(out, "P2")
    assert all(p2["beta_hat"] != pytest.approx(t["beta_hat"], rel=1e-3) for t in p2["tasks"])


@pytest.mark.slow
def test_a_named_set_stays_fixed(study):
    out = study / "named"
    grid = ",".join(f"{b:g}" for b in result(study / "default", "P1")["settings"]["beta_grid"])
    ok(invoke("study", study / "manifest.csv", "--out", out, "--betas", grid, "--check", "off",
              "--figures", "none", "--workers", "1"))
    for pid in PEOPLE:
        doc = result(out, pid)
        assert "refinement" not in doc and doc["settings"]["hypotheses"] == "fixed"
        assert len(doc["hypotheses"]) == len(resolve_thetas("paper-real", 5)) * len(grid.split(","))


@pytest.mark.slow
def test_a_study_made_without_refinement_resumes_and_may_refine(study):
    """--no-refine writes the study.json the defaults wrote before refinement existed; the default
    then resumes it (inference not run again), refines, and --no-refine again finds everything done."""
    out = study / "old"
    m = study / "manifest.csv"
    args = ("--check", "off", "--figures", "none", "--workers", "1")
    ok(invoke("study", m, "--out", out, "--no-refine", *args))
    ident = (out / "study.json").read_bytes()
    assert "refinement" not in result(out, "P1") and "refine" not in json.loads(ident)["options"]
    fixed = (out / "study.csv").read_bytes()
    res = invoke("study", m, "--out", out, *args[:-1], "2")  # the participants refined in 2 processes
    ok(res)
    assert "2 engine task(s) run, 2 already done" in res.stdout  # the refined θ̂'s optimal paths only
    assert "refinement" in result(out, "P1") and (out / "study.json").read_bytes() == ident
    assert (out / "study.csv").read_bytes() == (study / "default" / "study.csv").read_bytes()
    res = invoke("study", m, "--out", out, "--no-refine", *args)
    ok(res)
    assert "0 engine task(s) run, 4 already done" in res.stdout and (out / "study.csv").read_bytes() == fixed


@pytest.mark.slow
def test_the_check_runs_on_the_refined_posterior(study, monkeypatch, tmp_path):
    from expertise_irl.inference import misspecification
    from expertise_irl.userstudy.run import ReportOptions, StudyOptions, run_study

    seen = {}

    def spy(doc, tasks, posterior, **kw):
        seen[doc["participant"]] = posterior

    monkeypatch.setattr(misspecification, "add_to_result", spy)
    run_study(study / "manifest.csv", tmp_path / "out", StudyOptions(), workers=1,
              report=ReportOptions(figures="none", check="fast"))
    for pid in PEOPLE:
        doc = result(tmp_path / "out", pid)
        assert len(seen[pid]["theta"]) == doc["refinement"]["n_hypotheses"]
        np.testing.assert_allclose(seen[pid]["weights"], [h["probability"] for h in doc["hypotheses"]])
        np.testing.assert_allclose(seen[pid]["beta"], [h["beta"] for h in doc["hypotheses"]])


@pytest.mark.slow
@pytest.mark.parametrize("extra", [("--share", "beta"), ("--expertise", "changing")])
def test_refine_needs_one_theta_and_beta_per_participant(study, tmp_path, extra):
    assert_input_error(invoke("study", study / "manifest.csv", "--out", tmp_path / "x", "--refine", *extra),
                       "--refine needs --method discrete, --share both and --expertise stationary")
    assert not (tmp_path / "x").exists()
    with pytest.raises(InputError, match="--refine"):
        from expertise_irl.userstudy.run import ReportOptions, StudyOptions, refines

        refines(StudyOptions(share="beta"), ReportOptions(refine=True))
