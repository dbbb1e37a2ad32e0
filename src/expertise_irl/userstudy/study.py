"""The engine's side of ``expertise-irl study``: the tasks of a user study (Sec. VIII).

Three studies, each a pure function of a config that carries the study's data (every map:
floor plans and zone maps as text, MDP archives as their bytes in base64; and every task's
(state, action) pairs, as one JSON string), so workers need no access to the participants'
files and a changed input is a different sweep:

- ``user-study-discrete``: one task per distinct map. It solves the hypothesis set once on
  that map and returns, for every episode of every manifest row on it, the log-likelihood of
  each hypothesis: participants who share a map share one solve, and the per-episode values
  give the joint posterior (their sum) and every held-out split without another solve.
- ``user-study-continuous``: one task per participant (``--method map|nuts``): with
  ``share = "both"`` one (θ, β) for all their tasks (log-likelihoods summed), with
  ``share = "beta"`` one β and a θ per task (:mod:`..inference.shared_beta`).
- ``user-study-optimal``: one task per floor plan; it solves β = 0.001 for the estimates θ̂
  of every participant with a task on it and follows the most probable action from each
  episode's start (Table VI).
- ``user-study-pedagogical``: ``user-study-discrete`` for the teaching model (``--model
  pedagogical``, :mod:`..inference.pedagogical`): one ``maxent`` solve of the set per map and, for
  every episode, the log-likelihood of each hypothesis at each teaching weight λ of the grid
  (``lambdas``), the literal observer believing the set with a uniform prior on that map. Its
  λ = 0 values are ``user-study-discrete``'s under ``maxent``.
"""

from __future__ import annotations

import base64
import json
import time
import zlib
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..experiments.spec import ADDED_FIELD, Column, Study, TaskSpec
from ..inference.pedagogical import LAMBDAS, parse_lambdas
from ..inference.priors import DEFAULT_PRIOR
from ..models import DEFAULT_MODEL
from ..options import (
    DEFAULT_EXPERTISE,
    DEFAULT_METHOD,
    DEFAULT_SHARE,
    DEFAULT_THETAS,
    Expertise,
    Method,
    Preset,
    Share,
    choose,
    one_of,
)

#: The methods a study runs (Algorithm 1 takes one task: not a participant's several).
METHODS = tuple(m.value for m in Method if m != Method.BIRL)
#: What a participant's tasks share: ``both`` one (θ, β); ``beta`` one β, a θ per task.
SHARES = tuple(s.value for s in Share)
#: B of a study config that names none. The engine's config has no maps to choose a grid from, so it
#: keeps the paper's real-data set; ``expertise-irl study`` always names one (``--betas auto`` by
#: default, :data:`expertise_irl.options.AUTO_BETAS`, chosen from the maps before the config is made).
CONFIG_BETAS = Preset.PAPER_REAL


def lambdas_spec(spec) -> str:
    """A λ grid (``--lambdas``, or a sequence) as the study records it: its values sorted, by ``repr``.

    Args:
        spec: comma-separated numbers or a sequence (:func:`~..inference.pedagogical.parse_lambdas`).

    Returns:
        The grid's string, the same for the same grid however it was written.
    """
    return ",".join(repr(float(x)) for x in parse_lambdas(spec))


#: The teaching model's default λ grid, as a study records it.
DEFAULT_LAMBDAS = lambdas_spec(LAMBDAS)


@dataclass(frozen=True)
class UserStudyConfig:
    """Data and options of one user study (the CLI builds it from the manifest)."""

    data: str  # JSON: {"maps": {key: map entry}, "tasks": [task]} (see userstudy.run)
    thetas: str = DEFAULT_THETAS
    betas: str = CONFIG_BETAS
    model: str = DEFAULT_MODEL
    method: str = DEFAULT_METHOD
    prior: str = DEFAULT_PRIOR
    starts: int = 4
    chains: int = 4
    warmup: int = 500
    samples: int = 500
    share: str = DEFAULT_SHARE
    # map/nuts: "changing" also fits the learning curve (inference.trend) over each participant's
    # episodes in task order (the discrete set's curve needs no engine option: see userstudy.run)
    expertise: str = field(default=DEFAULT_EXPERTISE, metadata={ADDED_FIELD: True})
    # user-study-pedagogical: the grid of teaching weights λ (lambdas_spec)
    lambdas: str = field(default=DEFAULT_LAMBDAS, metadata={ADDED_FIELD: True})

    def __post_init__(self) -> None:
        one_of(self.method, METHODS, "method")
        choose(Share, self.share, "share")
        choose(Expertise, self.expertise, "expertise")


@lru_cache(maxsize=4)
def _data(text: str) -> dict:
    return json.loads(text)


def world_entry(world, mdp_bytes: bytes | None = None, name: str = "") -> dict:
    """The engine's copy of a task's map: a floor plan or zone map as text and settings, or an MDP
    archive's bytes (``world`` None) in base64."""
    from ..worlds.warehouse import WarehouseMap

    if world is None:
        return {"kind": "mdp", "name": name, "npz": base64.b64encode(mdp_bytes).decode("ascii")}
    entry = {"text": world.to_text(), "name": Path(world.name).name, "goal_bonus": world.goal_bonus,
             "gamma": world.gamma, "goal_reward_mode": world.goal_reward_mode}
    if isinstance(world, WarehouseMap):
        return {"kind": "floor-plan", **entry, "cell_size": world.cell_size, "y_up": world.y_up}
    return {"kind": "zones", **entry}


@lru_cache(maxsize=16)
def _plan_mdp(text: str, key: str):
    """(map or None, MDP) of the study's map ``key``."""
    from ..mdp import TabularMDP
    from ..worlds.warehouse import parse_floor_plan
    from ..worlds.zones import parse_map

    p = _data(text)["maps"][key]
    kind = p.get("kind", "floor-plan")
    if kind == "mdp":
        return None, TabularMDP.from_bytes(base64.b64decode(p["npz"]), source=p["name"])
    common = dict(name=p["name"], goal_bonus=p["goal_bonus"], gamma=p["gamma"],
                  goal_reward_mode=p.get("goal_reward_mode", "scaled"))
    if kind == "zones":
        world = parse_map(p["text"], **common)
    else:
        world = parse_floor_plan(p["text"], cell_size=p["cell_size"], y_up=p["y_up"], **common)
    return world, world.to_mdp()


def _hypotheses(cfg: UserStudyConfig, n_features: int):
    from ..inference.methods import DiscreteOptions

    return DiscreteOptions(thetas=cfg.thetas, betas=cfg.betas).hypotheses(n_features)


def participant_seed(participant: str) -> int:
    """The seed of a participant's chains and starts: from their ID, not their position."""
    return zlib.crc32(participant.encode("utf-8"))


def _map_tasks(cfg: UserStudyConfig) -> list[TaskSpec]:
    d = _data(cfg.data)
    keys = list(dict.fromkeys(t["map"] for t in d["tasks"]))
    return [TaskSpec(k, {"map": k}, 5.0) for k in keys]


def _participant_tasks(cfg: UserStudyConfig) -> list[TaskSpec]:
    d = _data(cfg.data)
    pids = list(dict.fromkeys(t["participant"] for t in d["tasks"]))
    return [TaskSpec(f"participant-{p}", {"participant": p}, 30.0) for p in pids]


# ------------------------------------------------------------------------ discrete
def run_discrete(cfg: UserStudyConfig, seed: int, params: dict) -> tuple[dict, dict]:
    """Log-likelihood of every hypothesis for every episode of every manifest row on one map."""
    from ..planning.soft_vi import solve
    from ..planning.table_likelihood import log_likelihood

    key = params["map"]
    _, mdp = _plan_mdp(cfg.data, key)
    hyp = _hypotheses(cfg, mdp.n_features)
    t0 = time.perf_counter()
    sol = solve(mdp, hyp.theta, hyp.beta, model=cfg.model)
    solve_time = time.perf_counter() - t0
    rows = [t for t in _data(cfg.data)["tasks"] if t["map"] == key]
    H = len(hyp)
    cols = {"task": [], "participant": [], "episode": [], "hypothesis": [], "log_likelihood": []}
    for t in rows:
        labels = np.asarray(t["episodes"])
        states, actions = np.asarray(t["states"]), np.asarray(t["actions"])
        for e, label in enumerate(dict.fromkeys(labels.tolist())):
            mask = labels == label
            cols["task"].append(np.full(H, t["task"]))
            cols["participant"].append(np.full(H, t["participant"], dtype=object))
            cols["episode"].append(np.full(H, e))
            cols["hypothesis"].append(np.arange(H))
            cols["log_likelihood"].append(log_likelihood(sol.log_policy, states[mask], actions[mask]))
    columns = {k: np.concatenate(v) for k, v in cols.items()}
    return columns, {"set_solve_time_s": solve_time, "set_solves": 1, "hypotheses_solved": H}


def run_teaching(cfg: UserStudyConfig, seed: int, params: dict) -> tuple[dict, dict]:
    """The teaching model's log-likelihood of every (λ, hypothesis) for every episode of every manifest
    row on one map: one ``maxent`` solve of the set, every hypothesis to the solver's tolerance (each is
    part of the literal observer, so none may be screened out)."""
    from ..demos.trajectories import Trajectories
    from ..inference.evidence import teaching_pair_log_likelihoods
    from ..planning.soft_vi import solve

    key = params["map"]
    _, mdp = _plan_mdp(cfg.data, key)
    hyp = _hypotheses(cfg, mdp.n_features)
    lam = parse_lambdas(cfg.lambdas)
    t0 = time.perf_counter()
    lp = np.asarray(solve(mdp, hyp.theta, hyp.beta, model="maxent").log_policy)
    solve_time = time.perf_counter() - t0
    H, L = len(hyp), len(lam)
    cols: dict[str, list] = {"task": [], "participant": [], "episode": [], "lambda": [], "hypothesis": [],
                             "log_likelihood": []}
    for t in (t for t in _data(cfg.data)["tasks"] if t["map"] == key):
        labels = np.asarray(t["episodes"])
        states, actions = np.asarray(t["states"]), np.asarray(t["actions"])
        for e, label in enumerate(dict.fromkeys(labels.tolist())):
            mask = labels == label
            pairs = Trajectories(np.zeros(int(mask.sum()), dtype=np.int64), np.arange(int(mask.sum())),
                                 states[mask], actions[mask])
            ll = teaching_pair_log_likelihoods(lp, hyp, pairs, lam)  # [L, H]
            cols["task"].append(np.full(L * H, t["task"]))
            cols["participant"].append(np.full(L * H, t["participant"], dtype=object))
            cols["episode"].append(np.full(L * H, e))
            cols["lambda"].append(np.repeat(np.arange(L), H))
            cols["hypothesis"].append(np.tile(np.arange(H), L))
            cols["log_likelihood"].append(ll.ravel())
    columns = {k: np.concatenate(v) for k, v in cols.items()}
    return columns, {"set_solve_time_s": solve_time, "set_solves": 1, "hypotheses_solved": H}


# ---------------------------------------------------------------------- continuous
def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def run_continuous(cfg: UserStudyConfig, seed: int, params: dict) -> tuple[dict, dict]:
    """MAP or NUTS on all of one participant's tasks: one (θ, β), their log-likelihoods summed, or with
    ``share = "beta"`` one β and a θ per task."""
    from ..demos.trajectories import Trajectories
    from ..inference.methods import get_method

    pid = params["participant"]
    mine = [t for t in _data(cfg.data)["tasks"] if t["participant"] == pid]
    mdps, trajs = [], []
    for t in mine:
        _, mdp = _plan_mdp(cfg.data, t["map"])
        mdps.append(mdp)
        trajs.append(
            Trajectories(
                np.asarray(t["episodes"]),
                np.asarray(t["steps"]),
                np.asarray(t["states"]),
                np.asarray(t["actions"]),
            )
        )
    method = get_method(cfg.method)
    opts = method.options_from(dict(starts=cfg.starts, chains=cfg.chains, warmup=cfg.warmup,
                                    samples=cfg.samples, prior=cfg.prior, model=cfg.model,
                                    expertise=cfg.expertise))
    seed = participant_seed(pid) + int(seed)
    if cfg.share == "beta":  # one β, a θ per task
        from ..inference.shared_beta import fit_shared_beta

        res = fit_shared_beta(cfg.method, mdps, trajs, opts, seed)
    else:
        res = method.run(mdps, trajs, opts, seed).fields
    if "draws" in res:
        chain, theta, beta = res.pop("draws")
        res["draws"] = {"chain": chain, "theta": theta, "beta": beta}
    doc = json.dumps(_jsonable(res), allow_nan=False)
    return {"participant": np.array([pid], dtype=object), "result": np.array([doc], dtype=object)}, {}


# ------------------------------------------------------------------------- optimal
def run_optimal(cfg: UserStudyConfig, seed: int, params: dict) -> tuple[dict, dict]:
    """The β = 0.001 path of each participant's θ̂ from each episode's start on one floor plan."""
    from ..experiments.studies.fixed_vs_joint import solve_padded
    from .paths import OPTIMAL_BETA, greedy_path

    key = params["map"]
    _, mdp = _plan_mdp(cfg.data, key)
    rows = [t for t in _data(cfg.data)["tasks"] if t["map"] == key]
    thetas = np.array([t["theta_hat"] for t in rows], dtype=np.float64)
    uniq, inv = np.unique(thetas, axis=0, return_inverse=True)
    t0 = time.perf_counter()
    _, log_policy = solve_padded(mdp, uniq, np.full(len(uniq), OPTIMAL_BETA), cfg.model)
    solve_time = time.perf_counter() - t0
    cols: dict[str, list] = {
        "task": [],
        "participant": [],
        "episode": [],
        "step": [],
        "state": [],
        "action": [],
        "reached_goal": [],
    }
    for t, h in zip(rows, inv.ravel().tolist(), strict=True):
        for e, start in enumerate(t["starts"]):
            s, a, done = greedy_path(mdp, log_policy[h], start)
            n = len(s)
            cols["task"].append(np.full(n, t["task"]))
            cols["participant"].append(np.full(n, t["participant"], dtype=object))
            cols["episode"].append(np.full(n, e))
            cols["step"].append(np.arange(n))
            cols["state"].append(s)
            cols["action"].append(a)
            cols["reached_goal"].append(np.full(n, done))
    columns = {k: (np.concatenate(v) if v else np.array([])) for k, v in cols.items()}
    return columns, {"set_solve_time_s": solve_time, "set_solves": 1, "hypotheses_solved": len(uniq)}


# -------------------------------------------------------------------------- schema
_TASK = Column("task", "int32", "manifest row (0-based, header and blank lines not counted)")
_PARTICIPANT = Column("participant", "string", "participant ID")



def _study(name: str, tasks, run_task, columns: tuple[Column, ...], sort_by: tuple[str, ...],
           description: str, version: int = 2) -> Study:
    """A user-study study: its config carries the data, so it has no scales. Version 2: over-relaxed
    solves (values move within the tolerance); 3: any map (zone maps, MDP archives), per-episode
    log-likelihoods, ``share``."""
    return Study(name=name, version=version,
                 description=description, config_type=UserStudyConfig, scales={}, tasks=tasks,
                 run_task=run_task, columns=columns, sort_by=sort_by)


_DISCRETE_COLUMNS = (_TASK, _PARTICIPANT,
                     Column("episode", "int32", "episode of the row (0-based, in file order)"),
                     Column("hypothesis", "int32", "hypothesis index (θ-major, β fastest)"),
                     Column("log_likelihood", "float64", "log P(Ξ_row | h) (−inf: impossible)"))
_TEACHING_COLUMNS = (_TASK, _PARTICIPANT,
                     Column("episode", "int32", "episode of the row (0-based, in file order)"),
                     Column("lambda", "int32", "index of the teaching weight λ in the config's grid"),
                     Column("hypothesis", "int32", "hypothesis index (θ-major, β fastest)"),
                     Column("log_likelihood", "float64", "log P(Ξ_row | h, λ) (−inf: impossible)"))
_CONTINUOUS_COLUMNS = (_PARTICIPANT, Column("result", "string", "the method's result fields (JSON)"))
_OPTIMAL_COLUMNS = (_TASK, _PARTICIPANT, Column("episode", "int32", "episode of the row (0-based)"),
                    Column("step", "int32", "step"), Column("state", "int64", "state"),
                    Column("action", "int32", "action"),
                    Column("reached_goal", "bool", "the path ends in a goal"))

DISCRETE = _study("user-study-discrete", _map_tasks, run_discrete, _DISCRETE_COLUMNS,
                  ("task", "episode", "hypothesis"),
                  "expertise-irl study: one solve per map, log-likelihoods of every episode of every row",
                  version=3)
CONTINUOUS = _study("user-study-continuous", _participant_tasks, run_continuous, _CONTINUOUS_COLUMNS,
                    ("participant",), "expertise-irl study --method map|nuts: one task per participant",
                    version=3)
OPTIMAL = _study("user-study-optimal", _map_tasks, run_optimal, _OPTIMAL_COLUMNS, ("task", "episode", "step"),
                 "expertise-irl study: optimal paths (β = 0.001, θ̂) per map", version=3)
TEACHING = _study("user-study-pedagogical", _map_tasks, run_teaching, _TEACHING_COLUMNS,
                  ("task", "episode", "lambda", "hypothesis"),
                  "expertise-irl study --model pedagogical: one maxent solve per map, the teaching model's "
                  "log-likelihoods of every episode of every row at every λ", version=1)
#: Registered as the entry point ``user-study`` (group ``expertise_irl.studies``, in pyproject.toml).
STUDIES = (DISCRETE, CONTINUOUS, OPTIMAL, TEACHING)
