"""MAP's θ prior and the continuous methods' point estimates, on people off every grid.

    python benchmarks/map_prior.py [--per-third 8] [--alphas 0.5,1,1.5,2,3] [--seed 0]
        [--nuts-per-third 0] [--nuts-alpha A] [--out benchmarks/results/map_prior.txt] [--json FILE]

The people: on the bundled map ``crossroads`` (185 cells, K = 5, γ = 0.95, model ``maxent``, no
start cells), ``--per-third`` people in each third of log β's range [0.01, 10] ([0.01, 0.1],
[0.1, 1], [1, 10]), each with θ* ~ Dirichlet(1, …, 1), β* log-uniform in its third and 5–20
episodes (uniform), all from ``default_rng([seed, third, person])``: no truth lies on a grid.

- ``map``, once per concentration α in ``--alphas`` (``get_method("map")`` with
  ``concentration=α``, 4 starts, seed 0, the log-uniform prior): the mode and the Laplace
  mean (:mod:`expertise_irl.inference.laplace`) as point estimates; the share of people whose
  Laplace 90% interval holds β*, and the share of θ* components inside theirs; the share with
  a warning, and with β̂ at a prior edge (each of them must be warned).
- ``nuts`` (``--nuts-per-third`` > 0, the first people of each third): 2 chains of 300 warm-up
  and 300 draws, concentration ``--nuts-alpha`` (default: the library's); point estimates: the
  posterior mean, the posterior median (β; θ: its mean) and the draw of highest density; the
  share whose 90% interval holds β*.

Per third: the median cosine of θ̂ to θ* and the median |log10(β̂/β*)|.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

THIRDS = ((0.01, 0.1), (0.1, 1.0), (1.0, 10.0))
EPISODES = (5, 20)


def people_of(mdp, per_third: int, seed: int) -> list[dict]:
    from expertise_irl.demos.simulation import simulate

    out = []
    for t, (lo, hi) in enumerate(THIRDS):
        for i in range(per_third):
            rng = np.random.default_rng([seed, t, i])
            theta = rng.dirichlet(np.ones(mdp.n_features))
            beta = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
            n = int(rng.integers(EPISODES[0], EPISODES[1] + 1))
            out.append({"third": t, "index": i, "theta": theta, "beta": beta, "episodes": n,
                        "trajs": simulate(mdp, theta, beta, n, rng)})
    return out


def cosine(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))


def scores(theta_hat, beta_hat, person) -> dict:
    return {"cosine": cosine(theta_hat, person["theta"]),
            "log_ratio": abs(float(np.log10(beta_hat / person["beta"])))}


def inside(ci, person) -> tuple[bool, float]:
    """Whether β* lies in the interval, and the share of θ* components inside theirs."""
    b_in = ci["beta"][0] <= person["beta"] <= ci["beta"][1]
    th = np.array(ci["theta"])
    return bool(b_in), float(np.mean((th[:, 0] <= person["theta"]) & (person["theta"] <= th[:, 1])))


def run_map(mdp, people, alpha: float) -> list[dict]:
    from expertise_irl.inference.methods import get_method

    method = get_method("map")
    opts = method.options_from({"concentration": alpha})
    rows = []
    for p in people:
        run = method.run(mdp, p["trajs"], opts, 0)
        f, lap = run.fields, run.fields["diagnostics"]["laplace"]
        row = {"third": p["third"], "alpha": alpha, "beta_hat": f["beta_hat"], "seconds": f["run_time_s"],
               "mode": scores(f["theta_hat"], f["beta_hat"], p),
               "warned": bool(f["diagnostics"]["warnings"]),
               "edge": any("edge of the prior" in w for w in f["diagnostics"]["warnings"])}
        if lap["positive_definite"]:
            row["laplace_mean"] = scores(lap["theta_mean"], lap["beta_mean"], p)
            row["beta_in"], row["theta_in"] = inside(f["credible_intervals"], p)
        rows.append(row)
    return rows


def run_nuts(mdp, people, alpha: float | None) -> list[dict]:
    from expertise_irl.inference.methods import get_method

    method = get_method("nuts")
    opts = method.options_from({"chains": 2, "warmup": 300, "samples": 300, "concentration": alpha})
    rows = []
    for p in people:
        run = method.run(mdp, p["trajs"], opts, 0)
        r, f = run.result, run.fields
        th = r.theta.reshape(-1, r.theta.shape[-1])
        rows.append({
            "third": p["third"], "seconds": f["run_time_s"], "divergences": r.divergences,
            "mean": scores(r.mean_theta, r.mean_beta, p),
            "median": scores(r.mean_theta, float(np.median(r.beta)), p),
            "best_draw": scores(f["map"]["theta"], f["map"]["beta"], p),
            "beta_in": inside(f["credible_intervals"], p)[0] if f["credible_intervals"]["beta"] else None,
            "theta_in": (inside(f["credible_intervals"], p)[1]
                         if all(c is not None for c in f["credible_intervals"]["theta"]) else None),
            "beta_hat": r.mean_beta, "theta_sd": float(th.std(axis=0).mean())})
    return rows


def _median(rows, key, stat) -> float:
    vals = [r[key][stat] for r in rows if key in r]
    return float(np.median(vals)) if vals else float("nan")


def _share(rows, key) -> str:
    vals = [r[key] for r in rows if r.get(key) is not None]
    return f"{np.mean(vals):.0%}" if vals else "-"


def table(rows: list[dict], label: str, estimates: tuple[str, ...]) -> list[str]:
    head = (f"{label:10} {'third':13} " + " ".join(f"{e + ' cos':>17} {e + ' |lg|':>17}" for e in estimates)
            + f" {'β* in 90%':>9} {'θ* in 90%':>9} {'warned':>6} {'edge':>5} {'s/person':>8}")
    out = [head]
    for key in sorted({r["group"] for r in rows}, key=lambda k: (str(k[0]), k[1])):
        for t, (lo, hi) in enumerate(THIRDS):
            mine = [r for r in rows if r["group"] == key and r["third"] == t]
            cells = " ".join(f"{_median(mine, e, 'cosine'):17.3f} {_median(mine, e, 'log_ratio'):17.3f}"
                             for e in estimates)
            edge = (f"{sum(r['edge'] for r in mine)}/{sum(r['edge'] and r['warned'] for r in mine)}w"
                    if "edge" in mine[0] else "-")
            out.append(f"{key[1]:10} [{lo:g}, {hi:g}]".ljust(24) + f" {cells} {_share(mine, 'beta_in'):>9} "
                       f"{_share(mine, 'theta_in'):>9} {_share(mine, 'warned'):>6} {edge:>5} "
                       f"{np.mean([r['seconds'] for r in mine]):8.1f}")
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-third", type=int, default=8, help="people in each third of log β's range")
    ap.add_argument("--alphas", default="0.5,1,1.5,2,3", help="MAP's θ concentrations to compare")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--nuts-per-third", type=int, default=0, help="people per third also run with NUTS")
    ap.add_argument("--nuts-alpha", type=float, default=None,
                    help="NUTS's concentration (default: the library's)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "map_prior.txt")
    ap.add_argument("--json", type=Path, help="also write every person's numbers here")
    args = ap.parse_args(argv)

    from _machine import machine_info

    from expertise_irl.worlds.maps import load_bundled_world

    lines: list[str] = []

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    t0 = time.perf_counter()
    for k, v in machine_info().items():
        say(f"{k}: {v}")
    mdp = load_bundled_world("crossroads").to_mdp()
    people = people_of(mdp, args.per_third, args.seed)
    acts = [len(p["trajs"]) for p in people]
    say(f"\ncrossroads ({mdp.n_states} states, K = {mdp.n_features}), model maxent; {args.per_third} "
        f"people per third of log β on [0.01, 10], θ* ~ Dirichlet(1), β* log-uniform, "
        f"{EPISODES[0]}–{EPISODES[1]} episodes ({min(acts)}–{max(acts)} actions per person)\n")
    rows = []
    for a in (float(x) for x in args.alphas.split(",")):
        for r in run_map(mdp, people, a):
            rows.append({**r, "group": ("map", f"map α={a:g}")})
        print(f"map α = {a:g} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    say("MAP: median cosine and median |log10(β̂/β*)| of the mode and of the Laplace mean; the Laplace "
        "interval's coverage; warned share; edge = at a prior edge / of them warned")
    for line in table(rows, "method", ("mode", "laplace_mean")):
        say(line)
    nuts_rows = []
    if args.nuts_per_third > 0:
        chosen = [p for p in people if p["index"] < args.nuts_per_third]
        nuts_rows = [{**r, "group": ("nuts", "nuts")} for r in run_nuts(mdp, chosen, args.nuts_alpha)]
        say(f"\nNUTS ({args.nuts_per_third} people per third, 2 chains × 300 + 300, concentration "
            f"{args.nuts_alpha if args.nuts_alpha is not None else 'default'}): posterior mean, posterior "
            f"median of β (θ: mean), highest-density draw; divergences "
            f"{sum(r['divergences'] for r in nuts_rows)}")
        for line in table(nuts_rows, "method", ("mean", "median", "best_draw")):
            say(line)
    say(f"\nwall: {time.perf_counter() - t0:.0f} s")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
    if args.json:
        args.json.write_text(json.dumps({"people": [{k: (v.tolist() if isinstance(v, np.ndarray) else v)
                                                     for k, v in p.items() if k != "trajs"} for p in people],
                                         "map": rows, "nuts": nuts_rows}, indent=1, default=str) + "\n")


if __name__ == "__main__":
    main()
