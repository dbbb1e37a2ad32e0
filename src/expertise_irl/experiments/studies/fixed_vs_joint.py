"""The ``conditions`` study (paper Sec. VI-A): Full set, Fixed θ, Fixed β and out-of-set truths.

Protocol. For each random environment e (Sec. V-A generator), run r and k, Θ_k is k
vectors drawn from the ``paper-sim`` grid and Ψ_k = Θ_k × B with the paper's six β. For each
expertise group g one simulated person has an in-set truth (θ*, β*) drawn from Ψ_k with β* in
g, and one has an out-of-set truth (θ*_out ∈ Θ \\ Θ_k, β*_out ~ U(0.01, 10)). Each person
demonstrates episodes from uniformly random start states to the map's one goal: ``episodes``
of them (20), or ``low_episodes`` (40, the Fig. 3 extension) for in-set low-expertise truths.
On the same episodes the in-set person is scored under three conditions, the out-of-set
person under the Full set only:

- ``full``: Ψ_k;
- ``fixed_theta``: Θ = {θ} for a θ ∈ Θ_k other than θ*, all of B;
- ``fixed_beta``: B = {β} for a β of another expertise group than β*, all of Θ_k.

After every episode count n = 1..N (one pass: the belief is updated episode by episode) a row
records β̂ = E[β], θ̂ = E[θ] and the three metrics of Sec. V-E; the regret of every condition
uses the true β* (Sec. VI-C).

Identities and seeds. A map is seeded by ``(e,)``, Θ_k by ``(e, r, k)``, a person by
``(e, r, k, g, t)`` with g the index of the group in (high, medium, low) and t = 0 in-set,
1 out-of-set. A person's stream is split into (truth, condition choices, episodes); episode j
has its own child seed, so the first n episodes are the same whatever N is. A person's
episodes come from a solve of their own (θ*, β*) alone, so they do not depend on which
hypothesis set a task solves.

Grouping. A task is one (e, r, k): it solves Ψ_k once and scores all its people and all
their conditions from row subsets of that one solve (the Fixed θ and Fixed β sets are subsets
of Ψ_k). Ungrouped, each (person, condition) would solve its own set.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...hypotheses import GROUP_NAMES as GROUPS
from ..spec import Column, Study, TaskSpec, seed_sequence
from .common import (
    BETA_HAT_MEAN,
    EPISODES_SEEN,
    FEATURES,
    GOAL_REWARD_MODE,
    MAP_COLUMNS,
    METRIC_COLUMNS,
    SEED,
    SET_COMPOSITION,
    TRUTH_PROBABILITY,
    check_goal_reward,
    composition_values,
    episode_columns,
    feature_columns,
    feature_values,
    truth_columns,
    truth_values,
)

if TYPE_CHECKING:
    from ...demos.trajectories import Trajectories

TRUTHS = ("in_set", "out_of_set")
CONDITIONS = ("full", "fixed_theta", "fixed_beta")


@lru_cache(maxsize=4)
def preset_grid(preset: str, n_features: int) -> np.ndarray:
    from ...hypotheses import THETA_PRESETS, theta_grid

    return theta_grid(THETA_PRESETS[preset], n_features)


def check_set_sizes(thetas: str, betas: str, ks) -> None:
    """The presets exist and every k leaves room for an out-of-set θ (k < |Θ| of the zone maps)."""
    from ...hypotheses import BETA_PRESETS, THETA_PRESETS

    if thetas not in THETA_PRESETS:
        raise InputError(f"thetas must be one of {', '.join(THETA_PRESETS)}, got {thetas!r}")
    if betas not in BETA_PRESETS:
        raise InputError(f"betas must be one of {', '.join(BETA_PRESETS)}, got {betas!r}")
    n = len(preset_grid(thetas, len(FEATURES)))
    if max(ks) >= n:
        raise InputError(f"k must be below {n} (the {thetas!r} grid's {len(FEATURES)}-feature θ directions, "
                         f"so an out-of-set θ exists), got {max(ks)}")


@dataclass(frozen=True)
class ConditionsConfig:
    """Factors of the study (paper values as defaults)."""

    environments: int = 5
    runs: int = 5
    ks: tuple[int, ...] = (5, 10, 15, 20)
    groups: tuple[str, ...] = GROUPS
    out_of_set: bool = True
    episodes: int = 20
    low_episodes: int = 40
    map_min_size: int = 10
    map_max_size: int = 30
    max_steps: int = 500
    thetas: str = "paper-sim"
    betas: str = "paper-sim"
    out_of_set_beta_low: float = 0.01
    out_of_set_beta_high: float = 10.0
    model: str = "maxent"  # observation model of the people and of the inference
    conditions: tuple[str, ...] = CONDITIONS  # which conditions in-set people are scored under
    goal_reward_mode: str = "scaled"  # the protocol: how the goal pays (worlds.grid.GOAL_REWARD_MODES)
    goal_bonus: float = 10.0  # what entering the goal pays (in `length` when scaled, outside θ·φ when fixed)

    def __post_init__(self) -> None:
        bad = [g for g in self.groups if g not in GROUPS]
        if bad:
            raise InputError(f"unknown expertise group {bad[0]!r} (groups: {', '.join(GROUPS)})")
        bad = [c for c in self.conditions if c not in CONDITIONS]
        if bad or "full" not in self.conditions:
            raise InputError(f"conditions must include 'full' and be among {', '.join(CONDITIONS)}, "
                             f"got {', '.join(self.conditions)}")
        if self.environments < 1 or self.runs < 1 or not self.ks or min(self.ks) < 2:
            raise InputError("need at least one environment and run, and every k >= 2")
        if self.episodes < 1 or self.low_episodes < 1:
            raise InputError("episodes must be at least 1")
        check_set_sizes(self.thetas, self.betas, self.ks)
        check_goal_reward(self.goal_reward_mode, self.goal_bonus)
        from ...models import check_model

        check_model(self.model)

    def n_episodes(self, group: str, truth: str) -> int:
        return self.low_episodes if (group == "low" and truth == "in_set") else self.episodes

    def person_conditions(self, truth: str) -> tuple[str, ...]:
        """The conditions a person is scored under (out-of-set people: the Full set only)."""
        return tuple(c for c in CONDITIONS if c in self.conditions) if truth == "in_set" else ("full",)

    def people(self) -> list[tuple[str, str]]:
        truths = TRUTHS if self.out_of_set else TRUTHS[:1]
        return [(g, t) for g in self.groups for t in truths]


SCALES = {
    "smoke": ConditionsConfig(environments=2, runs=1, ks=(3, 5), episodes=3, low_episodes=5,
                              map_min_size=5, map_max_size=7, max_steps=60),
    "small": ConditionsConfig(environments=5, runs=2),
    "paper": ConditionsConfig(),
}


# ------------------------------------------------------------------------- instances
@lru_cache(maxsize=8)
def _map(seed: int, e: int, lo: int, hi: int, mode: str = "scaled", bonus: float = 10.0):
    from ...worlds.zones import generate_map

    zm = generate_map(np.random.default_rng(seed_sequence(seed, (e,))), min_size=lo, max_size=hi,
                      name=f"environment {e} (seed {seed})", goal_reward_mode=mode, goal_bonus=bonus)
    return zm, zm.to_mdp()


def solve_padded(mdp, theta, beta, model: str = "maxent"):
    """:func:`~expertise_irl.planning.soft_vi.solve` with the batch padded to a power of two (at least 8).

    The solver compiles once per batch shape; padding (repeating the last hypothesis) keeps
    the shapes of a sweep to a handful, and a given input always gets the same padding, so
    the result is a function of the input alone.
    """
    from ...planning.soft_vi import solve

    theta = np.atleast_2d(np.asarray(theta, dtype=np.float64))
    beta = np.atleast_1d(np.asarray(beta, dtype=np.float64))
    H = len(theta)
    size = max(8, 1 << (H - 1).bit_length())
    pad = np.r_[np.arange(H), np.full(size - H, H - 1)]
    sol = solve(mdp, theta[pad], beta[pad], model=model)
    return sol.value[:H], sol.log_policy[:H]


def environment(cfg: ConditionsConfig, seed: int, e: int):
    """``(zone_map, mdp)`` of environment ``e`` (the same cells under either protocol)."""
    return _map(int(seed), int(e), cfg.map_min_size, cfg.map_max_size, cfg.goal_reward_mode,
                float(cfg.goal_bonus))


def theta_k(cfg: ConditionsConfig, seed: int, e: int, r: int, k: int) -> np.ndarray:
    """Θ_k of (environment, run, k): k distinct rows of the Θ grid."""
    from ...hypotheses import sample_thetas

    _, mdp = environment(cfg, seed, e)
    return sample_thetas(preset_grid(cfg.thetas, mdp.n_features), k,
                         np.random.default_rng(seed_sequence(seed, (e, r, k))))


@dataclass(frozen=True)
class Person:
    """One simulated person: truth, the condition sets' choices, and their episodes."""

    identity: tuple[int, int, int, int, int]
    group: str
    truth: str
    theta: np.ndarray
    beta: float
    fixed_theta: np.ndarray | None
    fixed_beta: float | None
    value: np.ndarray  # [S] soft value of the truth (for regret)
    trajectories: Trajectories
    random_theta: np.ndarray  # a θ drawn uniformly from the grid: the regret a guess costs


#: Child of a person's seed that draws their random θ (spawn keys 0-2 are the person's own streams).
RANDOM_THETA_CHILD = 99


def person(cfg: ConditionsConfig, seed: int, e: int, r: int, k: int, group: str, truth: str) -> Person:
    """Rebuild the person of identity ``(e, r, k, group, truth)`` (bit for bit, in any study)."""
    from ...hypotheses import BETA_PRESETS
    from ...inference.hypothesis_sets import (
        fixed_beta_set,
        fixed_theta_set,
        full_set,
        out_of_set_truth,
        sample_in_set_truth,
    )

    _, mdp = environment(cfg, seed, e)
    thetas = theta_k(cfg, seed, e, r, k)
    betas = BETA_PRESETS[cfg.betas]
    ident = (e, r, k, GROUPS.index(group), TRUTHS.index(truth))
    truth_ss, cond_ss, sim_ss = seed_sequence(seed, ident).spawn(3)
    rng_truth = np.random.default_rng(truth_ss)
    ft = fb = None
    if truth == "in_set":
        th, b = sample_in_set_truth(full_set(thetas, betas), group, rng_truth)
        rng_cond = np.random.default_rng(cond_ss)
        ft = fixed_theta_set(thetas, betas, th, rng_cond).thetas[0]
        fb = float(fixed_beta_set(thetas, betas, b, rng_cond).betas[0])
    else:
        th, b = out_of_set_truth(preset_grid(cfg.thetas, mdp.n_features), thetas, rng_truth,
                                 beta_range=(cfg.out_of_set_beta_low, cfg.out_of_set_beta_high))
    value, log_policy = solve_padded(mdp, th, b, cfg.model)
    trajs = simulate_episodes(mdp, log_policy[0], sim_ss, cfg.n_episodes(group, truth), cfg.max_steps)
    grid = preset_grid(cfg.thetas, mdp.n_features)
    rng_guess = np.random.default_rng(seed_sequence(seed, (*ident, RANDOM_THETA_CHILD)))
    guess = grid[int(rng_guess.integers(len(grid)))]
    return Person(ident, group, truth, th, b, ft, fb, value[0], trajs, guess)


def simulate_episodes(mdp, log_policy, seq: np.random.SeedSequence, n: int, max_steps: int) -> Trajectories:
    """``n`` episodes of a person with ``log_policy`` [S, A], episode j seeded by ``seq``'s j-th child
    (so the first n episodes are the same whatever the total)."""
    from ...demos.simulation import simulate
    from ...demos.trajectories import Trajectories

    parts = []
    for j, ss in enumerate(seq.spawn(n)):
        tr = simulate(mdp, None, None, 1, np.random.default_rng(ss), max_steps=max_steps,
                      log_policy=log_policy)
        parts.append((np.full(len(tr), j), tr.step, tr.state, tr.action))
    ep, step, state, action = (np.concatenate(c) for c in zip(*parts, strict=True))
    return Trajectories(ep, step, state, action)


# ------------------------------------------------------------------------------ tasks
def tasks(cfg: ConditionsConfig) -> list[TaskSpec]:
    """One task per (environment, run, k): largest k first, environments interleaved."""
    out = []
    seen: set[int] = set()
    for k in sorted(cfg.ks, reverse=True):
        for r in range(cfg.runs):
            for e in range(cfg.environments):
                est = estimate_s(cfg, k, first_on_map=e not in seen)
                seen.add(e)
                out.append(TaskSpec(f"e{e:03d}-r{r:03d}-k{k:03d}", {"environment": e, "run": r, "k": k}, est))
    return out


def estimate_s(cfg: ConditionsConfig, k: int, *, first_on_map: bool = False) -> float:
    """Rough seconds of one task for one worker of a 2-core laptop (measured at ``paper`` scale).

    The first task on a map also pays for compiling the solver's kernels for that map (in
    every worker that meets the map before the shared compilation cache holds them).
    """
    side = (cfg.map_min_size + cfg.map_max_size) / 2
    states = 0.75 * side * side
    person_episodes = sum(cfg.n_episodes(g, t) for g, t in cfg.people())
    compile_s = 4.0 + 40.0 * states / 500 if first_on_map else 0.0  # every worker compiles
    return 0.3 + states * (3.5e-5 * person_episodes + 2e-6 * 6 * k) + compile_s


def counts(cfg: ConditionsConfig) -> dict[str, int]:
    """Instances, rows and solves of hypothesis sets, with and without grouping by (e, r, k)."""
    n_b = 6
    people = cfg.people()
    n_tasks = cfg.environments * cfg.runs * len(cfg.ks)
    per_k_ungrouped = sum(len(cfg.person_conditions(t)) for _, t in people)
    rows = sum(len(cfg.person_conditions(t)) * cfg.n_episodes(g, t) for g, t in people)
    hyp_grouped = sum(n_b * k for k in cfg.ks)
    sizes = {"full": lambda k: n_b * k, "fixed_theta": lambda k: n_b, "fixed_beta": lambda k: k}
    hyp_ungrouped = sum(sizes[c](k) for k in cfg.ks for _, t in people for c in cfg.person_conditions(t))
    per_er = cfg.environments * cfg.runs
    return {"tasks": n_tasks, "instances": n_tasks * len(people), "rows": per_er * len(cfg.ks) * rows,
            "set_solves_grouped": n_tasks, "set_solves_ungrouped": n_tasks * per_k_ungrouped,
            "hypotheses_grouped": per_er * hyp_grouped, "hypotheses_ungrouped": per_er * hyp_ungrouped}


def _subset_rows(hyp, sub) -> np.ndarray:
    rows = [hyp.index(t, b) for t, b in zip(sub.theta, sub.beta, strict=True)]
    assert all(i is not None for i in rows)
    return np.asarray(rows, dtype=np.int64)


def run_task(cfg: ConditionsConfig, seed: int, params: dict) -> tuple[dict[str, np.ndarray], dict]:
    """Every person of one (environment, run, k), scored from one solve of Ψ_k."""
    from ...hypotheses import BETA_PRESETS
    from ...inference.hypothesis_sets import full_set

    e, r, k = int(params["environment"]), int(params["run"]), int(params["k"])
    _, mdp = environment(cfg, seed, e)
    hyp = full_set(theta_k(cfg, seed, e, r, k), BETA_PRESETS[cfg.betas])
    t0 = time.perf_counter()
    _, log_policy = solve_padded(mdp, hyp.theta, hyp.beta, cfg.model)
    solve_time = time.perf_counter() - t0
    cols: dict[str, list] = {}
    for g, t in cfg.people():
        p = person(cfg, seed, e, r, k, g, t)
        for name, values in score_person(cfg, seed, mdp, hyp, log_policy, p).items():
            cols.setdefault(name, []).append(values)
    columns = {n: np.concatenate(v) for n, v in cols.items()}
    return columns, {"set_solve_time_s": solve_time, "set_solves": 1, "hypotheses_solved": len(hyp)}


def score_person(cfg, seed, mdp, hyp, log_policy, p: Person) -> dict[str, np.ndarray]:
    """The rows of one person: every condition × episode count 1..N."""
    from ...demos.simulation import capped_flags
    from ...hypotheses import HypothesisSet, expertise_group
    from ...inference.belief import DiscreteBelief

    trajs = p.trajectories
    eps = trajs.episodes()
    N = len(eps)
    lengths = np.array([len(s) for s, _ in eps])
    capped = capped_flags(trajs, mdp, cfg.max_steps)
    conds = cfg.person_conditions(p.truth)
    g_true = expertise_group(p.beta)
    est: dict[str, list] = {n: [] for n in ("beta_hat", "theta_hat", "p_group_true", "truth_probability",
                                            "entropy", "n_hypotheses")}
    for c in conds:
        if c == "full":
            sub = hyp
        elif c == "fixed_theta":
            sub = HypothesisSet(p.fixed_theta[None], hyp.betas)
        else:
            sub = HypothesisSet(hyp.thetas, [p.fixed_beta])
        b = DiscreteBelief.from_log_policy(sub, log_policy[_subset_rows(hyp, sub)])
        truth_idx = sub.index(p.theta, p.beta) if p.truth == "in_set" else None
        for n, (s, a) in enumerate(eps):
            b = b.update_trajectory(s, a, episode=n)
            est["beta_hat"].append(b.mean_beta)
            est["theta_hat"].append(b.mean_theta)
            est["p_group_true"].append(b.group_probabilities()[g_true])
            est["truth_probability"].append(np.nan if truth_idx is None else b.probabilities[truth_idx])
            est["entropy"].append(b.entropy)
            est["n_hypotheses"].append(len(sub))
    theta_hat = np.array(est["theta_hat"])
    m = len(conds) * N
    e, r, k, _, _ = p.identity
    zm, _ = environment(cfg, seed, e)
    col = {
        "seed": np.full(m, seed), "environment": np.full(m, e), "run": np.full(m, r), "k": np.full(m, k),
        "group": np.full(m, p.group, dtype=object), "truth": np.full(m, p.truth, dtype=object),
        "condition": np.repeat(np.array(conds, dtype=object), N),
        "method": np.full(m, "discrete", dtype=object),
        "episodes": np.tile(np.arange(1, N + 1), len(conds)),
        "n_pairs": np.tile(np.cumsum(lengths), len(conds)),
        "n_capped": np.tile(np.cumsum(capped), len(conds)),
        "map_width": np.full(m, zm.width), "map_height": np.full(m, zm.height),
        "n_states": np.full(m, mdp.n_states), "n_hypotheses": np.array(est["n_hypotheses"]),
        **truth_values(m, p.theta, p.beta), **composition_values(m, p.theta, p.beta, hyp),
    }
    fb = p.fixed_beta if p.fixed_beta is not None else np.nan
    col["fixed_beta"] = np.where(col["condition"] == "fixed_beta", fb, np.nan).astype(np.float64)
    for i, f in enumerate(FEATURES):
        v = p.fixed_theta[i] if p.fixed_theta is not None else np.nan
        col[f"fixed_theta_{f}"] = np.where(col["condition"] == "fixed_theta", v, np.nan)
    col["beta_hat"] = np.array(est["beta_hat"])
    col["group_hat"] = np.array([expertise_group(x) for x in est["beta_hat"]], dtype=object)
    col.update(feature_values("theta_hat", theta_hat))
    col["p_group_true"] = np.array(est["p_group_true"])
    col["truth_probability"] = np.array(est["truth_probability"])
    col["entropy"] = np.array(est["entropy"])
    metrics = estimate_metrics(mdp, cfg.model, p.theta, p.beta, p.value,
                               np.vstack([theta_hat, p.random_theta]), np.r_[col["beta_hat"], p.beta])
    col.update({name: v[:-1] for name, v in metrics.items()})
    col["random_theta_regret"] = np.full(m, metrics["policy_regret"][-1])
    col["goal_reward_mode"] = np.full(m, cfg.goal_reward_mode, dtype=object)
    return col


def estimate_metrics(mdp, model: str, theta, beta: float, value, theta_hat,
                     beta_hat) -> dict[str, np.ndarray]:
    """Sec. V-E's metrics of one person's estimates ``theta_hat [N, K]``, ``beta_hat [N]``
    against their truth (θ*, β*, soft values ``value [S]``). The regret solves each distinct
    θ̂ once, at β* (Sec. VI-C), in one padded batch; the return regret (what θ̂'s optimal policy
    earns under θ*) once per distinct θ̂ too."""
    from ...metrics import cosine_similarity, expertise_distance, regret_from_values, return_regret_table

    uniq, inv = np.unique(theta_hat, axis=0, return_inverse=True)
    v_hat, _ = solve_padded(mdp, uniq, np.full(len(uniq), beta), model)
    return {"expertise_distance": np.array([expertise_distance(beta, x) for x in beta_hat]),
            "cosine_similarity": np.array([cosine_similarity(theta, t) for t in theta_hat]),
            "policy_regret": np.array([regret_from_values(value, v_hat[j], mdp.terminal)
                                       for j in inv.ravel()]),
            "return_regret": return_regret_table(mdp, theta, uniq)[inv.ravel()]}


# ----------------------------------------------------------------------------- schema
_ID = [
    SEED,
    GOAL_REWARD_MODE,
    Column("environment", "int32", "environment index e (its map is seeded by `(e,)`)"),
    Column("run", "int32", "run index r (Θ_k is seeded by `(e, r, k)`)"),
    Column("k", "int32", "number of preference vectors in Θ_k"),
    Column("group", "string", "the person's expertise-group slot: `high`, `medium`, `low` (for an "
           "out-of-set person only an index; see `group_true`)"),
    Column("truth", "string", "`in_set` (θ*, β*) ∈ Ψ_k, or `out_of_set` (θ* ∉ Θ_k, β* ~ U(0.01, 10))"),
    Column("condition", "string", "`full` (Ψ_k), `fixed_theta` (Θ = {θ}, θ ≠ θ*), `fixed_beta` "
           "(B = {β}, β in another group than β*)"),
    Column("method", "string", "inference method (`discrete`: the discrete-set belief)"),
    EPISODES_SEEN,
]
_CONTEXT = [
    *episode_columns(),
    *MAP_COLUMNS,
    Column("n_hypotheses", "int32", "hypotheses of the condition's set"),
    *truth_columns(),
    *SET_COMPOSITION,
    Column("fixed_beta", "float64", "the β of the Fixed β set (NaN in other conditions)"),
    *feature_columns("fixed_theta", "component `{f}` of the Fixed θ set's θ (NaN elsewhere)"),
]
_ESTIMATES = [
    BETA_HAT_MEAN,
    Column("group_hat", "string", "expertise group of β̂"),
    *feature_columns("theta_hat", "θ̂ = E[θ] component `{f}`"),
    Column("p_group_true", "float64", "posterior mass on β*'s expertise group"),
    TRUTH_PROBABILITY,
    Column("entropy", "float64", "posterior entropy (nats)"),
    *METRIC_COLUMNS,
    Column("random_theta_regret", "float64", "the regret (Eq. 17, at β*) of a θ drawn uniformly from the "
           "θ grid for this person: what a guess costs, the metric's scale for their β*"),
]

STUDY = Study(
    name="conditions",
    version=5,  # 5: return_regret; 4: goal_reward_mode (the protocol) and random_theta_regret
    description="Sec. VI-A: Full set vs Fixed θ vs Fixed β, in- and out-of-set truths, metrics per episode",
    config_type=ConditionsConfig, scales=SCALES, tasks=tasks, run_task=run_task, counts=counts,
    columns=(*_ID, *_CONTEXT, *_ESTIMATES),
    sort_by=("environment", "run", "k", "group", "truth", "condition", "method", "episodes"),
    report="expertise_irl.experiments.report.fixed_vs_joint:build",
)
