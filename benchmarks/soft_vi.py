"""Soft value iteration: the library's solver vs a naive baseline vs this machine's ceiling.

    python benchmarks/soft_vi.py [--quick] [--json results.json] [--workloads a,b,c]

Workloads (paper sizes):
  a  95 hypotheses (paper-real Θ over 3 features × paper-real B) on a warehouse-sized
     zone map of about 4,600 states (features: length, road, avoid);
  b  20 θ (sampled from paper-sim) × 6 β on the bundled 30×30 zone map `zones30`;
  c  the full paper-sim set, 3,031 θ × 6 β = 18,186 hypotheses, on `zones30`.

Implementations, on the same inputs and at matched accuracy (the error of every
V/β bounded by tol = 1e-8 nats):
  library  expertise_irl.planning.soft_vi.solve, steady state (a second identical call; the
           first call's extra time, JAX compilation, is reported separately);
  naive    benchmarks/naive_soft_vi.py, a per-hypothesis NumPy loop written from
           Eqs. 8-9. On workload c it runs on an evenly spread subset and its time is
           extrapolated to the whole set (marked in the output);
  vmap     benchmarks/vmap_soft_vi.py, a plain ``jax.vmap`` of a jitted ``while_loop`` over
           chunks of 512 hypotheses, what a researcher fluent in JAX writes in thirty lines
           (steady state, like the library; compilation reported separately).
Ceilings, each measured on the spot:
  NumPy    a soft backup needs one exp per (s, a) and one log per s, so NumPy's float64 exp
           and log throughput (SIMD kernels on cache-resident data, all cores) bounds
           backups per second: 1 / (1/exp_rate + 1/(A·log_rate)). NumPy has fast kernels only
           where it has AVX-512 ones, so this is NumPy's speed, not the machine's;
  XLA      the same fused max/exp/sum/log inside XLA, a jitted loop over arrays of the
           solver's shapes with no gather (measure_xla_ceiling): what the solver could reach;
  memory   the machine's streaming bandwidth over the bytes one sweep must move at least
           (bandwidth_backups); binding only when a sweep's data do not fit in cache.

Each workload × implementation runs in a fresh process, which reports its peak
resident memory (JAX and NumPy included). A backup is one (hypothesis, state,
action) update; backups/s = H·S·A·sweeps / wall time, with the sweeps each
hypothesis actually needed.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info

TOL = 1e-8


# --------------------------------------------------------------------------- workloads
def build_workload(name: str):
    """(mdp, theta [H, K], beta [H], description)."""
    from expertise_irl.hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, sample_thetas, theta_grid
    from expertise_irl.mdp import TabularMDP
    from expertise_irl.worlds.zones import generate_map, load_bundled

    if name == "a":
        zmap = generate_map(np.random.default_rng(11), width=70, height=70, name="warehouse-sized")
        full = zmap.to_mdp()
        keep = [0, 1, 2]  # length, road, avoid: the paper's three real-data features
        mdp = TabularMDP(full.next_state, full.features[:, :, keep], full.terminal, full.gamma,
                         tuple(full.feature_names[k] for k in keep), state_xy=full.state_xy)
        hyp = HypothesisSet(theta_grid(THETA_PRESETS["paper-real"], 3), BETA_PRESETS["paper-real"])
        desc = f"paper-real Θ×B ({len(hyp)}) on a {zmap.width}×{zmap.height} map, {mdp.n_states} states"
    elif name in ("b", "c"):
        mdp = load_bundled("zones30").to_mdp()
        grid = theta_grid(THETA_PRESETS["paper-sim"], 5)
        thetas = sample_thetas(grid, 20, np.random.default_rng(0)) if name == "b" else grid
        hyp = HypothesisSet(thetas, BETA_PRESETS["paper-sim"])
        desc = f"{hyp.n_theta} θ × {hyp.n_beta} β = {len(hyp)} on zones30 (30×30, {mdp.n_states} states)"
    else:
        raise SystemExit(f"unknown workload {name!r}")
    return mdp, hyp.theta, hyp.beta, desc


def check_subset(H: int, n: int) -> np.ndarray:
    """Evenly spread hypothesis indices (also the naive baseline's subset on big workloads)."""
    return np.unique(np.linspace(0, H - 1, min(n, H)).round().astype(int))


# --------------------------------------------------------------------------- children
def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run_library(name: str, n_check: int, queue) -> None:
    from expertise_irl.planning.soft_vi import solve

    mdp, theta, beta, _ = build_workload(name)
    base = _peak_mb()
    t = time.perf_counter()
    solve(mdp, theta, beta, tol=TOL)  # first call: compiles for this MDP and pool shape
    first = time.perf_counter() - t
    t = time.perf_counter()
    sol = solve(mdp, theta, beta, tol=TOL)  # steady state
    wall = time.perf_counter() - t
    compile_s = max(0.0, first - wall)
    idx = check_subset(len(beta), n_check)
    queue.put({"wall_s": wall, "compile_s": compile_s, "sweeps": sol.iterations.tolist(),
               "peak_mb": _peak_mb(), "base_mb": base, "check_idx": idx.tolist(),
               "check_log_pi": sol.log_policy[idx]})


def run_naive(name: str, subset: int | None, n_check: int, queue) -> None:
    from naive_soft_vi import naive_solve

    mdp, theta, beta, _ = build_workload(name)
    H = len(beta)
    idx = np.arange(H) if subset is None or subset >= H else check_subset(H, subset)
    base = _peak_mb()
    t = time.perf_counter()
    _, log_pi, its = naive_solve(mdp, theta[idx], beta[idx], tol=TOL)
    wall = time.perf_counter() - t
    scale = H / len(idx)
    check = check_subset(H, n_check)
    pos = np.searchsorted(idx, check)
    ok = (pos < len(idx)) & (idx[np.minimum(pos, len(idx) - 1)] == check)
    queue.put({"wall_s": wall * scale, "measured_wall_s": wall, "n_run": len(idx),
               "extrapolated": bool(scale > 1), "sweeps": (its * 1.0).tolist(), "sweeps_scale": scale,
               "peak_mb": _peak_mb(), "base_mb": base, "check_idx": check[ok].tolist(),
               "check_log_pi": log_pi[pos[ok]]})


def run_vmap(name: str, n_check: int, queue) -> None:
    from vmap_soft_vi import CHUNK, vmap_solve

    mdp, theta, beta, _ = build_workload(name)
    base = _peak_mb()
    chunk = min(CHUNK, len(beta))
    t = time.perf_counter()
    vmap_solve(mdp, theta[:chunk], beta[:chunk], tol=TOL, chunk=chunk)  # compiles the chunk program
    first = time.perf_counter() - t
    t = time.perf_counter()
    log_pi, its = vmap_solve(mdp, theta, beta, tol=TOL, chunk=chunk)
    wall = time.perf_counter() - t
    idx = check_subset(len(beta), n_check)
    queue.put({"wall_s": wall, "compile_s": max(0.0, first - wall * chunk / len(beta)),
               "sweeps": its.tolist(), "peak_mb": _peak_mb(), "base_mb": base,
               "check_idx": idx.tolist(), "check_log_pi": log_pi[idx]})


def in_child(target, *args):
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=target, args=(*args, queue))
    proc.start()
    out = queue.get()
    proc.join()
    return out


# --------------------------------------------------------------------------- ceiling
def measure_ceiling(seconds: float = 1.0) -> dict[str, float]:
    """float64 exp and log throughput (elements/s) on all cores, NumPy SIMD, in-cache data."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    n = 1 << 15  # 256 KiB per array: stays in each core's cache

    def rate(fn, lo, hi) -> float:
        def worker(seed: int) -> int:
            x = np.random.default_rng(seed).uniform(lo, hi, n)
            out = np.empty_like(x)
            count, t_end = 0, time.perf_counter() + seconds
            while time.perf_counter() < t_end:
                for _ in range(50):
                    fn(x, out=out)
                count += 50 * n
            return count

        t = time.perf_counter()
        with ThreadPoolExecutor(cores) as ex:
            total = sum(ex.map(worker, range(cores)))
        return total / (time.perf_counter() - t)

    return {"cores": cores, "exp_per_s": rate(np.exp, -30.0, 0.0), "log_per_s": rate(np.log, 1.0, 4.0)}


def measure_xla_ceiling(n_states: int, n_actions: int, seconds: float = 1.0, groups: int = 32) -> dict:
    """Backups per second of the backup's arithmetic inside XLA, with no gather, on all cores.

    A jitted loop over arrays of the solver's shapes (``[groups, A, S/2, lanes]`` float64 per
    half-sweep): q = r + γ v (v broadcast, not gathered), then max, exp, sum and log over
    actions, feeding v back so nothing is hoisted out of the loop. One such program per core
    runs at once (threads), as the solver's lane groups do.
    """
    import jax
    import jax.numpy as jnp

    from expertise_irl.planning.tuning import lane_width

    LANES = lane_width()
    jax.config.update("jax_enable_x64", True)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    nb = max(1, n_states // 2)
    g = max(1, groups // cores)
    rng = np.random.default_rng(0)
    r = jnp.asarray(rng.uniform(-1, 0, (g, n_actions, nb, LANES)))
    n_iter = 200

    @jax.jit
    def loop(v):
        def body(_, v):
            q = r + 0.95 * v[:, None]
            m = jnp.max(q, axis=1)
            return m + jnp.log(jnp.sum(jnp.exp(q - m[:, None]), axis=1))
        return jax.lax.fori_loop(0, n_iter, body, v)

    v0 = jnp.zeros((g, nb, LANES))
    loop(v0).block_until_ready()

    def worker(_):
        count, t_end = 0, time.perf_counter() + seconds
        while time.perf_counter() < t_end:
            loop(v0).block_until_ready()
            count += n_iter
        return count

    t = time.perf_counter()
    with ThreadPoolExecutor(cores) as ex:
        iters = sum(ex.map(worker, range(cores)))
    elapsed = time.perf_counter() - t
    backups = iters * g * n_actions * nb * LANES / elapsed

    # Memory bandwidth: a jitted streaming update of a 256 MiB array (read and write).
    big = jnp.ones(1 << 25)
    step = jax.jit(lambda x: x * 1.0000001)
    step(big).block_until_ready()
    t, reps = time.perf_counter(), 0
    while time.perf_counter() - t < seconds:
        big = step(big)
        reps += 1
    big.block_until_ready()
    bandwidth = reps * 2 * big.nbytes / (time.perf_counter() - t)
    return {"xla_backups_per_s": backups, "bandwidth_bytes_per_s": bandwidth, "xla_cores": cores}


def bandwidth_backups(bandwidth: float, n_states: int, n_actions: int, n_features: int) -> float:
    """Backups per second if one sweep only had to stream its data once from memory: per lane
    group, the values read and written (S × lanes × 8 B × 2) and the features (S × A × K × 8 B),
    for S × A × lanes backups (lanes: the solver's width on this machine). A bound that matters
    only when they do not fit in cache."""
    from expertise_irl.planning.tuning import lane_width

    LANES = lane_width()
    bytes_per_sweep = n_states * LANES * 8 * 2 + n_states * n_actions * n_features * 8
    return bandwidth * n_states * n_actions * LANES / bytes_per_sweep


def ceiling_backups(ceil: dict[str, float], n_actions: int) -> float:
    return 1.0 / (1.0 / ceil["exp_per_s"] + 1.0 / (n_actions * ceil["log_per_s"]))


# --------------------------------------------------------------------------- main
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small naive subsets; a few minutes in all")
    ap.add_argument("--workloads", default="a,b,c")
    ap.add_argument("--json", default=None, help="write the results here as JSON")
    args = ap.parse_args()
    info = machine_info()
    print("machine:", ", ".join(f"{k}={v}" for k, v in info.items()))
    ceil = measure_ceiling(0.5 if args.quick else 2.0)
    print(f"ceiling: exp {ceil['exp_per_s'] / 1e9:.2f} G/s, log {ceil['log_per_s'] / 1e9:.2f} G/s "
          f"(float64, NumPy SIMD, {ceil['cores']} threads)")
    n_check = 24
    naive_subset = {"a": None, "b": None, "c": 60 if args.quick else 300}
    if args.quick:
        naive_subset["a"] = 24
    rows = []
    for name in args.workloads.split(","):
        mdp, _, beta, desc = build_workload(name)
        H, S, A = len(beta), mdp.n_states, mdp.n_actions
        print(f"\nworkload {name}: {desc}")
        lib = in_child(run_library, name, n_check)
        naive = in_child(run_naive, name, naive_subset[name], n_check)
        vm = in_child(run_vmap, name, n_check)
        common = np.intersect1d(lib["check_idx"], naive["check_idx"])
        a = lib["check_log_pi"][np.searchsorted(lib["check_idx"], common)]
        b = naive["check_log_pi"][np.searchsorted(naive["check_idx"], common)]
        finite = np.isfinite(a)
        agree = float(np.max(np.abs(a[finite] - b[finite]))) if finite.any() else float("nan")
        cb = ceiling_backups(ceil, A)
        xla = measure_xla_ceiling(S, A, 0.5 if args.quick else 2.0)
        bw = bandwidth_backups(xla["bandwidth_bytes_per_s"], S, A, mdp.n_features)
        c = vm["check_log_pi"][np.searchsorted(vm["check_idx"], common)]
        vm_agree = float(np.max(np.abs(a[finite] - c[finite]))) if finite.any() else float("nan")
        for impl, res in (("library", lib), ("naive", naive), ("vmap", vm)):
            sweeps = np.asarray(res["sweeps"]) * res.get("sweeps_scale", 1.0)
            backups = S * A * float(np.sum(sweeps))
            rate = backups / res["wall_s"]
            row = {
                "workload": name, "description": desc, "implementation": impl, "hypotheses": H,
                "states": S, "actions": A, "wall_s": res["wall_s"],
                "extrapolated": res.get("extrapolated", False), "backups_per_s": rate,
                "speedup_vs_naive": naive["wall_s"] / res["wall_s"], "fraction_of_ceiling": rate / cb,
                "speedup_vs_vmap": vm["wall_s"] / res["wall_s"],
                "xla_ceiling_backups_per_s": xla["xla_backups_per_s"], "fraction_of_xla_ceiling":
                rate / xla["xla_backups_per_s"], "bandwidth_bytes_per_s": xla["bandwidth_bytes_per_s"],
                "bandwidth_bound_backups_per_s": bw, "fraction_of_bandwidth_bound": rate / bw,
                "sweeps_mean": float(np.mean(res["sweeps"])), "sweeps_max": float(np.max(res["sweeps"])),
                "peak_mb": res["peak_mb"], "peak_over_baseline_mb": res["peak_mb"] - res["base_mb"],
                "compile_s": res.get("compile_s"), "max_abs_log_pi_difference": agree,
            }
            rows.append(row)
        print(f"XLA ceiling {xla['xla_backups_per_s'] / 1e9:.2f} G backups/s (fused max/exp/sum/log, "
              f"no gather, "
              f"{xla['xla_cores']} threads); memory {xla['bandwidth_bytes_per_s'] / 1e9:.1f} GB/s, "
              f"bound {bw / 1e9:.2f} G backups/s if each sweep streamed its data")
        print(f"{'impl':8s} {'wall s':>9s} {'backups/s':>10s} {'vs naive':>8s} {'vs vmap':>8s} "
              f"{'NumPy c.':>8s} {'XLA c.':>7s} {'memory':>7s} {'sweeps':>7s} {'peak MB':>8s}")
        for row in rows[-3:]:
            star = "*" if row["extrapolated"] else " "
            print(f"{row['implementation']:8s} {row['wall_s']:8.2f}{star} "
                  f"{row['backups_per_s'] / 1e6:8.0f} M "
                  f"{row['speedup_vs_naive']:7.1f}x {row['speedup_vs_vmap']:7.1f}x "
                  f"{100 * row['fraction_of_ceiling']:7.1f}% {100 * row['fraction_of_xla_ceiling']:6.1f}% "
                  f"{100 * row['fraction_of_bandwidth_bound']:6.1f}% "
                  f"{row['sweeps_mean']:7.0f} {row['peak_mb']:8.0f}")
        note = (f"; * naive timed on {naive['n_run']} hypotheses, extrapolated"
                if naive["extrapolated"] else "")
        print(f"library compile {lib['compile_s']:.2f} s; |log π library − naive| ≤ {agree:.1e}, "
              f"− vmap ≤ {vm_agree:.1e} on {len(common)} hypotheses; "
              f"ceiling {cb / 1e9:.2f} G backups/s{note}")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": info, "ceiling": ceil, "rows": rows}, indent=1))
        print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
