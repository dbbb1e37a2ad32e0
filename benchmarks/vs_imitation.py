"""Side by side with the ``imitation`` library: its MCE IRL against our discrete set and MAP.

    python benchmarks/vs_imitation.py [--people 10] [--episodes 5] [--betas 0.05,0.5,5] [--seed 0]
        [--horizon 80] [--sigma 10] [--mce-max-iter 150] [--workers 2]
        [--imitation-python /tmp/imitation-venv/bin/python] [--no-mce]
        [--out benchmarks/results/vs_imitation.txt] [--json FILE]

imitation 1.0.1 requires ``gymnasium~=0.29`` and this package ``gymnasium>=1.0``, so imitation
lives in a virtual environment of its own, which this script runs as a subprocess for MCE IRL
(the rest runs here)::

    python3.11 -m venv /tmp/imitation-venv && /tmp/imitation-venv/bin/pip install imitation==1.0.1

``--no-mce`` runs without it: the ``mce`` column and the conversion checks are left out.

It needs nothing of ours installed: the worker imports ``expertise_irl``'s NumPy-only modules
(``mdp``, ``demos.trajectories``, ``demos.imitation_io``) from ``src/`` through ``PYTHONPATH``.

The people: on the bundled map ``crossroads`` (185 cells, K = 5 features, γ = 0.95, the paper's
``maxent`` model, no start cells: episodes start anywhere), ``--people`` people per β in
``--betas`` (one β per expertise group: high, medium, low), each with θ* drawn uniformly on the
simplex (Dirichlet(1, …, 1): in no method's hypothesis set) and ``--episodes`` simulated episodes
(at most 500 actions each), all from ``default_rng([seed, group, person])``.

The methods, on the same demonstrations:

- ``discrete``: ``get_method("discrete")``, the defaults of ``expertise-irl infer`` (paper-real
  Θ × paper-sim B, 1,266 hypotheses); θ̂ and β̂ are the posterior means, as ``infer`` reports them.
- ``map``: ``get_method("map")`` (``infer --method map``: 4 L-BFGS starts, the log-uniform prior),
  seed 0. The first person of the medium group is also run through the command line, and its
  θ̂ and β̂ must equal the API's.
- ``mce``: ``imitation.algorithms.mce_irl.MCEIRL`` on our MDP as an arrival chain
  (:func:`expertise_irl.demos.imitation_io.arrival_chain`: the moves are the states, so imitation's
  state-only reward can be our reward of a move; features φ/γ, so the learned linear weights are
  w = θ/β exactly) with the discount in the transitions (imitation 1.0.1 trains with an
  undiscounted policy whatever its ``discount``), ``--horizon`` steps (γ^80 = 0.017 of the
  weight is beyond), the person's own start states as the initial distribution (MCE IRL matches
  occupancies, so the model must start where the demonstrations do), and the demonstrations'
  discounted occupancy as imitation counts it from our trajectories (``MCEIRL(discount=γ)`` on
  :meth:`ArrivalChain.trajectories`, checked equal to :meth:`ArrivalChain.occupancy`). The
  reward net is linear without bias (w, float64, from 0) plus the fixed reward column; the
  optimiser is ``torch.optim.Rprop`` (lr 0.1) with an L2 penalty ‖w‖²/(2σ²) per person
  (``--sigma``; a Normal(0, σ²) prior on each weight, added to the gradient; without it the
  weights of features a person never meets, or of a goal they never enter, grow without bound),
  until MCEIRL's own stop (gradient norm ≤ 1e-4) or ``--mce-max-iter``. θ̂ = w/‖w‖₁, β̂ = 1/‖w‖₁.
  The worker also converts each person's demonstrations to imitation's real ``Trajectory``
  (one-hot) and back, and checks the round trip is exact.

Metrics per person: cosine of θ̂ to θ*; policy regret: the expected discounted return under θ*,
from the starts (every non-terminal cell, uniformly), of the optimal (β → 0) policy of θ* minus
that of the optimal policy of θ̂ (Q* from ``soft_vi.solve(..., model="boltzmann")``, ties to the
lower action index; the policy evaluated exactly); β̂ against β*, and β̂ against the MAP's β̂.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

MAP_NAME = "crossroads"
GROUPS = ("high", "medium", "low")
METHODS = ("discrete", "map", "mce")
DEFAULT_IMITATION_PYTHON = "/tmp/imitation-venv/bin/python"
MCE_LR = 0.1
MCE_GRAD_EPS = 1e-4


# ------------------------------------------------------------------ the MCE IRL worker (imitation's venv)
def mce_worker(job_dir: Path, people: list[int], out: Path) -> None:
    """MCE IRL for ``people`` of the job in ``job_dir``; writes a JSON list of results to ``out``."""
    import imitation
    import torch as th
    from imitation.algorithms import mce_irl
    from imitation.data import types
    from imitation.rewards import reward_nets

    from expertise_irl.demos.imitation_io import arrival_chain, from_imitation, tabular_pomdp, to_imitation
    from expertise_irl.demos.trajectories import Trajectories
    from expertise_irl.mdp import TabularMDP

    th.set_num_threads(1)

    class LinearReward(reward_nets.RewardNet):
        """r(x) = w·ψ(x) + fixed(x): a linear reward of the observation's features, no bias, w from 0;
        the observation's last column is the fixed reward."""

        def __init__(self, observation_space, action_space, n_features: int):
            super().__init__(observation_space, action_space, normalize_images=False)
            self.n = n_features
            self.w = th.nn.Parameter(th.zeros(n_features, dtype=th.float64))

        def forward(self, state, action, next_state, done):
            return state[:, : self.n] @ self.w + state[:, self.n]

    class RpropL2(th.optim.Rprop):
        """Rprop on the gradient plus ``l2 * w`` (a Normal prior on the weights); counts its steps."""

        def __init__(self, params, l2: float = 0.0, **kwargs):
            super().__init__(params, **kwargs)
            self.l2, self.steps = l2, 0

        @th.no_grad()
        def step(self, closure=None):
            for group in self.param_groups:
                for p in group["params"]:
                    if p.grad is not None:
                        p.grad.add_(p, alpha=self.l2)
            self.steps += 1
            return super().step(closure)

    job = np.load(job_dir / "job.npz")
    mdp = TabularMDP.load(job_dir / "mdp.npz")
    horizon, sigma, max_iter = int(job["horizon"]), float(job["sigma"]), int(job["max_iter"])
    rows = []
    for p in people:
        keep = job["person"] == p
        trajs = Trajectories(*(job[k][keep] for k in ("episode", "step", "state", "action")))
        t0 = time.perf_counter()
        back = from_imitation(to_imitation(trajs, mdp), mdp, episode_ids=trajs.episode_ids)
        round_trip = all(np.array_equal(getattr(back, k), getattr(trajs, k))
                         for k in ("episode", "step", "state", "action"))
        starts = np.array([s[0] for s, _ in trajs.episodes()])
        chain = arrival_chain(mdp, horizon, starts=starts, discounted_transitions=True)
        env = tabular_pomdp(chain)
        demos = chain.trajectories(trajs, mdp)
        assert isinstance(demos[0], types.Trajectory)
        counted = mce_irl.MCEIRL(demos, env, LinearReward(env.observation_space, env.action_space,
                                                          chain.features.shape[1]).double(),
                                 rng=np.random.default_rng(0), discount=mdp.gamma).demo_state_om
        om = chain.occupancy(trajs, mdp)
        om_equal = bool(np.allclose(counted, om, rtol=1e-12, atol=1e-12))
        net = LinearReward(env.observation_space, env.action_space, chain.features.shape[1]).double()
        l2 = 0.0 if sigma == 0 else 1.0 / (sigma**2 * trajs.n_episodes)
        mce = mce_irl.MCEIRL(counted, env, net, rng=np.random.default_rng(0), discount=1.0,
                             optimizer_cls=RpropL2, optimizer_kwargs={"lr": MCE_LR, "l2": l2},
                             linf_eps=0.0, grad_l2_eps=MCE_GRAD_EPS, log_interval=None)
        t1 = time.perf_counter()
        mce.train(max_iter=max_iter)
        w = net.w.detach().numpy().copy()
        rows.append({
            "person": int(p), "weights": w.tolist(), "iterations": mce.optimizer.steps,
            "grad_norm": float(np.linalg.norm(net.w.grad.numpy())), "train_s": time.perf_counter() - t1,
            "wall_s": time.perf_counter() - t0, "chain_states": chain.n_states,
            "round_trip_exact": round_trip, "occupancy_as_imitation_counts": om_equal,
        })
        print(f"person {p}: {mce.optimizer.steps} iterations, {rows[-1]['train_s']:.1f} s", flush=True)
    import gymnasium
    import seals

    versions = {"imitation": imitation.__version__, "torch": th.__version__,
                "gymnasium": gymnasium.__version__, "seals": getattr(seals, "__version__", "?"),
                "numpy": np.__version__,
                "python": sys.version.split()[0]}
    out.write_text(json.dumps({"versions": versions, "rows": rows}) + "\n")


# ----------------------------------------------------------------------------------- our side
def people_of(mdp, betas, n_people: int, episodes: int, seed: int) -> list[dict]:
    from expertise_irl.demos.simulation import simulate

    people = []
    for g, beta in enumerate(betas):
        for i in range(n_people):
            rng = np.random.default_rng([seed, g, i])
            theta = rng.dirichlet(np.ones(mdp.n_features))
            trajs = simulate(mdp, theta, beta, episodes, rng)
            people.append({"index": len(people), "group": GROUPS[g], "beta": float(beta), "theta": theta,
                           "trajs": trajs})
    return people


def write_job(job_dir: Path, mdp, people, horizon: int, sigma: float, max_iter: int) -> None:
    mdp.save(job_dir / "mdp.npz")
    cat = {k: np.concatenate([getattr(p["trajs"], k) for p in people]) for k in ("episode", "step", "state",
                                                                                  "action")}
    person = np.concatenate([np.full(len(p["trajs"]), p["index"]) for p in people])
    np.savez(job_dir / "job.npz", **cat, person=person, horizon=horizon, sigma=sigma, max_iter=max_iter)


def run_mce(job_dir: Path, n_people: int, workers: int, python: str) -> dict:
    """The MCE workers, ``workers`` processes at once (one thread each); their rows by person."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1", "PYTHONWARNINGS": "ignore"}
    procs = []
    for k in range(workers):
        mine = list(range(k, n_people, workers))
        if not mine:
            continue
        out = job_dir / f"mce-{k}.json"
        cmd = [python, str(Path(__file__).resolve()), "--mce-worker", str(job_dir), ",".join(map(str, mine)),
               str(out)]
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append((proc, out))
    rows, versions = {}, None
    for proc, out in procs:
        _, stderr = proc.communicate()
        if proc.returncode != 0:
            raise SystemExit(f"the MCE IRL worker failed:\n{stderr[-3000:]}")
        part = json.loads(out.read_text())
        versions = part["versions"]
        rows.update({r["person"]: r for r in part["rows"]})
    return {"rows": rows, "versions": versions}


def optimal_policy_returns(mdp, thetas: np.ndarray, theta_true: np.ndarray) -> np.ndarray:
    """``[H]`` expected discounted return under θ*, from a uniform start among the initial states,
    of the optimal (hard) policy of each θ in ``thetas [H, K]``."""
    from expertise_irl.planning.soft_vi import solve

    q = solve(mdp, thetas, np.full(len(thetas), 1.0), model="boltzmann").q  # hard Q* of each θ
    q = np.where(mdp.available[None], q, -np.inf)
    r_true = mdp.reward(theta_true)
    S = mdp.n_states
    live = ~mdp.terminal
    starts = mdp.initial_states()
    out = []
    for h in range(len(thetas)):
        a = np.argmax(q[h], axis=1)
        P = np.zeros((S, S))
        idx = np.flatnonzero(live)
        nxt = mdp.next_state[idx, a[idx]]
        P[idx, nxt] = 1.0
        P[:, mdp.terminal] = 0.0  # entering a goal ends the episode (value 0)
        r = np.zeros(S)
        r[idx] = r_true[idx, a[idx]]
        v = np.linalg.solve(np.eye(S) - mdp.gamma * P, r)
        out.append(float(v[starts].mean()))
    return np.array(out)


def cosine(a, b) -> float:
    return float(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b))


def cli_check(mdp, person, tmp: Path, api: dict) -> dict:
    """The person's demonstrations through ``expertise-irl infer`` (discrete and map): the same θ̂, β̂."""
    from expertise_irl.demos.csv_io import write_demos_csv

    demos = tmp / "demos.csv"
    write_demos_csv(demos, person["trajs"], mdp)
    exe = str(Path(sys.executable).with_name("expertise-irl"))
    out = {}
    for method in ("discrete", "map"):
        res = tmp / f"{method}.json"
        t = time.perf_counter()
        cmd = [exe, "infer", MAP_NAME, "--demos", str(demos), "--method", method, "--seed", "0",
               "--out", str(res)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"expertise-irl infer --method {method} failed:\n{proc.stderr[-2000:]}")
        doc = json.loads(res.read_text())
        b_api = api[method]["beta_hat"]
        same = (np.allclose(doc["theta_hat"], api[method]["theta_hat"], rtol=0, atol=1e-9)
                and abs(doc["beta_hat"] - b_api) <= 1e-9 * max(1.0, b_api))
        out[method] = {"same_as_api": bool(same), "wall_s": time.perf_counter() - t,
                       "theta_hat": doc["theta_hat"], "beta_hat": doc["beta_hat"]}
    return out


def summarise(rows: list[dict], betas, methods=METHODS) -> list[dict]:
    """One row per group and method (and the uniform θ̂ baseline, which has no β̂)."""
    from expertise_irl.hypotheses import expertise_group

    table = []
    for g, beta in zip(GROUPS, betas, strict=False):
        mine = [r for r in rows if r["group"] == g]
        for m in (*methods, "uniform"):
            cos = np.array([r[m]["cosine"] for r in mine])
            reg = np.array([r[m]["regret"] for r in mine])
            row = {"group": g, "beta_true": beta, "method": m, "people": len(mine),
                   "cosine_mean": float(cos.mean()), "cosine_min": float(cos.min()),
                   "regret_mean": float(reg.mean()), "regret_median": float(np.median(reg))}
            if m != "uniform":
                bh = np.array([r[m]["beta_hat"] for r in mine])
                row.update({
                    "beta_hat_median": float(np.median(bh)), "beta_hat_q25": float(np.quantile(bh, 0.25)),
                    "beta_hat_q75": float(np.quantile(bh, 0.75)),
                    "in_true_group": float(np.mean([expertise_group(b) == g for b in bh])),
                    "beta_hat_over_map_median": float(np.median([r[m]["beta_hat"] / r["map"]["beta_hat"]
                                                                 for r in mine])),
                    "negative_weight_share": float(np.mean([min(r[m]["theta_hat"]) < -0.05 for r in mine])),
                    "warned_share": float(np.mean([bool(r[m]["warnings"]) for r in mine])),
                    "seconds_per_person": float(np.mean([r[m]["seconds"] for r in mine])),
                })
            table.append(row)
    return table


def table_lines(table: list[dict]) -> list[str]:
    out = [f"{'group':6} {'β*':>5} {'method':8} {'cos mean':>8} {'cos min':>7} {'regret':>6} {'median':>6} "
           f"{'β̂ median [IQR]':>23} {'in group':>8} {'β̂/β̂_MAP':>8} {'w<0':>4} {'warned':>6} {'s/person':>8}"]
    for t in table:
        head = (f"{t['group']:6} {t['beta_true']:5g} {t['method']:8} {t['cosine_mean']:8.3f} "
                f"{t['cosine_min']:7.3f} {t['regret_mean']:6.3f} {t['regret_median']:6.3f}")
        if t["method"] == "uniform":
            out.append(head)
            continue
        iqr = f"{t['beta_hat_median']:.3g} [{t['beta_hat_q25']:.3g}, {t['beta_hat_q75']:.3g}]"
        out.append(f"{head} {iqr:>23} {t['in_true_group']:8.0%} {t['beta_hat_over_map_median']:8.3g} "
                   f"{t['negative_weight_share']:4.0%} {t['warned_share']:6.0%} "
                   f"{t['seconds_per_person']:8.1f}")
    return out


def person_line(row: dict, methods=METHODS) -> str:
    theta = ",".join(f"{x:.2f}" for x in row["theta_true"])
    parts = [f"{row['person']:2d} {row['group']:6} β* {row['beta_true']:<4g} θ* ({theta}) "
             f"goal {row['episodes_reaching_goal']}/{row['episodes']} {row['actions']:4d} actions |"]
    for m in methods:
        r = row[m]
        parts.append(f"{m} cos {r['cosine']:6.3f} β̂ {r['beta_hat']:<7.3g}")
    return " ".join(parts) + (f"| mce {row['mce']['iterations']} it" if "mce" in methods else "")


def attach_mce(args, mdp, people, rows: list[dict], tmp: Path) -> tuple[dict, float]:
    """MCE IRL on every person (imitation's environment, :func:`run_mce`): each row's ``mce``."""
    from expertise_irl.demos.imitation_io import arrival_chain

    write_job(tmp, mdp, people, args.horizon, args.sigma, args.mce_max_iter)
    t_mce = time.perf_counter()
    mce = run_mce(tmp, len(people), args.workers, args.imitation_python)
    mce_s = time.perf_counter() - t_mce
    chain = arrival_chain(mdp, args.horizon)
    for p, row in zip(people, rows, strict=True):
        r = mce["rows"][p["index"]]
        th_hat, b_hat = chain.theta_beta(r["weights"])
        row["mce"] = {"theta_hat": th_hat.tolist(), "beta_hat": b_hat, "weights": r["weights"],
                      "seconds": r["wall_s"], "iterations": r["iterations"], "grad_norm": r["grad_norm"],
                      "converged": r["grad_norm"] <= MCE_GRAD_EPS}
        row["mce"]["warnings"] = [] if row["mce"]["converged"] else [
            f"MCE IRL stopped at {r['iterations']} iterations with gradient {r['grad_norm']:.2g}"]
    return mce, mce_s


def score_rows(mdp, people, rows: list[dict], methods) -> None:
    """Each method's (and the uniform θ̂'s) cosine to θ* and regret, into the rows."""
    for p, row in zip(people, rows, strict=True):
        row["uniform"] = {"theta_hat": (np.ones(mdp.n_features) / mdp.n_features).tolist()}
        thetas = np.array([p["theta"], *(row[m]["theta_hat"] for m in (*methods, "uniform"))])
        ret = optimal_policy_returns(mdp, thetas, p["theta"])
        row["optimal_return"] = float(ret[0])
        for m, v in zip((*methods, "uniform"), ret[1:], strict=True):
            row[m]["cosine"] = cosine(row[m]["theta_hat"], p["theta"])
            row[m]["regret"] = float(ret[0] - v)


def mce_lines(mce: dict, rows: list[dict], n_people: int) -> list[str]:
    """imitation's versions, the conversion checks and MCE IRL's iterations, in words."""
    iters = [row["mce"]["iterations"] for row in rows]
    return [
        f"\nimitation's environment: {', '.join(f'{k} {v}' for k, v in mce['versions'].items())}",
        f"conversion checks (imitation's real Trajectory): round trip exact for "
        f"{sum(mce['rows'][i]['round_trip_exact'] for i in mce['rows'])}/{n_people} people; "
        f"MCEIRL's occupancy count = ArrivalChain.occupancy for "
        f"{sum(mce['rows'][i]['occupancy_as_imitation_counts'] for i in mce['rows'])}/{n_people}",
        f"MCE IRL iterations: median {int(np.median(iters))}, max {max(iters)}; converged (gradient ≤ "
        f"{MCE_GRAD_EPS:g}) {sum(row['mce']['converged'] for row in rows)}/{len(rows)}"]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=10, help="people per expertise group")
    ap.add_argument("--episodes", type=int, default=5, help="episodes per person")
    ap.add_argument("--betas", default="0.05,0.5,5", help="β of the high, medium and low groups")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--horizon", type=int, default=80, help="MCE IRL's horizon (steps)")
    ap.add_argument("--sigma", type=float, default=10.0,
                    help="MCE IRL's Normal(0, σ²) prior on each weight (0: none)")
    ap.add_argument("--mce-max-iter", type=int, default=150, help="MCE IRL's iteration cap")
    ap.add_argument("--workers", type=int, default=2, help="MCE IRL processes at once")
    ap.add_argument("--imitation-python", default=DEFAULT_IMITATION_PYTHON,
                    help="the Python of the environment imitation is installed in")
    ap.add_argument("--no-mce", action="store_true", help="leave MCE IRL out (no imitation environment)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "vs_imitation.txt")
    ap.add_argument("--json", type=Path, help="also write every person's numbers here")
    ap.add_argument("--mce-worker", nargs=3, metavar=("JOB_DIR", "PEOPLE", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.mce_worker:
        job_dir, people, out = args.mce_worker
        mce_worker(Path(job_dir), [int(p) for p in people.split(",")], Path(out))
        return
    betas = [float(b) for b in args.betas.split(",")]
    if len(betas) > len(GROUPS):
        ap.error(f"--betas takes at most {len(GROUPS)} values (one per group)")
    if not args.no_mce and not Path(args.imitation_python).exists():
        ap.error(f"{args.imitation_python} not found: create imitation's environment first (the docstring)")

    import tempfile

    from _machine import machine_info

    lines: list[str] = []

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    t_start = time.perf_counter()
    for k, v in machine_info().items():
        say(f"{k}: {v}")

    from expertise_irl.inference.methods import get_method
    from expertise_irl.worlds.maps import load_bundled_world

    mdp = load_bundled_world(MAP_NAME).to_mdp()
    people = people_of(mdp, betas, args.people, args.episodes, args.seed)
    n_pairs = [len(p["trajs"]) for p in people]
    say(f"\n{MAP_NAME} ({mdp.n_states} states, K = {mdp.n_features}, γ = {mdp.gamma}), model maxent; "
        f"{args.people} people × β {betas}, θ* ~ Dirichlet(1), {args.episodes} episodes each "
        f"({min(n_pairs)}–{max(n_pairs)} actions per person); MCE IRL: horizon {args.horizon}, "
        f"σ = {args.sigma:g}, Rprop lr {MCE_LR}, stop at gradient ≤ {MCE_GRAD_EPS:g} or "
        f"{args.mce_max_iter} iterations, {args.workers} processes")

    rows = []
    for p in people:
        rows.append({"person": p["index"], "group": p["group"], "beta_true": p["beta"],
                     "theta_true": p["theta"].tolist(), "actions": len(p["trajs"]), "episodes": args.episodes,
                     "episodes_reaching_goal": int(sum(
                         mdp.terminal[mdp.next_state[s[-1], a[-1]]] for s, a in p["trajs"].episodes()))})
    t_ours = time.perf_counter()
    for name in ("discrete", "map"):
        method = get_method(name)
        opts = method.options_from({})
        setup = method.setup(mdp, opts, 0)
        for p, row in zip(people, rows, strict=True):
            print(f"{name}: person {p['index'] + 1}/{len(people)}", end="\r", file=sys.stderr, flush=True)
            run = method.run(mdp, p["trajs"], opts, 0, setup=setup)
            if name == "discrete":
                post = run.result.posterior
                th_hat, b_hat = np.asarray(post.mean_theta), float(post.mean_beta)
            else:
                th_hat, b_hat = np.asarray(run.fields["theta_hat"]), float(run.fields["beta_hat"])
            row[name] = {"theta_hat": th_hat.tolist(), "beta_hat": b_hat, "seconds": run.fields["run_time_s"],
                         "warnings": run.fields["diagnostics"].get("warnings", [])}
    ours_s = time.perf_counter() - t_ours

    methods = tuple(m for m in METHODS if m != "mce" or not args.no_mce)
    with tempfile.TemporaryDirectory(prefix="vs-imitation-") as tmp:
        tmp = Path(tmp)
        check_person = next(p for p in people if p["group"] == "medium") if len(betas) > 1 else people[0]
        cli = cli_check(mdp, check_person, tmp, rows[check_person["index"]])
        mce, mce_s = (None, 0.0) if args.no_mce else attach_mce(args, mdp, people, rows, tmp)
    score_rows(mdp, people, rows, methods)

    table = summarise(rows, betas, methods)
    say()
    for row in rows:
        say(person_line(row, methods))
    if mce is not None:
        for line in mce_lines(mce, rows, len(people)):
            say(line)
    else:
        say("\nMCE IRL: left out (--no-mce)")
    say(f"command line = API (person {check_person['index']}, {check_person['group']}): " + ", ".join(
        f"{m} {'yes' if c['same_as_api'] else 'NO'} ({c['wall_s']:.1f} s)" for m, c in cli.items()))
    reach = {g: [row["episodes_reaching_goal"] for row in rows if row["group"] == g] for g in GROUPS}
    say("episodes reaching the goal: " + ", ".join(
        f"{g} {sum(v)}/{len(v) * args.episodes}" for g, v in reach.items() if v))
    vstar = {g: np.mean([row["optimal_return"] for row in rows if row["group"] == g]) for g in GROUPS}
    say("mean optimal return under θ* (the regret's scale): " + ", ".join(
        f"{g} {v:.2f}" for g, v in vstar.items() if np.isfinite(v)))

    say()
    for line in table_lines(table):
        say(line)
    say(f"\nwall: ours {ours_s:.0f} s (discrete and map, one process), MCE IRL {mce_s:.0f} s "
        f"({args.workers} processes), total {time.perf_counter() - t_start:.0f} s")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
    if args.json:
        args.json.write_text(json.dumps({"args": {k: (str(v) if isinstance(v, Path) else v)
                                                  for k, v in vars(args).items()},
                                         "mce_versions": mce and mce["versions"], "cli_check": cli,
                                         "table": table, "people": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
