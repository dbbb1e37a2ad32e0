"""Simulation-based calibration of the population model's NUTS (inference/population.py).

    python benchmarks/population_sbc.py [--studies 200] [--people 12] [--episodes 2] [--n-betas 20]
        [--warmup 500] [--samples 500] [--chains 2] [--target-accept 0.9] [--temper 1]
        [--rank-draws 99] [--bins 10] [--seed 0] [--out benchmarks/results/population_sbc.txt]
        [--json FILE]

One simulated study per ``--studies`` index s, everything drawn from ``default_rng([seed, s])``:

1. ψ* = (μ, σ, α, m) from the hyperprior NUTS uses (``Hyperprior().resolve(data)``, one group):
   μ ~ Normal(mu_loc, mu_scale), σ ~ HalfNormal(sigma_scale) truncated below at sigma_floor,
   log α ~ Normal(alpha_log_loc, alpha_log_scale), m ~ Dirichlet(1, …, 1);
2. each of ``--people`` participants' hypothesis h_i = (θ_j, β_k) drawn ON the grid from the
   population prior under ψ* (:func:`population_log_prior`, every θ allowed);
3. ``--episodes`` episodes per participant simulated from the solved log-policy of h_i itself
   (``simulate(..., log_policy=log_policy[h_i])``), so the data come from exactly the
   likelihood the model uses; ℓ_i = the sum of the episodes' grid log-likelihoods;
4. :func:`sample_population` (``seed`` = s) on those participants.

The grid: the bundled map ``crossroads`` (185 cells, K = 5 features), the paper-real Θ (211
directions), ``--n-betas`` β log-spaced on [0.02, 5] (the SBC holds for any grid, since the
model is exact on the grid it is given; 20 is tests/inference/test_population.py's grid, and the cost is
mostly the sampler's compilation, read back from JAX's persistent cache after the first
study), the maxent model.

If the sampler is exact, each true hyperparameter's rank among ``--rank-draws`` L draws evenly
spaced over the run (``sbc.thin``; roughly independent when the run's bulk ESS ≥ L, which each
row records) is uniform on {0, …, L}: a χ² test of each rank histogram in ``--bins`` bins
(``sbc.uniformity_test``) for μ, σ, α and each m_c, and the coverage of the 90% equal-tailed
intervals (from all draws). Rows are printed as studies finish; the whole output is written to
``--out``. ``--temper 2`` hands NUTS each participant's ℓ doubled (a posterior too confident by
about √2), to show that the test can fail.

Measured (results/population_sbc.txt, 200 studies, 2 cores shared with other jobs: ~13 min): χ²
p-values 0.34 (μ), 0.49 (σ), 0.16 (α), 0.23, 0.32, 0.39, 0.15, 0.95 (m_0…m_4): no rank histogram
departs from uniform. The 90% intervals covered 0.905, 0.900, 0.870, 0.890, 0.890, 0.905, 0.820,
0.870 of the truths: m_3's 0.82 (Clopper–Pearson 95% [0.76, 0.87]) and the mean of 0.88 over the
eight are a little low, a lead for a longer run rather than a verdict (the eight share studies
and draws). 38 studies had divergent transitions (104 in all, after σ's floor), 80 an R-hat above
1.01 (2 chains of 500: a noisy R-hat), 4 a bulk ESS below L. With ``--temper 2``
(results/population_sbc_temper2.txt, 100 studies) μ's histogram is rejected (χ² 38.6, p = 1.4e-5,
ranks piled at the top), α's p = 0.002, m_3's 0.035, σ's 0.055: the check sees a doubled
likelihood in μ and α, not in every hyperparameter.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info

warnings.filterwarnings("ignore", category=FutureWarning)

ROOT = Path(__file__).resolve().parent.parent
PROB = 0.9  # the central intervals whose coverage is reported
BETA_RANGE = (0.02, 5.0)
MAP = "crossroads"


@dataclass(frozen=True)
class Setup:
    """What every study shares: the map, the set, its solved log-policy and the run's lengths."""

    mdp: object
    hyp: object
    log_policy: np.ndarray
    people: int
    episodes: int
    warmup: int
    samples: int
    chains: int
    rank_draws: int
    target_accept: float = 0.9
    temper: float = 1.0
    max_steps: int = 500


def make_setup(*, n_betas: int = 20, thetas: str = "paper-real", **run) -> Setup:
    """Solve the set once (``thetas`` × ``n_betas`` β log-spaced on :data:`BETA_RANGE`)."""
    from expertise_irl.inference.methods import DiscreteOptions
    from expertise_irl.planning.soft_vi import solve
    from expertise_irl.worlds.maps import load_bundled_world

    mdp = load_bundled_world(MAP).to_mdp()
    betas = np.exp(np.linspace(math.log(BETA_RANGE[0]), math.log(BETA_RANGE[1]), n_betas))
    hyp = DiscreteOptions(thetas=thetas, betas=",".join(f"{b:.8g}" for b in betas)).hypotheses(mdp.n_features)
    return Setup(mdp, hyp, solve(mdp, hyp.theta, hyp.beta).log_policy, **run)


def quantity_names(K: int) -> list[str]:
    return ["mu", "sigma", "alpha", *(f"m[{c}]" for c in range(K))]


def draw_hyperparameters(prior, K: int, rng: np.random.Generator):
    """ψ* from the resolved hyperprior (the densities :func:`population._posterior` uses)."""
    from expertise_irl.inference.population import Hyperparameters

    mu = rng.normal(prior.mu_loc, prior.mu_scale)
    sigma = abs(rng.normal(0.0, prior.sigma_scale))
    while sigma < prior.sigma_floor:  # HalfNormal truncated below at the floor, by rejection
        sigma = abs(rng.normal(0.0, prior.sigma_scale))
    alpha = math.exp(rng.normal(prior.alpha_log_loc, prior.alpha_log_scale))
    return Hyperparameters(mu, sigma, alpha, rng.dirichlet(np.ones(K)))


def simulate_study(setup: Setup, rng: np.random.Generator):
    """``(ψ*, hypotheses [N], PopulationData)`` of one simulated study (steps 1–3 of the docstring)."""
    from expertise_irl.demos.simulation import simulate
    from expertise_irl.inference import population as pop
    from expertise_irl.planning.table_likelihood import log_likelihood

    hyp, N = setup.hyp, setup.people
    H, K = len(hyp), hyp.thetas.shape[1]
    blank = pop.population_data(np.zeros((N, H)), hyp)  # the grid and the (all-allowed) masks only
    psi = draw_hyperparameters(pop.Hyperprior().resolve(blank), K, rng)
    p = np.exp(pop.population_log_prior(blank, psi)[0].reshape(-1))
    h = rng.choice(H, size=N, p=p / p.sum())
    lls = []
    for hi in h:
        tr = simulate(setup.mdp, None, None, setup.episodes, rng, log_policy=setup.log_policy[hi],
                      max_steps=setup.max_steps)
        lls.append(log_likelihood(setup.log_policy, tr.state, tr.action))
    return psi, h, pop.population_data(lls, hyp)


def run_study(setup: Setup, study: int, seed: int = 0) -> dict:
    """One study: its truths, the ranks of the truths among L thinned draws, 90% intervals and
    the run's diagnostics."""
    from expertise_irl.inference import population as pop
    from expertise_irl.inference import sbc

    rng = np.random.default_rng([seed, study])
    psi, h, data = simulate_study(setup, rng)
    if setup.temper != 1.0:  # a deliberately wrong posterior: the likelihood raised to this power
        data = pop.population_data(setup.temper * data.log_lik.reshape(data.n, -1), setup.hyp)
    t = time.perf_counter()
    post = pop.sample_population(data, num_warmup=setup.warmup, num_samples=setup.samples,
                                 num_chains=setup.chains, seed=study,
                                 target_accept=setup.target_accept)
    wall = time.perf_counter() - t
    K = setup.hyp.thetas.shape[1]
    truths = np.array([psi.mu[0], psi.sigma[0], psi.alpha, *psi.m])
    joint = np.concatenate([post.mu, post.sigma, post.alpha[..., None], post.m], axis=-1)  # [C, D, 3+K]
    kept = sbc.thin(joint, setup.rank_draws)  # the same draws for every quantity
    rank = sbc.ranks(truths, kept.T, rng=study)
    lo, hi = sbc.central_intervals(joint.reshape(-1, joint.shape[-1]).T, PROB)
    ess = [v for v in post.ess_bulk.values() if v is not None]
    rhat = [v for v in post.r_hat.values() if v is not None]
    return {"study": study, "names": quantity_names(K), "truth": truths.tolist(), "rank": rank.tolist(),
            "low": lo.tolist(), "high": hi.tolist(), "hypotheses": h.tolist(),
            "wall_s": wall, "divergences": post.divergences,
            "r_hat_max": max(rhat) if rhat else None, "ess_min": min(ess) if ess else None,
            "thinned_enough": sbc.thinned_enough(min(ess) if ess else None, setup.rank_draws)}


def summarise(rows: list[dict], rank_draws: int, bins: int) -> dict:
    """Per quantity: the χ² uniformity test of its ranks and the 90% intervals' coverage."""
    from expertise_irl.inference import sbc

    names = rows[0]["names"]
    out = {"studies": len(rows), "divergences_total": int(sum(r["divergences"] for r in rows)),
           "studies_with_divergences": int(sum(r["divergences"] > 0 for r in rows)),
           "studies_r_hat_above_1.01": int(sum((r["r_hat_max"] or math.inf) > 1.01 for r in rows)),
           "studies_ess_below_L": int(sum(not r["thinned_enough"] for r in rows)),
           "median_wall_s": float(np.median([r["wall_s"] for r in rows])), "quantities": {}}
    for q, name in enumerate(names):
        rank = np.array([r["rank"][q] for r in rows], dtype=np.int64)
        test = sbc.uniformity_test(rank, rank_draws, bins)
        cov = sbc.coverage([r["truth"][q] for r in rows], [r["low"][q] for r in rows],
                           [r["high"][q] for r in rows])
        out["quantities"][name] = {"chi2": test.statistic, "p_value": test.p_value, "dof": test.dof,
                                   "counts": test.counts, "coverage90": cov.rate,
                                   "coverage90_ci": [cov.ci_low, cov.ci_high]}
    return out


def main(argv=None) -> None:
    from expertise_irl.planning.jax_cache import enable_jax_cache

    enable_jax_cache()  # the sampler's programs are the same for every study: compiled once, then read back
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--studies", type=int, default=200, help="simulated studies (default 200)")
    ap.add_argument("--people", type=int, default=12, help="participants per study")
    ap.add_argument("--episodes", type=int, default=2, help="episodes per participant")
    ap.add_argument("--n-betas", type=int, default=20, help="β grid size, log-spaced on [0.02, 5]")
    ap.add_argument("--warmup", type=int, default=500)
    ap.add_argument("--samples", type=int, default=500)
    ap.add_argument("--chains", type=int, default=2)
    ap.add_argument("--target-accept", type=float, default=0.9, help="NUTS's target acceptance (default 0.9)")
    ap.add_argument("--rank-draws", type=int, default=99, help="L, thinned draws each truth is ranked among")
    ap.add_argument("--bins", type=int, default=10, help="rank histogram bins (best a divisor of L + 1)")
    ap.add_argument("--temper", type=float, default=1.0,
                    help="raise the likelihood NUTS sees to this power (1: exact; 2: an overconfident "
                         "posterior, to measure the test's power)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "population_sbc.txt")
    ap.add_argument("--json", type=Path, help="also write the rows and the summary here")
    args = ap.parse_args(argv)
    if args.rank_draws > args.chains * args.samples:
        ap.error(f"--rank-draws {args.rank_draws} exceeds the run's {args.chains * args.samples} draws")
    lines: list[str] = []

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    for k, v in machine_info().items():
        say(f"{k}: {v}")
    t0 = time.perf_counter()
    setup = make_setup(n_betas=args.n_betas, people=args.people, episodes=args.episodes, warmup=args.warmup,
                       samples=args.samples, chains=args.chains, rank_draws=args.rank_draws,
                       target_accept=args.target_accept, temper=args.temper)
    say(f"\n{MAP}, paper-real Θ ({setup.hyp.n_theta}) × {setup.hyp.n_beta} β on {list(BETA_RANGE)} = "
        f"{len(setup.hyp)} hypotheses, solved in {time.perf_counter() - t0:.1f} s; {args.studies} studies × "
        f"{args.people} participants × {args.episodes} episodes; NUTS {args.chains} chains × "
        f"({args.warmup} + {args.samples}), target_accept {args.target_accept}; ranks among L = "
        f"{args.rank_draws} thinned draws, {args.bins} bins"
        + (f"; likelihood tempered ×{args.temper:g} (a wrong posterior)" if args.temper != 1.0 else ""))
    from expertise_irl.inference.population import Hyperprior, population_data

    blank = population_data(np.zeros((1, len(setup.hyp))), setup.hyp)
    say(f"hyperprior: {Hyperprior().resolve(blank).text()}\n")
    rows = []
    for s in range(args.studies):
        r = run_study(setup, s, args.seed)
        rows.append(r)
        truth = " ".join(f"{n}={v:.3g}" for n, v in zip(r["names"][:3], r["truth"][:3], strict=True))
        say(f"study {s:3d}: {truth}  ranks {r['rank']}  ESS_min {r['ess_min'] or math.nan:.0f}  "
            f"R-hat_max {r['r_hat_max'] or math.nan:.3f}  div {r['divergences']}  {r['wall_s']:.1f} s")
    summary = summarise(rows, args.rank_draws, args.bins)
    say()
    for k, v in summary.items():
        if k != "quantities":
            say(f"{k}: {v}")
    say(f"\n{'quantity':>9}  {'chi2':>7}  {'p':>6}  {'cover90':>7}  95% CI          "
        f"rank counts ({args.bins} bins)")
    for name, q in summary["quantities"].items():
        say(f"{name:>9}  {q['chi2']:7.2f}  {q['p_value']:6.3f}  {q['coverage90']:7.3f}  "
            f"[{q['coverage90_ci'][0]:.3f}, {q['coverage90_ci'][1]:.3f}]  {q['counts']}")
    say(f"\ntotal wall: {time.perf_counter() - t0:.0f} s")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": summary}, indent=1) + "\n")


if __name__ == "__main__":
    main()
