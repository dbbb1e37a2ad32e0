"""JAX's float64 is switched on by the functions that compute, not by importing a module.

Each case runs in a fresh interpreter (the test process has long had float64 on), with
``JAX_ENABLE_X64`` removed from its environment: importing every module of the package leaves JAX
in float32, and each path that needs float64 (a solve, the population model, MAP, NUTS,
Algorithm 1, the command line) switches it on itself.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

#: Imports every module of the package, then checks that none switched float64 on.
PRELUDE = """
import importlib, pkgutil
import jax, jax.numpy as jnp
import numpy as np
import expertise_irl
for m in pkgutil.walk_packages(expertise_irl.__path__, "expertise_irl."):
    importlib.import_module(m.name)
    assert not jax.config.jax_enable_x64, f"importing {m.name} switched float64 on"
from collections import deque
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.worlds.zones import load_bundled
mdp = load_bundled("corridor").to_mdp()
theta = np.array([0.5, 0.3, 0.1, 0.05, 0.05])
# a shortest path to the goal, found without solving (a solve would switch float64 on)
start = int(mdp.start_states[0])
came, queue = {start: None}, deque([start])
while not mdp.terminal[s := queue.popleft()]:
    for a in range(mdp.n_actions):
        if (n := int(mdp.next_state[s, a])) >= 0 and n not in came:
            came[n] = (s, a)
            queue.append(n)
pairs = []
while came[s] is not None:
    s, a = came[s]
    pairs.insert(0, (s, a))
demos = Trajectories(np.zeros(len(pairs)), np.arange(len(pairs)), *np.array(pairs).T)
"""

CASES = {
    "solve": """
from expertise_irl.planning import solve
sol = solve(mdp, theta, 0.5)
assert jax.config.jax_enable_x64 and sol.value.dtype == np.float64
""",
    "population": """
from expertise_irl.hypotheses import HypothesisSet
from expertise_irl.inference.population import Hyperparameters, log_marginals, population_data
hyp = HypothesisSet(np.eye(2), np.array([0.5, 1.0]))
data = population_data([np.array([-1.0, -2.0, -3.0, -4.0])], hyp)
out = log_marginals(data, Hyperparameters(np.zeros(1), np.ones(1), 2.0, np.full(2, 0.5)))
assert jax.config.jax_enable_x64 and data.arrays().log_lik.dtype == jnp.float64
""",
    "map": """
from expertise_irl.inference.gradient import map_estimate
map_estimate(mdp, demos, n_starts=1, rng=np.random.default_rng(0))
assert jax.config.jax_enable_x64
""",
    "nuts": """
from expertise_irl.inference.nuts import nuts_posterior
res = nuts_posterior(mdp, demos, num_warmup=5, num_samples=5, num_chains=1, laplace_init=False)
assert jax.config.jax_enable_x64 and res.theta.dtype == np.float64
""",
    "birl": """
from expertise_irl.inference.birl import extended_birl
extended_birl(mdp, demos, n_iter=3, rng=0)
assert jax.config.jax_enable_x64
""",
}


def _run(script: str) -> None:
    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]


@pytest.mark.slow
@pytest.mark.parametrize("path", list(CASES))
def test_each_path_that_computes_switches_float64_on_itself(path):
    _run(PRELUDE + CASES[path])


def test_before_jax_is_imported_the_switch_is_the_environment_variable_jax_reads():
    _run("""
import sys, os
from expertise_irl.numerics import enable_float64
enable_float64()
assert "jax" not in sys.modules and os.environ["JAX_ENABLE_X64"] == "1"
import jax, jax.numpy as jnp
assert jax.config.jax_enable_x64 and jnp.ones(1).dtype == jnp.float64
enable_float64()  # idempotent, and now through JAX's own setting
assert jax.config.jax_enable_x64
""")


def test_the_command_line_computes_in_float64():
    _run("""
import jax
from expertise_irl.cli import app
from typer.testing import CliRunner
assert not jax.config.jax_enable_x64
result = CliRunner().invoke(app, ["--version"])
assert result.exit_code == 0 and jax.config.jax_enable_x64
""")
