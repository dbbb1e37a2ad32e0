"""Hypothesis sets for the paper's evaluation conditions (Sec. VI-A) and out-of-set truths.

- **Full set**: Ψ_k = Θ_k × B with the truth inside it (joint inference).
- **Fixed θ**: Θ = {θ} with θ ≠ θ*, all of B (expertise inferred under a wrong preference).
- **Fixed β**: B = {β} with β from an expertise group other than β*'s, all of Θ_k
  (preferences inferred under a wrong expertise).
- **Out of set**: θ*_out drawn from Θ \\ Θ_k and β*_out ~ U(0.01, 10).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..hypotheses import HypothesisSet, expertise_group, normalize_theta, parse_betas


def _rows_equal(thetas: np.ndarray, theta: np.ndarray) -> np.ndarray:
    return np.all(np.isclose(thetas, theta, atol=1e-9), axis=1)


def full_set(thetas, betas) -> HypothesisSet:
    """Ψ = Θ × B, the joint-inference condition."""
    return HypothesisSet(np.asarray(thetas, dtype=np.float64), parse_betas(betas))


def fixed_theta_set(thetas, betas, theta_star, rng: np.random.Generator) -> HypothesisSet:
    """Θ = {θ} for one θ ≠ θ* drawn uniformly from ``thetas``; B unchanged."""
    thetas = np.asarray(thetas, dtype=np.float64)
    others = thetas[~_rows_equal(thetas, normalize_theta(theta_star))]
    if len(others) == 0:
        raise InputError("fixed-theta condition needs a θ in the set other than θ*")
    return HypothesisSet(others[int(rng.integers(len(others)))][None], parse_betas(betas))


def fixed_beta_set(thetas, betas, beta_star: float, rng: np.random.Generator) -> HypothesisSet:
    """B = {β} for one β drawn uniformly from the values of ``betas`` in another expertise group."""
    betas = parse_betas(betas)
    group = expertise_group(beta_star)
    others = betas[[expertise_group(b) != group for b in betas]]
    if len(others) == 0:
        raise InputError(f"fixed-beta condition needs a β outside the {group!r} expertise group")
    beta = float(others[int(rng.integers(len(others)))])
    return HypothesisSet(np.asarray(thetas, dtype=np.float64), [beta])


def sample_in_set_truth(hyp: HypothesisSet, group: str, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """(θ*, β*) drawn uniformly from Ψ with β* in the given expertise group."""
    betas = hyp.betas[[expertise_group(b) == group for b in hyp.betas]]
    if len(betas) == 0:
        raise InputError(f"no β of the {group!r} expertise group in the hypothesis set")
    return hyp.thetas[int(rng.integers(hyp.n_theta))].copy(), float(betas[int(rng.integers(len(betas)))])


def out_of_set_truth(
    all_thetas, set_thetas, rng: np.random.Generator, *, beta_range: tuple[float, float] = (0.01, 10.0)
) -> tuple[np.ndarray, float]:
    """θ*_out uniformly from ``all_thetas`` \\ ``set_thetas`` and β*_out ~ U(beta_range)."""
    all_thetas = np.asarray(all_thetas, dtype=np.float64)
    set_thetas = np.atleast_2d(np.asarray(set_thetas, dtype=np.float64))
    inside = np.zeros(len(all_thetas), dtype=bool)
    for t in set_thetas:
        inside |= _rows_equal(all_thetas, t)
    outside = all_thetas[~inside]
    if len(outside) == 0:
        raise InputError("every θ of the full grid is in the set; no out-of-set truth exists")
    lo, hi = beta_range
    if not 0 < lo < hi:
        raise InputError(f"beta_range must satisfy 0 < low < high, got {beta_range}")
    return outside[int(rng.integers(len(outside)))].copy(), float(rng.uniform(lo, hi))


def set_composition(theta_star, beta_star: float, thetas, betas) -> dict[str, float]:
    """How close a truth is to a set Θ × B (the factors of the paper's Table I).

    Returns ``theta_k_truth_similarity`` (mean cosine between θ* and the members of Θ),
    ``theta_k_diversity`` (mean cosine over the distinct pairs of Θ; 1.0 for a single member)
    and ``beta_set_distance`` (min |β* − b| over b ∈ B).
    """
    t = np.asarray(theta_star, dtype=np.float64)
    th = np.atleast_2d(np.asarray(thetas, dtype=np.float64))
    unit = th / np.linalg.norm(th, axis=1, keepdims=True)
    to_truth = unit @ (t / np.linalg.norm(t))
    pairs = unit @ unit.T
    iu = np.triu_indices(len(th), k=1)
    diversity = float(pairs[iu].mean()) if len(th) > 1 else 1.0
    b = parse_betas(betas)
    return {"theta_k_truth_similarity": float(to_truth.mean()), "theta_k_diversity": diversity,
            "beta_set_distance": float(np.min(np.abs(b - float(beta_star))))}
