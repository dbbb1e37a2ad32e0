"""The paper's priors (Sec. VII-A), shared by every continuous method.

θ: uniform (on [0, 1]^K for Algorithm 1's box, flat Dirichlet on the simplex otherwise).
β: Normal(5.005, 1.5) truncated to [0.01, 10].
"""

BETA_PRIOR_MEAN = 5.005
BETA_PRIOR_SD = 1.5
BETA_RANGE = (0.01, 10.0)
