"""Changing expertise (inference/changing.py): a simulated learner, stationary people, and the cost.

On the bundled map ``crossroads`` (185 cells, K = 5 features), model ``maxent-relative`` for
simulation and inference alike (under the paper's ``maxent`` a person at β = 2 or 1 walks the whole
500-step cap without reaching the goal, at θ* below in 40 of 40 episodes):

1. **Learner**: θ* = (0.5, 0.25, 0.25, 0, 0) (length, road, avoid; in the set), β falling
   log-linearly from 2 to 0.05 over 20 episodes, one episode each; the paper-real Θ (211
   directions at K = 5) × the paper-sim B (0.01 … 10) = 1,266 hypotheses, solved once. Prints the
   learning curve (true β_e, the smoothed model-averaged β̂_e mean and its 90% band, the changing
   model's mean, the filtered mean, the stationary β̂), the Bayes factor, ε, P(β_20 < β_1), θ̂'s
   cosine to θ* under both models, and the falling-trend chain's Bayes factor.
2. **Stationary people** (``--people``, 100): θ from the set with a positive length weight (so that
   episodes end), one β each, log-uniform in [0.05, 2] (off the grid), ``--episodes`` (15) episodes.
   Target: log BF > 1 for at most 5%. Also how often each episode's smoothed β̂ lies in the
   stationary 90% interval (grid quantiles): the median (a grid value, comparable) and the mean
   (off the grid, so compared with how often the stationary mean itself lies in that interval).
3. **Cost**: the full paper-sim set (3,031 θ × 6 β = 18,186 hypotheses) with ``--cost-episodes``
   (40) episodes of a learner: the stationary ``infer`` work (the set's solve + the per-episode
   log-likelihoods) against ``changing_posterior`` (target: < 20% added) and ``trend_summary``.
   Times are the best of two solves and of three changing passes.

    python benchmarks/changing_expertise.py [--people 100] [--episodes 15] [--cost-episodes 40]
                                            [--seed 0] [--json FILE]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info, report

MODEL = "maxent-relative"
THETA_STAR = np.array([1.0, 0.5, 0.5, 0.0, 0.0]) / 2.0


def cosine(a, b) -> float:
    return float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))


def learner_betas(n: int) -> np.ndarray:
    return 2.0 * (0.05 / 2.0) ** (np.arange(n) / max(n - 1, 1))


def simulate_learner(mdp, log_policy, betas, rng):
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.planning.table_likelihood import log_likelihood

    ll, steps = [], []
    for b in betas:
        tr = simulate(mdp, THETA_STAR, float(b), 1, rng, model=MODEL)
        ll.append(log_likelihood(log_policy, tr.state, tr.action))
        steps.append(len(tr))
    return np.array(ll), steps


def learner(mdp, hyp, log_policy, seed: int) -> dict:
    from scipy.stats import spearmanr

    from expertise_irl.inference.changing import (
        changing_posterior,
        changing_summary,
        expertise_by_episode,
        trend_summary,
    )

    E = 20
    true = learner_betas(E)
    ll, steps = simulate_learner(mdp, log_policy, true, np.random.default_rng(seed))
    p = changing_posterior(ll, hyp)
    falling = changing_posterior(ll, hyp, trend="falling")
    rows = expertise_by_episode(p, range(1, E + 1))
    changing_mean = p.beta_smoothed_changing @ hyp.betas
    filtered_mean = p.beta_filtered @ hyp.betas
    print("\nlearning curve (crossroads, maxent-relative, 1,266 hypotheses; β̂ smoothed, model-averaged):")
    print(" ep  steps  true_beta  beta_hat  q05    q95    changing_only  filtered  stationary")
    for r, t, n, c, f in zip(rows, true, steps, changing_mean, filtered_mean, strict=True):
        print(f"{r['episode']:3d}  {n:5d}  {t:9.4f}  {r['mean']:8.4f}  {r['q05']:5.2f}  {r['q95']:5.2f}"
              f"  {c:13.4f}  {f:8.4f}  {p.stationary.mean_beta:10.4f}")
    ts = trend_summary(p)
    return {
        "episodes": E, "true_beta": true.round(5).tolist(), "steps": steps,
        "beta_hat_mean": [round(r["mean"], 5) for r in rows], "beta_hat_q05": [r["q05"] for r in rows],
        "beta_hat_q95": [r["q95"] for r in rows], "beta_hat_changing_only": changing_mean.round(5).tolist(),
        "beta_hat_filtered": filtered_mean.round(5).tolist(),
        "beta_hat_stationary": round(float(p.stationary.mean_beta), 5),
        "spearman": float(spearmanr(true, [r["mean"] for r in rows]).statistic),
        **changing_summary(p), **ts,
        "theta_cosine_changing": cosine(p.mean_theta, THETA_STAR),
        "theta_cosine_stationary": cosine(p.stationary.mean_theta, THETA_STAR),
        "log_bayes_factor_falling_trend": falling.log_bayes_factor,
        "p_changing_falling_trend": falling.p_changing,
    }


def stationary_people(mdp, hyp, log_policy, people: int, episodes: int, seed: int) -> dict:
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.inference.changing import changing_posterior, episode_log_likelihoods
    from expertise_irl.inference.posterior import beta_quantile

    rng = np.random.default_rng(seed)
    cand = np.flatnonzero(hyp.thetas[:, 0] > 0)
    bfs, med_in, mean_in, changing_mean_in, stat_mean_in, times = [], [], [], [], [], []
    for _ in range(people):
        theta = hyp.thetas[rng.choice(cand)]
        beta = float(np.exp(rng.uniform(np.log(0.05), np.log(2.0))))
        tr = simulate(mdp, theta, beta, episodes, rng, model=MODEL)
        ll = episode_log_likelihoods(log_policy, tr)
        t = time.perf_counter()
        p = changing_posterior(ll, hyp)
        times.append(time.perf_counter() - t)
        bfs.append(p.log_bayes_factor)
        st = p.stationary
        lo, hi = (beta_quantile(hyp.betas, st.beta_marginal, q) for q in (0.05, 0.95))

        def inside(x, lo=lo, hi=hi):
            return np.mean((x >= lo * (1 - 1e-12)) & (x <= hi * (1 + 1e-12)))

        med_in.append(inside(beta_quantile(hyp.betas, p.beta_smoothed.T, 0.5)))
        mean_in.append(inside(p.mean_beta))
        changing_mean_in.append(inside(p.beta_smoothed_changing @ hyp.betas))
        stat_mean_in.append(inside(np.array([st.mean_beta])))
    bfs = np.array(bfs)
    n_fav = int(np.sum(bfs > 1))
    return {
        "people": people, "episodes_each": episodes,
        "favoured_changing_log_bf_gt_1": n_fav, "favoured_rate": n_fav / people,
        "target_rate_at_most": 0.05, "passes": n_fav / people <= 0.05,
        "log_bf_gt_0": int(np.sum(bfs > 0)), "log_bf_median": float(np.median(bfs)),
        "log_bf_max": float(bfs.max()),
        "episodes_median_in_stationary_90": float(np.mean(med_in)),
        "people_all_medians_in_stationary_90": float(np.mean(np.array(med_in) == 1)),
        "episodes_mean_in_stationary_90": float(np.mean(mean_in)),
        "episodes_changing_only_mean_in_stationary_90": float(np.mean(changing_mean_in)),
        "stationary_mean_in_own_90": float(np.mean(stat_mean_in)),
        "changing_posterior_ms_median": float(np.median(times) * 1e3),
    }


def cost(mdp, episodes: int, seed: int) -> dict:
    from expertise_irl.inference.changing import changing_posterior, episode_log_likelihoods, trend_summary
    from expertise_irl.inference.methods import DiscreteOptions
    from expertise_irl.planning.soft_vi import solve

    hyp = DiscreteOptions(thetas="paper-sim", betas="paper-sim").hypotheses(mdp.n_features)
    solve_runs = []
    for _ in range(2):  # the second without any compilation left to do
        t = time.perf_counter()
        log_policy = solve(mdp, hyp.theta, hyp.beta, model=MODEL).log_policy
        solve_runs.append(time.perf_counter() - t)
    solve_s = min(solve_runs)
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.demos.trajectories import Trajectories

    rng = np.random.default_rng(seed)
    parts = [simulate(mdp, THETA_STAR, float(b), 1, rng, model=MODEL) for b in learner_betas(episodes)]
    trajs = Trajectories(*(np.concatenate([getattr(p, k) + (e if k == "episode" else 0)
                                           for e, p in enumerate(parts)])
                           for k in ("episode", "step", "state", "action")))
    t = time.perf_counter()
    ll = episode_log_likelihoods(log_policy, trajs)
    ll_s = time.perf_counter() - t
    runs, trend_runs = [], []
    for _ in range(3):
        t = time.perf_counter()
        p = changing_posterior(ll, hyp)
        runs.append(time.perf_counter() - t)
        t = time.perf_counter()
        trend_summary(p)
        trend_runs.append(time.perf_counter() - t)
    stationary_s = solve_s + ll_s
    return {
        "hypotheses": len(hyp), "n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "episodes": episodes,
        "pairs": len(trajs), "solve_s": solve_s, "solve_s_runs": solve_runs,
        "episode_log_likelihoods_s": ll_s,
        "stationary_infer_work_s": stationary_s, "changing_posterior_s": min(runs),
        "changing_posterior_s_runs": runs, "added_fraction": min(runs) / stationary_s,
        "target_added_below": 0.2, "trend_summary_s": min(trend_runs),
        "added_fraction_with_trend_summary": (min(runs) + min(trend_runs)) / stationary_s,
        "log_bayes_factor": p.log_bayes_factor,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=100, help="stationary people")
    ap.add_argument("--episodes", type=int, default=15, help="episodes per stationary person")
    ap.add_argument("--cost-episodes", type=int, default=40, help="episodes of the cost measurement")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, help="write the numbers here")
    args = ap.parse_args()
    info = machine_info()
    for k, v in info.items():
        print(f"{k}: {v}")

    from expertise_irl.inference.methods import DiscreteOptions
    from expertise_irl.planning.soft_vi import solve
    from expertise_irl.worlds.maps import load_bundled_world

    mdp = load_bundled_world("crossroads").to_mdp()
    hyp = DiscreteOptions(thetas="paper-real", betas="paper-sim").hypotheses(mdp.n_features)
    t = time.perf_counter()
    log_policy = solve(mdp, hyp.theta, hyp.beta, model=MODEL).log_policy
    print(f"\nsolve of the 1,266-hypothesis set (includes JAX compilation): {time.perf_counter() - t:.1f} s")

    result = {"machine": info, "map": "crossroads", "model": MODEL}
    result["learner"] = learner(mdp, hyp, log_policy, args.seed)
    print()
    result["stationary_people"] = stationary_people(mdp, hyp, log_policy, args.people, args.episodes,
                                                    args.seed + 1)
    result["cost"] = cost(mdp, args.cost_episodes, args.seed + 2)
    print()
    flat = {f"{section}.{k}": v for section, part in result.items()
            if isinstance(part, dict) and section != "machine" for k, v in part.items()}
    report({"map": result["map"], "model": result["model"], **flat}, None)
    if args.json:
        import json

        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
