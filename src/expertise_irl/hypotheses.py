"""Hypothesis sets Ψ = Θ × B (paper Secs. V-D and VIII-A).

Θ grids hold non-negative preference vectors normalised to unit l1 norm
(the policy depends on θ/β only, so the scale of θ is fixed). The
zero vector has no direction and is dropped; vectors equal after
normalisation are kept once, in the order they first appear in the
lexicographic product.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .errors import InputError

#: Component values of the paper's Θ grids (applied over all K features).
THETA_PRESETS: dict[str, tuple[float, ...]] = {
    "paper-sim": (0.0, 0.3, 0.5, 0.7, 1.0),  # Sec. V-D: 3,031 unique directions for K = 5
    "paper-real": (0.0, 0.5, 1.0),  # Sec. VIII-A: 19 unique directions for K = 3
}

#: The paper's expertise (temperature) sets.
BETA_PRESETS: dict[str, tuple[float, ...]] = {
    "paper-sim": (0.01, 0.09, 0.5, 1.0, 5.0, 10.0),
    "paper-real": (0.1, 0.3, 1.0, 3.0, 10.0),
}

#: Expertise groups of Sec. V-D, by the paper-sim temperatures they contain.
EXPERTISE_GROUPS: dict[str, tuple[float, ...]] = {
    "high": (0.01, 0.09),
    "medium": (0.5, 1.0),
    "low": (5.0, 10.0),
}
#: The expertise groups' names, from most to least expert.
GROUP_NAMES: tuple[str, ...] = tuple(EXPERTISE_GROUPS)
#: Group boundaries: geometric midpoints between neighbouring groups (√(0.09·0.5), √(1·5)).
GROUP_BOUNDARIES = (float(np.sqrt(0.09 * 0.5)), float(np.sqrt(1.0 * 5.0)))

_DEDUP_DECIMALS = 12


def normalize_theta(theta, *, what: str = "theta") -> np.ndarray:
    """Return θ scaled to unit l1 norm; rejects negative, non-finite or all-zero vectors."""
    theta = np.asarray(theta, dtype=np.float64)
    if not np.all(np.isfinite(theta)):
        raise InputError(f"{what} must be finite, got {theta.tolist()}")
    if np.any(theta < 0):
        raise InputError(f"{what} must be non-negative (θ ≥ 0), got {theta.tolist()}")
    norm = theta.sum(axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise InputError(f"{what} must have at least one positive component, got {theta.tolist()}")
    return theta / norm


def unique_rows(x: np.ndarray) -> np.ndarray:
    """Rows of ``x`` without duplicates (to 1e-12), in order of first appearance."""
    keys = np.round(x, _DEDUP_DECIMALS) + 0.0  # + 0.0 turns -0.0 into 0.0
    _, first = np.unique(keys, axis=0, return_index=True)
    return x[np.sort(first)]


def theta_grid(values: Sequence[float], n_features: int) -> np.ndarray:
    """Unit-l1 Θ grid from per-component ``values`` over ``n_features`` features.

    ``theta_grid((0, .3, .5, .7, 1), 5)`` has 3,031 rows (the paper's 3,124 non-zero
    products less duplicate directions); ``theta_grid((0, .5, 1), 3)`` has 19.

    Args:
        values: the values each component takes (finite, non-negative, one of them positive).
        n_features: the number of components K.

    Returns:
        ``[N, K]`` every product of the values, scaled to unit l1 norm, duplicate directions
        dropped, in order of first appearance.

    Raises:
        InputError: ``values`` is empty, has a negative or non-finite number or no positive one,
            ``n_features`` is below 1, or the product would have over 5,000,000 rows.
    """
    vals = np.asarray(values, dtype=np.float64)
    if vals.ndim != 1 or vals.size == 0:
        raise InputError("theta values must be a non-empty list of numbers")
    if not np.all(np.isfinite(vals)) or np.any(vals < 0):
        raise InputError(f"theta values must be finite and non-negative, got {vals.tolist()}")
    if not np.any(vals > 0):
        raise InputError("theta values must include a positive number")
    if n_features < 1:
        raise InputError(f"n_features must be >= 1, got {n_features}")
    vals = np.unique(vals)
    n_rows = vals.size**n_features
    if n_rows > 5_000_000:
        raise InputError(
            f"theta grid of {vals.size} values over {n_features} features has {n_rows:,} rows; "
            "sample a subset instead"
        )
    grid = np.array(list(itertools.product(vals, repeat=n_features)), dtype=np.float64)
    grid = grid[grid.sum(axis=1) > 0]
    return unique_rows(grid / grid.sum(axis=1, keepdims=True))


def sample_thetas(thetas: np.ndarray, k: int, rng: np.random.Generator, *, include=None) -> np.ndarray:
    """Θ_k: ``k`` distinct rows of ``thetas`` drawn without replacement.

    If ``include`` (a θ) is given it is guaranteed to be among them (the paper's in-set truth).
    """
    thetas = np.asarray(thetas, dtype=np.float64)
    if not 1 <= k <= len(thetas):
        raise InputError(f"k must be between 1 and {len(thetas)}, got {k}")
    if include is None:
        idx = rng.choice(len(thetas), size=k, replace=False)
        return thetas[np.sort(idx)]
    include = normalize_theta(include, what="included theta")
    match = np.flatnonzero(np.all(np.isclose(thetas, include, atol=1e-9), axis=1))
    rest = np.setdiff1d(np.arange(len(thetas)), match[:1])
    idx = rng.choice(rest, size=k - 1, replace=False)
    out = np.concatenate([include[None], thetas[np.sort(idx)]])
    return out


def parse_betas(betas: Sequence[float], *, what: str = "beta") -> np.ndarray:
    """Validated, de-duplicated, sorted temperatures (each finite and > 0)."""
    b = np.asarray(betas, dtype=np.float64).ravel()
    if b.size == 0:
        raise InputError(f"{what} list is empty")
    bad = ~np.isfinite(b) | (b <= 0)
    if bad.any():
        raise InputError(f"{what} must be > 0, got {b[bad][0]:g}")
    return np.unique(b)


def expertise_group(beta: float) -> str:
    """``"high"``, ``"medium"`` or ``"low"`` expertise for a temperature β.

    Boundaries are the geometric midpoints between the paper's groups:
    β < 0.212 is high, 0.212 ≤ β < 2.236 is medium, β ≥ 2.236 is low.

    Args:
        beta: the temperature β (lower is more expert).

    Returns:
        The group's name.
    """
    lo, hi = GROUP_BOUNDARIES
    if beta < lo:
        return "high"
    if beta < hi:
        return "medium"
    return "low"


@dataclass(frozen=True, eq=False)
class HypothesisSet:
    """The product Ψ = Θ × B, flattened θ-major.

    Hypothesis ``h`` is ``(thetas[h // n_beta], betas[h % n_beta])``. The θs are scaled to unit
    l1 norm and the βs sorted and de-duplicated when the set is built.

    Attributes:
        thetas: ``[n_theta, K]`` unit-l1 preference vectors.
        betas: ``[n_beta]`` temperatures.

    Raises:
        InputError: a θ is negative, non-finite or all zero, or a β is not finite and > 0.
    """

    thetas: np.ndarray
    betas: np.ndarray

    def __post_init__(self) -> None:
        th = np.atleast_2d(np.asarray(self.thetas, dtype=np.float64))
        th = normalize_theta(th)
        object.__setattr__(self, "thetas", th)
        object.__setattr__(self, "betas", parse_betas(self.betas))

    @property
    def n_theta(self) -> int:
        return int(self.thetas.shape[0])

    @property
    def n_beta(self) -> int:
        return int(self.betas.shape[0])

    def __len__(self) -> int:
        return self.n_theta * self.n_beta

    @property
    def theta(self) -> np.ndarray:
        """``[H, K]`` θ of every hypothesis."""
        return np.repeat(self.thetas, self.n_beta, axis=0)

    @property
    def beta(self) -> np.ndarray:
        """``[H]`` β of every hypothesis."""
        return np.tile(self.betas, self.n_theta)

    def index(self, theta, beta: float) -> int | None:
        """Flat index of ``(theta, beta)`` if it is in the set (θ compared after normalising).

        Args:
            theta: the preference vector ``[K]``, at any scale.
            beta: the temperature.

        Returns:
            The hypothesis' index, or None when the pair is not in the set.
        """
        t = normalize_theta(theta)
        ti = np.flatnonzero(np.all(np.isclose(self.thetas, t, atol=1e-9), axis=1))
        bi = np.flatnonzero(np.isclose(self.betas, beta, rtol=1e-9, atol=0))
        if ti.size == 0 or bi.size == 0:
            return None
        return int(ti[0] * self.n_beta + bi[0])


def resolve_thetas(spec: str, n_features: int) -> np.ndarray:
    """Θ from a CLI spec: a preset name or comma-separated component values."""
    spec = spec.strip()
    if spec in THETA_PRESETS:
        return theta_grid(THETA_PRESETS[spec], n_features)
    values = _parse_floats(spec, "--thetas")
    try:
        return theta_grid(values, n_features)
    except InputError as exc:
        raise InputError(f"--thetas {spec!r}: {exc}") from None


def resolve_betas(spec: str) -> np.ndarray:
    """B from a CLI spec: a preset name or comma-separated temperatures."""
    spec = spec.strip()
    if spec in BETA_PRESETS:
        return np.asarray(BETA_PRESETS[spec])
    return parse_betas(_parse_floats(spec, "--betas"), what="--betas value")


def _parse_floats(spec: str, what: str) -> list[float]:
    out = []
    for item in spec.split(","):
        item = item.strip()
        try:
            out.append(float(item))
        except ValueError:
            presets = ", ".join(sorted(THETA_PRESETS if what == "--thetas" else BETA_PRESETS))
            raise InputError(
                f"{what}: {item!r} is neither a number nor a preset ({presets})"
            ) from None
    return out
