"""The engine's side of ``expertise-irl study``: the tasks of a user study (Sec. VIII).

Three studies, each a pure function of a config that carries the study's data (floor plans
as text and every task's (state, action) pairs, as one JSON string), so workers need no
access to the participants' files and a changed input is a different sweep:

- ``user-study-discrete``: one task per distinct floor plan. It solves the hypothesis set
  once on that plan and returns, for every manifest row on it, the log-likelihood of each
  hypothesis: participants who share a map share one solve.
- ``user-study-continuous``: one task per participant (``--method map|nuts``), the
  log-likelihoods of all their tasks summed.
- ``user-study-optimal``: one task per floor plan; it solves β = 0.001 for the estimates θ̂
  of every participant with a task on it and follows the most probable action from each
  episode's start (Table VI).
"""

from __future__ import annotations

import json
import time
import zlib
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import InputError
from ..experiments.spec import Column, Study, TaskSpec

METHODS = ("discrete", "map", "nuts")


@dataclass(frozen=True)
class UserStudyConfig:
    """Data and options of one user study (the CLI builds it from the manifest)."""

    data: str  # JSON: {"maps": {key: plan}, "tasks": [task]} (see userstudy.run)
    thetas: str = "paper-real"
    betas: str = "paper-real"
    model: str = "maxent"
    method: str = "discrete"
    prior: str = "log-uniform"
    starts: int = 4
    chains: int = 4
    warmup: int = 500
    samples: int = 500

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise InputError(f"--method must be one of {', '.join(METHODS)}, got {self.method!r}")


@lru_cache(maxsize=4)
def _data(text: str) -> dict:
    return json.loads(text)


@lru_cache(maxsize=16)
def _plan_mdp(text: str, key: str):
    from ..worlds.warehouse import parse_floor_plan

    p = _data(text)["maps"][key]
    plan = parse_floor_plan(
        p["text"],
        name=p["name"],
        cell_size=p["cell_size"],
        goal_bonus=p["goal_bonus"],
        gamma=p["gamma"],
        y_up=p["y_up"],
        goal_reward_mode=p.get("goal_reward_mode", "scaled"),
    )
    return plan, plan.to_mdp()


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
    """Log-likelihood of every hypothesis for every manifest row on one floor plan."""
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
    cols = {"task": [], "participant": [], "hypothesis": [], "log_likelihood": []}
    for t in rows:
        cols["task"].append(np.full(H, t["task"]))
        cols["participant"].append(np.full(H, t["participant"], dtype=object))
        cols["hypothesis"].append(np.arange(H))
        cols["log_likelihood"].append(log_likelihood(sol.log_policy, t["states"], t["actions"]))
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
    """MAP or NUTS on all of one participant's tasks (their log-likelihoods summed)."""
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
    opts = method.options_from(dict(
        starts=cfg.starts,
        chains=cfg.chains,
        warmup=cfg.warmup,
        samples=cfg.samples,
        prior=cfg.prior,
        model=cfg.model,
    ))
    res = method.run(mdps, trajs, opts, participant_seed(pid) + int(seed)).fields
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
    solves (values move within the tolerance)."""
    return Study(name=name, version=version,
                 description=description, config_type=UserStudyConfig, scales={}, tasks=tasks,
                 run_task=run_task, columns=columns, sort_by=sort_by)


_DISCRETE_COLUMNS = (_TASK, _PARTICIPANT,
                     Column("hypothesis", "int32", "hypothesis index (θ-major, β fastest)"),
                     Column("log_likelihood", "float64", "log P(Ξ_row | h) (−inf: impossible)"))
_CONTINUOUS_COLUMNS = (_PARTICIPANT, Column("result", "string", "the method's result fields (JSON)"))
_OPTIMAL_COLUMNS = (_TASK, _PARTICIPANT, Column("episode", "int32", "episode of the row (0-based)"),
                    Column("step", "int32", "step"), Column("state", "int64", "state"),
                    Column("action", "int32", "action"),
                    Column("reached_goal", "bool", "the path ends in a goal"))

DISCRETE = _study("user-study-discrete", _map_tasks, run_discrete, _DISCRETE_COLUMNS, ("task", "hypothesis"),
                  "expertise-irl study: one solve per floor plan, log-likelihoods of every manifest row")
CONTINUOUS = _study("user-study-continuous", _participant_tasks, run_continuous, _CONTINUOUS_COLUMNS,
                    ("participant",), "expertise-irl study --method map|nuts: one task per participant")
OPTIMAL = _study("user-study-optimal", _map_tasks, run_optimal, _OPTIMAL_COLUMNS, ("task", "episode", "step"),
                 "expertise-irl study: optimal paths (β = 0.001, θ̂) per floor plan")
#: Registered as the entry point ``user-study`` (group ``expertise_irl.studies``, in pyproject.toml).
STUDIES = (DISCRETE, CONTINUOUS, OPTIMAL)
