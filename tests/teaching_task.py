"""The small task the teaching model's tests share: crossroads with 31 θ × 3 β, solved once."""

import numpy as np

from expertise_irl.hypotheses import HypothesisSet, theta_grid
from expertise_irl.numerics import enable_float64
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.maps import resolve_world

#: The set of ``--thetas 0,1 --betas 0.1,0.5,2`` (31 θ × 3 β on crossroads' five features).
THETAS, BETAS = "0,1", "0.1,0.5,2"


def crossroads_task(tol: float = 1e-8):
    """``(mdp, hyp, log_policy)``: crossroads, the set above and its ``maxent`` solve to ``tol``."""
    enable_float64()
    mdp = resolve_world("crossroads").to_mdp()
    hyp = HypothesisSet(theta_grid((0.0, 1.0), mdp.n_features), np.array([0.1, 0.5, 2.0]))
    lp = np.asarray(solve(mdp, hyp.theta, hyp.beta, tol=tol).log_policy)
    return mdp, hyp, lp
