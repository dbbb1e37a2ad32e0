"""The paper's priors (Sec. VII-A), shared by every continuous method.

θ: uniform (on [0, 1]^K for Algorithm 1's box, flat Dirichlet on the simplex otherwise).
β: Normal(5.005, 1.5) truncated to [0.01, 10].
"""

BETA_PRIOR_MEAN = 5.005
BETA_PRIOR_SD = 1.5
BETA_RANGE = (0.01, 10.0)

#: The prior in words, as the command line prints it and results record it.
PRIOR_TEXT = (f"θ uniform (on the simplex; Algorithm 1's box: on [0, 1]^K), "
              f"β ~ Normal({BETA_PRIOR_MEAN:g}, {BETA_PRIOR_SD:g}) truncated to "
              f"[{BETA_RANGE[0]:g}, {BETA_RANGE[1]:g}] (the paper's Sec. VII-A)")
