"""A population model over a study's participants, exact over the discrete set.

Each participant i has one hypothesis h_i = (θ_j, β_k) of the study's set (the same set for
everyone, θ-major and β fastest), and the grid log-likelihood ``ℓ_i[j, k] = log P(Ξ_i | θ_j, β_k)``
of all their data (the solves the study already shares give it). Instead of a fixed uniform
prior, the prior over the grid is a population with hyperparameters ψ = (μ_g, σ_g for each group
g, α, m):

- **expertise**: ``P(β_k | μ, σ) ∝ exp(−(log β_k − μ)² / 2σ²)``, the normal density of log β at the
  grid's cells, normalised over the cells (μ and σ in natural-log units; participant i uses the
  (μ, σ) of their group, one group unless ``--group-by``);
- **preferences**: ``P(θ_j | α, m) ∝ Π_c θ̃_jc^(α·m_c − 1)`` over the θ's the participant allows
  (a feature that is 0 on all their tasks is kept at 0, as in the independent posterior), the
  Dirichlet(α·m) density. The set's θ's lie on the simplex but many on its boundary, where that
  density is 0 or ∞, so it is evaluated at ``θ̃ = (1 − ε)·θ + ε/K`` (:data:`THETA_SHRINK` ε =
  0.1): each point moved a tenth of the way to the simplex's centre. Then α·m = 1 gives the
  uniform prior exactly, and as α → ∞ with m = θ̃_j the prior puts all its mass on θ_j.

The prior factorises, so a participant's marginal likelihood is exact and cheap:

    log p(Ξ_i | ψ) = log Σ_j P(θ_j | α, m) Σ_k P(β_k | μ_g(i), σ_g(i)) exp ℓ_i[j, k],

a smooth function of ψ whose cost is N·|Θ|·|B|, independent of the map once the solves are
done. On it:

- :func:`type2_ml`: type-II maximum likelihood, ψ̂ = argmax Σ_i log p(Ξ_i | ψ), by L-BFGS-B on
  the exact gradient (JAX) in (μ, log σ, log α, z), m = softmax(z), from several starts;
- :func:`sample_population`: NUTS over ψ with every participant marginalised exactly, through the
  kernel and chain driver of :mod:`.nuts_kernel`, under the hyperprior :data:`HYPERPRIOR_TEXT`
  (:class:`Hyperprior`);
- :func:`shrunk_posteriors`: each participant's posterior over the grid under the population,
  ``P(h | Ξ_i, Ξ) = E_ψ[P(h | Ξ_i, ψ)]`` over the hyperparameter draws (or at ψ̂);
- :func:`heldout_comparison`: each participant's held-out units predicted three ways, in nats
  per action: independently (uniform prior, the study's held-out check), under the population
  fitted **without that participant** (type-II ML on the others), and fully pooled (one
  posterior shared by everyone, from the others' data and the participant's training data).

Limits (:mod:`tests.test_population` checks both): with σ → ∞ and α·m = 1 the prior is uniform
and each participant's posterior is the independent one; with σ → 0 and α → ∞ the prior sits on
one cell (θ_j*, β_k*) and the marginal likelihood is that of full pooling, Σ_i ℓ_i[j*, k*].
"""

from __future__ import annotations

import math
import warnings as _warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property, partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import logsumexp as jlse
from scipy.special import logsumexp

from ..errors import InputError
from ..hypotheses import HypothesisSet
from ..numerics import enable_float64
from .posterior import log_sum_exp

__all__ = ["HYPERPRIOR_TEXT", "THETA_SHRINK", "Hyperparameters", "Hyperprior", "PopulationData",
           "PopulationFit", "PopulationPosterior", "heldout_comparison", "log_marginals",
           "population_data", "population_log_prior", "population_theta_prior", "sample_population",
           "shrunk_posteriors", "type2_ml"]

#: ε of θ̃ = (1 − ε)·θ + ε/K, where the Dirichlet density of the θ set is evaluated.
THETA_SHRINK = 0.1
#: Type-II ML's box: σ and α (their logs are bounded), μ within this many nats of the grid.
SIGMA_RANGE = (1e-3, 20.0)
ALPHA_RANGE = (1e-2, 1e5)
MU_MARGIN = 3.0


# ----------------------------------------------------------------------------- data
@dataclass(frozen=True)
class PopulationData:
    """A study's participants as the population model sees them.

    Attributes:
        hypotheses: the set, shared by every participant.
        log_lik: ``[N, n_theta, n_beta]`` ℓ_i (all of participant i's data).
        allowed: ``[N, n_theta]`` the θ's each participant's prior allows.
        groups: ``[N]`` each participant's group index.
        group_names: the groups' names (``("all",)`` for one group).
        participants: the participants' names.
    """

    hypotheses: HypothesisSet
    log_lik: np.ndarray
    allowed: np.ndarray
    groups: np.ndarray
    group_names: tuple[str, ...]
    participants: tuple[str, ...]

    @property
    def n(self) -> int:
        return self.log_lik.shape[0]

    @property
    def n_groups(self) -> int:
        return len(self.group_names)

    def arrays(self) -> _Arrays:
        """The JAX arguments of :func:`log_marginals` (:class:`_Arrays`; computed once)."""
        return self._arrays

    @cached_property
    def _arrays(self) -> _Arrays:
        enable_float64()  # every computation of the model starts from these arrays
        hyp = self.hypotheses
        with np.errstate(divide="ignore", invalid="ignore"):
            masks, mask_index = np.unique(self.allowed, axis=0, return_inverse=True)
            log_allowed = np.where(masks, 0.0, -np.inf)
            row_max = self.log_lik.max(axis=2)
            scaled = np.exp(self.log_lik - np.where(np.isfinite(row_max), row_max, 0.0)[:, :, None])
        one_hot = np.eye(self.n_groups)[self.groups]
        K = hyp.thetas.shape[1]
        log_tt = np.log((1 - THETA_SHRINK) * hyp.thetas + THETA_SHRINK / K)
        return _Arrays(jnp.asarray(self.log_lik), jnp.asarray(log_allowed),
                       jnp.asarray(np.asarray(mask_index).reshape(-1)), jnp.asarray(one_hot),
                       jnp.asarray(np.log(hyp.betas)), jnp.asarray(log_tt), jnp.asarray(scaled),
                       jnp.asarray(row_max))


class _Arrays(NamedTuple):
    """The data of :func:`_log_marginals` (a pytree: the compiled programs' argument).

    Attributes:
        log_lik: ``[N, nT, nB]`` ℓ.
        log_allowed: ``[U, nT]`` 0 or −inf: the distinct sets of allowed θ's (usually one or two).
        mask_index: ``[N]`` which of them each participant has.
        one_hot: ``[N, G]`` each participant's group.
        log_b: ``[nB]`` log β of the grid.
        log_tt: ``[nT, K]`` log θ̃.
        scaled: ``[N, nT, nB]`` ``exp(ℓ_ijk − M_ij)``.
        row_max: ``[N, nT]`` ``M_ij = max_k ℓ_ijk``.
    """

    log_lik: jnp.ndarray
    log_allowed: jnp.ndarray
    mask_index: jnp.ndarray
    one_hot: jnp.ndarray
    log_b: jnp.ndarray
    log_tt: jnp.ndarray
    scaled: jnp.ndarray
    row_max: jnp.ndarray


def population_data(log_lik: Sequence[np.ndarray], hyp: HypothesisSet, *,
                    allowed: Sequence[np.ndarray] | None = None, groups: Sequence[str] | None = None,
                    participants: Sequence[str] | None = None) -> PopulationData:
    """:class:`PopulationData` from each participant's ``[H]`` grid log-likelihood (θ-major), the
    θ's each allows (``[n_theta]`` bool; all by default) and each one's group name (groups in order
    of first appearance). A participant whom every allowed hypothesis gives probability 0 has no
    place in the population: :class:`InputError` names them."""
    rows = [np.asarray(x, dtype=np.float64) for x in log_lik]
    N = len(rows)
    if N == 0:
        raise InputError("the population model needs at least one participant")
    names = tuple(str(p) for p in (participants if participants is not None else range(N)))
    if len(names) != N:
        raise InputError(f"need one name per participant, got {len(names)} for {N}")
    for i, x in enumerate(rows):
        if x.shape != (len(hyp),):
            raise InputError(f"participant {names[i]}: the log-likelihood must have one value per hypothesis "
                             f"({len(hyp)}), got shape {x.shape}")
    ll = np.stack(rows)
    if allowed is None:
        ok = np.ones((N, hyp.n_theta), dtype=bool)
    else:
        masks = [np.asarray(a, dtype=bool) for a in allowed]
        shapes = {m.shape for m in masks}
        ok = np.stack(masks) if len(shapes) == 1 else None
        if ok is None or ok.shape != (N, hyp.n_theta):
            got = ok.shape if ok is not None else f"{len(masks)} masks of shapes {sorted(shapes)}"
            raise InputError(f"allowed must be [participants, n_theta] = [{N}, {hyp.n_theta}], got {got}")
    grid = ll.reshape(N, hyp.n_theta, hyp.n_beta)
    for i in range(N):
        if np.isnan(grid[i]).any() or np.isposinf(grid[i]).any():
            raise InputError(f"participant {names[i]}: a log-likelihood is NaN or +inf")
        if not ok[i].any():
            raise InputError(f"participant {names[i]}: their prior allows no θ of the set")
        if not np.isfinite(grid[i][ok[i]]).any():
            raise InputError(f"participant {names[i]}: every hypothesis of the set gives their data "
                             "probability 0, so the population model cannot include them")
    if groups is None:
        gnames, gidx = ("all",), np.zeros(N, dtype=int)
    else:
        groups = [str(g) for g in groups]
        if len(groups) != N:
            raise InputError(f"need one group per participant, got {len(groups)} for {N}")
        gnames = tuple(dict.fromkeys(groups))
        gidx = np.array([gnames.index(g) for g in groups], dtype=int)
    return PopulationData(hyp, grid, ok, gidx, gnames, names)


# ----------------------------------------------------------------------------- the model
class Hyperparameters:
    """ψ: ``mu [G]``, ``sigma [G]`` (log β's mean and sd per group), ``alpha``, ``m [K]``."""

    def __init__(self, mu, sigma, alpha, m):
        self.mu = np.atleast_1d(np.asarray(mu, np.float64))
        self.sigma = np.atleast_1d(np.asarray(sigma, np.float64))
        self.alpha, self.m = float(alpha), np.asarray(m, np.float64)

    def to_dict(self, group_names: Sequence[str] | None = None) -> dict[str, Any]:
        names = list(group_names) if group_names is not None else [str(g) for g in range(len(self.mu))]
        return {"mu": dict(zip(names, self.mu.tolist(), strict=True)),
                "sigma": dict(zip(names, self.sigma.tolist(), strict=True)),
                "alpha": self.alpha, "m": self.m.tolist()}


def _log_priors(arrays: _Arrays, mu, sigma, alpha, m):
    """``([N, n_beta], [N, n_theta])``: each participant's log P(β_k) and log P(θ_j) (normalised;
    the θ prior once per distinct set of allowed θ's)."""
    lpb = -0.5 * ((arrays.log_b[None, :] - mu[:, None]) / sigma[:, None]) ** 2  # [G, nB]
    lpb = lpb - jlse(lpb, axis=1, keepdims=True)
    lpt = (arrays.log_tt @ (alpha * m - 1.0))[None, :] + arrays.log_allowed  # [U, nT]
    lpt = lpt - jlse(lpt, axis=1, keepdims=True)
    return arrays.one_hot @ lpb, lpt[arrays.mask_index]


#: Where a participant's scaled sum (see :func:`_log_marginals`) is below this, it counts as this.
ROW_FLOOR = 1e-300


def _log_marginals(arrays, mu, sigma, alpha, m):
    """``[N]`` log p(Ξ_i | ψ) (JAX-traceable).

    With the row-scaled likelihood ``s_ij = Σ_k P(β_k) exp(ℓ_ijk − M_ij)`` (``M_ij = max_k ℓ_ijk``,
    so ``s_ij ≤ 1``) and ``z_ij = M_ij + log P(θ_j)``, ``A_i = max_j z_ij``:

        log p(Ξ_i | ψ) = A_i + log Σ_j s_ij exp(z_ij − A_i),

    one product with the grid and one exponential per θ row, no logarithm per row (the
    transcendental functions, not the product, are most of a gradient's cost on a CPU). Every
    term is at most 1, so nothing overflows; the value is exact to double precision unless the
    sum falls below :data:`ROW_FLOOR` (the population puts its β mass where even the participant's
    most probable θ row explains them e^−690 worse than at that row's best β), where it counts as
    the floor: such a ψ lies e^−690 or more below where the participant's likelihood is, and no
    sampler or optimiser goes there (:func:`_log_marginals_lse` is the exact sum, for checks)."""
    lpb, lpt = _log_priors(arrays, mu, sigma, alpha, m)
    s = jnp.einsum("ijk,ik->ij", arrays.scaled, jnp.exp(lpb))
    z = arrays.row_max + lpt  # [N, nT]; −inf where the row is not allowed or has probability 0
    a = jax.lax.stop_gradient(jnp.max(z, axis=1, keepdims=True))  # the value does not depend on A_i
    total = jnp.sum(s * jnp.exp(z - a), axis=1)
    return a[:, 0] + jnp.log(jnp.maximum(total, ROW_FLOOR))


def _log_marginals_lse(arrays, mu, sigma, alpha, m):
    """``[N]`` log p(Ξ_i | ψ) as one log-sum-exp over every cell (exact; for checks)."""
    lpb, lpt = _log_priors(arrays, mu, sigma, alpha, m)
    inner = jlse(arrays.log_lik + lpb[:, None, :], axis=2)  # [N, nT]: Σ_k P(β_k) P(Ξ_i | θ_j, β_k)
    return jlse(inner + lpt, axis=1)


def log_marginals(data: PopulationData, psi: Hyperparameters) -> np.ndarray:
    """``[N]`` each participant's log marginal likelihood log p(Ξ_i | ψ)."""
    _check_psi(data, psi)
    return np.asarray(_log_marginals(data.arrays(), jnp.asarray(psi.mu), jnp.asarray(psi.sigma),
                                     psi.alpha, jnp.asarray(psi.m)))


def population_log_prior(data: PopulationData, psi: Hyperparameters) -> np.ndarray:
    """``[N, n_theta, n_beta]`` each participant's log prior over the grid under ψ."""
    _check_psi(data, psi)
    lpb, lpt = _log_priors(data.arrays(), jnp.asarray(psi.mu), jnp.asarray(psi.sigma), psi.alpha,
                           jnp.asarray(psi.m))
    return np.asarray(lpt[:, :, None] + lpb[:, None, :])


def population_theta_prior(hyp: HypothesisSet, psi: Hyperparameters) -> np.ndarray:
    """``[n_theta]`` the population's prior over the whole θ set under ψ, P(θ_j | α, m) ∝
    Π_c θ̃_jc^(α·m_c − 1) (every θ allowed)."""
    K = hyp.thetas.shape[1]
    lpt = np.log((1 - THETA_SHRINK) * hyp.thetas + THETA_SHRINK / K) @ (psi.alpha * psi.m - 1.0)
    return np.exp(lpt - logsumexp(lpt))


def _check_psi(data: PopulationData, psi: Hyperparameters) -> None:
    K = data.hypotheses.thetas.shape[1]
    if psi.mu.shape != (data.n_groups,) or psi.sigma.shape != (data.n_groups,):
        raise InputError(f"mu and sigma need one value per group ({data.n_groups})")
    if psi.m.shape != (K,) or not np.isclose(psi.m.sum(), 1.0) or (psi.m < 0).any():
        raise InputError(f"m must be a point of the {K}-simplex, got {psi.m.tolist()}")
    if (psi.sigma <= 0).any() or psi.alpha <= 0:
        raise InputError("sigma and alpha must be positive")


# ----------------------------------------------------------------------------- type-II ML
@dataclass(frozen=True)
class PopulationFit:
    """Type-II maximum likelihood: ψ̂, Σ_i log p(Ξ_i | ψ̂), every start's optimum."""

    psi: Hyperparameters
    log_marginal: float
    optima: np.ndarray
    evaluations: int


def _bounds(data: PopulationData):
    lb = np.log(data.hypotheses.betas)
    G, K = data.n_groups, data.hypotheses.thetas.shape[1]
    return ([(lb.min() - MU_MARGIN, lb.max() + MU_MARGIN)] * G
            + [tuple(math.log(v) for v in SIGMA_RANGE)] * G
            + [tuple(math.log(v) for v in ALPHA_RANGE)] + [(-20.0, 20.0)] * K)


def _unpack(x, G: int):
    return x[:G], jnp.exp(x[G:2 * G]), jnp.exp(x[2 * G]), jax.nn.softmax(x[2 * G + 1:])


def _pack(psi: Hyperparameters) -> np.ndarray:
    z = np.log(np.maximum(psi.m, 1e-9))
    return np.concatenate([psi.mu, np.log(psi.sigma), [math.log(psi.alpha)], z - z.mean()])


@partial(jax.jit, static_argnums=(3,))
def _type2_value_and_grad(x, arrays, w, G: int):
    """−Σ_i w_i log p(Ξ_i | ψ(x)) and its gradient, compiled once per shape (the data are arguments)."""
    def objective(x):
        mu, sigma, alpha, m = _unpack(x, G)
        return -jnp.sum(w * _log_marginals(arrays, mu, sigma, alpha, m))

    return jax.value_and_grad(objective)(x)


def type2_ml(data: PopulationData, *, n_starts: int = 4, rng: np.random.Generator | int = 0,
             weights: np.ndarray | None = None, start: Hyperparameters | None = None,
             ftol: float = 1e-13, gtol: float = 1e-8) -> PopulationFit:
    """ψ̂ = argmax Σ_i w_i log p(Ξ_i | ψ) (``weights`` w, 1 by default; 0 leaves a participant
    out) by L-BFGS-B on the exact gradient. Starts: the uniform-prior point (μ the grid's middle,
    σ = 1, α·m = 1) or ``start``, then ``n_starts − 1`` random ones (μ uniform over the grid, σ
    log-uniform on [0.1, 3], α log-uniform on [0.5·K, 20·K], m Dirichlet(1))."""
    from scipy.optimize import minimize

    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    arrays = data.arrays()
    G, K = data.n_groups, data.hypotheses.thetas.shape[1]
    w = jnp.ones(data.n) if weights is None else jnp.asarray(weights, dtype=jnp.float64)
    lb = np.log(data.hypotheses.betas)
    first = start or Hyperparameters(np.full(G, lb.mean()), np.ones(G), K, np.full(K, 1.0 / K))
    evaluations = 0

    def fun(x):
        nonlocal evaluations
        evaluations += 1
        v, g = _type2_value_and_grad(jnp.asarray(x), arrays, w, G)
        v = float(v)
        if not math.isfinite(v):
            return 1e300, np.zeros_like(x)
        return v, np.asarray(g, dtype=np.float64)

    bounds = _bounds(data)
    best, optima = None, []
    for i in range(n_starts):
        if i == 0:
            x0 = _pack(first)
        else:
            sigma = np.exp(rng.uniform(math.log(0.1), math.log(3.0), G))
            alpha = K * math.exp(rng.uniform(math.log(0.5), math.log(20.0)))
            mu, m = rng.uniform(lb.min(), lb.max(), G), rng.dirichlet(np.ones(K))
            x0 = _pack(Hyperparameters(mu, sigma, alpha, m))
        x0 = np.clip(x0, [b[0] for b in bounds], [b[1] for b in bounds])
        res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"maxiter": 1000, "ftol": ftol, "gtol": gtol})
        optima.append(-res.fun)
        if best is None or res.fun < best.fun:
            best = res
    mu, sigma, alpha, m = (np.asarray(v) for v in _unpack(jnp.asarray(best.x), G))
    return PopulationFit(Hyperparameters(mu, sigma, float(alpha), m), float(-best.fun), np.asarray(optima),
                         evaluations)


# ----------------------------------------------------------------------------- NUTS
@dataclass(frozen=True)
class Hyperprior:
    """The hyperprior of :func:`sample_population` (see :data:`HYPERPRIOR_TEXT`); ``None`` fields
    are set from the β grid by :meth:`resolve`: μ_g ~ Normal(middle of log β's grid, half its
    span, at least 1); σ_g's floor a quarter of the grid's smallest step in log β.

    Why the floor: below it the population already sits on one cell of the grid (the next cell
    gets e^−8 of its mass), and the normal density on the cells then switches from one cell to
    the next within a sliver of μ, a cliff NUTS cannot step across (its divergences). A floor
    there keeps every population the grid can tell apart and none of the cliff.
    """

    mu_loc: float | None = None
    mu_scale: float | None = None
    sigma_scale: float = 1.0
    alpha_log_loc: float | None = None  # log K by default: α·m = 1 at the median α and m uniform
    alpha_log_scale: float = 1.0
    sigma_floor: float | None = None

    def resolve(self, data: PopulationData) -> Hyperprior:
        lb = np.log(data.hypotheses.betas)
        K = data.hypotheses.thetas.shape[1]
        steps = np.diff(np.sort(lb))
        floor = self.sigma_floor
        if floor is None:
            floor = 0.25 * float(steps.min()) if steps.size else 0.25
        return Hyperprior(
            float(0.5 * (lb.min() + lb.max())) if self.mu_loc is None else self.mu_loc,
            max(1.0, float(0.5 * (lb.max() - lb.min()))) if self.mu_scale is None else self.mu_scale,
            self.sigma_scale, math.log(K) if self.alpha_log_loc is None else self.alpha_log_loc,
            self.alpha_log_scale, floor)

    def text(self) -> str:
        return (f"μ_g ~ Normal({self.mu_loc:.3g}, {self.mu_scale:.3g}) (log β), "
                f"σ_g ~ HalfNormal({self.sigma_scale:g}) on σ_g ≥ {self.sigma_floor:.3g}, "
                f"log α ~ Normal({self.alpha_log_loc:.3g}, {self.alpha_log_scale:g}), m ~ Dirichlet(1, …, 1)")


HYPERPRIOR_TEXT = ("μ_g ~ Normal(the middle of log β's grid, half its span, at least 1), "
                   "σ_g ~ HalfNormal(1) (natural-log units) truncated below at a quarter of the grid's "
                   "smallest step in log β, log α ~ Normal(log K, 1) (α·m = 1, the uniform prior, at its "
                   "median with m uniform), m ~ Dirichlet(1, …, 1); all independent")


@dataclass(frozen=True)
class PopulationPosterior:
    """NUTS draws of ψ and their diagnostics.

    Attributes:
        mu, sigma: ``[C, D, G]``; alpha: ``[C, D]``; m: ``[C, D, K]``.
        r_hat, ess_bulk: ``{name: value}`` per scalar hyperparameter (``mu[g]``, ``sigma[g]``,
            ``alpha``, ``m[c]``), None where unavailable.
        divergences: divergent transitions after warm-up.
        hyperprior: the resolved :class:`Hyperprior`.
        group_names: the groups' names.
    """

    mu: np.ndarray
    sigma: np.ndarray
    alpha: np.ndarray
    m: np.ndarray
    r_hat: dict[str, float | None]
    ess_bulk: dict[str, float | None]
    divergences: int
    hyperprior: Hyperprior
    group_names: tuple[str, ...]
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def scalars(self) -> dict[str, np.ndarray]:
        """``{name: [C, D]}`` every scalar hyperparameter's draws."""
        out = {}
        for g, name in enumerate(self.group_names):
            out[f"mu[{name}]"] = self.mu[..., g]
            out[f"sigma[{name}]"] = self.sigma[..., g]
        out["alpha"] = self.alpha
        for c in range(self.m.shape[-1]):
            out[f"m[{c}]"] = self.m[..., c]
        return out

    def draws(self) -> list[Hyperparameters]:
        C, D, G = self.mu.shape
        mu, sigma = self.mu.reshape(C * D, G), self.sigma.reshape(C * D, G)
        alpha, m = self.alpha.reshape(-1), self.m.reshape(C * D, -1)
        return [Hyperparameters(mu[s], sigma[s], alpha[s], m[s]) for s in range(C * D)]


class _Data:
    """What :func:`~.nuts_kernel.sample` reads of ``f``: the data (its compiled programs' argument)
    and a placeholder warm start."""

    def __init__(self, arrays):
        self.counts = arrays

    @staticmethod
    def zero_start():
        return jnp.zeros(())


def _posterior(data: PopulationData, prior: Hyperprior):
    """The :class:`~.nuts_kernel.Posterior` of ψ in x = (u_m [K−1], μ [G], log(σ − floor) [G], log α)."""
    import numpyro.distributions as dist
    from numpyro.distributions.transforms import biject_to

    from .nuts_kernel import Posterior

    G, K = data.n_groups, data.hypotheses.thetas.shape[1]
    m_map = biject_to(dist.constraints.simplex)
    n_u = K - 1

    def unpack(x):
        u = x[:n_u]
        m = m_map(u)
        mu, v, log_alpha = x[n_u:n_u + G], x[n_u + G:n_u + 2 * G], x[n_u + 2 * G]
        return u, m, mu, v, log_alpha

    def log_hyperprior(mu, v, log_alpha):
        # densities in (μ, v = log(σ − floor), log α): HalfNormal(σ)·e^v on σ ≥ floor, Normal(log α);
        # m's Dirichlet(1) is constant
        sigma = prior.sigma_floor + jnp.exp(v)
        lp = jnp.sum(-0.5 * ((mu - prior.mu_loc) / prior.mu_scale) ** 2)
        lp += jnp.sum(-0.5 * (sigma / prior.sigma_scale) ** 2 + v)
        lp += -0.5 * ((log_alpha - prior.alpha_log_loc) / prior.alpha_log_scale) ** 2
        return lp

    def potential(x, start, arrays):
        u, m, mu, v, log_alpha = unpack(x)
        ll = jnp.sum(_log_marginals(arrays, mu, prior.sigma_floor + jnp.exp(v), jnp.exp(log_alpha), m))
        return -(ll + log_hyperprior(mu, v, log_alpha) + m_map.log_abs_det_jacobian(u, m))

    def constrained(x):
        _, m, mu, v, log_alpha = unpack(x)
        return m, jnp.concatenate([mu, prior.sigma_floor + jnp.exp(v), jnp.exp(log_alpha)[None]])

    def log_density(m, rest, arrays):
        mu, sigma, alpha = rest[:G], rest[G:2 * G], rest[2 * G]
        return jnp.sum(_log_marginals(arrays, mu, sigma, alpha, m))

    return Posterior(potential, constrained, log_density, n_u + 2 * G + 1)


def sample_population(data: PopulationData, *, num_warmup: int = 500, num_samples: int = 500,
                      num_chains: int = 4, seed: int = 0, prior: Hyperprior = Hyperprior(),
                      target_accept: float = 0.9, progress=None) -> PopulationPosterior:
    """Sample P(ψ | Ξ) ∝ p(ψ) Π_i p(Ξ_i | ψ) with NUTS (the participants marginalised exactly)."""
    from .diagnostics import _MIN_DRAWS
    from .nuts_kernel import check_run, sample

    num_warmup, num_samples, num_chains = check_run(num_warmup, num_samples, num_chains, target_accept)
    prior = prior.resolve(data)
    G = data.n_groups
    post = _posterior(data, prior)
    m, rest, div, _, _ = sample(post, _Data(data.arrays()), num_warmup=num_warmup, num_samples=num_samples,
                                num_chains=num_chains, seed=int(seed), dense_mass=True,
                                target_accept=target_accept)
    m, rest = np.asarray(m, np.float64), np.asarray(rest, np.float64)
    out = PopulationPosterior(rest[..., :G], rest[..., G:2 * G], rest[..., 2 * G], m, {}, {},
                              int(div.sum()), prior, data.group_names)
    r_hat, ess = {}, {}
    C, D = out.alpha.shape
    import arviz as az

    for name, x in out.scalars().items():
        with _warnings.catch_warnings():
            _warnings.simplefilter("ignore")
            r = float(az.rhat(x)) if C >= 2 and D >= _MIN_DRAWS else math.nan
            e = float(az.ess(x, method="bulk")) if D >= _MIN_DRAWS else math.nan
        r_hat[name] = r if math.isfinite(r) else None
        ess[name] = e if math.isfinite(e) else None
    warns = []
    bad = [k for k, v in r_hat.items() if v is not None and v > 1.01]
    if bad:
        warns.append(f"R-hat above 1.01 for {', '.join(bad)}: the population's chains disagree; run longer")
    low = [k for k, v in ess.items() if v is not None and v < 100 * C / 4]
    if low:
        warns.append(f"bulk ESS below {100 * C // 4} for {', '.join(low)}: intervals are rough; run longer")
    if out.divergences:
        warns.append(f"{out.divergences} divergent transitions after warm-up")
    return PopulationPosterior(out.mu, out.sigma, out.alpha, out.m, r_hat, ess, out.divergences, prior,
                               data.group_names, tuple(warns))


# ----------------------------------------------------------------------------- posteriors
#: At most this many grid rows × draws at once (``[draws, N, n_theta]``) in the draws' loops.
DRAW_BLOCK = 20_000_000


def _stack(psis: Sequence[Hyperparameters]) -> tuple[jnp.ndarray, ...]:
    return (jnp.asarray(np.stack([p.mu for p in psis])), jnp.asarray(np.stack([p.sigma for p in psis])),
            jnp.asarray([p.alpha for p in psis]), jnp.asarray(np.stack([p.m for p in psis])))


def _blocks(n_draws: int, rows: int):
    step = max(1, DRAW_BLOCK // max(rows, 1))
    return [slice(s, min(s + step, n_draws)) for s in range(0, n_draws, step)]


@jax.jit
def _shrunk_block(arrays: _Arrays, mu, sigma, alpha, m):
    """Σ over a block of draws s of P_s(θ_j, β_k | Ξ_i), ``[N, nT, nB]``.

    Per draw the posterior is ``exp(ℓ_ijk + log P_s(θ_j) + log P_s(β_k) − log p_s(Ξ_i))`` =
    ``scaled_ijk · a_sij · b_sik`` with ``a_sij = exp(M_ij + log P_s(θ_j) − log p_s(Ξ_i))`` and
    ``b_sik = P_s(β_k)``, so the sum over draws is one batched matrix product ``aᵀ b`` per
    participant instead of an exponential per grid cell and draw. ``a`` is divided by the draw's
    total ``Σ_j a_sij s_sij`` (1 but where :data:`ROW_FLOOR` was hit), so each draw's posterior sums
    to 1; every exponent is at most ~690 (:func:`_log_marginals`), so nothing overflows."""
    def parts(mu, sigma, alpha, m):
        lpb, lpt = _log_priors(arrays, mu, sigma, alpha, m)
        b = jnp.exp(lpb)  # [N, nB]
        s = jnp.einsum("ijk,ik->ij", arrays.scaled, b)
        ea = arrays.row_max + lpt - _log_marginals(arrays, mu, sigma, alpha, m)[:, None]
        a = jnp.exp(ea)
        return a / jnp.sum(a * s, axis=1, keepdims=True), b

    a, b = jax.vmap(parts)(mu, sigma, alpha, m)  # [S, N, nT], [S, N, nB]
    return arrays.scaled * jnp.einsum("sij,sik->ijk", a, b)


def shrunk_posteriors(data: PopulationData,
                      psis: Sequence[Hyperparameters] | Hyperparameters) -> np.ndarray:
    """``[N, n_theta, n_beta]`` each participant's posterior over the grid under the population,
    averaged over ``psis`` (NUTS draws, or one ψ̂)."""
    psis = [psis] if isinstance(psis, Hyperparameters) else list(psis)
    if not psis:
        raise InputError("need at least one set of hyperparameters")
    for psi in psis:
        _check_psi(data, psi)
    arrays = data.arrays()
    stacked = _stack(psis)
    total = np.zeros(data.log_lik.shape)
    for block in _blocks(len(psis), data.n * data.hypotheses.n_theta):
        total += np.asarray(_shrunk_block(arrays, *(x[block] for x in stacked)))
    return total / len(psis)


def independent_posteriors(data: PopulationData) -> np.ndarray:
    """``[N, n_theta, n_beta]`` each participant's posterior under the uniform prior over their
    allowed θ's and the β grid (the study's independent posterior)."""
    with np.errstate(divide="ignore"):
        lp = data.log_lik + np.where(data.allowed, 0.0, -np.inf)[:, :, None]
    return np.exp(lp - logsumexp(lp, axis=(1, 2), keepdims=True))


# ----------------------------------------------------------------------------- held-out
def _predict(train: np.ndarray, unit: np.ndarray, log_prior: np.ndarray) -> float:
    """log P(unit | train) = log Σ_h P(h | train) P(unit | h) under ``log_prior`` (arrays over h)."""
    with np.errstate(invalid="ignore"):
        return float(log_sum_exp(train + unit + log_prior) - log_sum_exp(train + log_prior))


@jax.jit
def _participant_log_prior(arrays: _Arrays, i, mu, sigma, alpha, m):
    """``[H]`` participant i's log prior over the grid under ψ (θ-major)."""
    lpb, lpt = _log_priors(arrays, mu, sigma, alpha, m)
    return (lpt[i][:, None] + lpb[i][None, :]).reshape(-1)


def heldout_comparison(data: PopulationData, units: Sequence[Sequence[tuple[np.ndarray, int]]], *,
                       fit: PopulationFit | None = None, n_starts: int = 1) -> dict[str, Any]:
    """Each participant's held-out units predicted three ways, in nats per action.

    ``units[i]`` lists participant i's held-out units as ``(train [H], unit [H], actions)``: the
    log-likelihood of the rest of their data, of the unit alone, and the unit's number of actions
    (the study's split: leave-one-episode-out, else leave-one-task-out); an empty list leaves them
    out of the comparison. For each unit:

    - ``independent``: the uniform prior over their allowed θ's and the β grid;
    - ``population``: the population prior at ψ̂_−i, type-II ML on every other participant (warm
      started at ``fit``, the type-II fit on everyone, or fitted here), so the participant's own
      data never informs their prior;
    - ``pooled``: one posterior shared by everyone: the uniform prior times every other
      participant's likelihood and the participant's training data.

    Returns ``{"per_participant": [{participant, units, actions, independent, population,
    pooled}], "total": {independent, population, pooled}, "actions"}``; values in nats per action,
    None for a participant without units.
    """
    if len(units) != data.n:
        raise InputError(f"need the held-out units of every participant ({data.n}), got {len(units)}")
    fit = fit or type2_ml(data, n_starts=n_starts)
    arrays = data.arrays()
    ll = data.log_lik.reshape(data.n, -1)
    with np.errstate(divide="ignore"):
        flat_allowed = np.repeat(np.where(data.allowed, 0.0, -np.inf), data.hypotheses.n_beta, axis=1)
    uniform = flat_allowed - logsumexp(flat_allowed, axis=1, keepdims=True)
    total_ll = ll.sum(axis=0)
    rows, sums, n_all = [], dict.fromkeys(("independent", "population", "pooled"), 0.0), 0
    for i in range(data.n):
        if not units[i]:
            rows.append({"participant": data.participants[i], "units": 0, "actions": 0,
                         "independent": None, "population": None, "pooled": None})
            continue
        w = np.ones(data.n)
        w[i] = 0.0
        # warm started at ψ̂, to a relative change of 1e-10 in the objective: the held-out scores
        # move by far less than the differences they are compared on
        psi = (type2_ml(data, n_starts=1, weights=w, start=fit.psi, ftol=1e-10, gtol=1e-6).psi
               if data.n > 1 else fit.psi)
        lp_pop = np.asarray(_participant_log_prior(arrays, i, jnp.asarray(psi.mu), jnp.asarray(psi.sigma),
                                                   psi.alpha, jnp.asarray(psi.m)))
        others = total_ll - ll[i]
        score = dict.fromkeys(sums, 0.0)
        actions = 0
        for train, lu, n in units[i]:
            train, lu = np.asarray(train, dtype=np.float64), np.asarray(lu, dtype=np.float64)
            score["independent"] += _predict(train, lu, uniform[i])
            score["population"] += _predict(train, lu, lp_pop)
            score["pooled"] += _predict(train + others, lu, uniform[i])
            actions += int(n)
        rows.append({"participant": data.participants[i], "units": len(units[i]), "actions": actions,
                     **{k: v / actions for k, v in score.items()}})
        for k in sums:
            sums[k] += score[k]
        n_all += actions
    total = {k: (v / n_all if n_all else None) for k, v in sums.items()}
    return {"per_participant": rows, "total": total, "actions": n_all}
