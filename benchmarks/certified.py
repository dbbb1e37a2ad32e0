"""Certified solving (screen, eliminate, finish to the data's tolerance) against one solve of every
hypothesis to 1e-8, and both against a full-precision posterior, in one run.

    python benchmarks/certified.py [--sizes 100,200] [--fullset] [--out FILE]

The cases: the large-worlds person (θ* = (0.4, 0.2, 0.4), β* = 0.3, 3 episodes, seed 0) on the
``SIZE × SIZE`` floor plans of ``benchmarks/large_worlds.py`` with paper-real Θ × paper-real B (95
hypotheses); with ``--fullset``, the README's person (crossroads, θ* = (0.5, 0.5, 0, 0, 0), β* = 0.5,
20 episodes, seed 1) scored with the full paper-sim set on ``zones30`` (18,186 hypotheses; the
person simulated there with the same seed). For each, in one process after one warm-up solve of
the shapes: ``plain`` = :func:`~expertise_irl.planning.soft_vi.solve` of every hypothesis to 1e-8
by sweeps alone (the solve before certification and Newton's finish), ``certified`` =
:func:`~expertise_irl.inference.certified.certified_log_likelihoods` with its defaults, and the
reference, every hypothesis to 1e-10 with no elimination. Reported: seconds and sweeps of each,
the hypotheses eliminated, the certified bound on every probability, and the largest difference
of any posterior probability from the reference's (plain's and certified's).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import header

from expertise_irl.demos.simulation import simulate
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, resolve_thetas
from expertise_irl.inference.certified import certified_log_likelihoods
from expertise_irl.planning.soft_vi import solve
from expertise_irl.planning.table_likelihood import log_likelihood


def posterior(ll: np.ndarray) -> np.ndarray:
    p = np.exp(ll - ll[np.isfinite(ll)].max())
    return p / p.sum()


def timed_solve(mdp, hyp, trajs, tol):
    t0 = time.perf_counter()
    sol = solve(mdp, hyp.theta, hyp.beta, tol=tol, newton=False)
    ll = log_likelihood(np.asarray(sol.log_policy), trajs.state, trajs.action)
    return time.perf_counter() - t0, int(sol.iterations.sum()), posterior(ll)


def case(name: str, mdp, hyp, trajs) -> str:
    solve(mdp, hyp.theta[:8], hyp.beta[:8])  # compile the small shapes before timing
    t_plain, sw_plain, p_plain = timed_solve(mdp, hyp, trajs, 1e-8)
    t0 = time.perf_counter()
    c = certified_log_likelihoods([(mdp, [trajs])], hyp.theta, hyp.beta)
    t_cert = time.perf_counter() - t0
    _, _, p_ref = timed_solve(mdp, hyp, trajs, 1e-10)
    d_plain = float(np.max(np.abs(p_plain - p_ref)))
    d_cert = float(np.max(np.abs(posterior(c.log_likelihood) - p_ref)))
    line = (f"{name}: {len(hyp)} hypotheses, {len(trajs.state)} actions | plain {t_plain:.1f} s, "
            f"{sw_plain} sweeps, "
            f"max |p − p_ref| {d_plain:.1e} | certified {t_cert:.1f} s ({t_cert / t_plain:.2f}×), "
            f"{int(c.sweeps.sum())} sweeps, {int(c.eliminated.sum())} eliminated, tol {c.tol:.1e}, bound "
            f"{c.probability_error:.1e}, max |p − p_ref| {d_cert:.1e}")
    print(line, flush=True)
    return line


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,200")
    ap.add_argument("--fullset", action="store_true")
    ap.add_argument("--out", type=Path)
    a = ap.parse_args()
    lines = header("certified.py")
    from expertise_irl.worlds.floorplans import generate_floor_plan

    for size in [int(s) for s in a.sizes.split(",") if s]:
        mdp = generate_floor_plan(size, seed=0).to_mdp()
        trajs = simulate(mdp, np.array([0.4, 0.2, 0.4]), 0.3, 3, np.random.default_rng(0))
        hyp = HypothesisSet(resolve_thetas("paper-real", mdp.n_features), BETA_PRESETS["paper-real"])
        lines.append(case(f"{size}x{size} plan", mdp, hyp, trajs))
    if a.fullset:
        from expertise_irl.worlds.zones import load_bundled

        mdp = load_bundled("zones30").to_mdp()
        trajs = simulate(mdp, np.array([0.5, 0.5, 0, 0, 0]), 0.5, 20, np.random.default_rng(1))
        hyp = HypothesisSet(resolve_thetas("paper-sim", mdp.n_features), BETA_PRESETS["paper-sim"])
        lines.append(case("zones30 full set", mdp, hyp, trajs))
    if a.out:
        a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
