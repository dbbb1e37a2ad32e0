"""NUTS on the continuous space: chains as separate programs in threads, Laplace starts.

The sampler is NumPyro's NUTS (its tree building, step-size and mass-matrix adaptation),
driven one iteration at a time through its functional interface
(:func:`numpyro.infer.hmc.hmc` with a ``potential_fn_gen``). What this module adds, each
measured in ``benchmarks/nuts_speed.py``:

- **One program per chain, chains in threads.** XLA runs them on separate cores, and no
  chain waits for another's deeper tree or slower solve, as vectorised chains do.
- **Laplace starts.** Each chain starts near a mode with the Laplace approximation there as
  its initial mass matrix, so the first adaptation window does not run with the identity
  (whose trees were five times deeper).
- **Dense mass matrix** by default: θ's simplex coordinates and log β are correlated in
  the posterior, and with a diagonal one the trees were twice as deep.
- **The data as an input.** The counts are an argument of the compiled programs, so one
  compile serves every data set on a map, and with JAX's persistent cache (the command line
  turns it on) later runs do not compile again.
- **Warm starts** (opt-in, ``warm_start=True``): each iteration's potential carries a
  :class:`~expertise_irl.planning.differentiable.WarmStart`, the converged values and gradient adjoint at
  the chain's last draw, and every leapfrog step of the next trajectory starts its forward
  and adjoint fixed points there. NumPyro's potential is a pure function of the position,
  so the start is the trajectory's origin, not the previous leapfrog step. A solve's result
  does not depend on its start beyond the tolerance, so the target is the same.

The potential, the step kernel and the chain driver are in
:mod:`~expertise_irl.inference.nuts_kernel`; :func:`nuts_posterior` assembles them and
summarises the draws.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import jax
import numpy as np

from ..demos.trajectories import Trajectories
from ..mdp import TabularMDP
from ..models import DEFAULT_MODEL
from ..numerics import enable_float64
from .diagnostics import chain_statistics
from .gradient import credible_intervals
from .nuts_kernel import check_run, sample, unconstrained_posterior
from .priors import DEFAULT_PRIOR, numpyro_priors
from .task_likelihood import as_tasks, tasks_log_likelihood

__all__ = ["NUTSResult", "nuts_posterior"]

@dataclass(frozen=True)
class NUTSResult:
    """Posterior samples from NUTS and their diagnostics.

    Attributes:
        theta: ``[chains, draws, K]`` samples of θ (on the simplex).
        beta: ``[chains, draws]`` samples of β.
        idata: the ArviZ ``InferenceData`` (posterior, sample_stats).
        r_hat: ``{"beta": float, "theta": [K]}`` split-R̂ (rank-normalised), or None when the
            run is too short to compute it (fewer than 2 chains or 4 draws; see ``unavailable``).
        ess: ``{"beta": float, "theta": [K]}`` bulk effective sample size (0 where a chain did not
            move, see ``stuck``), or None (fewer than 4 draws per chain).
        divergences: number of divergent transitions after warm-up.
        log_density: ``[chains, draws]`` unnormalised log-posterior of each draw (θ, β space).
        unavailable: ``{statistic: reason}`` for each statistic that could not be computed.
        mean_tree_size: leapfrog steps per draw after warm-up, averaged over chains and draws.
        mean_accept_prob: mean acceptance statistic after warm-up.
        stuck: ``{i: {chain: value}}``, the parameters (0 = β, ``k + 1`` = θ_k) that a chain never
            moved, at the value it repeated (:func:`~.diagnostics.stuck_parameters`): their ESS is
            0, their R-hat ``None``, and the result document withholds their intervals.
    """

    theta: np.ndarray
    beta: np.ndarray
    idata: object
    r_hat: dict | None
    ess: dict | None
    divergences: int
    log_density: np.ndarray
    unavailable: dict
    mean_tree_size: float = float("nan")
    mean_accept_prob: float = float("nan")
    stuck: dict = field(default_factory=dict)

    @property
    def mean_theta(self) -> np.ndarray:
        return self.theta.reshape(-1, self.theta.shape[-1]).mean(axis=0)

    @property
    def mean_beta(self) -> float:
        return float(self.beta.mean())

    def credible_intervals(self, prob: float = 0.9) -> dict:
        """Equal-tailed intervals of the draws, all chains together.

        Args:
            prob: the intervals' probability.

        Returns:
            ``{"beta": [low, high], "theta": [[low, high], ...]}``.
        """
        return credible_intervals(self.theta.reshape(-1, self.theta.shape[-1]), self.beta.ravel(), prob)


def nuts_posterior(
    mdp: TabularMDP | Sequence[TabularMDP],
    trajs: Trajectories | Sequence[Trajectories],
    *,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 4,
    seed: int = 0,
    theta_prior=None,
    beta_prior=None,
    tol: float = 1e-8,
    progress: Callable[[int, int], None] | None = None,
    prior: str = DEFAULT_PRIOR,
    model: str = DEFAULT_MODEL,
    dense_mass: bool = True,
    warm_start: bool = False,
    laplace_init: bool = True,
    target_accept: float = 0.8,
    concentration: float | None = None,
) -> NUTSResult:
    """Sample P(θ, β | Ξ) with NUTS on the same log-density as :func:`map_estimate`.

    The draws are of the posterior on (θ, β) whatever the sampler's coordinates (their
    Jacobians are in the potential), so its means do not depend on them as MAP's mode does.
    Each chain is its own compiled program; the chains run in threads, as many at once as
    there are CPU cores, and the draws do not depend on how many run at once.

    Args:
        mdp: the task, or a list of tasks of the same person (their log-likelihoods are summed).
        trajs: the demonstrations, or a list of them as long as ``mdp``'s, one per task.
        num_warmup: warm-up iterations per chain.
        num_samples: draws kept per chain.
        num_chains: chains.
        seed: the seed of every chain's random key.
        theta_prior: a NumPyro distribution replacing ``prior``'s θ part.
        beta_prior: a NumPyro distribution replacing ``prior``'s β part.
        tol: soft value iteration's tolerance in the likelihood.
        progress: ``progress(done, total)`` counts iterations summed over the chains (warm-up
            included), every :data:`~.nuts_kernel.CHUNK` iterations of a chain.
        prior: ``"log-uniform"`` (the default: θ ~ Dirichlet(α) on the simplex and log β uniform
            on [1e-3, 1e2]) or ``"paper"`` (θ uniform, β ~ Normal(5.005, 1.5) truncated to
            [0.01, 10]).
        model: the observation model of :mod:`expertise_irl.models`.
        dense_mass: adapt a dense mass matrix (the default) instead of a diagonal one.
        warm_start: start every solve at the chain's last draw instead of at zero (same target;
            it was slower in ``benchmarks/nuts_speed.py``, so it is off by default).
        laplace_init: start each chain near a mode with the Laplace approximation as its mass
            matrix (see :func:`~.nuts_kernel._laplace_start`).
        target_accept: the step-size adaptation's target acceptance (NumPyro's default, 0.8;
            raising it to 0.95 halved the divergences of experts' posteriors on ``corridor`` at
            2-4× the time and, for one person, a fraction of the effective samples:
            docs/calibration.md).
        concentration: α of θ's Dirichlet (default: the prior's, :func:`.priors.concentration_of`).

    Returns:
        The draws, per chain, with their diagnostics.

    Raises:
        InputError: a run setting out of range, an unknown ``prior`` or ``model``, or tasks and
            demonstrations that do not pair up.
    """
    enable_float64()
    num_warmup, num_samples, num_chains = check_run(num_warmup, num_samples, num_chains, target_accept)
    f = tasks_log_likelihood(mdp, trajs, tol=tol, model=model)
    first = as_tasks(mdp, trajs)[0][0]
    named_theta, named_beta = numpyro_priors(prior, first.n_features, concentration)
    theta_prior = named_theta if theta_prior is None else theta_prior
    beta_prior = named_beta if beta_prior is None else beta_prior
    # The counts are an argument of every compiled program, not a constant in it: programs for
    # one map are then the same for every data set, and JAX's persistent cache (where enabled,
    # as the command line does) serves them to later runs without compiling again.
    post = unconstrained_posterior(f, first.n_features, theta_prior, beta_prior, warm_start=warm_start)
    draws = sample(post, f, num_warmup=num_warmup, num_samples=num_samples, num_chains=num_chains, seed=seed,
                   dense_mass=dense_mass, target_accept=target_accept, warm_start=warm_start,
                   laplace_init=laplace_init, progress=progress)
    return _summarise(*draws, post, f.counts, first.feature_names)


def _summarise(th, be, div, steps, acc, post, counts, feature_names) -> NUTSResult:
    """Draws ``[chains, draws, ...]`` after warm-up, their log densities and diagnostics."""
    import arviz as az

    density = jax.jit(jax.vmap(post.log_density, in_axes=(0, 0, None)))
    C_, D_ = be.shape
    log_density = np.asarray(density(th.reshape(C_ * D_, -1), be.reshape(-1), counts)).reshape(C_, D_)
    idata = az.from_dict(
        posterior={"theta": th, "beta": be},
        sample_stats={"diverging": div, "n_steps": steps, "acceptance_rate": acc, "lp": log_density},
        coords={"feature": list(feature_names)}, dims={"theta": ["feature"]},
    )
    stats = chain_statistics(th, be, feature_names=feature_names)
    return NUTSResult(
        theta=th, beta=be, idata=idata, r_hat=stats["r_hat"], ess=stats["ess_bulk"],
        divergences=int(div.sum()), log_density=log_density, unavailable=stats["unavailable"],
        mean_tree_size=float(steps.mean()), mean_accept_prob=float(acc.mean()), stuck=stats["stuck"],
    )
