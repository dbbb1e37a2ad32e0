"""The ``fullset`` study (beyond the paper): does the whole ``paper-sim`` set close the out-of-set gap?

The paper's discrete set degrades when the truth is not among its hypotheses (Sec. VI-D:
≈ 3× the β distance and ≈ 6× the regret), and it draws Ψ_k = Θ_k × B small, with k ≤ 20
(k ≤ 100 in Sec. VI-E), because "if all vectors in Θ were used, Ψ would include more than
15,000 hypotheses" (Sec. V-D). Here every person is scored twice on the same episodes:

- ``theta_k``: their own Ψ_k, as in the source study;
- ``full``: all of Θ × B (3,031 unique θ directions × 6 β = 18,186 hypotheses).

The people are those of the ``conditions`` study (its out-of-set people and, as the in-set
reference, its in-set people; the Full-set condition only) and of the ``optimisation`` study
(its instances: θ* ∉ Θ_20, β* ~ U(0.01, 5)), at the scale named by ``source_scale`` and the same
seed, rebuilt bit for bit from their identities (same truths, same episodes), so their
``theta_k`` rows equal the source study's discrete-set rows up to the solver's tolerance (the
full set is solved in other batches than Ψ_k). A θ* drawn from Θ \\ Θ_k is inside the full
set; a β* drawn from U(0.01, 10) is not (B has six values), so the full set can close the θ
part of the gap only.

Grouping. One task per environment: it solves the full set once on that map (the ``conditions``
and ``optimisation`` maps are the same for the same sizes; a map they do not share is solved
once more) and scores every person on it from that one solve, including their Ψ_k, whose rows
are a subset of the full set's.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ...errors import InputError
from ..spec import Column, Study, TaskSpec
from . import fixed_vs_joint as cond
from . import optimisation as opt
from .common import (
    BETA_HAT_MEAN,
    EPISODES_SEEN,
    FEATURES,
    METRIC_COLUMNS,
    N_STATES,
    TRUTH_PROBABILITY,
    check_among,
    episode_columns,
    feature_columns,
    feature_values,
    truth_columns,
    truth_values,
)

SOURCES = ("conditions", "optimisation")
SETS = ("theta_k", "full")


@dataclass(frozen=True)
class FullsetConfig:
    """Which people (the source studies at ``source_scale``) and which full set."""

    source_scale: str = "paper"
    sources: tuple[str, ...] = SOURCES
    in_set: bool = True  # also score conditions' in-set people (the reference of the gap)
    thetas: str = "paper-sim"
    betas: str = "paper-sim"

    def __post_init__(self) -> None:
        check_among("sources", self.sources, SOURCES)
        if self.source_scale not in cond.SCALES or self.source_scale not in opt.SCALES:
            raise InputError(f"source_scale must be one of {', '.join(cond.SCALES)}, "
                             f"got {self.source_scale!r}")

    def conditions(self) -> cond.ConditionsConfig:
        return cond.SCALES[self.source_scale]

    def optimisation(self) -> opt.OptimisationConfig:
        return opt.SCALES[self.source_scale]

    def environments(self) -> list[int]:
        n = 0
        if "conditions" in self.sources:
            n = max(n, self.conditions().environments)
        if "optimisation" in self.sources:
            n = max(n, self.optimisation().environments)
        return list(range(n))


SCALES = {s: FullsetConfig(source_scale=s) for s in ("smoke", "small", "paper")}


def _people(cfg: FullsetConfig, seed: int, e: int):
    """``(source, map config, identity dict, truth, Θ_k, θ*, β*, value, trajectories)`` on map e."""
    if "conditions" in cfg.sources and e < cfg.conditions().environments:
        c = cfg.conditions()
        truths = ("in_set", "out_of_set") if cfg.in_set else ("out_of_set",)
        for k in c.ks:
            for r in range(c.runs):
                thetas = cond.theta_k(c, seed, e, r, k)
                for g in c.groups:
                    for t in truths:
                        p = cond.person(c, seed, e, r, k, g, t)
                        ident = {"run": r, "k": k, "group": g, "instance": -1}
                        yield "conditions", c, ident, t, thetas, p.theta, p.beta, p.value, p.trajectories
    if "optimisation" in cfg.sources and e < cfg.optimisation().environments:
        o = cfg.optimisation()
        for i in range(o.instances):
            inst = opt.instance(o, seed, e, i)
            ident = {"run": -1, "k": o.k, "group": "", "instance": i}
            yield ("optimisation", o, ident, "out_of_set", inst.thetas, inst.theta, inst.beta, inst.value,
                   inst.trajectories)


def tasks(cfg: FullsetConfig) -> list[TaskSpec]:
    return [TaskSpec(f"e{e:03d}", {"environment": e}, estimate_s(cfg, e)) for e in cfg.environments()]


def estimate_s(cfg: FullsetConfig, e: int) -> float:
    """Rough seconds of one map's task for one worker of a 2-core laptop: the full set's solve
    (measured: 0.05 s per state for 18,186 hypotheses) plus each person's episodes scored
    under both sets and their regret solves (fitted to the timings of docs/reproduction/fullset-*,
    two workers side by side: about 0.6 s per person plus 2.5e-5 s per episode and state)."""
    from ...hypotheses import BETA_PRESETS

    n_hyp = len(cond.preset_grid(cfg.thetas, len(FEATURES))) * len(BETA_PRESETS[cfg.betas])
    total, maps = 2.0, set()
    for source, scfg in (("conditions", cfg.conditions()), ("optimisation", cfg.optimisation())):
        if source not in cfg.sources or e >= scfg.environments:
            continue
        side = (scfg.map_min_size + scfg.map_max_size) / 2
        states = 1.3 * side * side  # the generator's maps hold about 1.3 side² states on average
        if (scfg.map_min_size, scfg.map_max_size) not in maps:
            maps.add((scfg.map_min_size, scfg.map_max_size))
            total += 3.0 + 0.05 * states * n_hyp / 18186
        if source == "conditions":
            truths = ("in_set", "out_of_set") if cfg.in_set else ("out_of_set",)
            episodes = [scfg.n_episodes(g, t) for g in scfg.groups for t in truths] * scfg.runs * len(scfg.ks)
        else:
            episodes = [scfg.episodes] * scfg.instances
        total += sum(0.6 + n * states * 2.5e-5 for n in episodes)
    return total


def counts(cfg: FullsetConfig) -> dict[str, int]:
    rows = people = 0
    if "conditions" in cfg.sources:
        c = cfg.conditions()
        n = c.environments * c.runs * len(c.ks)
        truths = ("in_set", "out_of_set") if cfg.in_set else ("out_of_set",)
        people += n * len(c.groups) * len(truths)
        rows += n * sum(c.n_episodes(g, t) for g in c.groups for t in truths) * len(SETS)
    if "optimisation" in cfg.sources:
        o = cfg.optimisation()
        people += o.environments * o.instances
        rows += o.environments * o.instances * o.episodes * len(SETS)
    n_maps = len(cfg.environments())
    return {"tasks": n_maps, "instances": people, "rows": rows, "set_solves_grouped": n_maps,
            "set_solves_ungrouped": people}


def run_task(cfg: FullsetConfig, seed: int, params: dict) -> tuple[dict[str, np.ndarray], dict]:
    """Solve the full set once per map of environment e and score every person on it."""
    from ...hypotheses import BETA_PRESETS, HypothesisSet
    from ...inference.belief import DiscreteBelief
    from ...planning.soft_vi import solve

    e = int(params["environment"])
    solved: dict[tuple[int, int], tuple] = {}  # (min, max size) -> (mdp, full, belief, by_pair, time)
    cols: dict[str, list] = {}
    n_people = 0
    for source, scfg, ident, truth, thetas, theta, beta, value, trajs in _people(cfg, seed, e):
        key = (scfg.map_min_size, scfg.map_max_size)
        if key not in solved:
            _, mdp = cond.environment(scfg, seed, e)
            full = HypothesisSet(cond.preset_grid(cfg.thetas, mdp.n_features), BETA_PRESETS[cfg.betas])
            t0 = time.perf_counter()
            log_policy = solve(mdp, full.theta, full.beta, model=scfg.model).log_policy  # no padding
            spent = time.perf_counter() - t0
            # [S*A, H]: one observed pair is one contiguous row (a gather from [H, S, A] would
            # touch one cache line per hypothesis and pair).
            by_pair = np.ascontiguousarray(log_policy.reshape(len(full), -1).T)
            solved[key] = (mdp, full, DiscreteBelief.from_log_policy(full, log_policy), by_pair, spent)
        mdp, full, b_full, by_pair, spent = solved[key]
        own = HypothesisSet(thetas, BETA_PRESETS[cfg.betas])
        rows = np.array([full.index(t, b) for t, b in zip(own.theta, own.beta, strict=True)])
        b_own = DiscreteBelief.from_log_policy(own, b_full.log_policy[rows])
        inc = _episode_log_likelihoods(by_pair, mdp.n_actions, trajs)  # [N, H] of the full set
        for s, b0, ll in zip(SETS, (b_own, b_full), (inc[:, rows], inc), strict=True):
            part = _score(mdp, scfg, b0, ll, trajs, theta, beta, value)
            m = len(part["beta_hat"])
            part.update({
                "seed": np.full(m, seed), "environment": np.full(m, e),
                "source": np.full(m, source, dtype=object), "truth": np.full(m, truth, dtype=object),
                "run": np.full(m, ident["run"]), "k": np.full(m, ident["k"]),
                "group": np.full(m, ident["group"], dtype=object), "instance": np.full(m, ident["instance"]),
                "set": np.full(m, s, dtype=object), "n_states": np.full(m, mdp.n_states),
                "n_hypotheses": np.full(m, len(b0.hypotheses)), "set_solve_time_s": np.full(m, spent),
            })
            for name, v in part.items():
                cols.setdefault(name, []).append(v)
        n_people += 1
    columns = {n: np.concatenate(v) for n, v in cols.items()}
    return columns, {"set_solve_time_s": sum(v[-1] for v in solved.values()), "set_solves": len(solved),
                     "hypotheses_solved": sum(len(v[1]) for v in solved.values()), "people": n_people}


def _episode_log_likelihoods(by_pair: np.ndarray, n_actions: int, trajs) -> np.ndarray:
    """``[N, H]`` log P(episode n | h) from the ``[S*A, H]`` log-policy (each pair counted once
    per occurrence)."""
    out = np.empty((trajs.n_episodes, by_pair.shape[1]))
    for n, (s, a) in enumerate(trajs.episodes()):
        pairs, counts = np.unique(np.asarray(s) * n_actions + np.asarray(a), return_counts=True)
        out[n] = counts @ by_pair[pairs]  # counts >= 1: an impossible pair gives -inf, never NaN
    return out


def _score(mdp, scfg, belief, episode_ll, trajs, theta, beta, value) -> dict[str, np.ndarray]:
    """Rows for every episode count 1..N of one person under one set (one pass), from each
    episode's log-likelihood under every hypothesis of the set (``episode_ll [N, H]``)."""
    from ...demos.simulation import capped_flags

    eps = trajs.episodes()
    lengths = np.array([len(s) for s, _ in eps])
    capped = capped_flags(trajs, mdp, scfg.max_steps)
    truth_idx = belief.hypotheses.index(theta, beta)
    beta_hat, theta_hat, p_truth = [], [], []
    total = belief.log_likelihood
    for n, (s, _) in enumerate(eps):
        total = total + episode_ll[n]
        b = replace(belief, log_likelihood=total, n_observed=belief.n_observed + len(s))
        beta_hat.append(b.mean_beta)
        theta_hat.append(b.mean_theta)
        p_truth.append(np.nan if truth_idx is None else float(b.probabilities[truth_idx]))
    theta_hat = np.array(theta_hat)
    N = len(eps)
    col = {
        "episodes": np.arange(1, N + 1), "n_pairs": np.cumsum(lengths), "n_capped": np.cumsum(capped),
        **truth_values(N, theta, beta), "beta_hat": np.array(beta_hat),
        **feature_values("theta_hat", theta_hat),
    }
    col.update(cond.estimate_metrics(mdp, scfg.model, theta, beta, value, theta_hat, beta_hat))
    col["truth_probability"] = np.array(p_truth)
    return col


COLUMNS = (
    Column("seed", "int64", "the sweep's seed (`--seed`), shared with the source studies"),
    Column("environment", "int32", "environment index e (map `(e,)`)"),
    Column("source", "string", "`conditions` or `optimisation`: the study whose person this is"),
    Column("truth", "string", "`in_set` (θ*, β*) ∈ Ψ_k, or `out_of_set`"),
    Column("run", "int32", "conditions' run r (−1 for optimisation)"),
    Column("k", "int32", "size of the person's Θ_k"),
    Column("group", "string", "conditions' expertise-group slot (empty for optimisation)"),
    Column("instance", "int32", "optimisation's instance i (−1 for conditions)"),
    Column("set", "string", "`theta_k` (the person's own Ψ_k) or `full` (all of the paper-sim Θ × B)"),
    EPISODES_SEEN,
    *episode_columns(),
    N_STATES,
    Column("n_hypotheses", "int32", "hypotheses of the set"),
    *truth_columns(),
    BETA_HAT_MEAN,
    *feature_columns("theta_hat", "θ̂ = E[θ] component `{f}`"),
    *METRIC_COLUMNS,
    TRUTH_PROBABILITY,
    Column("set_solve_time_s", "float64", "wall time of the full set's solve on this map (one per map)"),
)

STUDY = Study(
    name="fullset",
    # 5: return_regret; 4: over-relaxed solves, no float32 phase (values move within the tolerance)
    version=5,
    description="beyond the paper: conditions' and optimisation's people scored with all 18,186 paper-sim "
                "hypotheses vs their Ψ_k",
    config_type=FullsetConfig, scales=SCALES, tasks=tasks, run_task=run_task, counts=counts,
    columns=COLUMNS,
    # The order the committed reports were built with (docs/reproduction/fullset-*): conditions'
    # in-set and out-of-set people of one slot stay in the order their task wrote them.
    sort_by=("source", "environment", "run", "k", "group", "instance", "set", "episodes"),
    report="expertise_irl.experiments.report.fullset:build",
)
