"""The typed result of one inference: frozen dataclasses, a schema version, ``to_json`` / ``from_json``.

A :class:`Result` is what :func:`expertise_irl.infer` returns and what ``infer``, ``demo``,
``study`` and ``live`` write as ``result.json``; ``plot`` and the command line read it back with
:meth:`Result.from_json`. Its parts:

- :class:`Estimate`: β̂, θ̂, the expertise group, the best point (``map``) and, by method, the
  group probabilities and entropy (discrete), the rescaled point (birl) and the 90% intervals
  (birl, map, nuts);
- :class:`DiscretePosterior`: the discrete set's posterior: :class:`Marginals`, every hypothesis
  (:class:`Hypotheses`), the log evidence and, with ``per_action``, the belief after every action
  (:class:`TraceEntry`);
- :class:`Samples`: the draws of birl and nuts, inline or the path of a CSV beside the JSON;
- :class:`Diagnostics` (warnings, statistics that could not be computed, the
  :class:`Misspecification` verdict, the identifiability of the features);
- :class:`ChangingExpertise` (``--expertise changing``: the learning curve and its evidence),
  :class:`Teaching` (``--model pedagogical``: teaching or doing, and the teaching weight λ),
  :class:`Refinement` (an adaptive set's record), :class:`Settings` (what was asked);
- ``data`` (what was read) and ``extra``: what a command adds beside the inference (``demo``'s
  truth and metrics, ``study``'s per-task counts, ``live``'s start log), carried as it is.

The JSON is the document every earlier version wrote, plus ``schema``: :data:`SCHEMA_VERSION`.
A file without ``schema`` (written before it existed) is schema 1 and loads unchanged; a newer
schema than this package knows is refused. ``Result.from_json(doc).to_json()`` equals ``doc``
for every document the package writes (a key it does not know is kept in ``extra``).

Nested values that the package records but does not interpret (a refinement round, a predictive
check's statistics) are kept as read-only mappings and tuples (:func:`freeze`); ``to_json`` turns
them back into JSON objects and arrays.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from types import MappingProxyType
from typing import Any

from .errors import InputError

#: The version of the result document's layout; a file without ``schema`` is version 1.
SCHEMA_VERSION = 1

#: The methods a result can come from, and those whose result holds posterior draws.
METHODS = ("discrete", "birl", "map", "nuts")
SAMPLED = ("birl", "nuts")



def _empty() -> Mapping[str, Any]:
    return MappingProxyType({})


def freeze(value: Any) -> Any:
    """A JSON value made read-only: objects as read-only mappings, arrays as tuples."""
    if isinstance(value, Mapping):
        return MappingProxyType({str(k): freeze(v) for k, v in value.items()})
    if isinstance(value, list | tuple):
        return tuple(freeze(v) for v in value)
    if hasattr(value, "tolist") and not isinstance(value, str):  # a NumPy array or scalar
        return freeze(value.tolist())
    return value


def thaw(value: Any) -> Any:
    """:func:`freeze` undone: plain dicts and lists, ready for :func:`json.dump`."""
    if isinstance(value, Mapping):
        return {k: thaw(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [thaw(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, str):
        return value.tolist()
    return value


def _floats(v: Sequence[Any]) -> tuple[float, ...]:
    return tuple(float(x) for x in v)


def _opt_float(v: Any) -> float | None:
    return None if v is None else float(v)


# ----------------------------------------------------------------------------- parts
@dataclass(frozen=True)
class Point:
    """One point of the posterior: the most probable hypothesis (discrete) or the best draw / mode.

    Attributes:
        theta: θ, one weight per feature.
        beta: β.
        probability: its posterior probability (discrete; None otherwise).
        log_posterior: its log posterior density (birl, map, nuts; None when not finite or discrete).
        has_log_posterior: whether the JSON holds ``log_posterior`` (null when not finite).
    """

    theta: tuple[float, ...]
    beta: float
    probability: float | None = None
    log_posterior: float | None = None
    has_log_posterior: bool = False

    def to_json(self) -> dict[str, Any]:
        """The point as a JSON object (plain values)."""
        out: dict[str, Any] = {"theta": list(self.theta), "beta": self.beta}
        if self.probability is not None:
            out["probability"] = self.probability
        if self.has_log_posterior:
            out["log_posterior"] = self.log_posterior
        return out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Point:
        """The point in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The point.
        """
        return cls(_floats(doc["theta"]), float(doc["beta"]), _opt_float(doc.get("probability")),
                   _opt_float(doc.get("log_posterior")), "log_posterior" in doc)


@dataclass(frozen=True)
class Estimate:
    """The point estimate and what is said of it.

    Attributes:
        beta_hat: β̂ (the posterior mean; map: the mode).
        theta_hat: θ̂, one weight per feature.
        expertise_group: ``high``, ``medium`` or ``low`` (:func:`~expertise_irl.hypotheses.expertise_group`).
        point: the best point (the JSON's ``map``).
        group_probabilities: the posterior mass of each expertise group (discrete).
        entropy: the posterior's entropy in nats (discrete).
        theta_hat_normalized, beta_hat_normalized: birl's estimate rescaled to ‖θ‖₁ = 1 (None on an
            MDP with a fixed goal reward).
        credible_intervals: 90% intervals of β and of each θ_i (birl, nuts; map: Laplace's); a
            withheld interval is None.
    """

    beta_hat: float
    theta_hat: tuple[float, ...]
    expertise_group: str
    point: Point | None = None
    group_probabilities: Mapping[str, float] | None = None
    entropy: float | None = None
    theta_hat_normalized: tuple[float, ...] | None = None
    beta_hat_normalized: float | None = None
    has_normalized: bool = False
    credible_intervals: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class Marginals:
    """The discrete posterior's marginals of β and of θ (values and their probabilities).

    Attributes:
        beta_values: the βs of the set.
        beta_probabilities: P(β) of each.
        theta_values: the θs of the set.
        theta_probabilities: P(θ) of each.
    """

    beta_values: tuple[float, ...]
    beta_probabilities: tuple[float, ...]
    theta_values: tuple[tuple[float, ...], ...]
    theta_probabilities: tuple[float, ...]

    def to_json(self) -> dict[str, Any]:
        """The marginals as a JSON object (plain values)."""
        return {"beta": {"values": list(self.beta_values), "probabilities": list(self.beta_probabilities)},
                "theta": {"values": [list(t) for t in self.theta_values],
                          "probabilities": list(self.theta_probabilities)}}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Marginals:
        """The marginals in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The marginals.
        """
        b, t = doc["beta"], doc["theta"]
        return cls(_floats(b["values"]), _floats(b["probabilities"]), tuple(_floats(v) for v in t["values"]),
                   _floats(t["probabilities"]))


@dataclass(frozen=True)
class Hypotheses:
    """Every hypothesis of a discrete set, column by column (row ``i`` is hypothesis ``i``).

    A log-likelihood or log posterior of −∞ (a hypothesis that cannot produce an observed action)
    is None, as the JSON's null.

    Attributes:
        theta: θ of each hypothesis.
        beta: β of each.
        log_likelihood: log P(Ξ | h) of each.
        log_posterior: its normalised log posterior.
        probability: its posterior probability.
    """

    theta: tuple[tuple[float, ...], ...]
    beta: tuple[float, ...]
    log_likelihood: tuple[float | None, ...]
    log_posterior: tuple[float | None, ...]
    probability: tuple[float, ...]

    def __len__(self) -> int:
        return len(self.beta)

    def to_json(self) -> list[dict[str, Any]]:
        """The hypotheses as JSON objects, one per row."""
        return [{"theta": list(t), "beta": b, "log_likelihood": ll, "log_posterior": lp, "probability": p}
                for t, b, ll, lp, p in zip(self.theta, self.beta, self.log_likelihood, self.log_posterior,
                                           self.probability, strict=True)]

    @classmethod
    def from_json(cls, rows: Sequence[Mapping[str, Any]]) -> Hypotheses:
        """The hypotheses in ``rows``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            rows: the JSON objects, one per hypothesis,.

        Returns:
            The hypotheses.
        """
        return cls(tuple(_floats(r["theta"]) for r in rows), tuple(float(r["beta"]) for r in rows),
                   tuple(_opt_float(r.get("log_likelihood")) for r in rows),
                   tuple(_opt_float(r.get("log_posterior")) for r in rows),
                   tuple(float(r["probability"]) for r in rows))


@dataclass(frozen=True)
class TraceEntry:
    """The belief after one action (``--per-action``); the first entry, the prior, has no action.

    Attributes:
        episode: the action's episode (None for the prior).
        step: its step in the episode (None for the prior).
        beta_hat: E[β].
        theta_hat: E[θ].
        entropy: the posterior's entropy (nats).
        group_probabilities: the posterior mass of each expertise group (None in a result written
            before traces recorded it).
        beta_band: the β marginal's 5% and 95% quantiles (None in a result written before traces
            recorded it).
    """

    episode: int | None
    step: int | None
    beta_hat: float
    theta_hat: tuple[float, ...]
    entropy: float
    group_probabilities: Mapping[str, float] | None = None
    beta_band: tuple[float, float] | None = None  # the β marginal's 5% and 95% quantiles

    def to_json(self) -> dict[str, Any]:
        """The entry as a JSON object (plain values; a part that is None is left out, as it was read)."""
        out: dict[str, Any] = {"episode": self.episode, "step": self.step, "beta_hat": self.beta_hat,
                               "theta_hat": list(self.theta_hat), "entropy": self.entropy}
        if self.group_probabilities is not None:
            out["group_probabilities"] = dict(self.group_probabilities)
        if self.beta_band is not None:
            out["beta_band"] = list(self.beta_band)
        return out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> TraceEntry:
        """The entry in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The entry.
        """
        band, groups = doc.get("beta_band"), doc.get("group_probabilities")
        return cls(doc.get("episode"), doc.get("step"), float(doc["beta_hat"]),
                   _floats(doc.get("theta_hat") or ()), float(doc["entropy"]),
                   None if not isinstance(groups, Mapping) else freeze(groups),
                   None if not band else (float(band[0]), float(band[1])))


@dataclass(frozen=True)
class DiscretePosterior:
    """The posterior over a discrete hypothesis set (method ``discrete``).

    Attributes:
        marginals: of β and of θ.
        hypotheses: every hypothesis with its log-likelihood, log posterior and probability.
        log_evidence: log Σ_h P(Ξ|h) P(h) (None when every hypothesis is impossible).
        n_impossible: hypotheses that cannot produce an observed action.
        trace: the belief after every action (``per_action``), else None.
    """

    marginals: Marginals
    hypotheses: Hypotheses | None
    log_evidence: float | None
    n_impossible: int
    trace: tuple[TraceEntry, ...] | None = None


@dataclass(frozen=True)
class Samples:
    """Posterior draws (birl, nuts): the chain of each, β and θ.

    Attributes:
        chain: the chain of each draw.
        beta: β of each draw.
        theta: θ of each draw, ``[n, K]`` (a study with ``--share beta``: ``[n, tasks, K]``).
    """

    chain: tuple[int, ...]
    beta: tuple[float, ...]
    theta: tuple[Any, ...]

    def to_json(self) -> dict[str, Any]:
        """The draws as a JSON object (plain values)."""
        return {"chain": list(self.chain), "beta": list(self.beta), "theta": thaw(self.theta)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Samples:
        """The draws in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The draws.
        """
        return cls(tuple(int(c) for c in doc["chain"]), _floats(doc["beta"]), freeze(doc["theta"]))


@dataclass(frozen=True)
class Misspecification:
    """Low expertise or missing features? (:mod:`~expertise_irl.inference.misspecification`).

    Attributes:
        check: ``fast`` or ``full``.
        verdict: one of the module's ``VERDICTS`` or "the hypothesis set was too coarse".
        reason: the verdict in words.
        details: the thresholds, the predictive checks, the competitor, ... as recorded.
    """

    check: str
    verdict: str
    reason: str
    details: Mapping[str, Any] = field(default_factory=_empty)

    def to_json(self) -> dict[str, Any]:
        """The verdict as a JSON object (plain values)."""
        return {"check": self.check, **thaw(self.details), "verdict": self.verdict, "reason": self.reason}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Misspecification:
        """The verdict in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The verdict.
        """
        rest = {k: v for k, v in doc.items() if k not in ("check", "verdict", "reason")}
        return cls(str(doc.get("check", "")), str(doc.get("verdict", "")), str(doc.get("reason", "")),
                   freeze(rest))


@dataclass(frozen=True)
class Diagnostics:
    """What a user should know about a run.

    Attributes:
        warnings: one line each, as the command printed them.
        unavailable: statistic -> why it could not be computed (None: the method records none).
        misspecification: the checks' verdict (None with ``check="off"``).
        identifiability: each feature's identifiability on the task (a list for several tasks).
        details: the method's own statistics (R-hat, ESS, acceptance rate, MAP's starts, ...).
    """

    warnings: tuple[str, ...] | None = ()
    unavailable: Mapping[str, Any] | None = None
    misspecification: Misspecification | None = None
    identifiability: Any = None
    details: Mapping[str, Any] = field(default_factory=_empty)

    def to_json(self) -> dict[str, Any]:
        """The diagnostics as a JSON object (plain values)."""
        out = thaw(self.details)
        if self.unavailable is not None:
            out["unavailable"] = thaw(self.unavailable)
        if self.warnings is not None:
            out["warnings"] = list(self.warnings)
        if self.identifiability is not None:
            out["identifiability"] = thaw(self.identifiability)
        if self.misspecification is not None:
            out["misspecification"] = self.misspecification.to_json()
        return out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Diagnostics:
        """The diagnostics in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The diagnostics.
        """
        known = ("warnings", "unavailable", "misspecification", "identifiability")
        mis = doc.get("misspecification")
        return cls(None if "warnings" not in doc else tuple(str(w) for w in doc["warnings"] or ()),
                   None if doc.get("unavailable") is None else freeze(doc["unavailable"]),
                   None if not isinstance(mis, Mapping) else Misspecification.from_json(mis),
                   freeze(doc.get("identifiability")),
                   freeze({k: v for k, v in doc.items() if k not in known}))


@dataclass(frozen=True)
class ChangingExpertise:
    """``--expertise changing``: a β per episode beside the one-β estimate.

    Attributes:
        by_episode: each episode's β posterior (mean, median, q05, q95; JSON ``expertise_by_episode``).
        evidence: the Bayes factor against one β (discrete; JSON ``changing``; map and nuts: None
            values with the reason).
        trend: the trend of β over the episodes.
        theta_hat: θ̂ under the changing model (discrete; JSON ``theta_hat_changing``).
        trace: the current episode's β after each action (discrete with ``per_action``).
    """

    by_episode: tuple[Mapping[str, Any], ...]
    evidence: Mapping[str, Any] | None
    trend: Mapping[str, Any] | None
    theta_hat: tuple[float, ...] | None = None
    trace: tuple[Mapping[str, Any], ...] | None = None

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ChangingExpertise:
        """The learning curve in a result document, as :meth:`Result.to_json` or an earlier version wrote it.

        ``doc`` is the whole document: the curve is its top-level ``expertise_by_episode``, ``changing``,
        ``trend``, ``theta_hat_changing`` and ``expertise_trace``.

        Args:
            doc: the result document.

        Returns:
            The learning curve and its evidence.
        """
        theta = doc.get("theta_hat_changing")
        return cls(freeze(doc.get("expertise_by_episode")), freeze(doc.get("changing")),
                   freeze(doc.get("trend")), None if theta is None else _floats(theta),
                   freeze(doc.get("expertise_trace")))


@dataclass(frozen=True)
class Teaching:
    """``--model pedagogical``: does the demonstrator teach or do the task? (JSON ``teaching``, written by
    :meth:`~expertise_irl.inference.pedagogical.TeachingPosterior.record`).

    Attributes:
        verdict: ``teaching``, ``doing`` or ``undecided`` (from 2 log BF).
        reading: the verdict in words, with β under the teaching model and under ``maxent``.
        log_bayes_factor: log P(Ξ | λ > 0) − log P(Ξ | λ = 0) (None when not finite).
        p_teaching: P(λ > 0 | Ξ).
        lambda_hat: E[λ | Ξ].
        lambda_interval: λ's 90% credible interval (grid quantiles).
        lambda_map: the most probable λ of the grid.
        lambdas: the grid of λ (0 first).
        lambda_prior: its prior (half on λ = 0).
        lambda_probabilities: its posterior.
        beta_hat_maxent: β̂ at λ = 0 (the ``maxent`` posterior on the same set).
        theta_hat_maxent: θ̂ at λ = 0.
        details: entries the package does not interpret, in the order written.
    """

    verdict: str
    reading: str
    log_bayes_factor: float | None
    p_teaching: float
    lambda_hat: float
    lambda_interval: tuple[float, float]
    lambda_map: float
    lambdas: tuple[float, ...]
    lambda_prior: tuple[float, ...]
    lambda_probabilities: tuple[float, ...]
    beta_hat_maxent: float
    theta_hat_maxent: tuple[float, ...]
    details: Mapping[str, Any] = field(default_factory=_empty)

    def to_json(self) -> dict[str, Any]:
        """The record as a JSON object (plain values)."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "details"}
        out.update({k: list(v) for k, v in out.items() if isinstance(v, tuple)})
        return {**out, **thaw(self.details)}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Teaching:
        """The record in ``doc``, as :meth:`to_json` wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The record.
        """
        lo, hi = doc["lambda_interval"]
        return cls(str(doc["verdict"]), str(doc["reading"]), _opt_float(doc["log_bayes_factor"]),
                   float(doc["p_teaching"]), float(doc["lambda_hat"]), (float(lo), float(hi)),
                   float(doc["lambda_map"]), _floats(doc["lambdas"]), _floats(doc["lambda_prior"]),
                   _floats(doc["lambda_probabilities"]), float(doc["beta_hat_maxent"]),
                   _floats(doc["theta_hat_maxent"]),
                   freeze({k: v for k, v in doc.items() if k not in _TEACHING_FIELDS}))


_TEACHING_FIELDS = frozenset(f for f in Teaching.__dataclass_fields__ if f != "details")


@dataclass(frozen=True)
class Refinement:
    """An adaptive set's record (:mod:`~expertise_irl.inference.adaptive`).

    Why it stopped, every round, what it cost.

    Attributes:
        converged: whether the estimate settled before a cap.
        stop_reason: why the refinement stopped.
        prior: the final set's prior in words.
        rounds: one record per round.
        record: the whole record as written (caps, tolerances, counts, seconds).
    """

    converged: bool | None
    stop_reason: str | None
    prior: str | None
    rounds: tuple[Mapping[str, Any], ...]
    record: Mapping[str, Any]

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Refinement:
        """The record in ``doc``, as :meth:`to_json` (or an earlier version) wrote it.

        Args:
            doc: the JSON object.

        Returns:
            The record.
        """
        return cls(doc.get("converged"), doc.get("stop_reason"), doc.get("prior"),
                   freeze(doc.get("rounds") or ()), freeze(doc))


@dataclass(frozen=True)
class Settings:
    """What the run was asked to do, as the result records it (``settings`` of the JSON).

    The common entries are attributes (None where a command does not record them); ``values``
    holds every entry in the order written.

    Attributes:
        values: every entry, read-only.
    """

    values: Mapping[str, Any] = field(default_factory=_empty)

    def get(self, key: str, default: Any = None) -> Any:
        """The entry ``key``, or ``default`` when it is not recorded.

        Args:
            key: the entry's name.
            default: what to return without it.

        Returns:
            The entry's value.
        """
        return self.values.get(key, default)

    def __getitem__(self, key: str) -> Any:
        return self.values[key]

    def __contains__(self, key: object) -> bool:
        return key in self.values

    @property
    def command(self) -> str | None:
        return self.values.get("command")

    @property
    def method(self) -> str | None:
        return self.values.get("method")

    @property
    def model(self) -> str | None:
        return self.values.get("model")

    @property
    def seed(self) -> int | None:
        return self.values.get("seed")

    @property
    def check(self) -> str | None:
        return self.values.get("check")

    @property
    def expertise(self) -> str:
        return self.values.get("expertise", "stationary")

    @property
    def n_hypotheses(self) -> int | None:
        return self.values.get("n_hypotheses")

    @property
    def prior(self) -> str | None:
        return self.values.get("prior")

    def with_values(self, **values: Any) -> Settings:
        """These settings with ``values`` added or replaced (new keys at the end).

        Args:
            **values: the entries to add or replace.

        Returns:
            New settings (these are unchanged).
        """
        return Settings(freeze({**thaw(self.values), **values}))


# ----------------------------------------------------------------------------- the result
#: Top-level keys that :class:`Result` reads into its typed parts; any other key goes to ``extra``.
_KNOWN = frozenset({
    "schema", "version", "method", "feature_names", "beta_hat", "theta_hat", "expertise_group", "map",
    "group_probabilities", "entropy", "log_evidence", "n_impossible", "marginals", "hypotheses", "trace",
    "theta_hat_normalized", "beta_hat_normalized", "credible_intervals", "samples", "diagnostics",
    "data", "settings", "refinement", "expertise_by_episode", "changing", "trend", "theta_hat_changing",
    "expertise_trace", "run_time_s", "teaching",
})


@dataclass(frozen=True)
class Result:
    """The result of one inference (see the module docstring).

    Attributes:
        method: ``discrete``, ``birl``, ``map`` or ``nuts``.
        feature_names: the features θ weighs, in order.
        estimate: β̂, θ̂ and what is said of them.
        posterior: the discrete set's posterior (None for the continuous methods).
        samples: the draws of birl and nuts, or the path of their CSV (None otherwise).
        diagnostics: warnings, checks, the method's statistics (None: a result that records none,
            as ``demo``'s).
        changing: the learning curve (``--expertise changing``), else None.
        refinement: the adaptive set's record, else None.
        teaching: teaching or doing, and the teaching weight (``--model pedagogical``), else None.
        settings: what was asked.
        data: what was read (episodes, actions, ...).
        run_time_s: the inference's seconds (None when not timed).
        version: the package version that wrote it.
        extra: what a command adds beside the inference (demo's ``truth`` and ``metrics``, a study
            participant's tasks and counts, the live page's ``live``), in the order written.
        schema: the layout version (:data:`SCHEMA_VERSION`).
        timing: seconds of the run's stages (``inference_s``, ``checks_s``) when it was just run; not
            written to the JSON and not compared.
    """

    method: str
    feature_names: tuple[str, ...]
    estimate: Estimate
    posterior: DiscretePosterior | None = None
    samples: Samples | str | None = None
    diagnostics: Diagnostics | None = field(default_factory=Diagnostics)
    changing: ChangingExpertise | None = None
    refinement: Refinement | None = None
    teaching: Teaching | None = None
    settings: Settings = field(default_factory=Settings)
    data: Mapping[str, Any] = field(default_factory=_empty)
    run_time_s: float | None = None
    version: str = ""
    extra: Mapping[str, Any] = field(default_factory=_empty)
    schema: int = SCHEMA_VERSION
    timing: Mapping[str, float] = field(default_factory=_empty, compare=False, repr=False)

    # ------------------------------------------------------------ shortcuts
    @property
    def beta_hat(self) -> float:
        return self.estimate.beta_hat

    @property
    def theta_hat(self) -> tuple[float, ...]:
        return self.estimate.theta_hat

    @property
    def warnings(self) -> tuple[str, ...]:
        d = self.diagnostics
        return () if d is None or d.warnings is None else d.warnings

    @property
    def misspecification(self) -> Misspecification | None:
        return None if self.diagnostics is None else self.diagnostics.misspecification

    def replace(self, **changes: Any) -> Result:
        """A copy with ``changes`` (:func:`dataclasses.replace`).

        Args:
            **changes: fields and their new values.

        Returns:
            The copy.
        """
        return replace(self, **changes)

    def with_extra(self, **values: Any) -> Result:
        """A copy with top-level entries added to (or replaced in) ``extra``.

        Args:
            **values: the entries.

        Returns:
            The copy.
        """
        return replace(self, extra=freeze({**thaw(self.extra), **values}))

    def with_warnings(self, *warnings: str, first: bool = False) -> Result:
        """A copy with ``warnings`` after (``first``: before) those it has.

        Args:
            *warnings: one line each.
            first: put them before the existing ones.

        Returns:
            The copy.
        """
        d = self.diagnostics or Diagnostics(warnings=())
        have = d.warnings or ()
        new = (*warnings, *have) if first else (*have, *warnings)
        return replace(self, diagnostics=replace(d, warnings=tuple(new)))

    # ------------------------------------------------------------------ JSON
    def to_json(self) -> dict[str, Any]:
        """The result document (plain JSON values; −∞ log-likelihoods as null)."""
        e = self.estimate
        doc: dict[str, Any] = {"schema": self.schema, "version": self.version, "method": self.method,
                               "feature_names": list(self.feature_names), "beta_hat": e.beta_hat,
                               "theta_hat": list(e.theta_hat), "expertise_group": e.expertise_group}
        if e.has_normalized:
            normalized = e.theta_hat_normalized
            doc["theta_hat_normalized"] = None if normalized is None else list(normalized)
            doc["beta_hat_normalized"] = e.beta_hat_normalized
        if e.group_probabilities is not None:
            doc["group_probabilities"] = dict(e.group_probabilities)
        if e.point is not None:
            doc["map"] = e.point.to_json()
        if e.entropy is not None:
            doc["entropy"] = e.entropy
        p = self.posterior
        if p is not None:
            doc["log_evidence"] = p.log_evidence
            doc["n_impossible"] = p.n_impossible
            doc["marginals"] = p.marginals.to_json()
            if p.hypotheses is not None:
                doc["hypotheses"] = p.hypotheses.to_json()
            if p.trace is not None:
                doc["trace"] = [t.to_json() for t in p.trace]
        if e.credible_intervals is not None:
            doc["credible_intervals"] = thaw(e.credible_intervals)
        if self.samples is not None:
            doc["samples"] = self.samples if isinstance(self.samples, str) else self.samples.to_json()
        doc["data"] = thaw(self.data)
        doc["settings"] = thaw(self.settings.values)
        if self.diagnostics is not None:
            doc["diagnostics"] = self.diagnostics.to_json()
        if self.refinement is not None:
            doc["refinement"] = thaw(self.refinement.record)
        c = self.changing
        if c is not None:
            doc["expertise_by_episode"] = thaw(c.by_episode)
            if c.trace is not None:
                doc["expertise_trace"] = thaw(c.trace)
            if c.evidence is not None:
                doc["changing"] = thaw(c.evidence)
            if c.trend is not None:
                doc["trend"] = thaw(c.trend)
            if c.theta_hat is not None:
                doc["theta_hat_changing"] = list(c.theta_hat)
        if self.teaching is not None:
            doc["teaching"] = self.teaching.to_json()
        if self.run_time_s is not None:
            doc["run_time_s"] = self.run_time_s
        doc.update(thaw(self.extra))
        return doc

    @classmethod
    def from_json(cls, doc: Mapping[str, Any], source: Any = "result") -> Result:
        """The result in ``doc`` (as :meth:`to_json` or any earlier version wrote it).

        Args:
            doc: the result document.
            source: names the document in messages (its path, say).

        Returns:
            The typed result.

        Raises:
            InputError: naming ``source``, if ``doc`` is not a result or its schema is newer.
        """
        check_document(doc, source)
        point = doc.get("map")
        estimate = Estimate(
            beta_hat=float(doc["beta_hat"]), theta_hat=_floats(doc["theta_hat"]),
            expertise_group=str(doc.get("expertise_group", "")),
            point=Point.from_json(point) if isinstance(point, Mapping) else None,
            group_probabilities=None if doc.get("group_probabilities") is None
            else freeze(doc["group_probabilities"]),
            entropy=_opt_float(doc.get("entropy")),
            theta_hat_normalized=None if doc.get("theta_hat_normalized") is None
            else _floats(doc["theta_hat_normalized"]),
            beta_hat_normalized=_opt_float(doc.get("beta_hat_normalized")),
            has_normalized="theta_hat_normalized" in doc or "beta_hat_normalized" in doc,
            credible_intervals=freeze(doc["credible_intervals"]) if "credible_intervals" in doc else None)
        posterior = None
        if "marginals" in doc:
            hyp = doc.get("hypotheses")
            posterior = DiscretePosterior(
                Marginals.from_json(doc["marginals"]), None if hyp is None else Hypotheses.from_json(hyp),
                _opt_float(doc.get("log_evidence")), int(doc.get("n_impossible") or 0),
                None if doc.get("trace") is None else tuple(TraceEntry.from_json(t) for t in doc["trace"]))
        samples = doc.get("samples")
        if isinstance(samples, Mapping):
            try:
                samples = Samples.from_json(samples)
            except (KeyError, TypeError, ValueError):
                raise InputError(f"{source}: 'samples' must hold chain, beta and theta "
                                 f"({len(doc['feature_names'])} per draw) of equal length") from None
        changing = ChangingExpertise.from_json(doc) if "expertise_by_episode" in doc else None
        teaching, known = _teaching_of(doc, source)
        diag = doc.get("diagnostics")
        return cls(
            method=str(doc["method"]), feature_names=tuple(doc["feature_names"]), estimate=estimate,
            posterior=posterior, samples=samples,
            diagnostics=Diagnostics.from_json(diag) if isinstance(diag, Mapping) else None,
            changing=changing,
            refinement=Refinement.from_json(doc["refinement"]) if isinstance(doc.get("refinement"), Mapping)
            else None,
            teaching=teaching,
            settings=Settings(freeze(doc.get("settings") or {})), data=freeze(doc.get("data") or {}),
            run_time_s=_opt_float(doc.get("run_time_s")), version=str(doc.get("version", "")),
            extra=freeze({k: v for k, v in doc.items() if k not in known}),
            schema=int(doc.get("schema", 1)))


def _teaching_of(doc: Mapping[str, Any], source: Any) -> tuple[Teaching | None, frozenset[str]]:
    """The document's ``teaching`` record (None without one) and the top-level keys read into typed
    parts (a ``teaching`` that is not an object stays in ``extra``, as before it had a type)."""
    rec = doc.get("teaching")
    if not isinstance(rec, Mapping):
        return None, _KNOWN - {"teaching"}
    try:
        return Teaching.from_json(rec), _KNOWN
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{source}: 'teaching' must hold the verdict, its reading and the λ grid's "
                         "prior and posterior (written by --model pedagogical)") from None


def check_document(doc: Any, source: Any = "result") -> None:
    """Raise :class:`InputError` naming ``source`` unless ``doc`` is a result document this package reads."""
    if not isinstance(doc, Mapping) or "method" not in doc:
        raise InputError(f"{source}: not an expertise-irl result (no 'method'; write one with "
                         "`expertise-irl infer`)")
    schema = doc.get("schema", 1)
    if not isinstance(schema, int) or isinstance(schema, bool) or schema < 1:
        raise InputError(f"{source}: 'schema' must be a positive integer, got {schema!r}")
    if schema > SCHEMA_VERSION:
        raise InputError(f"{source}: a result of schema {schema}, newer than this expertise-irl reads "
                         f"({SCHEMA_VERSION}); upgrade expertise-irl to read it")


def field_names(cls: type) -> tuple[str, ...]:
    """The field names of one of this module's dataclasses (for documentation and tests)."""
    return tuple(f.name for f in fields(cls))
