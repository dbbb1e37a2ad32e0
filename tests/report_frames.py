"""Hand-made sweeps for the report tests: rows with the studies' contract columns, written as a sweep DIR."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from expertise_irl.experiments.store import Store
from expertise_irl.hypotheses import expertise_group

FEATURES = ("length", "road", "avoid", "slow", "traffic")
#: ‖θ̂‖₁ of every birl_box row of :func:`optimisation_rows`.
BOX_L1 = 0.8
GROUP_BETAS = {"high": (0.01, 0.09), "medium": (0.5, 1.0), "low": (5.0, 10.0)}


def group_of(beta: float) -> str:
    """The group the studies write for β (the library's boundaries)."""
    return expertise_group(beta)


#: The record ``experiment run`` writes in ``runs/`` for one local worker (``run_record`` varies it).
RUN = {"started": "2026-01-01T00:00:00Z", "engine": "local", "scheduler": None, "workers": 1,
       "retry_failed": False, "tasks_to_run": 2}


def run_record(**changes) -> dict:
    return {**RUN, **changes}


def write_sweep(root: Path, study: str, rows: pd.DataFrame, config: dict, *, tasks: int = 2,
                done: int | None = None, timings: list[float] | None = None,
                keys: list[str] | None = None, timing_columns: list[dict] | None = None,
                runs: list[dict] | None = None) -> Path:
    """A sweep DIR as the engine leaves it: manifest, ``rows/`` split over ``done`` of ``tasks`` shards,
    ``timings/`` (``wall_time_s`` from ``timings``, more columns per task from ``timing_columns``) and
    ``runs/*.json`` (default: one run with one local worker)."""
    root = Path(root)
    store = Store(root)
    keys = keys or [f"t{i:03d}" for i in range(tasks)]
    tasks = len(keys)
    manifest = {"study": study, "study_version": 1, "scale": "custom", "seed": 0, "config": config,
                "layout_version": 1, "config_hash": "0" * 64, "task_keys": keys,
                "created": "2026-01-01T00:00:00Z", "versions": {"expertise-irl": "test"},
                "machine": {"host": "test", "cpus": 1}}
    root.mkdir(parents=True)
    store._make_dirs()
    (root / "manifest.json").write_text(json.dumps(manifest))
    done = tasks if done is None else done
    parts = np.array_split(np.arange(len(rows)), done)
    for i, idx in enumerate(parts):
        store.write_table("rows", keys[i], pa.Table.from_pandas(rows.iloc[idx], preserve_index=False))
        t = (timings or [1.0] * done)[i]
        extra = (timing_columns or [{}] * done)[i]
        store.write_table("timings", keys[i], pa.table({"task": [keys[i]], "wall_time_s": [float(t)],
                                                        **{k: [v] for k, v in extra.items()}}))
    (root / "runs").mkdir(exist_ok=True)
    for j, record in enumerate([run_record(tasks_to_run=tasks)] if runs is None else runs):
        (root / "runs" / f"2026-01-01T00000{j}Z-{j}.json").write_text(json.dumps(record))
    return root


def _theta(rng, n):
    t = rng.random((n, 5))
    return t / t.sum(axis=1, keepdims=True)


def optimisation_rows(seed: int = 0, environments: int = 2, instances: int = 6, counts=(10, 20, 30, 40),
                      methods=("discrete", "birl_box", "birl_simplex", "map", "nuts"),
                      nuts_instances: int = 3) -> pd.DataFrame:
    """Rows of the ``optimisation`` contract; metrics improve with episodes, birl_box beats discrete
    (its θ̂ has ‖θ̂‖₁ = :data:`BOX_L1`)."""
    rng = np.random.default_rng(seed)
    recs = []
    for e in range(environments):
        states = 100 + 50 * e
        for i in range(instances):
            beta = float(rng.uniform(0.01, 5))
            theta = _theta(rng, 1)[0]
            for m in methods:
                if m == "nuts" and i >= nuts_instances:
                    continue
                for n in counts:
                    capped = n if beta > 0.5 else n // 4
                    scale = {"discrete": 1.0, "birl_box": 0.5}.get(m, 0.6)
                    rec = {"seed": 0, "environment": e, "instance": i, "method": m, "episodes": n,
                           "n_pairs": n * 40, "n_capped": capped, "mean_episode_length": 40.0 + 50 * beta
                           + rng.normal(0, 1), "map_width": 10, "map_height": 10, "n_states": states,
                           "n_hypotheses": 120 if m == "discrete" else 0, "beta_true": beta,
                           "group_true": group_of(beta),
                           **{f"theta_true_{f}": theta[j] for j, f in enumerate(FEATURES)},
                           "theta_k_truth_similarity": rng.random(), "theta_k_diversity": rng.random(),
                           "beta_set_distance": rng.random(),
                           "prior": "uniform" if m == "discrete" else "paper",
                           "prior_text": "uniform over Ψ_20" if m == "discrete"
                           else "θ ~ U[0,1]^5, β ~ N(5.005, 1.5)",
                           "beta_hat": beta + rng.normal(0, 0.1), "expertise_distance":
                           scale * (1 + rng.random()) * 10 / n,
                           "cosine_similarity": min(1.0, (0.85 if m == "discrete" else 0.9)
                                                    + rng.normal(0, 0.02)),
                           "policy_regret": scale * (1 + rng.random()) / n,
                           "wall_time_s": (1.0 if m == "discrete" else 4.0) * n / 10
                           * (1 + 0.1 * rng.random()),
                           "acceptance_rate": 0.3 if m.startswith("birl") else np.nan,
                           "divergences": 0.0 if m == "nuts" else np.nan,
                           "max_rhat": 1.01 if m == "nuts" else np.nan}
                    for j, f in enumerate(FEATURES):  # birl_box's E[θ] off the simplex, as it comes out
                        rec[f"theta_hat_{f}"] = theta[j] * (BOX_L1 if m == "birl_box" else 1.0)
                    recs.append(rec)
    return pd.DataFrame(recs)


def conditions_like_rows(seed: int = 0, ks=(20, 40, 60, 80, 100), runs: int = 3, episodes: int = 20,
                         conditions=("full",)) -> pd.DataFrame:
    """Rows of the ``conditions`` schema (as ``cardinality`` writes them): one environment."""
    rng = np.random.default_rng(seed)
    recs = []
    for k in ks:
        for r in range(runs):
            for g in ("high", "medium", "low"):
                for t in ("in_set", "out_of_set"):
                    beta = (float(rng.choice(GROUP_BETAS[g])) if t == "in_set"
                            else float(rng.uniform(0.01, 10)))
                    theta = _theta(rng, 1)[0]
                    for c in conditions:
                        for n in range(1, episodes + 1):
                            gap = 3.0 if t == "out_of_set" else 1.0
                            recs.append({
                                "seed": 0, "environment": 0, "run": r, "k": k, "group": g, "truth": t,
                                "condition": c, "method": "discrete", "episodes": n, "n_pairs": 30 * n,
                                "n_capped": n if beta > 0.5 else 0, "map_width": 8, "map_height": 8,
                                "n_states": 50, "n_hypotheses": 6 * k, "beta_true": beta,
                                "group_true": group_of(beta),
                                **{f"theta_true_{f}": theta[j] for j, f in enumerate(FEATURES)},
                                "fixed_beta": np.nan, **{f"fixed_theta_{f}": np.nan for f in FEATURES},
                                "beta_hat": beta, "group_hat": group_of(beta),
                                **{f"theta_hat_{f}": theta[j] for j, f in enumerate(FEATURES)},
                                "p_group_true": 0.9, "truth_probability": 0.5 if t == "in_set" else np.nan,
                                "entropy": 1.0, "theta_k_truth_similarity": rng.random(),
                                "theta_k_diversity": rng.random(), "beta_set_distance": rng.random(),
                                "expertise_distance": gap * (0.5 + rng.random()) / n,
                                "cosine_similarity": 1 - gap * 0.05 * rng.random() - k / 2000,
                                "policy_regret": gap * (0.01 + 0.01 * rng.random()) * (1 + k / 100) / n})
    return pd.DataFrame(recs)


def fullset_rows(seed: int = 0, truth_column: bool = True) -> pd.DataFrame:
    """Rows of the ``fullset`` contract, with the study's ``truth`` column or (``truth_column=False``)
    without it, then with conditions' out-of-set people only (one person per slot)."""
    rng = np.random.default_rng(seed)
    recs = []
    people = [("conditions", e, r, 20, g, -1, t) for e in range(2) for r in range(3)
              for g in ("high", "medium", "low") for t in ("in_set", "out_of_set")
              if truth_column or t == "out_of_set"]
    people += [("optimisation", e, -1, 20, "", i, "out_of_set") for e in range(2) for i in range(5)]
    for source, e, r, k, g, i, t in people:
        beta = float(rng.choice(GROUP_BETAS[g])) if t == "in_set" else float(rng.uniform(0.01, 5))
        theta = _theta(rng, 1)[0]
        top = 20 if source == "conditions" else 40
        for s in ("theta_k", "full"):
            for n in range(1, top + 1):
                bad = 3.0 if (t == "out_of_set" and s == "theta_k") else 1.2 if t == "out_of_set" else 1.0
                recs.append({
                    "seed": 0, "environment": e, "source": source, **({"truth": t} if truth_column else {}),
                    "run": r, "k": k, "group": g,
                    "instance": i, "set": s, "episodes": n, "n_pairs": 30 * n,
                    "n_capped": n if beta > 0.5 else 0, "n_states": 60 + e,
                    "n_hypotheses": 18186 if s == "full" else 6 * k, "beta_true": beta,
                    "group_true": group_of(beta),
                    **{f"theta_true_{f}": theta[j] for j, f in enumerate(FEATURES)},
                    "beta_hat": beta, **{f"theta_hat_{f}": theta[j] for j, f in enumerate(FEATURES)},
                    "expertise_distance": bad * (0.5 + rng.random()) / n,
                    "cosine_similarity": 1 - bad * 0.05 * rng.random(),
                    "policy_regret": bad * (0.01 + 0.01 * rng.random()) / n,
                    "truth_probability": 0.4 if t == "in_set" else np.nan,
                    "set_solve_time_s": 12.0 + e})
    return pd.DataFrame(recs)


def conditions_rows(seed: int = 0, environments: int = 3, runs: int = 2, ks=(5, 10), episodes: int = 20,
                    low_episodes: int = 40) -> pd.DataFrame:
    """Rows of the ``conditions`` contract over several maps: in-set people under Full, Fixed θ and
    Fixed β (low-expertise ones up to ``low_episodes``), out-of-set people under Full. Full is better
    than both fixed conditions and improves with episodes; Fixed θ's β distance does not; every
    in-set person's group is right from 3 episodes on and wrong at 1 for every other person."""
    rng = np.random.default_rng(seed)
    recs = []
    for e in range(environments):
        for r in range(runs):
            for k in ks:
                for g in ("high", "medium", "low"):
                    for t in ("in_set", "out_of_set"):
                        recs += _person_rows(rng, e, r, k, g, t, episodes, low_episodes)
    return pd.DataFrame(recs)


def _person_rows(rng, e, r, k, g, t, episodes, low_episodes) -> list[dict]:
    beta = float(rng.choice(GROUP_BETAS[g])) if t == "in_set" else float(rng.uniform(0.01, 10))
    theta = _theta(rng, 1)[0]
    top = low_episodes if (t == "in_set" and g == "low") else episodes
    wrong_at_1 = bool(rng.random() < 0.5)
    base = {"seed": 0, "environment": e, "run": r, "k": k, "group": g, "truth": t, "method": "discrete",
            "map_width": 10, "map_height": 10, "n_states": 80 + 10 * e, "n_hypotheses": 6 * k,
            "beta_true": beta, "group_true": group_of(beta),
            **{f"theta_true_{f}": theta[j] for j, f in enumerate(FEATURES)},
            "theta_k_truth_similarity": rng.random(), "theta_k_diversity": rng.random(),
            "beta_set_distance": rng.random(), "entropy": 1.0, "p_group_true": 0.9,
            "truth_probability": 0.5 if t == "in_set" else np.nan}
    gap = 3.0 if t == "out_of_set" else 1.0
    out = []
    for c in (("full", "fixed_theta", "fixed_beta") if t == "in_set" else ("full",)):
        noise = rng.random()
        for n in range(1, top + 1):
            full = c == "full"
            right = not (n == 1 and wrong_at_1) and (full or n >= 3)
            out.append({**base, "condition": c, "episodes": n, "n_pairs": 30 * n,
                        "n_capped": n if beta > 0.5 else 0, "fixed_beta": np.nan,
                        **{f"fixed_theta_{f}": np.nan for f in FEATURES}, "beta_hat": beta,
                        "group_hat": group_of(beta) if right else "nobody",
                        **{f"theta_hat_{f}": theta[j] for j, f in enumerate(FEATURES)},
                        "expertise_distance": (gap * (0.5 + noise) / n if c != "fixed_theta"
                                               else 2.0 + 0.1 * noise),
                        "cosine_similarity": 1 - gap * 0.05 * noise - (0.2 if c == "fixed_beta" else 0),
                        "policy_regret": gap * (0.01 + 0.01 * noise) / n * (10 if c == "fixed_beta" else 1)})
    return out
