"""Teaching or doing, per participant of a discrete study (``study --model pedagogical`` and
``--models ...,pedagogical``).

The engine's ``user-study-pedagogical`` sweep gives, for every episode e of every task t of a
participant, the teaching model's log-likelihood ``ll[t][e, λ, h]`` of each hypothesis h of the
study's set at each teaching weight λ of the grid (:mod:`..inference.pedagogical`; the literal
observer believes the set with a uniform prior on each map). With the prior P(h) of the study
(:func:`.posteriors.log_prior_joint`: uniform, a participant's all-zero features kept at 0) and λ's
(half on λ = 0, the doer; half spread over the positive λ), ``--share both``:

- the posterior over Ψ × Λ, ``P(h, λ | Ξ) ∝ P(h) P(λ) Π_t Π_e P(ξ_te | h, λ)``; β̂ and θ̂ are its
  marginal over Ψ (λ marginalised), λ̂ with its 90% interval its marginal over Λ, and the verdict
  is read from the Bayes factor of teaching against doing (``TeachingPosterior.record``);
- the held-out check over Ψ × Λ (:func:`.posteriors.heldout_check` with λ's prior);
- in ``models.csv``, the teacher's log evidence, ``log mean_{λ > 0} P(Ξ | λ)``, as
  ``compare-models`` gives it: minus ``maxent``'s it is the Bayes factor of teaching.

What the study cannot do with the teaching model is refused by :func:`check_teaching`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import InputError
from ..inference.evidence import teacher_log_evidence, teaching_entry
from ..inference.pedagogical import TeachingPosterior, lambda_log_prior
from ..models import PEDAGOGICAL
from . import posteriors
from .study import DEFAULT_LAMBDAS

#: ``study.csv``'s columns of ``--model pedagogical`` (β̂ is the teaching model's, λ marginalised).
TEACHING_COLUMNS = ("lambda_hat", "lambda_q05", "lambda_q95", "teaching_log_bf", "teaching_verdict",
                    "beta_hat_maxent")
#: ``models.csv``'s columns of the pedagogical model (with ``--models ...,pedagogical``).
MODELS_TEACHING_COLUMNS = (*TEACHING_COLUMNS[:5], "beta_hat_pedagogical", "beta_hat_maxent")
VERDICTS = ("teaching", "doing", "undecided")


def solved_model(model: str) -> str:
    """The model a solver takes for ``model``: ``maxent`` for the teaching model (its values are the
    doer's), else ``model``."""
    return "maxent" if model == PEDAGOGICAL else model


def asks_teaching(opts) -> bool:
    """Whether the study fits the teaching model: ``--model pedagogical`` or pedagogical in ``--models``."""
    return opts.model == PEDAGOGICAL or PEDAGOGICAL in opts.models


def check_teaching(opts, report) -> None:
    """Refuse what the study cannot do with the teaching model, naming the option.

    Args:
        opts: the study's options (:class:`.identity.StudyOptions`).
        report: its report options (:class:`.identity.ReportOptions`).

    Raises:
        InputError: ``--lambdas`` without the teaching model; with it, a method other than discrete,
            ``--share beta``; with ``--model pedagogical``, ``--expertise changing``, ``--refine`` or
            ``--population``.
    """
    main = opts.model == PEDAGOGICAL
    if not asks_teaching(opts):
        if opts.lambdas != DEFAULT_LAMBDAS:
            raise InputError("--lambdas is the pedagogical model's grid of teaching weights: use --model "
                             "pedagogical or name pedagogical in --models")
        return
    which = "--model pedagogical" if main else "pedagogical in --models"
    if opts.method != "discrete":
        raise InputError(f"--method {opts.method}: {which} needs --method discrete (the exact posterior "
                         "over the study's set and the λ grid)")
    if opts.share != "both":
        raise InputError(f"--share {opts.share}: {which} needs --share both (one θ, the one the teacher "
                         "shows, on all of a participant's tasks)")
    if not main:
        return
    if opts.expertise != "stationary":
        raise InputError(f"--expertise {opts.expertise} is not built for --model pedagogical: the teaching "
                         "model has one β and one teaching weight λ for all of a participant's episodes")
    if report.refine:
        raise InputError("--refine cannot be used with --model pedagogical: the literal observer's set is "
                         "fixed before the data, and refining it where the posterior has its mass would "
                         "change the observer with the data")
    if report.population:
        raise InputError("--population is not built for --model pedagogical: the population model pools "
                         "the participants' maxent likelihoods")


def participant_posterior(episode_ll: Sequence[np.ndarray], hyp, zero: Sequence[int], lambdas: np.ndarray,
                          n_actions: int) -> tuple[TeachingPosterior, list[np.ndarray], np.ndarray]:
    """A participant's posterior over Ψ × Λ from their tasks' ``[E_t, L, H]`` log-likelihoods.

    Args:
        episode_ll: each task's per-episode log-likelihoods at every λ and hypothesis.
        hyp: the study's set.
        zero: the participant's features kept at θ_i = 0.
        lambdas: ``[L]`` the grid.
        n_actions: the participant's number of actions.

    Returns:
        ``(posterior, flat, log_prior)``: each task's ``[E_t, L·H]`` log-likelihoods and ``[L·H]`` the
        joint log prior over Ψ × Λ (λ-major), as :func:`.posteriors.heldout_check` takes them.

    Raises:
        InputError: a sweep of another grid than ``lambdas``.
    """
    if episode_ll and episode_ll[0].shape[1] != len(lambdas):
        raise InputError(f"the teaching sweep has {episode_ll[0].shape[1]} teaching weights, the study's "
                         f"grid {len(lambdas)}")
    lp = posteriors.log_prior_joint(hyp, zero)
    ll = np.sum([e.sum(axis=0) for e in episode_ll], axis=0)  # [L, H]
    tp = TeachingPosterior(hyp, np.asarray(lambdas, dtype=np.float64), lp, ll, int(n_actions))
    flat = [e.reshape(len(e), -1) for e in episode_ll]
    return tp, flat, (lambda_log_prior(tp.lambdas)[:, None] + lp[None, :]).ravel()


def teaching_fit(episode_ll: Sequence[np.ndarray], episode_actions, hyp, zero: Sequence[int],
                 lambdas: np.ndarray, n_actions: int, n_action_kinds: int) -> dict[str, Any]:
    """The pedagogical model's entry of a participant's ``model_evidence`` (:mod:`.evidence`).

    Args:
        episode_ll: each task's ``[E_t, L, H]`` log-likelihoods.
        episode_actions: ``episode_actions[t][e]``, the actions of task t's episode e.
        hyp: the study's set.
        zero: the features kept at θ_i = 0.
        lambdas: ``[L]`` the grid.
        n_actions: the participant's number of actions.
        n_action_kinds: the maps' number of actions (the beliefs' policy shape).

    Returns:
        ``model``, the teacher's ``log_evidence``, ``beta_hat`` and ``theta_hat`` (λ marginalised),
        ``heldout_log_likelihood_per_action`` (over Ψ × Λ), ``teaching`` (None when no hypothesis
        explains the data) and ``heldout`` (the check's dict).
    """
    tp, flat, prior = participant_posterior(episode_ll, hyp, zero, lambdas, n_actions)
    held = posteriors.heldout_check(flat, episode_actions, hyp, "both", zero, log_prior=prior)
    fit = {"model": PEDAGOGICAL, "log_evidence": -math.inf, "beta_hat": math.nan, "theta_hat": None,
           "heldout_log_likelihood_per_action": held["per_action"], "teaching": None}
    if np.isfinite(tp.log_evidence_by_lambda).any():
        empty = np.zeros((len(hyp), 0, n_action_kinds))
        b = tp.belief(empty)
        fit.update(log_evidence=teacher_log_evidence(tp), beta_hat=b.mean_beta,
                   theta_hat=b.mean_theta.tolist(), teaching=teaching_entry(tp, empty))
    return {**fit, "heldout": held}


def teaching_columns(record: dict[str, Any] | None) -> dict[str, Any]:
    """:data:`TEACHING_COLUMNS` from a ``teaching`` record (NaN and empty without one)."""
    if not record:
        return {**dict.fromkeys(TEACHING_COLUMNS, math.nan), "teaching_verdict": ""}
    lo, hi = record["lambda_interval"]
    return {"lambda_hat": _f(record["lambda_hat"]), "lambda_q05": _f(lo), "lambda_q95": _f(hi),
            "teaching_log_bf": _f(record["log_bayes_factor"]), "teaching_verdict": record["verdict"],
            "beta_hat_maxent": _f(record["beta_hat_maxent"])}


def _f(x) -> float:
    return math.nan if x is None else float(x)


def teaching_markdown(records: dict[str, dict[str, Any] | None], where: str) -> str:
    """The ``study.md`` section: the count of each verdict and each participant's reading.

    Args:
        records: each participant's ``teaching`` record (None: the model explains nothing of theirs).
        where: which fit they come from (``--model pedagogical`` or ``--models``).

    Returns:
        Markdown, empty without records.
    """
    if not records:
        return ""
    counts = {v: sum(1 for r in records.values() if r and r["verdict"] == v) for v in VERDICTS}
    first = next((r for r in records.values() if r), None)
    grid = ", ".join(f"{x:g}" for x in first["lambdas"]) if first else ""
    lines = ["## Teaching or doing? (pedagogical)", "",
             f"From {where}. A demonstrator who teaches chooses actions that show a literal observer what "
             "matters, with a teaching weight λ > 0 (λ = 0 is maxent, a person doing the task); 2 log BF is "
             "the evidence for teaching against doing on the study's set (≥ 6 reads as teaching, ≤ −2 as "
             f"doing, between as undecided). λ grid: {grid}; prior half on λ = 0.", "",
             f"**Verdicts:** teaching {counts['teaching']}, doing {counts['doing']}, undecided "
             f"{counts['undecided']} (of {len(records)} participant(s)).", ""]
    for pid, r in records.items():
        if not r:
            lines.append(f"- {pid}: no hypothesis of the set explains the demonstrations")
            continue
        lo, hi = r["lambda_interval"]
        lines.append(f"- {pid}: {r['reading']}; λ̂ = {r['lambda_hat']:.3g} (90% {lo:g}–{hi:g})")
    return "\n".join(lines) + "\n\n"
