"""Which observation model fits each participant of a discrete study (``study --models``).

For every model m named by ``--models`` the study's discrete inference phase runs once more
with that model (its own engine sweep, ``DIR/engine/inference-<m>``; the sweep of ``--model``
is the main one), and for each participant, over the hypothesis set Ψ with a uniform prior
and all their tasks t:

- **log evidence** ``log P(Ξ | m) = logsumexp_h(Σ_t log P(Ξ_t | h, m)) − log |Ψ|``;
- **log Bayes factor** against the participant's best model, ``log P(Ξ | m) − max_m'
  log P(Ξ | m')`` (≤ 0; 0 for the best), read as in ``compare-models``;
- **held-out log-likelihood per action**: the last episode (in file order) of every task
  with at least two episodes is held out, the posterior from everything else (the other
  episodes and every single-episode task) predicts it:
  ``(logsumexp_h(ll_fit + ll_test) − logsumexp_h(ll_fit)) / n_test_actions``. A
  participant without a task of two episodes has no held-out check (``unavailable`` says
  why).

The held-out split rides on the discrete phase: the study's engine data gets, for each
manifest row with two or more episodes, two more rows (``part`` = ``fit`` / ``heldout``),
whose log-likelihoods the phase returns like any row's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.special import logsumexp

from ..errors import InputError
from ..inference.evidence import bayes_factor_reading, check_model_list

FIT, HELDOUT = "fit", "heldout"


def parse_models(spec: str) -> tuple[str, ...]:
    """``--models M1,M2,...`` as a tuple of known, distinct models."""
    return check_model_list([m.strip() for m in spec.split(",") if m.strip()])


def check_models(models: Sequence[str], method: str) -> None:
    """``--models`` is for ``--method discrete`` only (evidence is a sum over the hypothesis set)."""
    if models and method != "discrete":
        raise InputError(f"--models needs --method discrete (got --method {method})")
    if models:
        parse_models(",".join(models))


def split_rows(tasks: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The extra engine rows: each row with ≥ 2 episodes as its fit part and its last episode."""
    extra = []
    n = max((t["task"] for t in tasks), default=-1) + 1
    for t in tasks:
        ids = list(dict.fromkeys(t["episodes"]))
        if len(ids) < 2:
            continue
        last = np.asarray(t["episodes"]) == ids[-1]
        for part, mask in ((FIT, ~last), (HELDOUT, last)):
            row = {k: t[k] for k in ("participant", "map")}
            for k in ("episodes", "steps", "states", "actions"):
                row[k] = np.asarray(t[k])[mask].tolist()
            row.update({"task": n + len(extra), "part": part, "row": t["task"]})
            extra.append(row)
    return extra


def _lse(x: np.ndarray) -> float:
    with np.errstate(divide="ignore"):
        return float(logsumexp(x))


def participant_evidence(
    tasks: Sequence[dict[str, Any]], lls: dict[str, dict[int, np.ndarray]], hypotheses
) -> dict[str, dict[str, Any]]:
    """Per participant, the ``model_evidence`` of their ``result.json``.

    ``tasks`` are the engine rows (manifest rows and their parts, :func:`split_rows`);
    ``lls[m][row]`` is the ``[H]`` log-likelihood of engine row ``row`` under model ``m``.
    """
    H = len(hypotheses)
    rows = [t for t in tasks if "part" not in t]
    parts = {(t["row"], t["part"]): t for t in tasks if "part" in t}
    out = {}
    for pid in dict.fromkeys(t["participant"] for t in rows):
        mine = [t for t in rows if t["participant"] == pid]
        held = [parts[(t["task"], HELDOUT)] for t in mine if (t["task"], HELDOUT) in parts]
        fits = []
        for m, ll in lls.items():
            total = np.sum([ll[t["task"]] for t in mine], axis=0)
            z = _lse(total)
            p = np.exp(total - z) if math.isfinite(z) else None  # the posterior (uniform prior)
            fit = {
                "model": m,
                "log_evidence": z - math.log(H),
                "beta_hat": float(p @ hypotheses.beta) if p is not None else math.nan,
                "theta_hat": (p @ hypotheses.theta).tolist() if p is not None else None,
                "heldout_log_likelihood_per_action": None,
            }
            if held:
                ll_fit = np.sum(
                    [ll[parts[(t["task"], FIT)]["task"]] if (t["task"], FIT) in parts else ll[t["task"]]
                     for t in mine],
                    axis=0,
                )
                ll_test = np.sum([ll[h["task"]] for h in held], axis=0)
                z_fit = _lse(ll_fit)
                if math.isfinite(z_fit):
                    n_test = sum(len(h["actions"]) for h in held)
                    fit["heldout_log_likelihood_per_action"] = (_lse(ll_fit + ll_test) - z_fit) / n_test
            fits.append(fit)
        best = max(f["log_evidence"] for f in fits)
        best_model = next(f["model"] for f in fits if f["log_evidence"] == best) if best > -math.inf else None
        for f in fits:
            f["log_bayes_factor"] = f["log_evidence"] - best if best_model else math.nan
            f["reading"] = bayes_factor_reading(f["log_bayes_factor"]) if best_model else None
        episodes = sum(len(dict.fromkeys(t["episodes"])) for t in mine)
        doc: dict[str, Any] = {
            "best": best_model,
            "prior": "uniform",
            "n_hypotheses": H,
            "models": fits,
            "heldout": {
                "rule": "the last episode of each task with at least 2 episodes",
                "fit_episodes": episodes - len(held),
                "test_episodes": len(held),
                "test_actions": sum(len(h["actions"]) for h in held),
            },
            "unavailable": {},
        }
        if not held:
            doc["unavailable"]["heldout_log_likelihood_per_action"] = (
                f"the held-out check needs a task with at least 2 episodes; {pid}'s "
                f"{len(mine)} task(s) have {episodes} episode(s) in all"
            )
        out[pid] = doc
    return out


def models_columns(models: Sequence[str]) -> list[str]:
    return [
        "participant",
        *(f"log_evidence_{m}" for m in models),
        "best_model",
        *(f"log_bf_{m}" for m in models),
        "heldout_episodes",
        "heldout_actions",
        *(f"heldout_per_action_{m}" for m in models),
    ]


def models_rows(evidence: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One ``models.csv`` row per participant (NaN, written empty, where a value is undefined)."""
    rows = []
    for pid, doc in evidence.items():
        r: dict[str, Any] = {
            "participant": pid,
            "best_model": doc["best"] or "",
            "heldout_episodes": doc["heldout"]["test_episodes"],
            "heldout_actions": doc["heldout"]["test_actions"],
        }
        for f in doc["models"]:
            m, held = f["model"], f["heldout_log_likelihood_per_action"]
            r[f"log_evidence_{m}"] = float(f["log_evidence"])
            r[f"log_bf_{m}"] = float(f["log_bayes_factor"])
            r[f"heldout_per_action_{m}"] = math.nan if held is None else float(held)
        rows.append(r)
    return rows


def evidence_markdown(evidence: dict[str, dict[str, Any]], models: Sequence[str], main_model: str) -> str:
    """The ``study.md`` section: each model's log evidence, Bayes factor and held-out check."""
    if not evidence:
        return ""
    H = next(iter(evidence.values()))["n_hypotheses"]
    lines = [
        "",
        "## Model evidence",
        "",
        f"Log evidence log Σ_h P(Ξ | h) P(h) of all of a participant's tasks over the {H} hypotheses "
        "(uniform prior), per observation model; log BF = log evidence − the participant's best "
        "(0 for the best; 2 |log BF| < 2 barely worth mentioning, 2–6 positive, 6–10 strong, "
        "> 10 very strong). Held-out: log-likelihood per action of the last episode of each task with "
        f"at least 2 episodes, predicted from the rest. The tables above use --model {main_model}.",
        "",
        "| participant | " + " | ".join(f"log evidence ({m})" for m in models) + " | best | "
        + " | ".join(f"log BF ({m})" for m in models) + " | held-out actions | "
        + " | ".join(f"held-out / action ({m})" for m in models) + " |",
        "|---" * (3 + 3 * len(models)) + "|",
    ]

    def num(x: float | None, fmt: str) -> str:
        return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)

    for pid, doc in evidence.items():
        by = {f["model"]: f for f in doc["models"]}
        n_test = doc["heldout"]["test_actions"]
        lines.append(
            f"| {pid} | "
            + " | ".join(num(by[m]["log_evidence"], ".2f") for m in models)
            + f" | {doc['best'] or 'n/a'} | "
            + " | ".join(num(by[m]["log_bayes_factor"], ".2f") for m in models)
            + f" | {n_test or 'n/a'} | "
            + " | ".join(num(by[m]["heldout_log_likelihood_per_action"], ".4f") for m in models)
            + " |"
        )
    return "\n".join(lines) + "\n"
