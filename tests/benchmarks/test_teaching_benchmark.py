"""benchmarks/teaching.py (issue 48's checks of ``--model pedagogical``) at a tiny size: its AUC and
its standard error against independent formulas, its readings against the plain ``maxent``
posterior, and the whole script with ``--quick``."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from argparse import Namespace
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def load_benchmark():
    if "teaching_benchmark" not in sys.modules:
        path = ROOT / "benchmarks" / "teaching.py"
        spec = importlib.util.spec_from_file_location("teaching_benchmark", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules["teaching_benchmark"] = module
        spec.loader.exec_module(module)
    return sys.modules["teaching_benchmark"]


def test_auc_is_mann_whitneys_u_over_the_pairs():
    """scipy's U statistic (ties counted half) over n₁·n₂, on scores with many ties."""
    from scipy.stats import mannwhitneyu

    bench = load_benchmark()
    rng = np.random.default_rng(0)
    pos, neg = rng.integers(0, 6, 17), rng.integers(0, 5, 23)
    u = mannwhitneyu(pos, neg, alternative="two-sided").statistic
    assert bench.auc(pos, neg) == pytest.approx(u / (17 * 23), abs=1e-12)
    assert bench.auc([3, 4], [1, 2]) == 1.0 and bench.auc([1], [1]) == 0.5


def test_auc_standard_error_at_chance_is_the_exact_null_one():
    """At AUC = 0.5 Hanley and McNeil's variance is the exact null variance of U/(n₁n₂) without
    ties, (n₁ + n₂ + 1)/(12 n₁ n₂): a check of the formula from a fact it was not written from."""
    bench = load_benchmark()
    for n1, n2 in ((5, 5), (20, 40), (33, 7)):
        assert bench.auc_se(0.5, n1, n2) == pytest.approx(np.sqrt((n1 + n2 + 1) / (12 * n1 * n2)), rel=1e-12)
    assert bench.auc_se(1.0, 10, 10) == 0.0


def test_a_person_is_read_by_both_models_on_the_maps_set():
    """One person on an 8 × 8 floor plan (304 hypotheses): three demonstrations with the same θ*
    and β*, λ* in its ranges, and ``maxent``'s reading equal to the plain posterior mean of β and θ
    from the set's log-likelihoods under a uniform prior."""
    from expertise_irl.hypotheses import HypothesisSet, resolve_thetas
    from expertise_irl.inference import pedagogical as ped
    from expertise_irl.planning.soft_vi import solve
    from expertise_irl.planning.table_likelihood import log_likelihood
    from expertise_irl.worlds.floorplans import generate_floor_plan

    bench = load_benchmark()
    mdp = generate_floor_plan(8, seed=0).to_mdp()
    hyp = HypothesisSet(resolve_thetas("paper-real", mdp.n_features), bench.BETAS)
    lp = np.asarray(solve(mdp, hyp.theta, hyp.beta, tol=1e-8).log_policy)
    theta, beta, lam, strong = bench.draw_person(mdp.n_features, 0, 0, 0)
    assert bench.BETA_RANGE[0] <= beta <= bench.BETA_RANGE[1]
    assert bench.LAMBDA_RANGE[0] <= lam <= bench.LAMBDA_RANGE[1] <= strong <= bench.STRONG_RANGE[1]
    who = {"map_type": "floor", "map": "tiny", "m": 0, "person": 0, "theta": theta, "beta": beta,
           "lambda": lam, "lambda_strong": strong}
    a = Namespace(seed=0, episodes=2, max_steps=40)
    rows, demos = bench.person_rows(mdp, lp, hyp, ped.observer(hyp, lp), who, a)
    assert [r["role"] for r in rows] == list(bench.ROLES)
    assert [r["lambda"] for r in rows] == [0.0, lam, strong]
    for r in rows:
        assert r["theta"] == theta.tolist() and r["beta"] == beta
        ll = log_likelihood(lp, demos[r["role"]].state, demos[r["role"]].action)
        p = np.exp(ll - ll.max())
        p /= p.sum()
        assert r["beta_max"] == pytest.approx(float(p @ hyp.beta), rel=1e-9)
        np.testing.assert_allclose(r["theta_max"], p @ hyp.theta, rtol=0, atol=1e-9)
        assert r["cos_ped"] == pytest.approx(bench.cosine(theta, r["theta_ped"]), abs=1e-12)
        assert 0.0 <= r["lambda_hat"] <= 1.0


@pytest.mark.slow  # ~25 s: the script end to end on two small maps, the cost timings included
def test_the_quick_run_writes_its_checks(tmp_path):
    out, js = tmp_path / "teaching.txt", tmp_path / "teaching.json"
    subprocess.run([sys.executable, str(ROOT / "benchmarks" / "teaching.py"), "--quick", "--pairs", "2",
                    "--episodes", "2", "--cost-repeats", "1", "--out", str(out), "--json", str(js)],
                   check=True, capture_output=True, text=True, cwd=ROOT)
    text = out.read_text()
    for line in ("== zone maps, teachers: 2 pairs", "== floor maps, teachers: 2 pairs",
                 "== pooled, teachers: 4 pairs", "== pooled, strong teachers: 4 pairs", "cost on "):
        assert line in text
    assert text.count("AUC") >= 6 and "machine:" in text
    data = json.loads(js.read_text())
    assert len(data["rows"]) == 2 * 2 * 3
    assert {c["map"] for c in data["cost"]} == {"generated 10x10", "floor plan 12x12 seed 0"}
