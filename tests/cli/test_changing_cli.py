"""``infer --expertise changing``: the learning curve in the result, its summary, and ``plot``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok

from expertise_irl.demos.csv_io import write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.worlds.maps import load_bundled_world

THETA = np.array([0.5, 0.25, 0.25, 0.0, 0.0])


@pytest.fixture(scope="module")
def learner(tmp_path_factory):
    """A person on crossroads whose β falls log-linearly from 2 to 0.05 over 12 episodes
    (``maxent-relative``, so that the noisy early episodes still end at the goal)."""
    d = tmp_path_factory.mktemp("learner")
    mdp = load_bundled_world("crossroads").to_mdp()
    rng = np.random.default_rng(0)
    betas = np.exp(np.linspace(np.log(2.0), np.log(0.05), 12))
    parts = []
    for e, b in enumerate(betas):
        t = simulate(mdp, THETA, b, 1, rng, model="maxent-relative")
        parts.append(Trajectories(np.full(len(t), 10 + e), t.step, t.state, t.action))
    tr = Trajectories(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("episode", "step", "state",
                                                                                 "action")))
    write_demos_csv(d / "demos.csv", tr, mdp)
    common = ("infer", "crossroads", "--demos", d / "demos.csv", "--model", "maxent-relative")
    ok(invoke(*common, "--no-refine", "--out", d / "stationary.json"))  # the set changing expertise keeps
    res = invoke(*common, "--expertise", "changing", "--out", d / "changing.json")
    ok(res)
    return d, betas, res


@pytest.mark.slow
def test_the_result_has_the_learning_curve_beside_the_stationary_estimate(learner):
    from scipy.stats import spearmanr

    d, betas, res = learner
    doc = json.loads((d / "changing.json").read_text())
    still = json.loads((d / "stationary.json").read_text())
    # beta_hat and theta_hat stay the stationary estimate, a stationary run's: the same to the solvers'
    # tolerances (the changing run solves every hypothesis to 1e-8 nats, the stationary one is
    # certified: every probability within 1e-6, here far closer)
    assert doc["beta_hat"] == pytest.approx(still["beta_hat"], rel=1e-9)
    np.testing.assert_allclose(doc["theta_hat"], still["theta_hat"], rtol=1e-9, atol=1e-12)
    curve = doc["expertise_by_episode"]
    assert [c["episode"] for c in curve] == list(range(10, 22))  # the file's labels, in order
    for c in curve:
        assert c["q05"] <= c["median"] <= c["q95"]
    # 12 episodes falling 40-fold: the curve follows them and the evidence favours change.
    assert spearmanr(betas, [c["mean"] for c in curve]).statistic >= 0.8
    ch = doc["changing"]
    assert ch["log_bayes_factor"] > 0 and ch["p_changing"] > 0.5 and 0 < ch["epsilon_mean"] <= 0.2
    assert doc["trend"]["p_falls"] > 0.5 and doc["trend"]["log_ratio_mean"] < 0
    assert doc["settings"]["expertise"] == "changing" and doc["settings"]["epsilons"][0] == 0.0
    assert still["settings"]["expertise"] == "stationary" and "expertise_by_episode" not in still
    assert "changing expertise: log Bayes factor" in res.stdout


@pytest.mark.slow
def test_plot_draws_the_learning_curve(learner):
    from expertise_irl.plots.results import result_figure

    d, _, _ = learner
    doc = json.loads((d / "changing.json").read_text())
    fig = result_figure(doc, source=d / "changing.json")
    gids = {a.get_gid() for ax in fig.get_axes() for a in ax.get_children()}
    assert {"curve-band", "curve-mean", "curve-median", "curve-stationary"} <= gids
    ok(invoke("plot", d / "changing.json", "--out", d / "curve.png"))
    assert (d / "curve.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_changing_expertise_is_refused_where_it_is_not_built(learner):
    d, _, _ = learner
    base = ("infer", "crossroads", "--demos", d / "demos.csv", "--out", d / "x.json")
    assert_input_error(invoke(*base, "--expertise", "sometimes"),
                       "--expertise must be one of stationary, changing")
    assert_input_error(invoke(*base, "--expertise", "changing", "--method", "birl"),
                       "--expertise applies only to --method discrete or --method map or --method nuts")
    assert not (d / "x.json").exists()


def _two_task_manifest(d, mdp, people, rng) -> None:
    """``d/m.csv``: each person's β per episode (``people[pid]``, even length) split over two
    crossroads tasks in order, one demonstrations file per task (episodes labelled from 0)."""
    lines = ["participant,map,demos"]
    for pid, betas in people.items():
        half = len(betas) // 2
        for task in range(2):
            parts = []
            for e in range(half):
                t = simulate(mdp, THETA, betas[half * task + e], 1, rng, model="maxent-relative")
                parts.append(Trajectories(np.full(len(t), e), t.step, t.state, t.action))
            tr = Trajectories(*(np.concatenate([getattr(p, k) for p in parts])
                                for k in ("episode", "step", "state", "action")))
            write_demos_csv(d / f"{pid}-{task}.csv", tr, mdp)
            lines.append(f"{pid},crossroads,{pid}-{task}.csv")
    (d / "m.csv").write_text("\n".join(lines) + "\n")


@pytest.mark.slow
def test_a_study_with_changing_expertise_tests_whether_people_improve(tmp_path):
    """Four learners (β falling 2 → 0.05 over 8 episodes, 4 per task, two tasks on crossroads) and
    one steady person: each participant's curve runs over their tasks in manifest order and is the
    library's on their episodes; study.md counts who improves and gives the sign test."""
    import csv

    from expertise_irl.demos.csv_io import read_demos_csv
    from expertise_irl.inference.changing import changing_posterior, trend_summary
    from expertise_irl.inference.methods import DiscreteOptions
    from expertise_irl.planning.soft_vi import solve
    from expertise_irl.planning.table_likelihood import log_likelihood

    mdp = load_bundled_world("crossroads").to_mdp()
    rng = np.random.default_rng(3)
    people = {f"L{i}": np.exp(np.linspace(np.log(2.0), np.log(0.05), 8)) for i in range(4)}
    people["S"] = np.full(8, 0.3)
    _two_task_manifest(tmp_path, mdp, people, rng)
    out = tmp_path / "out"
    ok(invoke("study", tmp_path / "m.csv", "--out", out, "--workers", "1", "--betas", "paper-sim",
              "--model", "maxent-relative", "--expertise", "changing", "--figures", "none"))
    rows = {r["participant"]: r for r in csv.DictReader(open(out / "study.csv", encoding="utf-8"))}
    assert sum(float(rows[f"L{i}"]["trend_p_falls"]) > 0.5 for i in range(4)) == 4
    md = (out / "study.md").read_text()
    falls = sum(float(r["trend_p_falls"]) > 0.5 for r in rows.values())
    assert f"**Do people improve?** {falls} of 5 participants" in md
    # L0's curve: 8 episodes over its two tasks, the library's result on them.
    doc = json.loads((out / "participants" / "L0" / "result.json").read_text())
    curve = doc["expertise_by_episode"]
    order = [(c["task"], c["task_episode"]) for c in curve]
    assert order == [(0, e) for e in range(4)] + [(1, e) for e in range(4)]
    hyp = DiscreteOptions(thetas="paper-real", betas="paper-sim").hypotheses(5)
    lp = solve(mdp, hyp.theta, hyp.beta, model="maxent-relative").log_policy
    ell = [log_likelihood(lp, s, a) for task in range(2)
           for s, a in read_demos_csv(tmp_path / f"L0-{task}.csv", mdp).episodes()]
    cp = changing_posterior(np.stack(ell), hyp)
    assert doc["trend"]["p_falls"] == pytest.approx(trend_summary(cp)["p_falls"], abs=1e-9)
    np.testing.assert_allclose([c["mean"] for c in curve], cp.mean_beta, rtol=1e-9)
    # Where the model does not apply, the study says so before doing anything.
    for extra in (("--share", "beta"), ("--share", "beta", "--method", "map")):
        assert_input_error(invoke("study", tmp_path / "m.csv", "--out", tmp_path / "x",
                                  "--expertise", "changing", *extra), "needs --share both")
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_a_map_study_fits_each_participants_curve_over_their_tasks(tmp_path):
    """``study --method map --expertise changing``: each participant's learning curve runs over
    their manifest rows in order (two tasks, three episodes each), is the library's MAP curve on those
    tasks, and study.md's sign test counts the MAP slopes (no Bayes factor from a point estimate)."""
    import csv

    from expertise_irl.demos.csv_io import read_demos_csv
    from expertise_irl.inference.priors import concentration_of
    from expertise_irl.inference.trend import trend_objective

    mdp = load_bundled_world("crossroads").to_mdp()
    rng = np.random.default_rng(4)
    people = {"L": np.exp(np.linspace(np.log(2.0), np.log(0.05), 6)), "S": np.full(6, 0.3)}
    _two_task_manifest(tmp_path, mdp, people, rng)
    out = tmp_path / "out"
    ok(invoke("study", tmp_path / "m.csv", "--out", out, "--workers", "1", "--method", "map",
              "--model", "maxent-relative", "--expertise", "changing", "--figures", "none"))
    rows = {r["participant"]: r for r in csv.DictReader(open(out / "study.csv", encoding="utf-8"))}
    assert rows["L"]["changing_log_bf"] == "" and rows["L"]["trend_p_falls"] == ""
    assert float(rows["L"]["trend_log_ratio"]) < -1.0  # β fell 40-fold: λ* = −3.69
    doc = json.loads((out / "participants" / "L" / "result.json").read_text())
    curve, tr = doc["expertise_by_episode"], doc["trend"]
    assert [(c["task"], c["line"], c["task_episode"]) for c in curve] == \
        [(0, 2, 0), (0, 2, 1), (0, 2, 2), (1, 3, 0), (1, 3, 1), (1, 3, 2)]
    assert [c["episode"] for c in curve] == list(range(6))
    assert curve[0]["mean"] == pytest.approx(tr["beta0"], rel=1e-12)
    assert curve[-1]["mean"] == pytest.approx(tr["beta0"] * np.exp(tr["slope"]), rel=1e-12)
    # The reported optimum is the six-episode objective's value at the reported curve, θ's Dirichlet(α)
    # written in z counted at its optimal scale: α·Σ log θ_i + Kα·log(Kα) − Kα.
    trajs = [read_demos_csv(tmp_path / f"L-{task}.csv", mdp) for task in range(2)]
    f, _ = trend_objective([mdp, mdp], trajs, model="maxent-relative")
    ll, lp = f(np.asarray(tr["theta_hat"]), np.log(tr["beta0"]), tr["slope"])
    a, K = concentration_of("log-uniform"), len(tr["theta_hat"])
    theta_part = a * np.log(tr["theta_hat"]).sum() + K * a * np.log(K * a) - K * a
    assert tr["log_posterior"] == pytest.approx(float(ll + lp) + theta_part, abs=1e-6)
    md = (out / "study.md").read_text()
    falls = sum(float(r["trend_log_ratio"]) < 0 for r in rows.values())
    assert f"**Do people improve?** {falls} of 2 participants are estimated to end more expert" in md


def test_the_filtered_beta_after_each_action_is_the_model_on_the_data_so_far():
    """``filtered_by_action`` after action t equals the changing model run on everything up to t
    (the finished episodes and the current one so far), its last filtered row; to 1e-12."""
    from expertise_irl.hypotheses import HypothesisSet
    from expertise_irl.inference.changing import changing_posterior, filtered_by_action

    rng = np.random.default_rng(5)
    hyp = HypothesisSet(np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]), np.array([0.1, 0.5, 2.0]))
    index = np.array([0, 0, 0, 1, 1, 2, 2, 2, 2])
    step = rng.normal(-1.5, 1.0, size=(len(index), len(hyp)))
    step[4, 2] = -np.inf  # an impossible action under one hypothesis
    live = filtered_by_action(step, index, hyp)
    for t in range(len(index)):
        e = index[t]
        rows = [step[(index == k)].sum(axis=0) for k in range(e)]
        rows.append(step[: t + 1][index[: t + 1] == e].sum(axis=0))
        want = changing_posterior(np.stack(rows), hyp).beta_filtered[-1]
        np.testing.assert_allclose(live[t], want, rtol=1e-12, atol=1e-15)


@pytest.mark.slow
def test_per_action_results_carry_the_current_episodes_beta(learner):
    d, _, _ = learner
    ok(invoke("infer", "crossroads", "--demos", d / "demos.csv", "--model", "maxent-relative",
              "--expertise", "changing", "--per-action", "--out", d / "live.json"))
    doc = json.loads((d / "live.json").read_text())
    live = doc["expertise_trace"]
    assert len(live) == doc["data"]["actions"] == len(doc["trace"]) - 1
    assert [(x["episode"], x["step"]) for x in live] == [(t["episode"], t["step"]) for t in doc["trace"][1:]]
    for x in live:
        assert x["q05"] <= x["q95"]
    # After the last action, filtering has seen everything: the smoothed last episode's β.
    assert live[-1]["beta_mean"] == pytest.approx(doc["expertise_by_episode"][-1]["mean"], rel=1e-9)
    # Early on the person is noisy, at the end expert: the live estimate falls with them.
    assert live[0]["beta_mean"] > 5 * live[-1]["beta_mean"]


@pytest.mark.slow
def test_map_gives_the_learning_curve_beside_the_one_beta_estimate(learner):
    from expertise_irl.plots.results import result_figure

    d, _, _ = learner
    common = ("infer", "crossroads", "--demos", d / "demos.csv", "--model", "maxent-relative",
              "--method", "map", "--starts", "2")
    ok(invoke(*common, "--out", d / "map1.json"))
    res = invoke(*common, "--expertise", "changing", "--out", d / "map2.json")
    ok(res)
    one, doc = (json.loads((d / n).read_text()) for n in ("map1.json", "map2.json"))
    assert doc["beta_hat"] == one["beta_hat"] and doc["theta_hat"] == one["theta_hat"]  # one β, unchanged
    curve = doc["expertise_by_episode"]
    assert len(curve) == 12 and doc["trend"]["slope"] < 0 and curve[0]["mean"] > curve[-1]["mean"]
    assert doc["changing"]["log_bayes_factor"] is None
    assert "MAP gives no evidence" in doc["changing"]["unavailable"]
    assert "learning curve: log β_e = log β_0 + λ·" in res.stdout
    gids = {a.get_gid() for ax in result_figure(doc).get_axes() for a in ax.get_children()}
    assert "curve-mean" in gids and "curve-band" not in gids


@pytest.mark.slow  # two NUTS runs (the one-β posterior and the curve's), short chains
def test_nuts_gives_the_learning_curves_posterior_beside_the_one_beta_posterior(learner):
    d, _, _ = learner
    ok(invoke("infer", "crossroads", "--demos", d / "demos.csv", "--model", "maxent-relative",
              "--method", "nuts", "--chains", "2", "--warmup", "100", "--samples", "100",
              "--expertise", "changing", "--out", d / "nuts.json"))
    doc = json.loads((d / "nuts.json").read_text())
    curve, tr = doc["expertise_by_episode"], doc["trend"]
    assert len(curve) == 12 and all(c["q05"] <= c["median"] <= c["q95"] for c in curve)
    # β fell 40-fold (λ* = log 0.025 = −3.69): the draws say it fell.
    assert tr["p_falls"] > 0.9 and tr["slope_q05"] < tr["slope"] < tr["slope_q95"] < 0
    assert doc["changing"]["log_bayes_factor"] is None and doc["changing"]["unavailable"]
    assert doc["settings"]["expertise"] == "changing"


def test_the_engine_option_leaves_stationary_studies_as_they_were():
    """``UserStudyConfig.expertise`` came after studies were run without it: at its default it is
    not part of the config (so their sweeps keep their hash and resume), and it round-trips."""
    from expertise_irl.experiments.spec import config_dict, config_from_dict
    from expertise_irl.userstudy.study import CONTINUOUS, UserStudyConfig

    still = config_dict(UserStudyConfig(data="{}", method="map"))
    assert "expertise" not in still and still["share"] == "both"
    changing = config_dict(UserStudyConfig(data="{}", method="map", expertise="changing"))
    assert changing == {**still, "expertise": "changing"}
    assert config_from_dict(CONTINUOUS, changing).expertise == "changing"
    assert config_from_dict(CONTINUOUS, still) == UserStudyConfig(data="{}", method="map")
    with pytest.raises(Exception, match=r"^expertise must be one of stationary, changing"):
        UserStudyConfig(data="{}", expertise="sometimes")
