"""expertise-irl: joint inference of reward (θ) and expertise (β) from demonstrations.

The public names below are imported on first use, so ``import expertise_irl`` (and the
command line's ``--help``) does not pay for JAX. Importing a module switches nothing on: the
functions that compute with JAX switch it to float64 when they are called (soft value iteration
at small β needs it), through :func:`expertise_irl.numerics.enable_float64`.
"""

from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING, Any

try:
    __version__ = version("expertise-irl")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"
del version, PackageNotFoundError

#: public name -> module that defines it (relative to this package)
_EXPORTS = {
    "Trajectories": ".demos.trajectories", "read_demos_csv": ".demos.csv_io",
    "simulate": ".demos.simulation", "simulate_teacher": ".demos.simulation",
    "write_demos_csv": ".demos.csv_io",
    "ArgumentError": ".errors", "ConvergenceError": ".errors", "ExpertiseIRLError": ".errors",
    "InputError": ".errors",
    "BETA_PRESETS": ".hypotheses", "THETA_PRESETS": ".hypotheses", "HypothesisSet": ".hypotheses",
    "expertise_group": ".hypotheses", "theta_grid": ".hypotheses",
    "DiscreteBelief": ".inference.belief",
    "OnlineEstimator": ".inference.online", "next_start": ".inference.active",
    "compare_models": ".inference.evidence", "MODELS": ".models",
    "extended_birl": ".inference.birl", "BIRLResult": ".inference.birl",
    "map_estimate": ".inference.gradient", "MAPResult": ".inference.gradient",
    "nuts_posterior": ".inference.nuts", "NUTSResult": ".inference.nuts",
    "TabularMDP": ".mdp",
    "OptionError": ".options", "infer": ".pipeline", "prepare": ".pipeline",
    "Result": ".result", "read_result": ".results", "write_result": ".results",
    "cosine_similarity": ".metrics", "expertise_distance": ".metrics", "policy_regret": ".metrics",
    "SoftSolution": ".planning.soft_vi", "solve": ".planning.soft_vi",
    "ZoneMap": ".worlds.zones", "generate_map": ".worlds.zones", "load_bundled": ".worlds.zones",
    "load_map": ".worlds.zones", "parse_map": ".worlds.zones",
}

__all__ = [
    "BETA_PRESETS",
    "MODELS",
    "THETA_PRESETS",
    "ArgumentError",
    "BIRLResult",
    "ConvergenceError",
    "DiscreteBelief",
    "ExpertiseIRLError",
    "HypothesisSet",
    "InputError",
    "MAPResult",
    "NUTSResult",
    "OnlineEstimator",
    "OptionError",
    "Result",
    "SoftSolution",
    "TabularMDP",
    "Trajectories",
    "ZoneMap",
    "__version__",
    "compare_models",
    "cosine_similarity",
    "expertise_distance",
    "expertise_group",
    "extended_birl",
    "generate_map",
    "infer",
    "load_bundled",
    "load_map",
    "map_estimate",
    "next_start",
    "nuts_posterior",
    "parse_map",
    "policy_regret",
    "prepare",
    "read_demos_csv",
    "read_result",
    "simulate",
    "simulate_teacher",
    "solve",
    "theta_grid",
    "write_demos_csv",
    "write_result",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'expertise_irl' has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return __all__


if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from .demos.csv_io import read_demos_csv, write_demos_csv
    from .demos.simulation import simulate, simulate_teacher
    from .demos.trajectories import Trajectories
    from .errors import ArgumentError, ConvergenceError, ExpertiseIRLError, InputError
    from .hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, expertise_group, theta_grid
    from .inference.active import next_start
    from .inference.belief import DiscreteBelief
    from .inference.birl import BIRLResult, extended_birl
    from .inference.evidence import compare_models
    from .inference.gradient import MAPResult, map_estimate
    from .inference.nuts import NUTSResult, nuts_posterior
    from .inference.online import OnlineEstimator
    from .mdp import TabularMDP
    from .metrics import cosine_similarity, expertise_distance, policy_regret
    from .models import MODELS
    from .options import OptionError
    from .pipeline import infer, prepare
    from .planning.soft_vi import SoftSolution, solve
    from .result import Result
    from .results import read_result, write_result
    from .worlds.zones import ZoneMap, generate_map, load_bundled, load_map, parse_map
