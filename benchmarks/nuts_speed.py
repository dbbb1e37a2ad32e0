"""NUTS speed: wall time and effective samples per second, before and after, in one run.

    python benchmarks/nuts_speed.py [--quick] [--json out.json]

Data: `crossroads`, 40 simulated episodes from random starts, θ* = (.4, .3, .1, .1, .1):
  expert    β* = 0.1, maxent (the paper's model);
  medium    β* = 0.5, maxent-relative (under maxent most episodes never finish);
  novice    β* = 2,   maxent-relative (long episodes: 5× the actions).
Every configuration samples 4 chains × (500 warm-up + 500 draws) under the default prior
(log-uniform), tolerance 1e-8 on V/β, and starts cold: compilation is included and JAX's
persistent cache is off, as on a user's first run.
  numpyro-vectorised   NumPyro's MCMC with vectorised chains and a diagonal mass matrix,
                       every solve from zero: the library's sampler before this benchmark;
  library              `nuts_posterior` defaults: a program per chain in threads, Laplace
                       starts, dense mass matrix;
  + warm-start         the same with solves warm-started at each chain's last draw;
  - laplace            the library without Laplace starts (identity mass to begin with);
  - dense              the library with a diagonal mass matrix.
Reported: wall and CPU seconds, the smallest bulk ESS over β and θ_i, ESS per wall second,
leapfrog steps per draw, divergences and the posterior mean of β.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

os.environ.setdefault("EXPERTISE_IRL_JAX_CACHE", "off")  # cold starts: compilation included

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info

from expertise_irl.demos.simulation import simulate
from expertise_irl.inference.diagnostics import chain_statistics
from expertise_irl.inference.nuts import nuts_posterior
from expertise_irl.inference.priors import numpyro_priors
from expertise_irl.inference.task_likelihood import pair_counts
from expertise_irl.planning.differentiable import make_log_likelihood
from expertise_irl.worlds.zones import load_bundled

warnings.filterwarnings("ignore", category=FutureWarning)

THETA = np.array([0.4, 0.3, 0.1, 0.1, 0.1])
DATA = {"expert": (0.1, "maxent"), "medium": (0.5, "maxent-relative"), "novice": (2.0, "maxent-relative")}
WARMUP = SAMPLES = 500
CHAINS = 4


def numpyro_vectorised(mdp, trajs, model: str, seed: int):
    """NumPyro's own driver, vectorised chains, diagonal mass, every solve from zero."""
    import jax
    import numpyro
    from numpyro.infer import MCMC, NUTS

    f = make_log_likelihood(mdp, pair_counts(mdp, trajs), tol=1e-8, model=model)
    theta_prior, beta_prior = numpyro_priors("log-uniform", mdp.n_features)

    def numpyro_model():
        theta = numpyro.sample("theta", theta_prior)
        beta = numpyro.sample("beta", beta_prior)
        numpyro.factor("log_likelihood", f(theta, beta)[0])

    mcmc = MCMC(NUTS(numpyro_model), num_warmup=WARMUP, num_samples=SAMPLES, num_chains=CHAINS,
                chain_method="vectorized", progress_bar=False)
    mcmc.run(jax.random.PRNGKey(seed), extra_fields=("diverging", "num_steps"))
    s = mcmc.get_samples(group_by_chain=True)
    extra = mcmc.get_extra_fields(group_by_chain=True)
    theta, beta = np.asarray(s["theta"]), np.asarray(s["beta"])  # blocks until the run is done
    divergences = int(np.asarray(extra["diverging"]).sum())
    return theta, beta, divergences, float(np.asarray(extra["num_steps"]).mean())


def library(**options):
    def run(mdp, trajs, model: str, seed: int):
        r = nuts_posterior(mdp, trajs, num_warmup=WARMUP, num_samples=SAMPLES, num_chains=CHAINS, seed=seed,
                           model=model, **options)
        return r.theta, r.beta, r.divergences, r.mean_tree_size
    return run


CONFIGS = {
    "numpyro-vectorised": numpyro_vectorised,
    "library": library(),
    "+ warm-start": library(warm_start=True),
    "- laplace": library(laplace_init=False),
    "- dense": library(dense_mass=False),
}


def measure(name: str, fn, mdp, trajs, model: str) -> dict:
    c0, t0 = time.process_time(), time.perf_counter()
    theta, beta, divergences, tree = fn(mdp, trajs, model, 0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    stats = chain_statistics(theta, beta)
    ess = min([stats["ess_bulk"]["beta"], *stats["ess_bulk"]["theta"]])
    return {"config": name, "wall_s": wall, "cpu_s": cpu, "min_ess": ess, "ess_per_s": ess / wall,
            "tree_size": tree, "divergences": divergences, "beta_mean": float(beta.mean()),
            "max_r_hat": max(float("inf") if r is None else r  # a stuck parameter has no R-hat: the worst
                             for r in [stats["r_hat"]["beta"], *stats["r_hat"]["theta"]])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the expert data set, before and after only")
    ap.add_argument("--data", default=None, help=f"comma-separated subset of {', '.join(DATA)}")
    ap.add_argument("--configs", default=None, help=f"comma-separated subset of {', '.join(CONFIGS)}")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    info = machine_info()
    for k, v in info.items():
        print(f"{k}: {v}")
    data = ["expert"] if args.quick else list(DATA) if args.data is None else args.data.split(",")
    configs = (["numpyro-vectorised", "library"] if args.quick else list(CONFIGS) if args.configs is None
               else args.configs.split(","))
    mdp = load_bundled("crossroads").to_mdp()
    rows = []
    print(f"\n{'data':8s} {'config':20s} {'wall s':>7s} {'cpu s':>7s} {'min ESS':>8s} {'ESS/s':>7s} "
          f"{'steps':>6s} {'div':>4s} {'mean β':>8s} {'R-hat':>6s}")
    for d in data:
        beta_true, model = DATA[d]
        trajs = simulate(mdp, THETA, beta_true, 40, np.random.default_rng(1), model=model)
        for c in configs:
            r = {"data": d, "beta_true": beta_true, "model": model, "actions": len(trajs),
                 **measure(c, CONFIGS[c], mdp, trajs, model)}
            rows.append(r)
            print(f"{d:8s} {c:20s} {r['wall_s']:7.1f} {r['cpu_s']:7.1f} {r['min_ess']:8.0f} "
                  f"{r['ess_per_s']:7.1f} {r['tree_size']:6.1f} {r['divergences']:4d} {r['beta_mean']:8.4f} "
                  f"{r['max_r_hat']:6.3f}",
                  flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": info, "rows": rows}, indent=1))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
