"""Active vs random start states: how fast the belief finds a simulated person's expertise.

    python benchmarks/active.py [--people 20] [--episodes 10] [--quick] [--json out.json]

Setting: the bundled 30×30 map ``zones30`` (every free cell a possible start), the
paper's simulation set B = {0.01, 0.09, 0.5, 1, 5, 10} and, per person, Θ_20 (20
directions drawn from the paper-sim grid, the person's own among them), so 120
hypotheses. ``--people`` people per expertise group (high: β* ∈ {0.01, 0.09},
medium: {0.5, 1}, low: {5, 10}, alternating), θ* drawn from the grid; every person is
seeded by its identity (group, index). Each person acts out up to ``--episodes``
episodes (at most 200 actions each) from starts chosen by

  active   next_start(belief, every free cell) — expected information gain about (θ, β),
           48 simulated episodes per candidate, 32 candidates (a seeded subsample);
  active-β the same, scoring the entropy of the β marginal only;
  random   a free cell drawn uniformly.

The same person (θ*, β*, Θ_20) is used by every strategy. Reported per group and
strategy: the number of episodes until the true group has posterior probability
≥ 0.9 (median over people; people who never reach it within ``--episodes`` count as
``--episodes`` + 1, and how many reached it is shown), and the mean |β* − β̂| after 3
and after 5 episodes (± its standard error over people); the time of one start choice.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info
from online import cpu_flags

from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import (
    BETA_PRESETS,
    EXPERTISE_GROUPS,
    THETA_PRESETS,
    HypothesisSet,
    expertise_group,
    sample_thetas,
    theta_grid,
)
from expertise_irl.inference.active import next_start
from expertise_irl.inference.online import OnlineEstimator
from expertise_irl.worlds.zones import load_bundled

STRATEGIES = ("active", "active-β", "random")
PERSON_MAX_STEPS = 200
THRESHOLD = 0.9


def run_person(mdp, group: str, index: int, episodes: int, strategies) -> dict:
    ss = np.random.SeedSequence(["hml".index(group[0]), index])  # seeded by identity
    person_rng, *strategy_seeds = ss.spawn(1 + len(strategies))
    prng = np.random.default_rng(person_rng)
    grid = theta_grid(THETA_PRESETS["paper-sim"], mdp.n_features)
    theta = grid[prng.integers(len(grid))]
    beta = EXPERTISE_GROUPS[group][index % 2]
    hyp = HypothesisSet(sample_thetas(grid, 20, prng, include=theta), BETA_PRESETS["paper-sim"])
    base = OnlineEstimator.from_mdp(mdp, hyp)
    truth = hyp.index(theta, beta)
    lp_true = base.belief().log_policy[truth]
    cand = np.flatnonzero(~mdp.terminal)
    out = {"group": group, "index": index, "beta": beta, "theta": theta.tolist()}
    for name, seed in zip(strategies, strategy_seeds, strict=True):
        rng = np.random.default_rng(seed)
        est = OnlineEstimator.from_belief(mdp, base.belief())
        p_group, dist, choose_s = [], [], []
        for _ in range(episodes):
            t = time.perf_counter()
            if name == "random":
                s = int(rng.choice(cand))
            else:
                target = "beta" if name == "active-β" else "joint"
                s = next_start(est, cand, target=target, rng=rng)
            choose_s.append(time.perf_counter() - t)
            ep = simulate(mdp, None, None, 1, rng, starts=[s], max_steps=PERSON_MAX_STEPS, log_policy=lp_true)
            for st, a in zip(ep.state.tolist(), ep.action.tolist(), strict=True):
                est.observe(st, a)
            est.end_episode()
            r = est.estimate
            p_group.append(r.group_probabilities[group])
            dist.append(abs(beta - r.beta_hat))
        reached = next((k + 1 for k, p in enumerate(p_group) if p >= THRESHOLD), None)
        out[name] = {"p_group": p_group, "beta_distance": dist, "episodes_to_group": reached,
                     "choose_s": float(np.mean(choose_s))}
    assert expertise_group(beta) == group
    return out


def summarise(rows, strategies, episodes: int) -> list[dict]:
    table = []
    for group in EXPERTISE_GROUPS:
        rs = [r for r in rows if r["group"] == group]
        for name in strategies:
            n_ep = [r[name]["episodes_to_group"] or episodes + 1 for r in rs]
            reached = sum(r[name]["episodes_to_group"] is not None for r in rs)
            d = np.array([r[name]["beta_distance"] for r in rs])
            table.append({
                "group": group, "strategy": name, "people": len(rs),
                "median_episodes_to_group": float(np.median(n_ep)), "reached": reached,
                "mean_episodes_to_group": float(np.mean(n_ep)),
                "beta_distance_3": float(d[:, 2].mean()) if d.shape[1] >= 3 else None,
                "beta_distance_5": float(d[:, 4].mean()) if d.shape[1] >= 5 else None,
                "beta_distance_3_se": float(d[:, 2].std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else None,
                "beta_distance_5_se": float(d[:, 4].std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else None,
                "choose_s": float(np.mean([r[name]["choose_s"] for r in rs])),
            })
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=20, help="simulated people per expertise group")
    ap.add_argument("--episodes", type=int, default=10, help="episodes per person (at least 5)")
    ap.add_argument("--quick", action="store_true", help="3 people per group, 5 episodes")
    ap.add_argument("--json", type=Path, help="write every person's numbers here")
    args = ap.parse_args()
    if args.quick:
        args.people, args.episodes = 3, 5
    info = machine_info()
    info["cpu_flags"] = cpu_flags()
    for k, v in info.items():
        print(f"{k}: {v}")
    mdp = load_bundled("zones30").to_mdp()
    print(f"map zones30: {mdp.n_states} states; {args.people} people per group; up to {args.episodes} "
          f"episodes of at most {PERSON_MAX_STEPS} actions; Θ_20 × paper-sim B = 120 hypotheses")
    t0 = time.perf_counter()
    rows = []
    for group in EXPERTISE_GROUPS:
        for i in range(args.people):
            rows.append(run_person(mdp, group, i, args.episodes, STRATEGIES))
        print(f"  {group}: done ({time.perf_counter() - t0:.0f} s)", flush=True)
    table = summarise(rows, STRATEGIES, args.episodes)
    print()
    print(f"| group | starts | episodes until P(true group) ≥ {THRESHOLD} (median; reached) | "
          "mean \\|β*−β̂\\| after 3 | after 5 | time per start choice |")
    print("|---|---|---|---|---|---|")
    for t in table:
        d3 = f"{t['beta_distance_3']:.2f} ± {t['beta_distance_3_se']:.2f}"
        d5 = f"{t['beta_distance_5']:.2f} ± {t['beta_distance_5_se']:.2f}"
        print(f"| {t['group']} | {t['strategy']} | {t['median_episodes_to_group']:g} "
              f"({t['reached']}/{t['people']}) | {d3} | {d5} | "
              f"{t['choose_s'] * 1e3:.0f} ms |")
    print(f"\n(people who never reach {THRESHOLD} within {args.episodes} episodes count as "
          f"{args.episodes + 1}; ± one standard error over people); total {time.perf_counter() - t0:.0f} s")
    if args.json:
        args.json.write_text(json.dumps({"machine": info, "table": table, "people": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
