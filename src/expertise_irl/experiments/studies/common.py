"""What the paper's studies share: the zone maps' feature names, the columns each of them writes
(defined here once, with the values that fill them), and the check of a config's named choices."""

from __future__ import annotations

import numpy as np

from ...errors import InputError
from ..spec import Column

FEATURES = ("length", "road", "avoid", "slow", "traffic")


def check_goal_reward(mode: str, bonus: float) -> None:
    """A one-line InputError unless the protocol's goal reward settings are valid."""
    import math

    from ...worlds.grid import check_goal_reward_mode

    check_goal_reward_mode(mode, "config")
    if isinstance(bonus, bool) or not isinstance(bonus, int | float) or not math.isfinite(bonus):
        raise InputError(f"goal_bonus must be a finite number, got {bonus!r}")


def check_among(name: str, values, allowed) -> None:
    """A one-line InputError unless ``values`` is non-empty and every one is in ``allowed``."""
    if not values or any(v not in allowed for v in values):
        raise InputError(f"{name} must be among {', '.join(allowed)}, got {', '.join(values)}")


def float_columns(docs: dict[str, str]) -> tuple[Column, ...]:
    """``float64`` columns, name -> meaning."""
    return tuple(Column(name, "float64", doc) for name, doc in docs.items())


def feature_columns(prefix: str, doc: str) -> tuple[Column, ...]:
    """``float64`` columns ``{prefix}_{feature}``, one per feature; ``{f}`` in ``doc`` names it."""
    return tuple(Column(f"{prefix}_{f}", "float64", doc.format(f=f)) for f in FEATURES)


def episode_columns(pairs_doc: str = "actions seen in the first n episodes",
                    capped_doc: str = "episodes among the first n that hit `max_steps` without "
                                      "reaching the goal") -> tuple[Column, ...]:
    """``n_pairs`` and ``n_capped``: what the rows' episodes hold."""
    return Column("n_pairs", "int64", pairs_doc), Column("n_capped", "int32", capped_doc)


def truth_columns(beta_doc: str = "β* of the person",
                  theta_doc: str = "θ* component `{f}` (unit l1 norm)") -> tuple[Column, ...]:
    """``beta_true``, ``group_true`` and ``theta_true_*``: the person's truth (:func:`truth_values`)."""
    return (Column("beta_true", "float64", beta_doc), Column("group_true", "string", "expertise group of β*"),
            *feature_columns("theta_true", theta_doc))


SEED = Column("seed", "int64", "the sweep's seed (`--seed`)")
GOAL_REWARD_MODE = Column("goal_reward_mode", "string",
                          "the protocol: how the goal pays (config `goal_reward_mode`): `scaled` (part of "
                          "`length`, weighted by θ_length) or `fixed` (`goal_bonus` outside θ·φ)")
N_STATES = Column("n_states", "int32", "states of the MDP")
MAP_COLUMNS = (Column("map_width", "int32", "map width (cells)"),
               Column("map_height", "int32", "map height (cells)"), N_STATES)
EPISODES_SEEN = Column("episodes", "int32", "episodes seen, n = 1..N")
BETA_HAT_MEAN = Column("beta_hat", "float64", "β̂ = E[β] after n episodes")
TRUTH_PROBABILITY = Column("truth_probability", "float64",
                           "posterior probability of (θ*, β*) (NaN if not in the set)")
#: The metrics of Sec. V-E, as ``fixed_vs_joint.estimate_metrics`` computes them (every study's rows).
METRIC_COLUMNS = float_columns({
    "expertise_distance": "|β* − β̂|",
    "cosine_similarity": "cosine of θ* and θ̂",
    "policy_regret": "Eq. 17 with θ̂ evaluated at the true β*",
    "return_regret": "what acting on θ̂ costs under θ*: the return of θ̂'s optimal policy short of the best "
                     "policy's, as a share of the uniform random policy's shortfall (0 best, 1 random; "
                     "`expertise_irl.metrics.return_regret`)",
})
#: Table I's factors: how close the truth is to the person's Ψ_k = Θ_k × B (:func:`composition_values`).
SET_COMPOSITION = float_columns({
    "theta_k_truth_similarity": "mean cosine between θ* and the members of Θ_k",
    "theta_k_diversity": "mean cosine over the distinct pairs of Θ_k",
    "beta_set_distance": "min |β* − b| over the set B",
})


def feature_values(prefix: str, values) -> dict[str, np.ndarray]:
    """The ``{prefix}_*`` columns of ``values [n, K]`` (K = the features)."""
    values = np.asarray(values)
    return {f"{prefix}_{f}": values[:, i] for i, f in enumerate(FEATURES)}


def truth_values(n: int, theta, beta: float) -> dict[str, np.ndarray]:
    """The :func:`truth_columns` of ``n`` rows of one person with truth (θ*, β*)."""
    from ...hypotheses import expertise_group

    return {"beta_true": np.full(n, beta), "group_true": np.full(n, expertise_group(beta), dtype=object),
            **{f"theta_true_{f}": np.full(n, theta[i]) for i, f in enumerate(FEATURES)}}


def composition_values(n: int, theta, beta: float, hypotheses) -> dict[str, np.ndarray]:
    """The :data:`SET_COMPOSITION` columns of ``n`` rows of one person scored with ``hypotheses``."""
    from ...inference.hypothesis_sets import set_composition

    return {name: np.full(n, v)
            for name, v in set_composition(theta, beta, hypotheses.thetas, hypotheses.betas).items()}
