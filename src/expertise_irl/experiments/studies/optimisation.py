"""The ``optimisation`` study (paper Sec. VII, Figs. 8–9, Table IV): continuous methods vs the set.

Protocol (Sec. VII-A). For each of the random environments e (the ``conditions`` study's
maps: the same generator and seed ``(e,)``, so the ``fullset`` study's one solve per map
serves both) and each instance i: Θ_20 is 20 vectors drawn from the ``paper-sim`` grid, the
truth has θ* drawn from Θ \\ Θ_20 and β* ~ U(0.01, 5), and the person demonstrates 40
episodes from uniformly random start states to the map's one goal. Every method then sees
the first n episodes for each n in ``episode_counts`` (10, 20, 30, 40):

- ``discrete``: the discrete set Ψ_20 = Θ_20 × B (Eq. 13), posterior means;
- ``birl_box``: **Algorithm 1 as printed** (the box [0, 1]^5, ‖θ‖₁ ≤ 1, both moves every
  step), 1,000 iterations, posterior means: the paper's optimisation approach, on which the
  Sec. VII claims are judged;
- ``birl_simplex``: Algorithm 1 on the simplex (‖θ‖₁ = 1), posterior means;
- ``map``: L-BFGS-B on the simplex and β from 4 starts (a mode, not a mean);
- ``nuts``: NumPyro NUTS, posterior means (at ``small`` scale on the first ``nuts_instances``
  instances of each environment only).

Every continuous method uses the paper's prior (Sec. VII-A: θ uniform on [0, 1]^5 / the
simplex, β ~ Normal(5.005, 1.5) truncated to [0.01, 10]), passed explicitly, so a later change
of the library's default prior does not move the reproduction. The rows carry the prior's name
and text.

Choices where the paper is silent. Θ_20 is drawn per instance (the paper says only "as in
Sec. V-D with k = 20"). The metrics are those of Sec. V-E with the regret of θ̂ evaluated at
β*. Algorithm 1's box estimate is used as it comes out, as printed: E[θ] and E[β] on a scale
the data cannot fix (only θ/β matters), so its cosine is unaffected but its β̂ and regret
carry that scale. Wall times: each method is
timed in the task's process after one untimed warm-up call on the instance's map (a few
iterations on two episodes), so what is timed is the method's work, not JAX compilation;
compare them from a sweep run with ``--workers 1`` (Sec. VII-D compares methods on one
processor). The discrete time is the solve of Ψ_20 plus the belief update over the n episodes.

Seeds. A map is seeded by ``(e,)`` as in ``conditions``; an instance draws from
``SeedSequence(entropy=[seed, STREAM], spawn_key=(e, i))``, a stream apart from the
``conditions`` identities, split into (Θ_20, truth, episodes, methods); episode j has its own
child seed, so the first n episodes are the same whatever the maximum.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ..spec import Column, Study, TaskSpec
from .common import (
    GOAL_REWARD_MODE,
    MAP_COLUMNS,
    METRIC_COLUMNS,
    SEED,
    SET_COMPOSITION,
    check_among,
    check_goal_reward,
    composition_values,
    episode_columns,
    feature_columns,
    feature_values,
    float_columns,
    truth_columns,
    truth_values,
)
from .fixed_vs_joint import (
    check_set_sizes,
    environment,
    estimate_metrics,
    preset_grid,
    simulate_episodes,
    solve_padded,
)

if TYPE_CHECKING:
    from ...demos.trajectories import Trajectories

METHODS = ("discrete", "birl_box", "birl_simplex", "map", "nuts")
#: Entropy word that keeps this study's instance seeds apart from ``conditions``' identities.
STREAM = 7


@dataclass(frozen=True)
class OptimisationConfig:
    """Factors of the study (paper values as defaults)."""

    environments: int = 5
    instances: int = 20
    episode_counts: tuple[int, ...] = (10, 20, 30, 40)
    k: int = 20
    beta_low: float = 0.01
    beta_high: float = 5.0
    methods: tuple[str, ...] = METHODS
    birl_iterations: int = 1000
    map_starts: int = 4
    nuts_chains: int = 4
    nuts_warmup: int = 500
    nuts_samples: int = 500
    nuts_instances: int = -1  # NUTS runs on instances i < nuts_instances of each map; -1: all
    prior: str = "paper"
    map_min_size: int = 10
    map_max_size: int = 30
    max_steps: int = 500
    thetas: str = "paper-sim"
    betas: str = "paper-sim"
    model: str = "maxent"
    goal_reward_mode: str = "scaled"  # the protocol: how the goal pays (worlds.grid.GOAL_REWARD_MODES)
    goal_bonus: float = 10.0  # what entering the goal pays (in `length` when scaled, outside θ·φ when fixed)
    # Algorithm 1's budget ablation: each entry adds a method `birl_box@<entry>`, `birl_chains` chains
    # of the box variant pooled, run for that many iterations each, or ("rhat") until their split
    # R-hat is below `birl_rhat` (checked every 1,000 iterations, at most `birl_max_iterations`); an
    # entry ending in ":log" (e.g. "5000:log") runs the same on a log-spaced β lattice, each step
    # multiplying β by `birl_beta_ratio` (ours; the paper's steps add 0.1)
    birl_budgets: tuple[str, ...] = ()
    birl_chains: int = 4
    birl_rhat: float = 1.01
    birl_max_iterations: int = 20_000
    birl_beta_ratio: float = 1.072  # 100 values from 0.01 to 10, as many as the additive lattice

    def __post_init__(self) -> None:
        from ...inference.priors import get_prior
        from ...models import check_model

        check_among("methods", self.methods, METHODS)
        if self.environments < 1 or self.instances < 1 or self.k < 2:
            raise InputError("need at least one environment and instance, and k >= 2")
        if not self.episode_counts or min(self.episode_counts) < 1:
            raise InputError("episode_counts must be positive")
        if not 0 < self.beta_low < self.beta_high:
            raise InputError(f"need 0 < beta_low < beta_high, got {self.beta_low}, {self.beta_high}")
        if self.birl_iterations < 1 or self.map_starts < 1 or self.nuts_chains < 1:
            raise InputError("birl_iterations, map_starts and nuts_chains must be at least 1")
        object.__setattr__(self, "birl_budgets", tuple(str(b) for b in self.birl_budgets))
        for b in self.birl_budgets:
            base = budget_iterations(b)
            if base != "rhat" and not (base.isdigit() and int(base) >= 1):
                raise InputError(f"birl_budgets entries must be a number of iterations or \"rhat\", "
                                 f"either followed by \":log\" or not, got {b!r}")
        if not self.birl_beta_ratio > 1:
            raise InputError(f"birl_beta_ratio must be > 1, got {self.birl_beta_ratio:g}")
        uses_rhat = any(budget_iterations(b) == "rhat" for b in self.birl_budgets)
        if self.birl_chains < (2 if uses_rhat else 1):
            raise InputError(f"birl_chains must be at least 1 (2 with \"rhat\"), got {self.birl_chains}")
        if not self.birl_rhat > 1 or self.birl_max_iterations < 1000:
            raise InputError("birl_rhat must be > 1 and birl_max_iterations at least 1000")
        get_prior(self.prior)
        check_model(self.model)
        check_set_sizes(self.thetas, self.betas, (self.k,))
        check_goal_reward(self.goal_reward_mode, self.goal_bonus)

    @property
    def episodes(self) -> int:
        return max(self.episode_counts)

    @property
    def budget_methods(self) -> tuple[str, ...]:
        """The methods of the budget ablation, ``birl_box@<budget>``, in ``birl_budgets``' order."""
        return tuple(f"birl_box@{b}" for b in self.birl_budgets)

    def runs_nuts(self, instance: int) -> bool:
        return "nuts" in self.methods and (self.nuts_instances < 0 or instance < self.nuts_instances)


SCALES = {
    "smoke": OptimisationConfig(environments=1, instances=2, episode_counts=(2, 4), k=5,
                                birl_iterations=30, map_starts=2, nuts_chains=1, nuts_warmup=30,
                                nuts_samples=30, nuts_instances=1, map_min_size=5, map_max_size=7,
                                max_steps=40),
    "small": OptimisationConfig(instances=4, nuts_chains=2, nuts_warmup=300, nuts_samples=300,
                                nuts_instances=1),
    # NUTS on the first instance of each map (5 of the 100), 2 chains of 300 + 300: on all 100 with
    # the defaults (4 chains of 500 + 500) it would take about 12 h on one core of a 2-core laptop.
    "paper": OptimisationConfig(nuts_chains=2, nuts_warmup=300, nuts_samples=300, nuts_instances=1),
}


# ------------------------------------------------------------------------- instances
def instance_seed(seed: int, e: int, i: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(entropy=[int(seed), STREAM], spawn_key=(int(e), int(i)))


@dataclass(frozen=True)
class Instance:
    """One instance: Θ_20, the truth, its episodes and the methods' seeds."""

    identity: tuple[int, int]
    thetas: np.ndarray  # [k, K] Θ_k
    theta: np.ndarray
    beta: float
    value: np.ndarray  # [S] soft value of the truth (for regret)
    trajectories: Trajectories
    method_seeds: dict[str, int]
    log_policy: np.ndarray  # [S, A] the truth's policy (for its log-likelihood)


@lru_cache(maxsize=4)
def instance(cfg: OptimisationConfig, seed: int, e: int, i: int) -> Instance:
    """Rebuild instance ``(e, i)`` of sweep ``seed`` (bit for bit)."""
    from ...hypotheses import sample_thetas
    from ...inference.hypothesis_sets import out_of_set_truth

    _, mdp = environment(cfg, seed, e)
    grid = preset_grid(cfg.thetas, mdp.n_features)
    set_ss, truth_ss, sim_ss, method_ss = instance_seed(seed, e, i).spawn(4)
    thetas = sample_thetas(grid, cfg.k, np.random.default_rng(set_ss))
    theta, beta = out_of_set_truth(grid, thetas, np.random.default_rng(truth_ss),
                                   beta_range=(cfg.beta_low, cfg.beta_high))
    value, log_policy = solve_padded(mdp, theta, beta, cfg.model)
    trajs = simulate_episodes(mdp, log_policy[0], sim_ss, cfg.episodes, cfg.max_steps)
    seeds = {m: int(ss.generate_state(1)[0]) for m, ss in zip(METHODS, method_ss.spawn(len(METHODS)),
                                                              strict=True)}
    return Instance((e, i), thetas, theta, beta, value[0], trajs, seeds, log_policy[0])


# ------------------------------------------------------------------------------ tasks
def tasks(cfg: OptimisationConfig) -> list[TaskSpec]:
    """One task per instance; instances interleaved across maps (NUTS ones first)."""
    order = sorted(((i, e) for i in range(cfg.instances) for e in range(cfg.environments)),
                   key=lambda ie: (not cfg.runs_nuts(ie[0]), ie[0], ie[1]))
    return [TaskSpec(f"e{e:03d}-i{i:03d}", {"environment": e, "instance": i}, estimate_s(cfg, i))
            for i, e in order]


def estimate_s(cfg: OptimisationConfig, i: int) -> float:
    """Rough seconds of one instance for one worker on a 2-core laptop (measured at ``small`` scale:
    a 746-state map took 0.23 s for the set, 6.5 s per Algorithm 1 run of 1,000 iterations, 2 s
    per MAP fit and 47 s per NUTS run of 2 × (300 + 300) iterations)."""
    side = (cfg.map_min_size + cfg.map_max_size) / 2
    states = 1.3 * side * side  # the generator's maps hold about 1.3 side² states on average
    n = len(cfg.episode_counts)
    alg1 = states * 8.7e-3 * cfg.birl_iterations / 1000
    per = {"discrete": 0.1 + states * 3e-4, "birl_box": alg1, "birl_simplex": alg1,
           "map": 0.5 + states * 2.7e-3,
           "nuts": 2.0 + states * 5.2e-5 * cfg.nuts_chains * (cfg.nuts_warmup + cfg.nuts_samples)}
    budgets = sum(cfg.birl_max_iterations if budget_iterations(b) == "rhat" else int(budget_iterations(b))
                  for b in cfg.birl_budgets)
    return 2.0 + sum(per[m] * (1 if m == "discrete" else n) for m in cfg.methods
                     if m != "nuts" or cfg.runs_nuts(i)) + states * 8.7e-6 * budgets * cfg.birl_chains * n


def counts(cfg: OptimisationConfig) -> dict[str, int]:
    inst = cfg.environments * cfg.instances
    nuts_inst = cfg.environments * sum(cfg.runs_nuts(i) for i in range(cfg.instances))
    per = len([m for m in cfg.methods if m != "nuts"]) + len(cfg.birl_budgets)
    return {"tasks": inst, "instances": inst,
            "rows": len(cfg.episode_counts) * (inst * per + nuts_inst),
            "set_solves_grouped": inst if "discrete" in cfg.methods else 0,
            "set_solves_ungrouped": inst * len(cfg.episode_counts) if "discrete" in cfg.methods else 0}


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def run_task(cfg: OptimisationConfig, seed: int, params: dict) -> tuple[dict[str, np.ndarray], dict]:
    """Every method at every episode count on one instance."""
    from ...demos.trajectories import Trajectories
    from ...hypotheses import BETA_PRESETS, HypothesisSet
    from ...inference.belief import DiscreteBelief
    from ...inference.methods import BIRLOptions, MAPOptions, NUTSOptions, get_method

    e, i = int(params["environment"]), int(params["instance"])
    zm, mdp = environment(cfg, seed, e)
    inst = instance(cfg, seed, e, i)
    trajs, seeds = inst.trajectories, inst.method_seeds
    common = {"prior": cfg.prior, "model": cfg.model}
    hyp = HypothesisSet(inst.thetas, BETA_PRESETS[cfg.betas])

    def discrete():
        """Every count from one solve and one pass (the belief is updated episode by episode)."""
        sol, spent = _timed(lambda: solve_padded(mdp, hyp.theta, hyp.beta, cfg.model))
        b = DiscreteBelief.from_log_policy(hyp, sol[1])
        ids, out, done = trajs.episode_ids, {}, 0
        for c in sorted(cfg.episode_counts):
            t0 = time.perf_counter()
            keep = np.isin(trajs.episode, ids[done:c])
            b = b.update(Trajectories(trajs.episode[keep], trajs.step[keep], trajs.state[keep],
                                      trajs.action[keep]))
            spent += time.perf_counter() - t0
            done = c
            out[c] = (b.mean_theta, b.mean_beta, spent, {})
        return out

    def birl(variant: str):
        def fit(tr, n_iter, rng):
            opts = BIRLOptions(iterations=n_iter, variant=variant, **common)
            return get_method("birl").fit(mdp, tr, opts, rng).result

        def one(n: int):
            r, t = _timed(lambda: fit(trajs.first(n), cfg.birl_iterations,
                                      np.random.default_rng([seeds[f"birl_{variant}"], n])))
            return r.mean_theta, r.mean_beta, t, {"acceptance_rate": r.acceptance_rate}

        return (lambda: fit(trajs.first(2), 3, np.random.default_rng(0))), one

    def map_one(n: int):
        opts = MAPOptions(starts=cfg.map_starts, **common)
        r, t = _timed(lambda: get_method("map").fit(mdp, trajs.first(n), opts,
                                                    np.random.default_rng([seeds["map"], n])).result)
        return r.theta, r.beta, t, {}

    def nuts_fit(tr, warmup, samples, chains, s):
        opts = NUTSOptions(chains=chains, warmup=warmup, samples=samples, **common)
        return get_method("nuts").fit(mdp, tr, opts, s).result

    def nuts_one(n: int):
        r, t = _timed(lambda: nuts_fit(trajs.first(n), cfg.nuts_warmup, cfg.nuts_samples,
                                       cfg.nuts_chains, seeds["nuts"] + n))
        # a parameter without R-hat (a chain that did not move in it) is the worst case, never dropped
        rhat = np.nan if r.r_hat is None else max(np.inf if x is None else float(x)
                                                  for x in [r.r_hat["beta"], *r.r_hat["theta"]])
        return r.mean_theta, r.mean_beta, t, {"divergences": float(r.divergences), "max_rhat": rhat}

    methods = {
        **_budget_runs(cfg, mdp, trajs, seeds, common),
        "birl_box": birl("box"),
        "birl_simplex": birl("simplex"),
        "map": (lambda: get_method("map").fit(mdp, trajs.first(2), MAPOptions(starts=1, **common),
                                              np.random.default_rng(0)), map_one),
        "nuts": (lambda: nuts_fit(trajs.first(2), 5, 5, 1, 0), nuts_one),
    }
    results: dict[str, dict[int, tuple]] = {}
    for m in (*cfg.methods, *cfg.budget_methods):
        if m == "discrete":
            solve_padded(mdp, hyp.theta, hyp.beta, cfg.model)  # warm-up: compile this shape
            results[m] = discrete()
        elif m != "nuts" or cfg.runs_nuts(i):
            warm, one = methods[m]
            warm()
            results[m] = {n: one(n) for n in cfg.episode_counts}
    return _rows(cfg, seed, zm, mdp, inst, hyp, results), {}


#: A ``birl_budgets`` entry ending in it runs on the log-spaced β lattice (``birl_beta_ratio``).
LOG_SUFFIX = ":log"


def budget_iterations(budget: str) -> str:
    """A ``birl_budgets`` entry without its ``:log`` suffix: a number of iterations or ``rhat``."""
    return budget.removesuffix(LOG_SUFFIX)


def budget_options(cfg: OptimisationConfig, budget: str) -> dict:
    """:func:`~expertise_irl.inference.birl_chains.birl_chains`' options for a ``birl_budgets`` entry."""
    base = budget_iterations(budget)
    kw = ({"rhat_below": cfg.birl_rhat, "max_iter": cfg.birl_max_iterations, "block": 1000}
          if base == "rhat" else {"n_iter": int(base)})
    if budget.endswith(LOG_SUFFIX):
        kw["beta_ratio"] = cfg.birl_beta_ratio
    return kw


def _budget_runs(cfg, mdp, trajs, seeds, common) -> dict[str, tuple]:
    """The budget ablation's methods (:attr:`OptimisationConfig.budget_methods`): a warm-up and a
    run per episode count, each ``birl_chains`` chains of the box variant pooled."""
    from ...inference.birl_chains import birl_chains

    def fit(tr, budget: str, rng):
        return birl_chains(mdp, tr, chains=cfg.birl_chains, rng=rng, variant="box",
                           **budget_options(cfg, budget), **common)

    def run(budget: str, b: int):
        def one(n: int):
            rng = np.random.default_rng([seeds["birl_box"], n, b])
            r, t = _timed(lambda: fit(trajs.first(n), budget, rng))
            extra = {"acceptance_rate": r.acceptance_rate, "max_rhat": r.max_rhat,
                     "birl_iterations": r.iterations, "birl_chains": cfg.birl_chains}
            return r.mean_theta, r.mean_beta, t, extra
        return (lambda: birl_chains(mdp, trajs.first(2), chains=2, n_iter=3, rng=np.random.default_rng(0),
                                    **common)), one

    pairs = zip(cfg.budget_methods, cfg.birl_budgets, strict=True)
    return {m: run(b, k + 1) for k, (m, b) in enumerate(pairs)}


def _rows(cfg, seed, zm, mdp, inst: Instance, hyp, results) -> dict[str, np.ndarray]:
    from ...demos.simulation import capped_episodes
    from ...inference.priors import get_prior

    keys = [(m, n) for m in results for n in cfg.episode_counts]
    theta_hat = np.array([results[m][n][0] for m, n in keys], dtype=np.float64)
    beta_hat = np.array([results[m][n][1] for m, n in keys], dtype=np.float64)
    L = len(keys)
    e, i = inst.identity
    first = {n: inst.trajectories.first(n) for n in cfg.episode_counts}
    pairs = np.array([len(first[n]) for _, n in keys])
    episodes = np.array([n for _, n in keys])
    methods = np.array([m for m, _ in keys], dtype=object)
    continuous = methods != "discrete"
    col = {
        "seed": np.full(L, seed), "environment": np.full(L, e), "instance": np.full(L, i),
        "method": methods, "episodes": episodes, "n_pairs": pairs,
        "n_capped": np.array([capped_episodes(first[n], mdp, cfg.max_steps) for _, n in keys]),
        "mean_episode_length": pairs / episodes,
        "map_width": np.full(L, zm.width), "map_height": np.full(L, zm.height),
        "n_states": np.full(L, mdp.n_states),
        "n_hypotheses": np.where(continuous, 0, len(hyp)),
        **truth_values(L, inst.theta, inst.beta), **composition_values(L, inst.theta, inst.beta, hyp),
    }
    col["prior"] = np.where(continuous, cfg.prior, "uniform").astype(object)
    col["prior_text"] = np.where(continuous, get_prior(cfg.prior).text,
                                 f"uniform over the {len(hyp)} hypotheses of Ψ_{cfg.k}").astype(object)
    col["beta_hat"] = beta_hat
    col.update(feature_values("theta_hat", theta_hat))
    col.update(estimate_metrics(mdp, cfg.model, inst.theta, inst.beta, inst.value, theta_hat, beta_hat))
    col.update(log_likelihoods(cfg, mdp, inst, keys, theta_hat, beta_hat, first))
    col["goal_reward_mode"] = np.full(L, cfg.goal_reward_mode, dtype=object)
    col["wall_time_s"] = np.array([results[m][n][2] for m, n in keys], dtype=np.float64)
    for name in ("acceptance_rate", "divergences", "max_rhat"):
        col[name] = np.array([results[m][n][3].get(name, np.nan) for m, n in keys], dtype=np.float64)
    one_chain = {"birl_box": (cfg.birl_iterations, 1), "birl_simplex": (cfg.birl_iterations, 1)}
    budget = [(results[m][n][3].get("birl_iterations"), results[m][n][3].get("birl_chains"))
              if m not in one_chain else one_chain[m] for m, n in keys]
    col["birl_iterations"] = np.array([it or 0 for it, _ in budget], dtype=np.int64)
    col["birl_chains"] = np.array([c or 0 for _, c in budget], dtype=np.int32)
    return col


def log_likelihoods(cfg, mdp, inst: Instance, keys, theta_hat, beta_hat, first) -> dict[str, np.ndarray]:
    """Eq. 11 of the episodes each row saw, at the truth and at the row's estimate (θ̂, β̂): how
    far the data pin the truth down (an estimate above the truth is what any fit finds; the size
    of the gap is the evidence). The estimates are solved in one padded batch."""
    from ...planning.table_likelihood import log_likelihood

    _, log_pi = solve_padded(mdp, theta_hat, beta_hat, cfg.model)
    truth = {n: float(log_likelihood(inst.log_policy[None], tr.state, tr.action)[0])
             for n, tr in first.items()}
    hat = [float(log_likelihood(log_pi[j][None], first[n].state, first[n].action)[0])
           for j, (_, n) in enumerate(keys)]
    return {"log_likelihood_truth": np.array([truth[n] for _, n in keys]),
            "log_likelihood_hat": np.array(hat)}


# ----------------------------------------------------------------------------- schema
COLUMNS = (
    SEED,
    GOAL_REWARD_MODE,
    Column("environment", "int32", "environment index e (the `conditions` study's map `(e,)`)"),
    Column("instance", "int32", "instance index i within the environment"),
    Column("method", "string", "`discrete` (Ψ_20), `birl_box` (Algorithm 1 as printed), `birl_simplex`, "
           "`map`, `nuts`, and the budget ablation's `birl_box@<iterations>` / `birl_box@rhat`"),
    Column("episodes", "int32", "episodes the method saw (the first n of the instance's 40)"),
    *episode_columns("actions in those episodes",
                     "episodes among them that hit `max_steps` without reaching the goal"),
    Column("mean_episode_length", "float64", "n_pairs / episodes (Table IV's average episode length)"),
    *MAP_COLUMNS,
    Column("n_hypotheses", "int32", "hypotheses of the discrete set (0 for continuous methods)"),
    *truth_columns("β* ~ U(beta_low, beta_high)", "θ* component `{f}` (unit l1 norm; θ* ∉ Θ_20)"),
    *SET_COMPOSITION,
    Column("prior", "string", "the prior's name (`paper` for the continuous methods, `uniform` for the set)"),
    Column("prior_text", "string", "the prior in words"),
    Column("beta_hat", "float64", "β̂ (posterior mean; MAP: the mode)"),
    *feature_columns("theta_hat", "θ̂ component `{f}` (Algorithm 1 box: unnormalised)"),
    *METRIC_COLUMNS,
    *float_columns({
        "log_likelihood_truth": "log-likelihood (Eq. 11, nats) of the episodes seen at the truth (θ*, β*)",
        "log_likelihood_hat": "log-likelihood (Eq. 11, nats) of the episodes seen at the estimate (θ̂, β̂)",
        "wall_time_s": "the method's wall time at this episode count, after a warm-up (discrete: the set's "
                       "solve plus the belief updates)",
        "acceptance_rate": "Algorithm 1's accepted moves / iterations (NaN otherwise)",
        "divergences": "NUTS divergent transitions after warm-up (NaN otherwise)",
        "max_rhat": "NUTS, and the budget ablation's Algorithm 1 (`birl_box@…`, over β and θ/‖θ‖₁): largest "
                    "split-R̂ over β and θ (inf when a chain did not move in one of them; NaN for the other "
                    "methods or when R̂ is not computed)",
    }),
    Column("birl_iterations", "int64", "Algorithm 1's iterations per chain (0 for the other methods)"),
    Column("birl_chains", "int32", "Algorithm 1's independent chains, pooled (1 for `birl_box` and "
           "`birl_simplex`, `birl_chains` for `birl_box@…`; 0 for the other methods)"),
)

STUDY = Study(
    name="optimisation",
    # 4: return_regret, the budget ablation (birl_iterations, birl_chains); 3: goal_reward_mode (the
    # protocol) and the log-likelihoods at the truth and estimate
    version=4,
    description="Sec. VII: Algorithm 1 (as printed), ours (simplex, MAP, NUTS) vs the discrete set Ψ_20",
    config_type=OptimisationConfig, scales=SCALES, tasks=tasks, run_task=run_task, counts=counts,
    columns=COLUMNS,
    sort_by=("environment", "instance", "method", "episodes"),
    report="expertise_irl.experiments.report.optimisation:build",
)
