"""Low expertise or missing features? Three simulated populations and the verdict of ``--check full``.

    python benchmarks/misspecification.py [--people 50] [--episodes 20] [--set fixed|adaptive]
        [--json out.json] [--out DIR]

Setting: a 12×7 zone map (``MAP`` below; 84 states) whose avoid zone lies across the straight way
from the start cells to the goal, so that avoiding it costs a detour of 2–4 moves. Every person
demonstrates ``--episodes`` episodes from the start cells. Inference always uses the *reduced*
features: the map's five without ``avoid`` (length, road, slow, traffic), with the discrete set
Θ = paper-real over those four (65 directions) × 22 β log-spaced from 10^-2.5 to 10 (uniform prior;
``--set fixed``, the default) or the set ``infer`` refines by default from its coarse start
(``--set adaptive``: every truth then lies off the set it starts from), and then ``--check full``
(:func:`expertise_irl.inference.misspecification.misspecification`).

- **A** (careful, hidden preference): θ* with θ_length ~ U(0.25, 0.35), θ_avoid ~ U(0.5, 0.7), the
  rest split over road, slow, traffic by a Dirichlet(1, 1, 1); β* = 0.05.
- **B** (truly noisy, no weight on the zone): the same draws with θ_avoid = 0 (renormalised), and
  β* = β_B chosen so that B's median β̂ matches A's: the median β̂ of 10 calibration people (seeds
  apart from B's) is computed at 7 log-spaced β from 0.05 to 1 and β_B is the log-interpolated β
  where it equals A's median.
- **C** (no weight on the zone, expert): B's θ* with β* = 0.05.

Reported: each population's verdict counts, median β̂; the AUC separating A from B by the
competitor's held-out gain (nats/action) and by its z-score (gain / standard error) — the
Mann–Whitney statistic, ties half — with the ROC points; on C the share judged "features explain";
and the calibration of C's predictive p-values: per statistic, the Kolmogorov–Smirnov test of the
50 p-values against Uniform(0, 1) and the share below 0.05.
Every person is seeded by (population, index) through ``SeedSequence``.
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

from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import HypothesisSet, resolve_thetas
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.inference.misspecification import UNEXPLAINED, VERDICTS, misspecification
from expertise_irl.mdp import TabularMDP
from expertise_irl.worlds.zones import parse_map

MAP = """
..ss........
S...........
S...xxxx....
S...xxxx...G
S...xxxx....
S...........
..>>>>>>..tt
"""
REDUCED = (0, 1, 3, 4)  # length, road, slow, traffic: avoid (2) is hidden
BETAS = np.round(np.logspace(-2.5, 1, 22), 5)
POPULATIONS = {"A": 0, "B": 1, "C": 2, "calibration": 3}


def maps():
    full = parse_map(MAP.strip("\n"), name="detour").to_mdp()
    reduced = TabularMDP(full.next_state, full.features[..., list(REDUCED)], full.terminal, gamma=full.gamma,
                         feature_names=tuple(full.feature_names[i] for i in REDUCED),
                         start_states=full.start_states, state_xy=full.state_xy, source="detour (no avoid)")
    return full, reduced


def theta_of(rng: np.random.Generator, hidden: bool) -> np.ndarray:
    length, avoid = rng.uniform(0.25, 0.35), rng.uniform(0.5, 0.7)
    rest = rng.dirichlet(np.ones(3)) * max(0.0, 1 - length - avoid)
    th = np.array([length, rest[0], avoid if hidden else 0.0, rest[1], rest[2]])
    return th / th.sum()


def posterior(prior, reduced, trajs):
    """The posterior of ``trajs``: over the fixed set of ``prior``, or (``prior`` None) over the set
    ``infer`` refines by default (:mod:`expertise_irl.inference.adaptive`)."""
    if prior is not None:
        return prior.update(trajs)
    from expertise_irl.inference.adaptive import refine, start_resolution, start_set

    K = reduced.n_features
    r = refine(reduced, trajs, start_set(K), theta_step=1 / start_resolution(K))
    return DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior).update(trajs)


def person(pop: str, i: int, beta: float, full, reduced, prior, episodes: int, check: str = "full") -> dict:
    rng = np.random.default_rng(np.random.SeedSequence([32, POPULATIONS[pop], i]))
    th = theta_of(rng, hidden=(pop == "A"))
    trajs = simulate(full, th, beta, episodes, rng)
    post = posterior(prior, reduced, trajs)
    t0 = time.perf_counter()
    hyp = post.hypotheses
    mis = misspecification([(reduced, trajs)], check=check, theta=hyp.theta, beta=hyp.beta,
                           weights=post.probabilities, tables=[post.log_policy], theta_hat=post.mean_theta,
                           beta_hat=post.mean_beta, model="maxent", seed=1000 * POPULATIONS[pop] + i)
    comp = mis["competitor"] or {}
    stats = mis["predictive"]["statistics"]
    return {"population": pop, "index": i, "theta_true": th.round(4).tolist(), "beta_true": beta,
            "beta_hat": post.mean_beta, "actions": len(trajs), "verdict": mis["verdict"],
            "failed": mis["predictive"]["failed"], "gain": comp.get("gain"), "gain_se": comp.get("gain_se"),
            "beta_features": comp.get("beta_features"), "beta_richer": comp.get("beta_richer"),
            "beta_ratio": comp.get("beta_ratio"), "p_values": {k: v["p_value"] for k, v in stats.items()},
            "check_s": time.perf_counter() - t0, "trajs": trajs}


def auc(pos, neg) -> float:
    """P(score of a positive > score of a negative), ties half (the Mann–Whitney U / n_pos n_neg)."""
    pos, neg = np.asarray(pos, float)[:, None], np.asarray(neg, float)[None, :]
    return float(np.mean((pos > neg) + 0.5 * (pos == neg)))


def roc(pos, neg) -> list[list[float]]:
    cuts = np.unique(np.concatenate([pos, neg]))[::-1]
    pts = [[0.0, 0.0]]
    for c in cuts:
        pts.append([float(np.mean(np.asarray(neg) >= c)), float(np.mean(np.asarray(pos) >= c))])
    return pts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=50)
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--set", choices=("fixed", "adaptive"), default="fixed",
                    help="fixed: paper-real Θ × 22 β (below); adaptive: the set infer refines by default")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--out", type=Path, help="Write a person of A's demonstrations and the MDP here.")
    ap.add_argument("--roc", type=Path, help="Draw the ROC of the held-out gain (A against B) to this PNG; "
                    "with --from, from an earlier run's JSON without running again.")
    ap.add_argument("--from", dest="source", type=Path, help="An earlier run's --json (with --roc).")
    args = ap.parse_args()
    if args.source is not None:
        if args.roc is None:
            raise SystemExit("--from needs --roc")
        draw_roc(json.loads(args.source.read_text()), args.roc)
        return
    info = machine_info()
    t0 = time.perf_counter()
    full, reduced = maps()
    prior = None if args.set == "adaptive" else DiscreteBelief.from_mdp(
        reduced, HypothesisSet(resolve_thetas("paper-real", 4), BETAS))
    rows = [person("A", i, 0.05, full, reduced, prior, args.episodes) for i in range(args.people)]
    median_a = float(np.median([r["beta_hat"] for r in rows]))
    grid = np.logspace(np.log10(0.05), 0.0, 7)
    calib = []
    for b in grid:
        got = [_beta_hat("calibration", j, float(b), full, reduced, prior, args.episodes) for j in range(10)]
        calib.append(float(np.median(got)))
    beta_b = float(np.exp(np.interp(np.log(median_a), np.log(calib), np.log(grid))))
    rows += [person("B", i, beta_b, full, reduced, prior, args.episodes) for i in range(args.people)]
    rows += [person("C", i, 0.05, full, reduced, prior, args.episodes) for i in range(args.people)]
    if args.out is not None:
        from expertise_irl.demos.csv_io import write_demos_csv

        args.out.mkdir(parents=True, exist_ok=True)
        reduced.save(args.out / "detour-no-avoid.npz")
        (args.out / "detour.txt").write_text(MAP.strip("\n") + "\n")
        write_demos_csv(args.out / "person-A0.csv", rows[0]["trajs"], reduced)
    for r in rows:
        del r["trajs"]
    by = {p: [r for r in rows if r["population"] == p] for p in ("A", "B", "C")}
    table = {}
    for p, rs in by.items():
        table[p] = {"people": len(rs), "beta_true": rs[0]["beta_true"],
                    "median_beta_hat": float(np.median([r["beta_hat"] for r in rs])),
                    "verdicts": {v: sum(r["verdict"] == v for r in rs) for v in VERDICTS},
                    "median_gain": float(np.median([r["gain"] for r in rs])),
                    "median_beta_ratio": float(np.median([r["beta_ratio"] for r in rs])),
                    "checks_failed": sum(bool(r["failed"]) for r in rs)}
    gain_a, gain_b = [r["gain"] for r in by["A"]], [r["gain"] for r in by["B"]]
    z = {p: [r["gain"] / r["gain_se"] for r in by[p]] for p in ("A", "B")}
    unexplained = {p: [float(r["verdict"] == UNEXPLAINED) for r in by[p]] for p in ("A", "B")}
    from scipy.stats import kstest

    calibration = {}
    for name in by["C"][0]["p_values"]:
        ps = np.array([r["p_values"][name] for r in by["C"] if r["p_values"][name] is not None])
        calibration[name] = {"n": len(ps), "ks_p": float(kstest(ps, "uniform").pvalue),
                             "mean": float(ps.mean()), "share_below_0.05": float(np.mean(ps < 0.05))}
    result = {
        "machine": info, "people_per_population": args.people, "episodes": args.episodes, "set": args.set,
        "beta_b": beta_b, "calibration_grid": grid.tolist(), "calibration_median_beta_hat": calib,
        "table": table,
        "auc_gain_A_vs_B": auc(gain_a, gain_b), "auc_z_A_vs_B": auc(z["A"], z["B"]),
        "auc_verdict_A_vs_B": auc(unexplained["A"], unexplained["B"]),
        "C_features_explain_share": table["C"]["verdicts"][VERDICTS[0]] / len(by["C"]),
        "C_p_value_calibration": calibration,
        "roc_gain_A_vs_B": roc(gain_a, gain_b),
        "wall_s": time.perf_counter() - t0, "people": rows,
    }
    for k in ("machine", "set", "beta_b", "calibration_median_beta_hat", "table", "auc_gain_A_vs_B",
              "auc_z_A_vs_B", "auc_verdict_A_vs_B", "C_features_explain_share", "C_p_value_calibration",
              "wall_s"):
        print(f"{k}: {json.dumps(result[k])}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1) + "\n")
    if args.roc:
        draw_roc(result, args.roc)


def draw_roc(result: dict, png: Path) -> None:
    """The ROC of the competitor's held-out gain separating A (hidden preference) from B (noisy)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fpr, tpr = np.asarray(result["roc_gain_A_vs_B"]).T
    fig, ax = plt.subplots(figsize=(4.2, 4.0), dpi=150)
    ax.plot(fpr, tpr, color="#b2182b", lw=2, drawstyle="steps-post",
            label=f"held-out gain, AUC {result['auc_gain_A_vs_B']:.3f}")
    ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls="--", label="chance")
    n = result["people_per_population"]
    ax.set(xlabel=f"false positive rate (B, {n} truly noisy people)",
           ylabel=f"true positive rate (A, {n} with a hidden preference)", xlim=(0, 1), ylim=(0, 1.01),
           title="Low expertise or missing features?")
    ax.legend(loc="lower right", fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(png)
    plt.close(fig)


def _beta_hat(pop: str, i: int, beta: float, full, reduced, prior, episodes: int) -> float:
    rng = np.random.default_rng(np.random.SeedSequence([32, POPULATIONS[pop], i]))
    th = theta_of(rng, hidden=False)
    return posterior(prior, reduced, simulate(full, th, beta, episodes, rng)).mean_beta


if __name__ == "__main__":
    main()
