"""Teaching or doing: a demonstrator who shows what matters (``--model pedagogical``).

After Ho, Littman, MacGlashan, Cushman and Austerweil, "Showing versus doing: teaching by
demonstration" (NIPS 2016), in the tractable per-action form the docs argue for
(``docs/teaching.md``).

**The literal observer.** It watches one action ``a`` in state ``s`` and believes the doer's model
(``maxent``) over a fixed hypothesis set Ψ = Θ × B with prior P(h). Its predictive of the action
is ``π̄(a|s) = Σ_h P(h) π_h(a|s)``, and given θ, ``π̄_θ(a|s) = Σ_b P(b|θ) π_{θ,b}(a|s)``. What the
action tells it about θ is the pointwise mutual information

    I_θ(s, a) = log P_lit(θ | s, a) − log P(θ) = log π̄_θ(a|s) − log π̄(a|s).

**The teacher.** With preferences θ, expertise β and a teaching weight λ ≥ 0 (reward units per
nat of the observer's belief), it acts by

    π_show(a | s) ∝ exp((Q_{θ,β}(s, a) + λ log P_lit(θ | s, a)) / β)
                  = π_{θ,β}(a|s) · exp(λ/β · I_θ(s, a)) / Z(s)

(``log P(θ)`` is the same for every action and cancels). λ = 0 is ``maxent`` exactly. The
bonus is the action's own: the values Q are the doer's, so a teacher shows with each step and
plans as a doer (the trajectory-level model, which plans for the whole demonstration's
informativeness, has no tractable likelihood on these maps; see the docs).

**The posterior** is exact over Ψ × Λ, Λ a grid of λ with 0 in it. The prior gives λ = 0 (a doer)
half the mass and spreads the other half evenly over the grid's positive λ (a teacher), so that
the posterior odds of teaching are the Bayes factor ``log P(Ξ | λ > 0) − log P(Ξ | λ = 0)``. One
solve of Ψ (under ``maxent``) serves every λ: the teacher's policy is the doer's policy reweighted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..hypotheses import HypothesisSet
from ..planning.teaching import (
    MAX_LAMBDA,
    Observer,
    observer,
    solved_observer,
    teacher_log_policy,
    teaching_log_policy,
    theta_predictive,
)
from .posterior import beta_quantile, log_sum_exp

# The model (the observer, the teacher's policy) lives in planning.teaching, below the simulator;
# its names are this module's too.
__all__ = ["LAMBDAS", "MAX_LAMBDA", "Observer", "TeachingPosterior", "lambda_log_prior", "observed_counts",
           "observer", "parse_lambdas", "solved_observer", "teacher_log_policy", "teaching_log_likelihoods",
           "teaching_log_policy", "teaching_posterior", "theta_predictive"]

#: The default grid of teaching weights λ (reward units per nat); 0 is the doer.
LAMBDAS = (0.0, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0)
#: The credible interval of λ (grid quantiles).
INTERVAL = (0.05, 0.95)
#: ``2 log BF`` (teaching against doing) at or above which the verdict is ``teaching`` (Kass and
#: Raftery's "strong"), and at or below which it is ``doing`` (their "positive", the other way).
TEACHING_2LOGBF = 6.0
DOING_2LOGBF = -2.0
#: Neighbouring βs of the set further apart than this draw a warning with a verdict other than ``doing``.
COARSE_BETA_RATIO = 2.0
#: Elements of ``[H, states, actions]`` handled at once when the likelihood is summed.
BLOCK = 2**22


def parse_lambdas(spec) -> np.ndarray:
    """The λ grid from ``--lambdas`` or a sequence.

    Args:
        spec: comma-separated numbers, or a sequence of numbers.

    Returns:
        ``[L]`` sorted, distinct, finite values ≥ 0 with 0 first.

    Raises:
        InputError: a value that is not a finite number ≥ 0, no positive value, or no 0.
    """
    if isinstance(spec, str):
        items = [x.strip() for x in spec.split(",") if x.strip()]
        try:
            values = [float(x) for x in items]
        except ValueError:
            raise InputError(f"--lambdas must be comma-separated numbers, got {spec!r}") from None
    else:
        values = [float(x) for x in spec]
    lam = np.unique(np.asarray(values, dtype=np.float64))
    if lam.size == 0 or not np.all(np.isfinite(lam)) or lam[0] < 0 or lam[-1] > MAX_LAMBDA:
        raise InputError(f"--lambdas must be numbers from 0 to {MAX_LAMBDA:g} (λ = 1 already pays a "
                         f"step's reward per nat of the observer's belief), got {spec!r}")
    if lam[0] != 0 or lam.size < 2:
        raise InputError(f"--lambdas must hold 0 (the doer) and at least one λ > 0, got {spec!r}")
    return lam


def lambda_log_prior(lambdas: np.ndarray) -> np.ndarray:
    """``[L]`` log prior of the grid: half on λ = 0, half spread evenly over the positive λ."""
    n = len(lambdas) - 1
    return np.array([math.log(0.5)] + [math.log(0.5 / n)] * n)


# ----------------------------------------------------------------------------- the posterior
def observed_counts(trajs: Trajectories, n_actions: int) -> tuple[np.ndarray, np.ndarray]:
    """``(states, counts)``: the distinct observed states ``[S']`` and ``[S', A]`` pair counts."""
    states, inverse = np.unique(trajs.state, return_inverse=True)
    counts = np.zeros((len(states), n_actions))
    np.add.at(counts, (inverse, trajs.action), 1.0)
    return states, counts


def teaching_log_likelihoods(observer_: Observer, log_policy: np.ndarray, counts: np.ndarray,
                             lambdas: np.ndarray) -> np.ndarray:
    """``[L, H]`` log P(Ξ | h, λ): the observed pairs' log π_show summed, for every λ and hypothesis.

    Args:
        observer_: the observer at the observed states (its set is the hypotheses').
        log_policy: ``[H, S', A]`` the doers' log-policies at those states.
        counts: ``[S', A]`` how often each pair was observed.
        lambdas: ``[L]`` the grid.
    """
    hyp = observer_.hypotheses
    nt, nb = hyp.n_theta, hyp.n_beta
    info = observer_.informativeness()  # [n_theta, S', A]
    seen = counts > 0
    out = np.empty((len(lambdas), nt * nb))
    per_theta = nb * max(1, counts.size)
    step = max(1, BLOCK // per_theta)
    for t0 in range(0, nt, step):
        t1 = min(nt, t0 + step)
        lp = log_policy[t0 * nb:t1 * nb].reshape(t1 - t0, nb, *counts.shape)
        inf = info[t0:t1, None]
        for i, lam in enumerate(lambdas):
            pol = teaching_log_policy(lp, inf, lam / hyp.betas[None, :]) if lam else lp
            terms = np.where(seen, pol, 0.0) * counts
            out[i, t0 * nb:t1 * nb] = terms.sum(axis=(-2, -1)).reshape(-1)
    return out


@dataclass(frozen=True, eq=False)
class TeachingPosterior:
    """The exact posterior over Ψ × Λ of a demonstrator who may be teaching.

    Attributes:
        hypotheses: the set Ψ = Θ × B (the observer's and the inference's).
        lambdas: ``[L]`` the λ grid (``lambdas[0] == 0``).
        log_prior: ``[H]`` the normalised log prior over Ψ.
        log_likelihood: ``[L, H]`` log P(Ξ | h, λ).
        n_observed: the number of pairs observed.
    """

    hypotheses: HypothesisSet
    lambdas: np.ndarray
    log_prior: np.ndarray
    log_likelihood: np.ndarray
    n_observed: int

    @property
    def log_prior_lambda(self) -> np.ndarray:
        return lambda_log_prior(self.lambdas)

    @property
    def log_evidence_by_lambda(self) -> np.ndarray:
        """``[L]`` log P(Ξ | λ) = log Σ_h P(h) P(Ξ | h, λ)."""
        return log_sum_exp(self.log_likelihood + self.log_prior[None, :], axis=1)

    @property
    def marginal_log_likelihood(self) -> np.ndarray:
        """``[H]`` log P(Ξ | h) with λ marginalised under its prior."""
        return log_sum_exp(self.log_likelihood + self.log_prior_lambda[:, None], axis=0)

    @property
    def lambda_probabilities(self) -> np.ndarray:
        """``[L]`` P(λ | Ξ)."""
        z = self.log_evidence_by_lambda + self.log_prior_lambda
        return np.exp(z - log_sum_exp(z))

    @property
    def log_bayes_factor(self) -> float:
        """log P(Ξ | λ > 0) − log P(Ξ | λ = 0): the evidence for teaching against doing."""
        z = self.log_evidence_by_lambda
        return float(log_sum_exp(z[1:]) - math.log(len(z) - 1) - z[0])

    def lambda_interval(self) -> tuple[float, float]:
        """The 90% credible interval of λ (grid quantiles)."""
        p = self.lambda_probabilities
        return tuple(float(beta_quantile(self.lambdas, p, q)) for q in INTERVAL)

    @property
    def verdict(self) -> str:
        """``teaching``, ``doing`` or ``undecided``, from 2 log BF (:data:`TEACHING_2LOGBF`)."""
        x = 2 * self.log_bayes_factor
        return "teaching" if x >= TEACHING_2LOGBF else "doing" if x <= DOING_2LOGBF else "undecided"

    def warnings(self) -> list[str]:
        """What may make a doer read as teaching: a β grid so coarse that λ takes up the misfit.

        Returns:
            One warning when neighbouring βs of the set are more than :data:`COARSE_BETA_RATIO`
            apart and the verdict is not ``doing``, else none.
        """
        b = self.hypotheses.betas
        if len(b) == 1 or self.verdict == "doing":  # one β: no β between the set's to misfit
            return []
        ratio = float(np.max(b[1:] / b[:-1]))
        if ratio <= COARSE_BETA_RATIO:
            return []
        return [f"teaching: the set's βs are up to {ratio:.3g}× apart, and a doer whose β falls between "
                "them can read as teaching (λ takes up the misfit); name a finer --betas, e.g. 16 values "
                "1.58× apart (docs/teaching.md)"]

    def belief(self, log_policy: np.ndarray, *, doer: bool = False):
        """The posterior over Ψ as a :class:`~.belief.DiscreteBelief`.

        Args:
            log_policy: ``[H, S, A]`` the doers' log-policies the belief carries.
            doer: the posterior at λ = 0 (the ``maxent`` posterior on the same set and prior)
                instead of the one with λ marginalised.

        Returns:
            The belief after the demonstrations.
        """
        from .belief import DiscreteBelief

        ll = self.log_likelihood[0] if doer else self.marginal_log_likelihood
        return DiscreteBelief(self.hypotheses, log_policy, self.log_prior, ll, self.n_observed)

    def record(self, log_policy: np.ndarray) -> dict:
        """The result's ``teaching`` entry (see ``docs/teaching.md``).

        Args:
            log_policy: ``[H, S, A]`` the doers' log-policies (for the two beliefs' estimates).

        Returns:
            The verdict and its one-line reading, the log Bayes factor of teaching, P(teaching), λ̂
            with its 90% interval and grid mode, the grid with its prior and posterior, and β̂ and θ̂
            under ``maxent`` (the λ = 0 slice).
        """
        taught, doer = self.belief(log_policy), self.belief(log_policy, doer=True)
        lbf, p = self.log_bayes_factor, self.lambda_probabilities
        b, b0 = float(taught.mean_beta), float(doer.mean_beta)
        verdict, shown = self.verdict, round(2 * lbf, 1) + 0.0  # + 0.0: never "-0.0"
        head = {"teaching": "demonstrations read as teaching",
                "doing": "demonstrations read as doing the task",
                "undecided": "the demonstrations do not tell teaching from doing"}[verdict]
        return {
            "verdict": verdict,
            "reading": f"{head} (2 log BF = {shown:.1f}): β under the teaching model {b:.3g} "
                       f"against {b0:.3g} under maxent",
            "log_bayes_factor": lbf, "p_teaching": float(p[1:].sum()),
            "lambda_hat": float(p @ self.lambdas), "lambda_interval": list(self.lambda_interval()),
            "lambda_map": float(self.lambdas[int(np.argmax(p))]),
            "lambdas": self.lambdas.tolist(), "lambda_prior": np.exp(self.log_prior_lambda).tolist(),
            "lambda_probabilities": p.tolist(),
            "beta_hat_maxent": b0, "theta_hat_maxent": doer.mean_theta.tolist(),
        }


def teaching_posterior(log_policy: np.ndarray, hypotheses: HypothesisSet, trajs: Trajectories, *,
                       lambdas=LAMBDAS, prior: np.ndarray | None = None) -> TeachingPosterior:
    """The posterior over Ψ × Λ of ``trajs`` from the set's ``maxent`` log-policies.

    Args:
        log_policy: ``[H, S, A]`` log π_h(a|s) under ``maxent`` (one solve of the set).
        hypotheses: the set Ψ; the literal observer believes in it with the same prior.
        trajs: the demonstrations.
        lambdas: the λ grid (:func:`parse_lambdas`).
        prior: ``[H]`` prior weights over Ψ; uniform when None.

    Returns:
        The posterior.

    Raises:
        InputError: a bad λ grid, or demonstrations impossible under every hypothesis.
    """
    lam = parse_lambdas(lambdas)
    H = len(hypotheses)
    if prior is None:
        log_prior = np.full(H, -math.log(H))
    else:
        with np.errstate(divide="ignore"):
            log_prior = np.log(np.asarray(prior, dtype=np.float64) / np.sum(prior))
    states, counts = observed_counts(trajs, log_policy.shape[2])
    lp = np.asarray(log_policy[:, states, :], dtype=np.float64)
    obs = observer(hypotheses, lp, log_prior)
    ll = teaching_log_likelihoods(obs, lp, counts, lam)
    if not np.isfinite(ll[0] + log_prior).any():
        raise InputError("the demonstrations are impossible under every hypothesis of the set")
    return TeachingPosterior(hypotheses, lam, log_prior, ll, len(trajs))
