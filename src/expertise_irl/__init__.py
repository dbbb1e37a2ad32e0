"""expertise-irl: joint inference of reward (θ) and expertise (β) from demonstrations.

Importing the package enables float64 in JAX: soft value iteration at
small β needs it.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("expertise-irl")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"
from .demos import Trajectories, read_demos_csv, simulate, write_demos_csv
from .errors import InputError
from .hypotheses import BETA_PRESETS, THETA_PRESETS, HypothesisSet, expertise_group, theta_grid
from .inference.belief import DiscreteBelief
from .mdp import TabularMDP
from .metrics import cosine_similarity, expertise_distance, policy_regret
from .planning import ConvergenceError, SoftSolution, solve
from .worlds.zones import ZoneMap, generate_map, load_bundled, load_map, parse_map

del version, PackageNotFoundError

__all__ = [
    "BETA_PRESETS",
    "THETA_PRESETS",
    "ConvergenceError",
    "DiscreteBelief",
    "HypothesisSet",
    "InputError",
    "SoftSolution",
    "TabularMDP",
    "Trajectories",
    "ZoneMap",
    "__version__",
    "cosine_similarity",
    "expertise_distance",
    "expertise_group",
    "generate_map",
    "load_bundled",
    "load_map",
    "parse_map",
    "policy_regret",
    "read_demos_csv",
    "simulate",
    "solve",
    "theta_grid",
    "write_demos_csv",
]
