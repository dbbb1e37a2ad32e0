"""Which observation model fits each participant of a discrete study (``study --models``).

For every model m named by ``--models`` the study's discrete inference phase runs once more
with that model (its own engine sweep, ``DIR/engine/inference-<m>``; the sweep of ``--model``
is the main one), and for each participant, over the hypothesis set Ψ with the study's prior
(uniform, with any feature constant at 0 on all their tasks kept at θ_i = 0) and all their
tasks, shared as ``--share`` says (:mod:`.posteriors`):

- **log evidence** ``log P(Ξ | m)``: ``logsumexp_h(log P(h) + Σ_t log P(Ξ_t | h, m))`` with
  ``--share both``; with ``--share beta`` the product over tasks of each task's θ-marginal;
- **log Bayes factor** against the participant's best model, ``log P(Ξ | m) − max_m'
  log P(Ξ | m')`` (≤ 0; 0 for the best), read as in ``compare-models``;
- **held-out log-likelihood per action**: the study's held-out check
  (:func:`.posteriors.heldout_check`: leave-one-episode-out within tasks of ≥ 2 episodes,
  else leave-one-task-out with ``--share both``) under each model. ``unavailable`` says why a
  participant has none.

``pedagogical`` (``--share both`` only; :mod:`.teaching`) is the teacher's evidence, ``log
mean_{λ > 0} P(Ξ | λ)`` over the grid's positive teaching weights, so that minus ``maxent``'s it is
the Bayes factor of teaching against doing; its held-out check is over Ψ × Λ, its β̂ and θ̂ λ's
marginal, and its entry adds ``teaching`` (λ̂, its interval, the verdict, ``maxent``'s β̂), which
``models.csv`` carries in :data:`.teaching.MODELS_TEACHING_COLUMNS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import InputError
from ..inference.evidence import bayes_factor_reading, check_model_list
from ..inference.pedagogical import LAMBDAS, parse_lambdas
from ..models import PEDAGOGICAL
from . import posteriors
from .teaching import MODELS_TEACHING_COLUMNS, teaching_columns, teaching_fit


def parse_models(spec: str) -> tuple[str, ...]:
    """``--models M1,M2,...`` as a tuple of known, distinct models."""
    return check_model_list([m.strip() for m in spec.split(",") if m.strip()])


def check_models(models: Sequence[str], method: str) -> None:
    """``--models`` is for ``--method discrete`` only (evidence is a sum over the hypothesis set); what
    ``pedagogical`` needs besides is checked by :func:`.teaching.check_teaching`."""
    if models and method != "discrete":
        raise InputError(f"--models needs --method discrete (got --method {method})")
    if models:
        parse_models(",".join(models))


def participant_evidence(manifest, lls: dict[str, dict[int, np.ndarray]], hypotheses, share: str = "both",
                         zero_features: dict[str, list[int]] | None = None,
                         lambdas=LAMBDAS) -> dict[str, dict[str, Any]]:
    """Per participant, the ``model_evidence`` of their ``result.json``.

    ``lls[m][row]`` is the ``[E, H]`` per-episode log-likelihood of manifest row ``row`` under
    model ``m`` (``pedagogical``: ``[E, L, H]``, at each λ of ``lambdas``); ``zero_features[pid]``
    the features kept at θ_i = 0 for that participant.
    """
    zero_features = zero_features or {}
    lam = parse_lambdas(lambdas)
    out = {}
    for pid in manifest.participants:
        mine = manifest.tasks_of(pid)
        hyp = hypotheses[mine[0].mdp.n_features] if isinstance(hypotheses, dict) else hypotheses
        H = len(hyp)
        zero = zero_features.get(pid, [])
        actions = [[len(s) for s, _ in t.trajectories.episodes()] for t in mine]
        fits, held = [], None
        for m, ll in lls.items():
            ep = [ll[t.index] for t in mine]
            if m == PEDAGOGICAL:
                fit = teaching_fit(ep, actions, hyp, zero, lam, sum(len(t.trajectories) for t in mine),
                                   mine[0].mdp.n_actions)
                held = fit.pop("heldout")
            else:
                fit, held = _doer_fit(m, ep, actions, hyp, share, zero)
            fits.append(fit)
        best = max(f["log_evidence"] for f in fits)
        best_model = next(f["model"] for f in fits if f["log_evidence"] == best) if best > -math.inf else None
        for f in fits:
            f["log_bayes_factor"] = f["log_evidence"] - best if best_model else math.nan
            f["reading"] = bayes_factor_reading(f["log_bayes_factor"]) if best_model else None
        episodes = sum(t.trajectories.n_episodes for t in mine)
        test_episodes = (held["units"] if held["split"] == "episode"
                         else sum(t.trajectories.n_episodes for t in mine) if held["split"] == "task" else 0)
        doc: dict[str, Any] = {
            "best": best_model,
            "prior": "uniform" + (f" (θ_{', θ_'.join(str(i) for i in zero)} kept at 0)" if zero else ""),
            "n_hypotheses": H,
            "share": share,
            "models": fits,
            "heldout": {
                "rule": posteriors.HELDOUT_RULE,
                "split": held["split"],
                "fit_episodes": episodes,
                "test_episodes": test_episodes,
                "test_actions": held["actions"],
            },
            "unavailable": {},
        }
        if held["unavailable"]:
            doc["unavailable"]["heldout_log_likelihood_per_action"] = f"{pid}: {held['unavailable']}"
        out[pid] = doc
    return out


def _doer_fit(m: str, ep: list[np.ndarray], actions, hyp, share: str, zero) -> tuple[dict[str, Any], dict]:
    """A model with a Bellman backup: its entry of ``model_evidence`` and its held-out check's dict."""
    task_ll = [e.sum(axis=0) for e in ep]
    z = posteriors.log_evidence(task_ll, hyp, share, zero)
    held = posteriors.heldout_check(ep, actions, hyp, share, zero)
    if share == "both" and math.isfinite(z):
        p = np.exp(np.sum(task_ll, axis=0) + posteriors.log_prior_joint(hyp, zero) - z)
        beta_hat, theta_hat = float(p @ hyp.beta), (p @ hyp.theta).tolist()
    elif math.isfinite(z):
        sb = posteriors.shared_beta_posterior(task_ll, hyp, zero)
        beta_hat, theta_hat = sb.mean_beta, None
    else:
        beta_hat, theta_hat = math.nan, None
    return ({"model": m, "log_evidence": z, "beta_hat": beta_hat, "theta_hat": theta_hat,
             "heldout_log_likelihood_per_action": held["per_action"]}, held)


def models_columns(models: Sequence[str]) -> list[str]:
    """``models.csv``'s columns: each model's evidence, Bayes factor and held-out score, and with
    ``pedagogical`` its λ̂, interval, Bayes factor of teaching, verdict and the two β̂."""
    return [
        "participant",
        *(f"log_evidence_{m}" for m in models),
        "best_model",
        *(f"log_bf_{m}" for m in models),
        "heldout_split",
        "heldout_episodes",
        "heldout_actions",
        *(f"heldout_per_action_{m}" for m in models),
        *(MODELS_TEACHING_COLUMNS if PEDAGOGICAL in models else ()),
    ]


def models_rows(evidence: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One ``models.csv`` row per participant (NaN, written empty, where a value is undefined)."""
    rows = []
    for pid, doc in evidence.items():
        r: dict[str, Any] = {
            "participant": pid,
            "best_model": doc["best"] or "",
            "heldout_split": doc["heldout"]["split"],
            "heldout_episodes": doc["heldout"]["test_episodes"],
            "heldout_actions": doc["heldout"]["test_actions"],
        }
        for f in doc["models"]:
            m, held = f["model"], f["heldout_log_likelihood_per_action"]
            r[f"log_evidence_{m}"] = float(f["log_evidence"])
            r[f"log_bf_{m}"] = float(f["log_bayes_factor"])
            r[f"heldout_per_action_{m}"] = math.nan if held is None else float(held)
            if m == PEDAGOGICAL:
                r.update(teaching_columns(f.get("teaching")), beta_hat_pedagogical=float(f["beta_hat"]))
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
        "> 10 very strong). Held-out: log-likelihood per held-out action "
        f"({posteriors.HELDOUT_RULE}). The tables above use --model {main_model}."
        + (" pedagogical's is a teacher's, log of the mean of P(Ξ | λ) over the grid's λ > 0 (its held-out "
           "check over every (h, λ)): minus maxent's it is the Bayes factor of teaching against doing "
           "(below)." if PEDAGOGICAL in models else ""),
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
