"""Adaptive hypothesis sets (inference.adaptive): the lattice, exactness over the final set, caps,
and the default of ``infer`` when no set is named."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from cli_helpers import invoke, ok

from expertise_irl.demos.csv_io import write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.hypotheses import HypothesisSet
from expertise_irl.inference import adaptive
from expertise_irl.inference.adaptive import Refinement, refine, simplex_lattice, start_resolution, start_set
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.methods import DiscreteOptions
from expertise_irl.worlds.zones import parse_map

MAP = """
S.....s...
S..xx.....
S..xx....G
S.....tt..
..>>>>>>..
"""


@pytest.fixture(scope="module")
def mdp():
    return parse_map(MAP, name="adaptive-test").to_mdp()


@pytest.fixture(scope="module")
def person(mdp):
    """θ* from a Dirichlet and β* = 0.42 (between the start set's 0.316 and 1): on no grid."""
    rng = np.random.default_rng(7)
    theta = rng.dirichlet(np.ones(mdp.n_features))
    return theta, 0.42, simulate(mdp, theta, 0.42, 25, rng, max_steps=200)


@pytest.mark.parametrize(("K", "n"), [(2, 5), (3, 4), (5, 4)])
def test_simplex_lattice_is_every_composition(K, n):
    grid = simplex_lattice(K, n)
    assert len(grid) == math.comb(n + K - 1, K - 1)
    assert np.allclose(grid.sum(axis=1), 1.0) and (grid >= 0).all()
    assert len(np.unique(np.round(grid * n).astype(int), axis=0)) == len(grid)
    assert np.allclose(grid * n, np.round(grid * n))


def test_start_set_is_small_and_covers_both_ends():
    hyp = start_set(5)
    assert start_resolution(5) == 4 and hyp.n_theta == 70  # C(8, 4)
    assert hyp.betas[0] == pytest.approx(0.01) and hyp.betas[-1] == pytest.approx(10.0)
    assert np.allclose(np.diff(np.log10(hyp.betas)), 0.5)
    assert len(start_set(3).thetas) <= adaptive.START_THETAS_MAX


@pytest.mark.slow
def test_the_posterior_is_exact_over_the_final_set(mdp, person):
    """The refined set's policies, stacked in its order, equal a fresh solve of that set, so the
    posterior over it is Eq. 13 with the recorded prior weights."""
    _, _, trajs = person
    r = refine(mdp, trajs, start_set(mdp.n_features), theta_step=1 / start_resolution(mdp.n_features))
    assert len(r.record["rounds"]) >= 2 and r.record["n_hypotheses"] == len(r.hypotheses)
    mine = DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior).update(trajs)
    fresh = DiscreteBelief.from_mdp(mdp, r.hypotheses, prior=r.prior).update(trajs)
    np.testing.assert_allclose(mine.probabilities, fresh.probabilities, atol=1e-9)
    # the last round's record is this posterior's
    last = r.record["rounds"][-1]
    assert last["beta_hat"] == pytest.approx(mine.mean_beta, rel=1e-9)
    np.testing.assert_allclose(last["theta_hat"], mine.mean_theta, atol=1e-9)


def test_refinement_reads_a_beta_between_the_grid_values(mdp, person):
    """Off the grid, the refined β̂ is closer to β* than the start set's, and within a factor 1.6
    (the posterior's 90% interval here is about ±25%; 1.6 is two of its half-widths)."""
    _, beta, trajs = person
    hyp = start_set(mdp.n_features)
    coarse = DiscreteBelief.from_mdp(mdp, hyp).update(trajs)
    r = refine(mdp, trajs, hyp, theta_step=1 / start_resolution(mdp.n_features))
    fine = DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior).update(trajs)
    assert abs(math.log(fine.mean_beta / beta)) < abs(math.log(coarse.mean_beta / beta))
    assert abs(math.log(fine.mean_beta / beta)) < math.log(1.6)
    assert r.hypotheses.n_beta > hyp.n_beta or r.record["pruned_mass"] > 0
    assert r.warnings == [] and r.record["converged"]


def test_the_prior_weighs_each_cell(mdp, person):
    """Start hypotheses weigh 1; a θ refined l times 2^-(K-1)·l, a β 2^-l."""
    _, _, trajs = person
    r = refine(mdp, trajs, start_set(mdp.n_features), theta_step=0.25)
    K = mdp.n_features
    w = r.prior.reshape(r.hypotheses.n_theta, r.hypotheses.n_beta)
    assert np.allclose(w / w[:, :1], w[:1] / w[0, 0])  # a product of a θ part and a β part
    lt, lb = np.log2(w[:, 0] / w[:, 0].max()), np.log2(w[0] / w[0].max())
    assert np.allclose(lt / (K - 1), np.round(lt / (K - 1))) and np.allclose(lb, np.round(lb))
    assert lt.min() < 0 and lb.min() < 0  # both were refined


def test_a_cap_stops_with_a_warning_and_the_posterior_so_far(mdp, person):
    _, _, trajs = person
    hyp = start_set(mdp.n_features)
    r = refine(mdp, trajs, hyp, theta_step=0.25, settings=Refinement(max_hypotheses=len(hyp) + 5))
    assert not r.record["converged"] and "--max-hypotheses" in r.record["stop_reason"]
    assert len(r.warnings) == 1 and "stopped before the estimate settled" in r.warnings[0]
    assert len(r.hypotheses) <= len(hyp)  # the start set, less what was pruned
    start = DiscreteBelief.from_mdp(mdp, hyp).update(trajs)
    mine = DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior).update(trajs)
    assert mine.mean_beta == pytest.approx(start.mean_beta, rel=1e-6)


def test_bad_settings_are_refused():
    from expertise_irl.errors import InputError

    with pytest.raises(InputError, match="tol_beta"):
        Refinement(tol_beta=0)
    with pytest.raises(InputError, match="max_hypotheses"):
        DiscreteOptions(max_hypotheses=0)


def test_a_named_set_is_used_as_given():
    assert DiscreteOptions().refines and not DiscreteOptions(betas="0.1,1,10").refines
    assert not DiscreteOptions(sample_thetas=5).refines and DiscreteOptions(betas="1", refine=True).refines
    fixed = DiscreteOptions(refine=False).hypotheses(5)
    assert (fixed.n_theta, fixed.n_beta) == (211, 6)  # paper-real Θ × paper-sim B, as before
    hyp = DiscreteOptions(thetas="0,1", betas="0.1,1,10").hypotheses(5)
    assert isinstance(hyp, HypothesisSet) and len(hyp) == 31 * 3


def test_infer_refines_by_default_and_keeps_a_named_set(tmp_path, mdp, person):
    _, _, trajs = person
    npz, demos = tmp_path / "task.npz", tmp_path / "demos.csv"
    mdp.save(npz)
    write_demos_csv(demos, trajs, mdp)
    ok(invoke("infer", "--mdp", npz, "--demos", demos, "--out", tmp_path / "a.json", "--check", "off"))
    doc = json.loads((tmp_path / "a.json").read_text())
    assert doc["settings"]["hypotheses"] == "adaptive" and doc["settings"]["thetas"] == "adaptive"
    ref = doc["refinement"]
    assert ref["n_hypotheses"] == doc["settings"]["n_hypotheses"] == len(doc["hypotheses"])
    assert sum(r["solved"] for r in ref["rounds"]) == ref["solved"]
    assert doc["beta_hat"] == pytest.approx(ref["rounds"][-1]["beta_hat"], rel=1e-9)
    ok(invoke("infer", "--mdp", npz, "--demos", demos, "--out", tmp_path / "b.json", "--check", "off",
              "--thetas", "0,0.5,1", "--betas", "0.1,1,10"))
    doc = json.loads((tmp_path / "b.json").read_text())
    assert "refinement" not in doc and doc["settings"]["hypotheses"] == "fixed"
    assert doc["settings"]["n_hypotheses"] == 211 * 3


def test_changing_expertise_keeps_the_paper_grid():
    """A β per episode needs a grid spanning every episode's β, not the one-β posterior's refinement."""
    from expertise_irl.errors import InputError

    opts = DiscreteOptions(expertise="changing")
    assert not opts.refines and len(opts.hypotheses(5)) == 1266
    with pytest.raises(InputError, match="expertise changing"):
        DiscreteOptions(expertise="changing", refine=True)


@pytest.mark.slow
def test_a_coarse_named_set_is_told_from_missing_features(tmp_path):
    """The README's example: β* = 0.5 lies between 0.1 and 1 of the named set, whose posterior fails
    the predictive checks; refined, the same checks pass, so the verdict is a coarse set and there is
    no missing-features warning."""
    from expertise_irl.inference.misspecification import COARSE, UNEXPLAINED

    demos, out = tmp_path / "demos.csv", tmp_path / "trace.json"
    ok(invoke("simulate", "crossroads", "--theta", "0.5,0.5,0,0,0", "--beta", "0.5", "--episodes", "20",
              "--seed", "1", "--out", demos))
    res = invoke("infer", "crossroads", "--demos", demos, "--thetas", "0,0.5,1", "--betas", "0.1,1,10",
                 "--out", out)
    ok(res)
    doc = json.loads(out.read_text())
    mis = doc["diagnostics"]["misspecification"]
    assert mis["verdict"] == COARSE and mis["first"]["verdict"] == UNEXPLAINED
    assert 0.1 < mis["refined"]["beta_hat"] < 1.0 and mis["refined"]["n_hypotheses"] > 633
    assert doc["beta_hat"] == pytest.approx(1.0, rel=1e-6)  # the named set's own estimate is kept
    assert not any(w.startswith(UNEXPLAINED) for w in doc["diagnostics"]["warnings"])
    assert any(w.startswith(COARSE) for w in doc["diagnostics"]["warnings"])
    assert "too coarse" in res.output
    # plot --check wraps the long reason instead of widening the page (one line of it was 3,563 px wide)
    import matplotlib.image as mpimg

    ok(invoke("plot", out, "--check", "--map", "crossroads", "--out", tmp_path / "check.png"))
    height, width = mpimg.imread(tmp_path / "check.png").shape[:2]
    assert width < 1.3 * height


def test_the_round_cap_warns_only_when_the_estimate_has_not_settled(mdp, person):
    _, _, trajs = person
    hyp = start_set(mdp.n_features)
    free = refine(mdp, trajs, hyp, theta_step=0.25)
    n = len(free.record["rounds"]) - 1  # the rounds it needed
    enough = refine(mdp, trajs, hyp, theta_step=0.25, settings=Refinement(max_rounds=n))
    assert enough.warnings == [] and enough.record["converged"]
    short = refine(mdp, trajs, hyp, theta_step=0.25, settings=Refinement(max_rounds=1))
    assert not short.record["converged"] and "1 round (the cap)" in short.record["stop_reason"]
    assert len(short.warnings) == 1 and len(short.record["rounds"]) == 2


# ----------------------------------------------------------------------------- several tasks
OTHER = """
S....tt...
S..ss.....
S..ss..xxG
S.........
..<<<<<<..
"""


@pytest.mark.slow
def test_several_tasks_share_one_hypothesis_and_sum_their_log_likelihoods(mdp, person):
    """Over two maps the refined set's log-likelihood of a hypothesis is the sum of a fresh solve's on
    each map, each map's policies are kept in task order, and the record's last estimate is the
    posterior of that sum with the recorded prior."""
    theta, beta, trajs = person
    other = parse_map(OTHER, name="adaptive-other").to_mdp()
    shown = simulate(other, theta, beta, 10, np.random.default_rng(8), max_steps=200)
    step = 1 / start_resolution(mdp.n_features)
    r = adaptive.refine_tasks([(mdp, trajs), (other, shown)], start_set(mdp.n_features), theta_step=step)
    assert isinstance(r.log_policy, tuple) and len(r.log_policy) == 2
    parts = [DiscreteBelief.from_mdp(m, r.hypotheses, tol=1e-11).update(t)
             for m, t in ((mdp, trajs), (other, shown))]
    # each log-likelihood within its certified error of a fresh solve to 1e-11 nats (whose own
    # error is at most 2e-11 per action), the eliminated ones too, at their screening tolerance
    fresh = parts[0].log_likelihood + parts[1].log_likelihood
    slack = r.log_likelihood_error + 2e-11 * (len(trajs.state) + len(shown.state))
    assert np.all(np.abs(r.log_likelihood - fresh) <= slack)
    assert r.eliminated.any() and (r.log_likelihood_error[~r.eliminated] < 1e-4).all()
    np.testing.assert_allclose(parts[1].log_likelihood[~r.eliminated],
                               DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy[1]).update(shown)
                               .log_likelihood[~r.eliminated], rtol=1e-9)
    logw = r.log_likelihood + np.log(r.prior)
    p = np.exp(logw - logw.max())
    p /= p.sum()
    assert r.record["rounds"][-1]["beta_hat"] == pytest.approx(p @ r.hypotheses.beta, rel=1e-9)
    # one task alone reads another β̂: the second task moved the estimate
    alone = refine(mdp, trajs, start_set(mdp.n_features), theta_step=step)
    b_hat = r.record["rounds"][-1]["beta_hat"]
    assert b_hat != pytest.approx(alone.record["rounds"][-1]["beta_hat"], rel=1e-3)


def test_known_start_log_likelihoods_are_not_solved_again(mdp, person):
    """Given the start set's log-likelihoods, the refinement solves only what it adds and reaches the
    set a refinement that solved the start itself reaches."""
    _, _, trajs = person
    hyp, step = start_set(mdp.n_features), 1 / start_resolution(mdp.n_features)
    known = DiscreteBelief.from_mdp(mdp, hyp).update(trajs).log_likelihood
    r = adaptive.refine_tasks([(mdp, trajs)], hyp, theta_step=step, start_log_likelihood=known,
                              keep_policies=False)
    full = refine(mdp, trajs, hyp, theta_step=step)
    assert r.log_policy is None and r.record["rounds"][0]["solved"] == 0
    assert r.record["solved"] == full.record["solved"] - len(hyp)
    np.testing.assert_array_equal(r.hypotheses.thetas, full.hypotheses.thetas)
    np.testing.assert_array_equal(r.hypotheses.betas, full.hypotheses.betas)
    # equal within their certified errors (a hypothesis eliminated at a screening stage is known
    # only that well; the known ones were solved to 1e-8)
    gap = np.abs(r.log_likelihood - full.log_likelihood)
    assert np.all(gap <= r.log_likelihood_error + full.log_likelihood_error + 1e-6)
    np.testing.assert_allclose(r.log_likelihood[~full.eliminated], full.log_likelihood[~full.eliminated],
                               rtol=1e-9)
    with pytest.raises(InputError, match="keep_policies=False"):
        adaptive.refine_tasks([(mdp, trajs)], hyp, start_log_likelihood=known)


def test_features_kept_at_zero_stay_zero_and_the_beta_range_covers_the_start(mdp, person):
    _, _, trajs = person
    hyp = HypothesisSet(start_set(mdp.n_features).thetas, [0.03, 0.3, 3.0, 30.0])
    r = adaptive.refine_tasks([(mdp, trajs)], hyp, theta_step=0.25, zero_features=(4,), keep_policies=False,
                              settings=Refinement(max_rounds=2))
    assert len(r.record["rounds"]) >= 2  # it refined
    assert np.all(r.hypotheses.thetas[:, 4] == 0)
    assert adaptive._Pool.of(hyp, 0.25).limits == (adaptive.BETA_LIMITS[0], 30.0)
    assert adaptive._Pool.of(start_set(3), 0.25).limits == adaptive.BETA_LIMITS


def test_a_time_cap_stops_with_a_warning(mdp, person, tmp_path):
    from expertise_irl.errors import InputError

    _, _, trajs = person
    r = refine(mdp, trajs, start_set(mdp.n_features), theta_step=0.25,
               settings=Refinement(max_seconds=1e-9))
    assert "--max-seconds" in r.record["stop_reason"] and len(r.record["rounds"]) == 1
    assert len(r.warnings) == 1 and "the posterior is the best so far" in r.warnings[0]
    with pytest.raises(InputError, match=r"^max_seconds must be a finite number > 0"):
        DiscreteOptions(max_seconds=0.0)


def test_a_cap_below_the_start_set_is_refused(mdp, person):
    from expertise_irl.errors import InputError

    _, _, trajs = person
    hyp = start_set(mdp.n_features)
    with pytest.raises(InputError, match=f"--max-hypotheses 3 is below the {len(hyp)} hypotheses"):
        refine(mdp, trajs, hyp, theta_step=0.25, settings=Refinement(max_hypotheses=3))


def test_warm_starts_save_sweeps_and_leave_the_posterior_unchanged(mdp, person, monkeypatch):
    """New hypotheses start from their solved neighbours' values (interpolated in ln β between two
    solved β): fewer sweeps than cold starts, the same log-likelihoods (the pool's sweeps certify the
    tolerance whatever the start, so both agree within their certified errors, and the survivors to
    the data's tolerance)."""
    _, _, trajs = person
    kw = {"theta_step": 1 / start_resolution(mdp.n_features)}
    warm = refine(mdp, trajs, start_set(mdp.n_features), **kw)
    monkeypatch.setattr(adaptive, "WARM_VALUE_BYTES", 0)  # nothing kept: every solve starts cold
    cold = refine(mdp, trajs, start_set(mdp.n_features), **kw)
    assert warm.record["solved"] == cold.record["solved"]
    kept = ~warm.eliminated & ~cold.eliminated  # the eliminated are known only within their bounds
    assert kept.sum() >= 10
    np.testing.assert_allclose(warm.log_likelihood[kept], cold.log_likelihood[kept], atol=1e-6)
    gap = np.abs(warm.log_likelihood - cold.log_likelihood)
    assert np.all(gap <= warm.log_likelihood_error + cold.log_likelihood_error)
    assert warm.record["rounds"][0]["sweeps"] == cold.record["rounds"][0]["sweeps"]  # the start: cold
    assert warm.record["sweeps"] == sum(e["sweeps"] for e in warm.record["rounds"])

    def refining(r):
        return sum(e["sweeps"] for e in r.record["rounds"][1:])

    # deterministic counts; here the warm rounds take 7% fewer sweeps (45% on crossroads)
    assert refining(warm) < 0.97 * refining(cold)
