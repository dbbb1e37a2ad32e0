"""``study`` with the teaching model: ``--model pedagogical`` (each result's teaching record, β̂ the teaching
model's), ``--models ...,pedagogical`` (its evidence and columns in models.csv), the report's verdicts, and
what the study refuses with it."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from scipy.special import logsumexp
from teaching_task import crossroads_task

from expertise_irl.demos.csv_io import read_demos_csv, write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.hypotheses import HypothesisSet, theta_grid
from expertise_irl.inference import pedagogical as P
from expertise_irl.numerics import enable_float64
from expertise_irl.planning.soft_vi import solve
from expertise_irl.userstudy.teaching import MODELS_TEACHING_COLUMNS, TEACHING_COLUMNS

#: crossroads' five features; 31 θ × 3 β, every θ with a 0 component, so nobody's prior keeps one at 0
SET = ("--thetas", "0,1", "--betas", "0.1,0.5,2")


@pytest.fixture(scope="module")
def task():
    return crossroads_task()


def episodes(task, lam: float, seed: int, n: int):
    """θ = (1, 0, 0, 0, 0) at β = 0.1 (a hypothesis of the set), teaching at ``lam``. At seed 1, 10 episodes:
    the teacher's 2 log BF is 44.3 (tests/inference/test_evidence_pedagogical.py measures its spread)."""
    mdp, hyp, lp = task
    pol = P.teacher_log_policy(mdp, hyp.thetas[15], 0.1, lam, P.observer(hyp, lp))
    return simulate(mdp, None, None, n, np.random.default_rng(seed), log_policy=pol, max_steps=100)


@pytest.fixture
def study_dir(task, tmp_path):
    """T, a teacher (10 episodes); D, a doer on two rows (5 episodes each), all on crossroads."""
    mdp = task[0]
    for name, lam, seed, n in (("t", 1.0, 1, 10), ("d1", 0.0, 1, 5), ("d2", 0.0, 2, 5)):
        write_demos_csv(tmp_path / f"{name}.csv", episodes(task, lam, seed, n), mdp)
    (tmp_path / "manifest.csv").write_text("participant,map,demos\nT,crossroads,t.csv\nD,crossroads,d1.csv\n"
                                           "D,crossroads,d2.csv\n", encoding="utf-8")
    return tmp_path


def read_csv(path):
    with open(path, encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


def posterior_of(task, study_dir, files, lambdas=P.LAMBDAS):
    """A participant's posterior over Ψ × Λ without the study: each row's pairs through the core, their
    [L, H] log-likelihoods summed over rows (the observer is per state, so the sum is the whole's)."""
    mdp, hyp, lp = task
    parts = [P.teaching_posterior(lp, hyp, read_demos_csv(study_dir / f, mdp), lambdas=lambdas)
             for f in files]
    return P.TeachingPosterior(hyp, parts[0].lambdas, parts[0].log_prior,
                               sum(p.log_likelihood for p in parts), sum(p.n_observed for p in parts))


@pytest.mark.slow
def test_model_pedagogical_reads_the_teacher_as_teaching(task, study_dir):
    out = study_dir / "out"
    args = ("study", study_dir / "manifest.csv", "--out", out, *SET, "--model", "pedagogical",
            "--models", "maxent,pedagogical", "--figures", "none", "--workers", "1")
    res = invoke(*args)
    ok(res)
    _, hyp, lp = task
    docs = {p: json.loads((out / "participants" / p / "result.json").read_text()) for p in ("T", "D")}
    truth = {"T": posterior_of(task, study_dir, ["t.csv"]),
             "D": posterior_of(task, study_dir, ["d1.csv", "d2.csv"])}
    for pid, doc in docs.items():
        tp, rec = truth[pid], docs[pid]["teaching"]
        assert doc["settings"]["model"] == "pedagogical" and doc["settings"]["lambdas"] == list(P.LAMBDAS)
        assert rec["verdict"] == tp.verdict and rec["log_bayes_factor"] == pytest.approx(tp.log_bayes_factor,
                                                                                         abs=1e-8)
        assert rec["lambda_probabilities"] == pytest.approx(tp.lambda_probabilities.tolist(), abs=1e-9)
        assert doc["beta_hat"] == pytest.approx(tp.belief(lp).mean_beta, abs=1e-9)  # the teaching model's β̂
        assert "pedagogical" in doc["diagnostics"]["unavailable"]["misspecification"]
    assert docs["T"]["teaching"]["verdict"] == "teaching" and docs["D"]["teaching"]["verdict"] != "teaching"
    # T's held-out check (leave-one-episode-out) over Ψ × Λ, episode by episode through the core
    mdp = task[0]
    t = read_demos_csv(study_dir / "t.csv", mdp)
    prior = (P.lambda_log_prior(truth["T"].lambdas)[:, None] + truth["T"].log_prior[None, :]).ravel()
    masks = [t.episode == e for e in t.episode_ids]
    one = [Trajectories(t.episode[m], t.step[m], t.state[m], t.action[m]) for m in masks]
    ell = [P.teaching_posterior(lp, hyp, e).log_likelihood.ravel() for e in one]
    total = logsumexp(sum(ell) + prior)
    want = sum(total - logsumexp(sum(ell) - ell[k] + prior) for k in range(len(ell))) / len(t)
    assert docs["T"]["heldout"]["per_action"] == pytest.approx(want, abs=1e-9)
    # models.csv: maxent's evidence is the λ = 0 evidence of the teaching sweep (no sweep of its own)
    rows = {r["participant"]: r for r in read_csv(out / "models.csv")}
    assert list(rows["T"])[-len(MODELS_TEACHING_COLUMNS):] == list(MODELS_TEACHING_COLUMNS)
    for pid, r in rows.items():
        ped = docs[pid]["model_evidence"]["models"][1]
        assert ped["model"] == "pedagogical"
        assert float(r["log_evidence_maxent"]) == pytest.approx(ped["teaching"]["log_evidence_by_lambda"][0],
                                                                abs=1e-9)
        lbf = float(r["log_evidence_pedagogical"]) - float(r["log_evidence_maxent"])
        assert float(r["teaching_log_bf"]) == pytest.approx(lbf, abs=1e-9)
        assert lbf == pytest.approx(truth[pid].log_bayes_factor, abs=1e-8)
        assert r["teaching_verdict"] == docs[pid]["teaching"]["verdict"]
    assert rows["T"]["best_model"] == "pedagogical" and rows["D"]["best_model"] == "maxent"
    assert not (out / "engine" / "inference-maxent").exists()
    study = {r["participant"]: r for r in read_csv(out / "study.csv")}
    assert list(study["T"])[-len(TEACHING_COLUMNS):] == list(TEACHING_COLUMNS)
    assert study["T"]["teaching_verdict"] == "teaching"
    md = (out / "study.md").read_text(encoding="utf-8")
    assert "## Teaching or doing? (pedagogical)" in md
    assert f"**Verdicts:** teaching 1, doing {int(study['D']['teaching_verdict'] == 'doing')}," in md
    assert "- T: demonstrations read as teaching (2 log BF = " in md
    assert "teaching verdicts: teaching 1" in res.stdout
    assert "lambdas" not in json.loads((out / "study.json").read_text())["options"]  # the default grid
    again = invoke(*args)
    ok(again)
    assert "0 engine task(s) run" in again.stdout


@pytest.mark.slow
def test_models_pedagogical_beside_maxent_has_its_own_sweep_and_grid(task, study_dir):
    out = study_dir / "out"
    ok(invoke("study", study_dir / "manifest.csv", "--out", out, *SET, "--models", "maxent,pedagogical",
              "--lambdas", "1,0,0.1", "--figures", "none", "--workers", "1", "--check", "off"))
    rows = {r["participant"]: r for r in read_csv(out / "models.csv")}
    assert (out / "engine" / "inference-pedagogical").is_dir()
    for pid, files in (("T", ["t.csv"]), ("D", ["d1.csv", "d2.csv"])):
        tp = posterior_of(task, study_dir, files, lambdas=(0, 0.1, 1))
        z = tp.log_evidence_by_lambda
        r = rows[pid]
        # maxent's own sweep (another solve, to the same tolerance) gives the teaching sweep's λ = 0
        assert float(r["log_evidence_maxent"]) == pytest.approx(z[0], abs=1e-9)
        assert float(r["log_evidence_pedagogical"]) == pytest.approx(float(logsumexp(z[1:]) - math.log(2)),
                                                                     abs=1e-9)
        assert float(r["lambda_hat"]) == pytest.approx(float(tp.lambda_probabilities @ tp.lambdas), abs=1e-9)
        lo, hi = tp.lambda_interval()
        assert (float(r["lambda_q05"]), float(r["lambda_q95"])) == (lo, hi)
        assert float(r["beta_hat_maxent"]) == pytest.approx(tp.belief(task[2], doer=True).mean_beta, abs=1e-9)
    doc = json.loads((out / "participants" / "T" / "result.json").read_text())
    assert doc["settings"]["model"] == "maxent" and doc["settings"]["lambdas"] == [0.0, 0.1, 1.0]
    assert "teaching" not in doc  # the main result is maxent's
    assert "teaching_verdict" not in read_csv(out / "study.csv")[0]
    md = (out / "study.md").read_text(encoding="utf-8")
    assert "From --models" in md and "λ grid: 0, 0.1, 1;" in md
    assert json.loads((out / "study.json").read_text())["options"]["lambdas"] == "0.0,0.1,1.0"


@pytest.mark.parametrize("options, fragment", [
    (["--model", "pedagogical", "--method", "map"], "--method map: --model pedagogical needs --method"),
    (["--model", "pedagogical", "--method", "nuts"], "--method nuts: --model pedagogical needs"),
    (["--model", "pedagogical", "--share", "beta"], "--share beta: --model pedagogical needs --share both"),
    (["--models", "maxent,pedagogical", "--share", "beta"], "--share beta: pedagogical in --models needs"),
    (["--model", "pedagogical", "--expertise", "changing"], "--expertise changing is not built for --model "
                                                            "pedagogical"),
    (["--model", "pedagogical", "--refine"], "--refine cannot be used with --model pedagogical"),
    (["--model", "pedagogical", "--population"], "--population is not built for --model pedagogical"),
    (["--lambdas", "0,0.1"], "--lambdas is the pedagogical model's"),
    (["--model", "pedagogical", "--lambdas", "0.1,1"], "--lambdas must hold 0"),
    (["--models", "pedagogical", "--lambdas", "0,x"], "--lambdas must be comma-separated numbers"),
])
def test_what_the_study_cannot_do_with_the_teaching_model_is_refused(tmp_path, options, fragment):
    (tmp_path / "manifest.csv").write_text("participant,map,demos\nT,crossroads,t.csv\n", encoding="utf-8")
    out = tmp_path / "out"
    assert_input_error(invoke("study", tmp_path / "manifest.csv", "--out", out, *options), fragment)
    assert not out.exists()


def test_the_teaching_sweep_is_the_core_per_episode_and_its_lambda_zero_is_the_discrete_sweep():
    """The engine's side on a small zone map: each episode's [L, H] values are the core's posterior of that
    episode alone, and λ = 0 is ``user-study-discrete``'s maxent log-likelihood (one solve each, the same
    tolerance)."""
    from expertise_irl.userstudy.study import (
        UserStudyConfig,
        lambdas_spec,
        run_discrete,
        run_teaching,
        world_entry,
    )
    from expertise_irl.worlds.zones import parse_map

    enable_float64()
    world = parse_map("S...\n.#..\n...G\n", name="small")
    mdp = world.to_mdp()
    trajs = simulate(mdp, np.array([0.6, 0.1, 0.1, 0.1, 0.1]), 0.5, 3, np.random.default_rng(0), max_steps=30)
    task = {"task": 0, "participant": "P", "map": "m", "episodes": trajs.episode.tolist(),
            "steps": trajs.step.tolist(), "states": trajs.state.tolist(), "actions": trajs.action.tolist()}
    cfg = UserStudyConfig(data=json.dumps({"maps": {"m": world_entry(world)}, "tasks": [task]}), thetas="0,1",
                          betas="0.5,2", lambdas=lambdas_spec("1, 0,0.1"))
    teach, _ = run_teaching(cfg, 0, {"map": "m"})
    doer, _ = run_discrete(cfg, 0, {"map": "m"})
    hyp = HypothesisSet(theta_grid((0.0, 1.0), mdp.n_features), np.array([0.5, 2.0]))
    H, L = len(hyp), 3
    got = teach["log_likelihood"].reshape(3, L, H)  # (episode, λ, hypothesis), in that order
    assert teach["lambda"].reshape(3, L, H)[0, :, 0].tolist() == [0, 1, 2]
    np.testing.assert_allclose(got[:, 0, :], doer["log_likelihood"].reshape(3, H), rtol=0, atol=1e-12)
    lp = np.asarray(solve(mdp, hyp.theta, hyp.beta).log_policy)
    for e in range(3):
        m = trajs.episode == e
        one = Trajectories(trajs.episode[m], trajs.step[m], trajs.state[m], trajs.action[m])
        want = P.teaching_posterior(lp, hyp, one, lambdas=(0, 0.1, 1)).log_likelihood
        np.testing.assert_allclose(got[e], want, rtol=0, atol=1e-9)
