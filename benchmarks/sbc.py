"""Simulation-based calibration of NUTS under the default prior, for each observation model.

    python benchmarks/sbc.py [--people 100] [--models maxent,maxent-relative,boltzmann]
        [--map corridor] [--episodes 10] [--max-steps 100] [--warmup 500] [--samples 500]
        [--chains 4] [--rank-draws 99] [--bins 10] [--out benchmarks/results/sbc]
        [--plots docs/images] [--json summary.json] [--quick]

Person i (the same truths for every model): (θ*, β*) drawn from the NumPyro distributions of
the default prior (:func:`expertise_irl.inference.priors.numpyro_priors`, the ones NUTS
uses) with key ``PRNGKey(i)``; ``--episodes`` episodes simulated with the model (at most
``--max-steps`` actions each) from ``default_rng([i, m])``, m the model's index in
``MODELS``; ``nuts_posterior(..., seed=i, model=model)``. Ranks of β* and each θ*_k among
``--rank-draws`` L draws evenly spaced over all the run's draws (``sbc.thin``; roughly
independent when the run's bulk ESS is at least L, which each row records), a χ² test of
each rank histogram in ``--bins`` bins, and the coverage of the run's 90% equal-tailed
intervals (from all its draws) overall and by β* bins. docs/calibration.md describes the
protocol and the results.

Rows go to DIR/sbc-<model>.jsonl, one per person, appended as each finishes; a rerun with
the same settings skips the people already there (a killed run resumes), a rerun with other
settings into the same DIR is refused. The summary (per model and quantity: χ² statistic,
p-value, coverage) is printed and written to DIR/summary.json (and --json); the rank
histograms to PLOTS/calibration-<model>.png.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_flags, machine_info

from expertise_irl.demos.simulation import simulate
from expertise_irl.inference import sbc
from expertise_irl.inference.nuts import nuts_posterior
from expertise_irl.inference.priors import DEFAULT_PRIOR, get_prior, numpyro_priors
from expertise_irl.models import MODELS
from expertise_irl.planning.jax_cache import enable_jax_cache
from expertise_irl.worlds.zones import load_bundled

warnings.filterwarnings("ignore", category=FutureWarning)

ROOT = Path(__file__).resolve().parent.parent
PROB = 0.9  # the central intervals whose coverage is reported
EXPERT_BETA = 0.05  # β* from here up: the experts the prior covers, reported on their own
BETA_EDGES_INNER = (EXPERT_BETA, 1.0)  # inner edges of the β* bins; the outer ones are the prior's
FULL = {"people": 100, "warmup": 500, "samples": 500, "chains": 4, "rank_draws": 99, "bins": 10,
        "out": ROOT / "benchmarks" / "results" / "sbc"}
QUICK = {"people": 10, "warmup": 150, "samples": 150, "chains": 2, "rank_draws": 19, "bins": 5,
         "out": ROOT / "benchmarks" / "results" / "sbc-quick"}


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, help=f"simulated people per model (default {FULL['people']})")
    ap.add_argument("--models", default=",".join(MODELS), help="comma-separated observation models")
    ap.add_argument("--map", default="corridor", help="bundled map (default corridor: 48 states)")
    ap.add_argument("--episodes", type=int, default=10, help="episodes per person")
    ap.add_argument("--max-steps", type=int, default=100, help="actions per episode at most")
    ap.add_argument("--warmup", type=int, help=f"NUTS warm-up per chain (default {FULL['warmup']})")
    ap.add_argument("--samples", type=int, help=f"NUTS draws per chain (default {FULL['samples']})")
    ap.add_argument("--chains", type=int, help=f"NUTS chains (default {FULL['chains']})")
    ap.add_argument("--rank-draws", type=int,
                    help=f"L, thinned draws each truth is ranked among (default {FULL['rank_draws']})")
    ap.add_argument("--bins", type=int, help=f"rank histogram bins (default {FULL['bins']}; "
                                             "best a divisor of L + 1)")
    ap.add_argument("--out", type=Path, help="directory of the per-person JSONL files and summary.json "
                                             "(default benchmarks/results/sbc, --quick: sbc-quick)")
    ap.add_argument("--plots", type=Path, default=ROOT / "docs" / "images",
                    help="directory of the calibration-<model>.png figures (default docs/images)")
    ap.add_argument("--json", type=Path, help="also write the summary here")
    ap.add_argument("--quick", action="store_true",
                    help=f"smaller defaults: {QUICK['people']} people, {QUICK['chains']} chains × "
                         f"({QUICK['warmup']} + {QUICK['samples']}), L = {QUICK['rank_draws']}, "
                         f"{QUICK['bins']} bins")
    args = ap.parse_args(argv)
    for key, value in (QUICK if args.quick else FULL).items():
        if getattr(args, key) is None:
            setattr(args, key, value)
    args.models = [m.strip() for m in args.models.split(",") if m.strip()]
    bad = [m for m in args.models if m not in MODELS]
    if bad:
        ap.error(f"unknown model(s) {', '.join(bad)}; choose from {', '.join(MODELS)}")
    if args.rank_draws > args.chains * args.samples:
        ap.error(f"--rank-draws {args.rank_draws} exceeds the run's {args.chains * args.samples} draws")
    if not 1 <= args.bins <= args.rank_draws + 1:
        ap.error(f"--bins must be in [1, L + 1] = [1, {args.rank_draws + 1}]")
    return args


def settings(args: argparse.Namespace, model: str) -> dict:
    """What a row depends on: rows with other settings are never mixed into one file."""
    return {"model": model, "map": args.map, "episodes": args.episodes, "max_steps": args.max_steps,
            "warmup": args.warmup, "samples": args.samples, "chains": args.chains,
            "rank_draws": args.rank_draws, "prior": DEFAULT_PRIOR}


def truth(person: int, n_features: int) -> tuple[np.ndarray, float]:
    """(θ*, β*) of ``person``: one draw of the default prior's NumPyro distributions."""
    import jax

    theta_prior, beta_prior = numpyro_priors(DEFAULT_PRIOR, n_features)
    k_theta, k_beta = jax.random.split(jax.random.PRNGKey(person))
    theta = np.asarray(theta_prior.sample(k_theta), dtype=np.float64)
    return theta / theta.sum(), float(beta_prior.sample(k_beta))


def run_person(mdp, person: int, model: str, args: argparse.Namespace) -> dict:
    theta, beta = truth(person, mdp.n_features)
    row: dict = {"person": person, "settings": settings(args, model),
                 "theta_true": theta.tolist(), "beta_true": beta}
    trajs = simulate(mdp, theta, beta, args.episodes, np.random.default_rng([person, MODELS.index(model)]),
                     model=model, max_steps=args.max_steps)
    ends = [p[-1] for p in trajs.paths(mdp)]
    row["pairs"] = len(trajs)
    row["episodes_finished"] = int(np.sum(mdp.terminal[ends])) if ends else 0
    t = time.perf_counter()
    try:
        res = nuts_posterior(mdp, trajs, num_warmup=args.warmup, num_samples=args.samples,
                             num_chains=args.chains, seed=person, model=model)
    except Exception as exc:  # recorded, not dropped: a failure is part of the calibration
        row.update(wall_s=time.perf_counter() - t, error=f"{type(exc).__name__}: {exc}")
        return row
    row["wall_s"] = time.perf_counter() - t
    # [C, D, 1 + K]: β then θ, so that one thinning keeps the same draws of every quantity.
    joint = np.concatenate([res.beta[..., None], res.theta], axis=-1)
    kept = sbc.thin(joint, args.rank_draws)  # [L, 1 + K]
    truths = np.array([beta, *theta])
    rank = sbc.ranks(truths, kept.T, rng=person)
    lo, hi = sbc.central_intervals(joint.reshape(-1, joint.shape[-1]).T, PROB)
    ess = [v for v in ([res.ess["beta"], *res.ess["theta"]] if res.ess else []) if v is not None]
    rhat = [v for v in ([res.r_hat["beta"], *res.r_hat["theta"]] if res.r_hat else []) if v is not None]
    row.update(
        rank={"beta": int(rank[0]), "theta": rank[1:].tolist()},
        interval={"beta": [float(lo[0]), float(hi[0])],
                  "theta": [[float(a), float(b)] for a, b in zip(lo[1:], hi[1:], strict=True)]},
        divergences=res.divergences,
        r_hat_max=max(rhat) if rhat else None,
        ess_min=min(ess) if ess else None,
        thinned_enough=sbc.thinned_enough(min(ess) if ess else None, args.rank_draws),
    )
    return row


def load_rows(path: Path, want: dict) -> list[dict]:
    """Rows already in ``path`` (a torn last line, from a killed run, is dropped)."""
    if not path.exists():
        return []
    text = path.read_text()
    lines = text.splitlines()
    if text and not text.endswith("\n"):
        lines = lines[:-1]
        path.write_text("".join(f"{ln}\n" for ln in lines))
    rows = [json.loads(ln) for ln in lines if ln.strip()]
    for r in rows:
        if r["settings"] != want:
            sys.exit(f"{path} holds results with other settings ({r['settings']}, now {want}); "
                     "use another --out")
    return rows


def quantity_names(feature_names) -> list[str]:
    return ["β", *(f"θ_{n}" for n in feature_names)]


def summarise(rows: list[dict], feature_names, args: argparse.Namespace) -> dict:
    ok = [r for r in rows if "error" not in r]
    lo_b, hi_b = get_prior(DEFAULT_PRIOR).beta_range
    edges = [lo_b, *BETA_EDGES_INNER, hi_b]
    beta_true = np.array([r["beta_true"] for r in ok])
    out: dict = {
        "people": len(rows), "failed": len(rows) - len(ok),
        "errors": [{"person": r["person"], "error": r["error"]} for r in rows if "error" in r],
        "divergences_total": int(sum(r["divergences"] for r in ok)),
        "people_with_divergences": int(sum(r["divergences"] > 0 for r in ok)),
        "people_r_hat_above_1.01": int(sum((r["r_hat_max"] or math.inf) > 1.01 for r in ok)),
        "people_ess_below_L": int(sum(not r["thinned_enough"] for r in ok)),
        "median_wall_s": float(np.median([r["wall_s"] for r in ok])) if ok else None,
        "beta_bins": [[a, b] for a, b in itertools.pairwise(edges)],
        "quantities": {},
    }
    if not ok:
        return out
    for k, name in enumerate(quantity_names(feature_names)):
        def pick(r, key, k=k):
            return r[key]["beta"] if k == 0 else r[key]["theta"][k - 1]
        truths = beta_true if k == 0 else np.array([r["theta_true"][k - 1] for r in ok])
        rank = np.array([pick(r, "rank") for r in ok], dtype=np.int64)
        lo = np.array([pick(r, "interval")[0] for r in ok])
        hi = np.array([pick(r, "interval")[1] for r in ok])
        test = sbc.uniformity_test(rank, args.rank_draws, args.bins)

        def by_beta(e, truths=truths, lo=lo, hi=hi):
            return sbc.coverage_by_bins(truths, lo, hi, beta_true, e)
        out["quantities"][name] = {
            "chi2": test.statistic, "p_value": test.p_value, "dof": test.dof,
            "counts": test.counts, "expected": test.expected,
            "coverage": sbc.coverage(truths, lo, hi).to_dict(),
            "coverage_by_beta": [c.to_dict() for _, _, c in by_beta(edges)],
            "coverage_experts": by_beta([EXPERT_BETA, hi_b])[0][2].to_dict(),
        }
    return out


def _cov(c: dict) -> str:
    return "   –   (n=0) " if c["n"] == 0 else f"{c['rate']:.2f}±{c['se']:.2f} (n={c['n']})"


def print_summary(model: str, s: dict) -> None:
    print(f"\n{model}: {s['people']} people ({s['failed']} failed), divergences {s['divergences_total']} "
          f"in {s['people_with_divergences']} people, R-hat > 1.01 in {s['people_r_hat_above_1.01']}, "
          f"ESS < L in {s['people_ess_below_L']}, median NUTS time "
          f"{s['median_wall_s'] or float('nan'):.1f} s")
    bins = [f"β*∈[{a:g},{b:g}{']' if i == len(s['beta_bins']) - 1 else ')'}"
            for i, (a, b) in enumerate(s["beta_bins"])]
    head = [f"{'quantity':<14}", f"{'χ²':>7}", f"{'p':>7}", f"{f'{PROB:.0%} coverage':>19}",
            *(f"{b:>19}" for b in bins), f"{f'β* ≥ {EXPERT_BETA:g}':>19}"]
    print(" ".join(head))
    for name, q in s["quantities"].items():
        print(" ".join([f"{name:<14}", f"{q['chi2']:7.2f}", f"{q['p_value']:7.3f}",
                        f"{_cov(q['coverage']):>19}",
                        *(f"{_cov(c):>19}" for c in q["coverage_by_beta"]),
                        f"{_cov(q['coverage_experts']):>19}"]))


def plot(model: str, s: dict, args: argparse.Namespace, path: Path) -> None:
    """Rank histograms, one panel per quantity, with the 99% band of each bin's count under
    uniformity (binomial quantiles)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import binom

    qs = s["quantities"]
    fig, axes = plt.subplots(1, len(qs), figsize=(2.6 * len(qs), 2.6), sharey=True, squeeze=False)
    n = s["people"] - s["failed"]
    for ax, (name, q) in zip(axes[0], qs.items(), strict=True):
        counts, expected = np.asarray(q["counts"]), np.asarray(q["expected"])
        x = np.arange(len(counts))
        band_lo, band_hi = binom.ppf(0.005, n, expected / n), binom.ppf(0.995, n, expected / n)
        ax.fill_between(np.append(x, x[-1] + 1) - 0.5, np.append(band_lo, band_lo[-1]),
                        np.append(band_hi, band_hi[-1]), step="post", color="0.85", label="99% band")
        ax.bar(x, counts, width=0.9, color="C0")
        ax.set_title(f"{name}\nχ² p = {q['p_value']:.2g}", fontsize=9)
        ax.set_xticks([0, len(counts) - 1], ["low", "high"])
        ax.set_xlabel("rank of truth")
    axes[0][0].set_ylabel("people")
    fig.suptitle(f"SBC of NUTS, {model} model, {args.map}: {n} people, L = {args.rank_draws}", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> None:
    enable_jax_cache()  # one compile per model and map, not per person
    args = parse_args(argv)
    info = machine_info()
    info.setdefault("cpu_flags", cpu_flags())
    for k, v in info.items():
        print(f"{k}: {v}")
    mdp = load_bundled(args.map).to_mdp()
    print(f"map {args.map}: {mdp.n_states} states, features {', '.join(mdp.feature_names)}; "
          f"prior {DEFAULT_PRIOR}: {get_prior(DEFAULT_PRIOR).text}")
    print(f"{args.people} people per model, {args.episodes} episodes (≤ {args.max_steps} actions), NUTS "
          f"{args.chains} chains × ({args.warmup} warm-up + {args.samples} draws), ranks among "
          f"L = {args.rank_draws} thinned draws, {args.bins} bins, {PROB:.0%} intervals")
    args.out.mkdir(parents=True, exist_ok=True)
    summary = {"machine": info, "settings": {k: str(v) if isinstance(v, Path) else v
                                              for k, v in vars(args).items()}, "models": {}}
    for model in args.models:
        path = args.out / f"sbc-{model}.jsonl"
        rows = load_rows(path, settings(args, model))
        done = {r["person"] for r in rows}
        if done:
            print(f"\n{model}: {len(done)} people already in {path}")
        print(f"\n{model}: {'person':>6} {'β*':>8} {'rank β':>6} {'β in 90%':>8} {'pairs':>6} {'done':>4} "
              f"{'div':>4} {'R-hat':>6} {'ESS':>6} {'s':>6}")
        for person in range(args.people):
            if person in done:
                continue
            row = run_person(mdp, person, model, args)
            with path.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
            rows.append(row)
            if "error" in row:
                print(f"{model}: {person:>6} {row['beta_true']:8.3g} failed: {row['error']}")
                continue
            b_lo, b_hi = row["interval"]["beta"]
            print(f"{model}: {person:>6} {row['beta_true']:8.3g} {row['rank']['beta']:>6} "
                  f"{'yes' if b_lo <= row['beta_true'] <= b_hi else 'no':>8} {row['pairs']:>6} "
                  f"{row['episodes_finished']:>4} {row['divergences']:>4} "
                  f"{row['r_hat_max'] or float('nan'):6.3f} "
                  f"{row['ess_min'] or float('nan'):6.0f} {row['wall_s']:6.1f}", flush=True)
        rows = sorted((r for r in rows if r["person"] < args.people), key=lambda r: r["person"])
        s = summarise(rows, mdp.feature_names, args)
        summary["models"][model] = s
        print_summary(model, s)
        if s["quantities"]:
            png = args.plots / f"calibration-{model}.png"
            plot(model, s, args, png)
            print(f"rank histograms: {png}")
    text = json.dumps(summary, indent=1)
    (args.out / "summary.json").write_text(text)
    if args.json:
        args.json.write_text(text)


if __name__ == "__main__":
    main()
