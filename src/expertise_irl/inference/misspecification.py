"""Low expertise or missing features? The verdict every result carries (``diagnostics.misspecification``).

In this model every departure from the features' optimum reads as noise: a careful person who
avoids something the features do not describe is reported as a novice. Two checks tell the cases
apart (``--check``):

- ``fast`` (the default): the posterior predictive checks of :mod:`.predictive_checks`
  (path length, steps to goal, each feature's sum, the visit distribution, agreement with the
  posterior's most probable action; Holm's rule at family-wise level 0.05);
- ``full``: also the richer competitor of :mod:`.tabular_reward` (θ̂·φ plus a penalised per-state
  reward, fitted with β), compared on held-out episodes;
- ``off``: neither.

**Verdict** (thresholds are the module constants):

1. *behaviour the features do not explain* when a predictive check is rejected (Holm), or, with
   ``full``, the richer reward predicts held-out actions better by at least :data:`GAIN_MIN` =
   0.02 nats per action, at least :data:`GAIN_Z` = 2 standard errors (episodes as units), and
   needs a β at most :data:`BETA_RATIO_MAX` = 0.8 times the features' (it explains as structure
   what the features call noise). β̂ is then an upper bound on the person's noise, and the
   result says where the richer reward departs most from θ̂·φ;
2. *not enough data to tell* with fewer than :data:`MIN_EPISODES` = 4 episodes or
   :data:`MIN_ACTIONS` = 40 actions, or when the richer reward's gain reaches :data:`GAIN_MIN`
   but not :data:`GAIN_Z` standard errors;
3. *features explain the behaviour* otherwise;
4. *the hypothesis set was too coarse* when a named discrete set's posterior is judged (1) but the
   same checks pass once the set is refined (:mod:`.adaptive`): the person lies between the set's
   values, and no feature is missing. The refined estimate is recorded beside the verdict.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..mdp import TabularMDP
from ..options import DEFAULT_CHECK as DEFAULT_CHECK_CHOICE
from ..options import Check
from .predictive_checks import ALPHA, MAX_DRAWS, REPLICATES, Task, predictive_checks

CHECKS = tuple(c.value for c in Check)
DEFAULT_CHECK = DEFAULT_CHECK_CHOICE.value

EXPLAINED = "features explain the behaviour"
UNEXPLAINED = "behaviour the features do not explain"
UNKNOWN = "not enough data to tell"
VERDICTS = (EXPLAINED, UNEXPLAINED, UNKNOWN)
#: The verdict of a named discrete set that the refined set explains (``infer`` alone refits).
COARSE = "the hypothesis set was too coarse"

GAIN_MIN = 0.02
GAIN_Z = 2.0
BETA_RATIO_MAX = 0.8
MIN_EPISODES = 4
MIN_ACTIONS = 40
#: States listed in ``competitor.top_states`` (largest |departure| first).
TOP_STATES = 5


def check_level(check: str, field: str = "check") -> str:
    """``check`` as one of :class:`~expertise_irl.options.Check`; an ``OptionError`` naming ``field``
    if it is none."""
    from ..options import choose

    return choose(Check, check, field).value


def thresholds() -> dict[str, Any]:
    return {"alpha": ALPHA, "multiple_testing": "Holm's step-down rule (family-wise level alpha)",
            "gain_min_nats_per_action": GAIN_MIN, "gain_min_standard_errors": GAIN_Z,
            "beta_ratio_max": BETA_RATIO_MAX, "min_episodes": MIN_EPISODES, "min_actions": MIN_ACTIONS}


# ---------------------------------------------------------------------------- draws
def draw_policies(mdps: Sequence[TabularMDP], theta: np.ndarray, beta: np.ndarray, weights: np.ndarray | None,
                  rng: np.random.Generator, model: str, replicates: int = REPLICATES,
                  tables: Sequence[np.ndarray] | None = None) -> tuple[list[np.ndarray], np.ndarray, int]:
    """The policies of posterior draws on each task and which draw each replicate uses.

    ``theta [n, K]``, ``beta [n]``: hypotheses or draws, with posterior ``weights [n]`` (None: the
    draws are equally weighted samples). ``tables``: each task's ``[n, S, A]`` log-policies when they
    are at hand (a discrete set's); otherwise at most :data:`MAX_DRAWS` distinct draws are solved.
    Returns ``(per task [D, S, A], which [replicates], D)``.
    """
    n = len(beta)
    if weights is None:
        pick = np.unique(np.linspace(0, n - 1, min(n, MAX_DRAWS)).round().astype(int))
        which = pick[rng.integers(0, len(pick), size=replicates)]
    else:
        p = np.asarray(weights, dtype=np.float64)
        which = rng.choice(n, size=replicates, p=p / p.sum())
    used, inv = np.unique(which, return_inverse=True)
    if tables is not None:
        return [np.asarray(t)[used] for t in tables], inv, len(used)
    out = [_POLICIES.get(m, theta[used], beta[used], model) for m in mdps]
    return out, inv, len(used)


def _mdp_key(mdp: TabularMDP) -> bytes:
    h = hashlib.sha1()
    for a in (mdp.next_state, mdp.features, mdp.terminal, getattr(mdp, "reward_offset", None)):
        if a is not None:
            h.update(np.ascontiguousarray(a).tobytes())
    h.update(repr(float(mdp.gamma)).encode())
    return h.digest()


class _PolicyCache:
    """Log-policies of (map, θ, β, model) already solved in this process, least recently used
    first out beyond :data:`POLICY_CACHE_BYTES`.

    The participants of a study share maps and their posteriors share hypotheses of the set, so
    most draws of a study's checks were solved for someone before. The hypotheses not yet solved
    are solved :data:`SOLVE_BATCH` at a time (the last batch padded), so that each map compiles
    one program rather than one per participant's number of draws."""

    def __init__(self, max_bytes: int):
        self.max_bytes, self.bytes = max_bytes, 0
        self.items: OrderedDict[tuple, np.ndarray] = OrderedDict()

    def get(self, mdp: TabularMDP, theta: np.ndarray, beta: np.ndarray, model: str) -> np.ndarray:
        from ..planning.soft_vi import solve

        base = _mdp_key(mdp)
        keys = [(base, model, np.asarray(t, np.float64).tobytes(), float(b)) for t, b in zip(theta, beta,
                                                                                           strict=True)]
        todo = list(dict.fromkeys(k for k in keys if k not in self.items))
        if todo:
            index = {k: i for i, k in enumerate(keys)}
            rows = [index[k] for k in todo]
            for c in range(0, len(rows), SOLVE_BATCH):
                part = rows[c:c + SOLVE_BATCH]
                padded = part + [part[-1]] * (SOLVE_BATCH - len(part))
                lp = np.asarray(solve(mdp, theta[padded], beta[padded], model=model).log_policy)
                for j, k in enumerate(todo[c:c + SOLVE_BATCH]):
                    self.items[k] = lp[j]
                    self.bytes += lp[j].nbytes
            while self.bytes > self.max_bytes and len(self.items) > len(keys):
                _, old = self.items.popitem(last=False)
                self.bytes -= old.nbytes
        for k in keys:
            self.items.move_to_end(k)
        return np.stack([self.items[k] for k in keys])


#: Hypotheses per solve of the checks' policies (one compiled shape per map).
SOLVE_BATCH = 16
#: The policy cache's size; one policy is S·A·8 bytes (8 KB on a 200-state map with 5 actions).
POLICY_CACHE_BYTES = 512 * 2**20
_POLICIES = _PolicyCache(POLICY_CACHE_BYTES)


# ---------------------------------------------------------------------------- verdict
def verdict(n_episodes: int, n_actions: int, predictive: dict | None,
            competitor: dict | None) -> tuple[str, str]:
    """The verdict and its reason in one line (see the module docstring)."""
    failed = predictive["failed"] if predictive else []
    if failed:
        verb = "lies" if len(failed) == 1 else "lie"
        return UNEXPLAINED, (f"the demonstrations' {', '.join(failed)} {verb} outside what the posterior "
                             f"predicts (Holm, family-wise level {ALPHA:g})")
    if competitor is not None:
        g, se, ratio = competitor["gain"], competitor["gain_se"], competitor["beta_ratio"]
        if g >= GAIN_MIN and g >= GAIN_Z * se and ratio <= BETA_RATIO_MAX:
            return UNEXPLAINED, (f"a per-state reward predicts held-out actions {g:.3g} ± {se:.2g} "
                                 f"nats/action better and needs β {ratio:.2g} times the features'")
    if n_episodes < MIN_EPISODES or n_actions < MIN_ACTIONS:
        return UNKNOWN, (f"{n_episodes} episode(s), {n_actions} action(s): the checks need at least "
                         f"{MIN_EPISODES} episodes and {MIN_ACTIONS} actions")
    if competitor is not None and competitor["gain"] >= GAIN_MIN:
        return UNKNOWN, (f"a per-state reward predicts held-out actions {competitor['gain']:.3g} ± "
                         f"{competitor['gain_se']:.2g} nats/action better, short of {GAIN_Z:g} "
                         "standard errors"
                         + ("" if competitor["beta_ratio"] <= BETA_RATIO_MAX else " or of a smaller β"))
    what = "no predictive check is rejected" + ("" if competitor is None else
                                                " and the per-state reward predicts no better")
    return EXPLAINED, what


def _top_states(mdp: TabularMDP, dep: dict) -> list[dict[str, Any]]:
    states, values = np.asarray(dep["states"]), np.asarray(dep["values"])
    order = np.argsort(-np.abs(values))[:TOP_STATES]
    out = []
    for i in order:
        s = int(states[i])
        entry: dict[str, Any] = {"state": s, "departure": float(values[i])}
        if mdp.state_xy is not None:
            entry["x"], entry["y"] = (int(v) for v in mdp.state_xy[s])
        out.append(entry)
    return out


def warning_of(doc: dict[str, Any], beta_hat: float) -> str:
    """The stderr warning of an *unexplained* verdict."""
    where = ""
    comp = doc.get("competitor")
    if comp and comp.get("top_states"):
        cells = [f"({e['x']}, {e['y']})" if "x" in e else f"state {e['state']}"
                 for e in comp["top_states"][:3]]
        where = f"; the per-state reward departs most from θ̂·φ at {', '.join(cells)}"
    return (f"behaviour the features do not explain ({doc['reason']}): β̂ = {beta_hat:.4g} is an upper "
            f"bound on the person's noise, not a measure of it{where} (see diagnostics.misspecification; "
            "plot --check draws it)")


def misspecification(tasks: Sequence[tuple[TabularMDP, Trajectories]], *, check: str, theta: np.ndarray,
                     beta: np.ndarray, weights: np.ndarray | None, theta_hat, beta_hat: float, model: str,
                     seed: int = 0, tables: Sequence[np.ndarray] | None = None,
                     draws_note: str | None = None) -> dict[str, Any] | None:
    """``diagnostics.misspecification`` of a result (None for ``check="off"``).

    ``tasks``: the person's ``(mdp, trajectories)``; ``theta``/``beta``/``weights``/``tables``: the
    posterior (:func:`draw_policies`); ``theta_hat``, ``beta_hat``: the result's estimate (the
    competitor departs from θ̂·φ).
    """
    check_level(check)
    if check == "off":
        return None
    rng = np.random.default_rng([int(seed), 32])
    mdps = [m for m, _ in tasks]
    n_episodes = sum(t.n_episodes for _, t in tasks)
    n_actions = sum(len(t) for _, t in tasks)
    doc: dict[str, Any] = {"check": check, "thresholds": thresholds(), "unavailable": {}}
    predictive = None
    if n_actions > 0:
        pols, which, n_draws = draw_policies(mdps, np.atleast_2d(theta), np.atleast_1d(beta), weights, rng,
                                             model, tables=tables)
        predictive = predictive_checks([Task(m, t, p) for (m, t), p in zip(tasks, pols, strict=True)],
                                       which, rng)
        predictive["draws"] = n_draws
        if draws_note:
            predictive["draws_note"] = draws_note
    else:
        doc["unavailable"]["predictive"] = "no actions to check"
    doc["predictive"] = predictive
    competitor = None
    if check == "full":
        short = min(t.n_episodes for _, t in tasks)
        if short < 2:
            doc["unavailable"]["competitor"] = ("the held-out comparison needs at least 2 episodes per "
                                                f"task; a task has {short}")
        else:
            from .tabular_reward import compare

            try:
                competitor = compare(tasks, theta_hat, model=model, rng=rng)
            except InputError as exc:
                doc["unavailable"]["competitor"] = str(exc)
            if competitor is not None:
                competitor["top_states"] = _top_states(mdps[0], competitor["departure"][0])
                competitor["reward"] = "θ̂·φ(s, a) + r(next state), r/β ~ Normal(0, 1/penalty)"
    else:
        doc["unavailable"]["competitor"] = "not run: --check full fits the per-state reward"
    doc["competitor"] = competitor
    doc["verdict"], doc["reason"] = verdict(n_episodes, n_actions, predictive, competitor)
    if doc["verdict"] == UNEXPLAINED:
        doc["beta_upper_bound"] = float(beta_hat)
    return _finite(doc)


def _finite(x):
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def posterior_of_run(run, mdp: TabularMDP) -> dict[str, Any]:
    """The posterior of a :class:`~.methods.MethodRun` as :func:`misspecification` takes it: a discrete
    set's hypotheses with their probabilities and solved policies, a sampler's draws, or MAP's point."""
    from .methods import DiscreteFit

    if isinstance(run.result, DiscreteFit):
        post = run.result.posterior
        hyp = post.hypotheses
        return {"theta": hyp.theta, "beta": hyp.beta, "weights": post.probabilities,
                "tables": [post.log_policy]}
    fields = run.fields
    if fields.get("draws") is not None:
        _, theta, beta = fields["draws"]
        return {"theta": np.asarray(theta), "beta": np.asarray(beta), "weights": None}
    point = fields["map"]
    return {"theta": np.asarray([point["theta"]]), "beta": np.asarray([point["beta"]]), "weights": None,
            "draws_note": "the MAP point (no posterior draws): a plug-in check"}


def refit_of_run(run, mdp: TabularMDP, trajs: Trajectories, opts):
    """The ``refit`` of :func:`add_to_result` for a named discrete set that was not refined (None for any
    other run): the named set joined with the default start set (:func:`.adaptive.start_set`) and refined,
    its posterior, estimate and size."""
    from .methods import DiscreteFit, refined_set

    fit = run.result
    if not isinstance(fit, DiscreteFit) or fit.refined is not None or fit.changing is not None:
        return None

    def refit():
        from ..hypotheses import HypothesisSet, unique_rows
        from .adaptive import start_set
        from .belief import DiscreteBelief

        named, coarse = fit.posterior.hypotheses, start_set(mdp.n_features)  # named, and the default start
        both = HypothesisSet(unique_rows(np.concatenate([named.thetas, coarse.thetas])),
                             np.concatenate([named.betas, coarse.betas]))
        r = refined_set(mdp, trajs, both, opts)
        b = DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior).update(trajs)
        post = {"theta": b.hypotheses.theta, "beta": b.hypotheses.beta, "weights": b.probabilities,
                "tables": [b.log_policy]}
        return post, b.mean_theta, b.mean_beta, len(b.hypotheses)

    return refit


def episode_starts(trajs: Trajectories) -> np.ndarray:
    return np.array([s[0] for s, _ in trajs.episodes() if len(s)], dtype=np.int64)


def add_to_result(doc: dict[str, Any], tasks: Sequence[tuple[TabularMDP, Trajectories]],
                  posterior: dict[str, Any], *, check: str, model: str, seed: int = 0, refit=None) -> None:
    """Write ``diagnostics.identifiability`` and ``diagnostics.misspecification`` into the result ``doc``
    and their warnings into ``diagnostics.warnings`` (nothing for ``check="off"``).

    ``refit``: for a named discrete set, ``refit() -> (posterior, theta_hat, beta_hat, n_hypotheses)`` of
    the set refined (:mod:`.adaptive`); an *unexplained* verdict is then checked again there, and
    becomes :data:`COARSE` if the refined set explains the behaviour."""
    from .identifiability import feature_identifiability

    if check_level(check) == "off":
        return
    diag = doc.setdefault("diagnostics", {})
    warnings = diag.setdefault("warnings", [])
    idents = []
    for i, (m, t) in enumerate(tasks):
        ident = feature_identifiability(m, episode_starts(t) if len(t) else None)
        prefix = f"task {i + 1}: " if len(tasks) > 1 else ""
        warnings += [prefix + w for w in ident["warnings"]]
        idents.append(ident)
    diag["identifiability"] = idents[0] if len(idents) == 1 else idents
    mis = misspecification(tasks, check=check, theta_hat=doc["theta_hat"], beta_hat=doc["beta_hat"],
                           model=model, seed=seed, **posterior)
    if mis["verdict"] == UNEXPLAINED and refit is not None:
        mis = _coarse_or_not(mis, tasks, refit, check=check, model=model, seed=seed)
    diag["misspecification"] = mis
    if mis["verdict"] == UNEXPLAINED:
        warnings.append(warning_of(mis, doc["beta_hat"]))
    elif mis["verdict"] == COARSE:
        warnings.append(f"{COARSE}: {mis['reason']}")


def _coarse_or_not(mis: dict[str, Any], tasks, refit, *, check: str, model: str, seed: int) -> dict[str, Any]:
    """An *unexplained* verdict of a named set checked again on the set refined (``refit()`` returns the
    refined posterior, its estimate and its size): the verdict :data:`COARSE` when the behaviour is
    explained there, the first verdict (with the refined one beside it) when it is not."""
    post, theta_hat, beta_hat, size = refit()
    again = misspecification(tasks, check=check, theta_hat=theta_hat, beta_hat=beta_hat, model=model,
                             seed=seed, **post)
    refined = {"n_hypotheses": size, "beta_hat": float(beta_hat), "theta_hat": [float(x) for x in theta_hat],
               "verdict": again["verdict"], "reason": again["reason"]}
    if again["verdict"] != EXPLAINED:  # only a refined set the features explain shows the set was coarse
        return {**mis, "refined": refined}
    theta = ", ".join(f"{x:.3g}" for x in theta_hat)
    return {**again, "verdict": COARSE, "first": {"verdict": mis["verdict"], "reason": mis["reason"]},
            "refined": refined,
            "reason": (f"on the named set {mis['reason']}, but refined to {size} hypotheses "
                       f"(β̂ = {beta_hat:.3g}, θ̂ = [{theta}]) {again['reason']}: the person lies between "
                       "the set's values; name a finer set or leave --thetas/--betas out to refine it")}
