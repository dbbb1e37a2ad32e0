# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Teaching or clumsiness?
#
# The same person walks the bundled `zones30` map twice: once doing the task, once showing it
# to someone who watches. They want the same things (θ*) and are as skilled both times (β*).
# We ask two questions of each recording: was this person teaching, and what is their β once
# teaching is allowed for?
#
# The model is on [Teaching or clumsiness?](../../teaching/). This page was executed when the
# site was built; its source is `docs/tutorials/teaching.py`, a
# [jupytext](https://jupytext.readthedocs.io) file that also runs as a script.

# %%
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from IPython.display import Image, display

work = Path(tempfile.mkdtemp(prefix="expertise-irl-teaching-"))


def expertise_irl(*args: str, expect: int = 0) -> None:
    """Run ``expertise-irl ARGS`` in ``work``, print what it says, check its exit code."""
    exe = Path(sys.executable).with_name("expertise-irl")  # installed beside this Python
    command = [str(exe) if exe.exists() else "expertise-irl", *args]
    env = {k: v for k, v in os.environ.items()
           if k not in ("FORCE_COLOR", "CLICOLOR_FORCE", "MPLBACKEND")}
    env.update(NO_COLOR="1", TERM="dumb", COLUMNS="90")  # plain text, no animation
    proc = subprocess.run(command, cwd=work, capture_output=True, text=True, env=env)
    lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "━" not in ln]  # no progress bars
    print("\n".join(lines).strip())
    assert proc.returncode == expect, f"exit code {proc.returncode}, expected {expect}"


# %% [markdown]
# ## A doer and a teacher
#
# The person's weights over `zones30`'s five features are θ* = (0.3, 0.4, 0.1, 0, 0.2): short
# paths and roads matter most. Their temperature is β* = 0.2, a medium expert. `simulate
# --model pedagogical --lambda 1` makes them a teacher. Each action is reweighted by how much
# it tells a literal observer about θ*, with weight λ = 1. The observer believes paper-real Θ ×
# sixteen β log-spaced from 0.01 to 10 (`--observer-betas`), the set we infer on below.
# `--lambda 0`, the default, is a doer: the paper's `maxent` person. Both recordings use the
# same seed.

# %%
betas = ",".join(f"{b:.3g}" for b in np.logspace(-2, 1, 16))
person = ["zones30", "--theta", "0.3,0.4,0.1,0,0.2", "--beta", "0.2", "--episodes", "20",
          "--max-steps", "300", "--seed", "2", "--observer-betas", betas]
expertise_irl("simulate", *person, "--model", "pedagogical", "--out", "doer.csv")
expertise_irl("simulate", *person, "--model", "pedagogical", "--lambda", "1", "--out", "teacher.csv")

# %% [markdown]
# ## Inference under the teaching model
#
# `infer --model pedagogical` computes the exact posterior over θ, β and the teaching weight λ
# on a fixed set. The λ grid holds 0, so the same run also gives `maxent`'s reading (the
# λ = 0 slice). The paper's six β values are far apart (0.09 and 0.5 around β* = 0.2), so we
# name the log-spaced grid of sixteen, 1.58× apart: a β within 1.26× of anyone's is in it.

# %%
for who in ("doer", "teacher"):
    expertise_irl("infer", "zones30", "--demos", f"{who}.csv", "--model", "pedagogical",
                  "--betas", betas, "--check", "off", "--out", f"{who}.json")

# %% [markdown]
# Each result's `teaching` entry holds:
#
# - the verdict, from the Bayes factor of teaching against doing;
# - λ̂ with its 90% interval;
# - β̂ under `maxent` beside the teaching model's.

# %%
truth = 0.2
for who in ("doer", "teacher"):
    doc = json.loads((work / f"{who}.json").read_text())
    t = doc["teaching"]
    print(f"{who:8s} verdict {t['verdict']:9s} 2 log BF = {2 * t['log_bayes_factor']:7.1f}   "
          f"λ̂ = {t['lambda_hat']:.3f} [{t['lambda_interval'][0]:g}, {t['lambda_interval'][1]:g}]   "
          f"β̂ {doc['beta_hat']:.3f} (maxent {t['beta_hat_maxent']:.3f}, truth {truth})")

# %% [markdown]
# The doer reads as doing. Their β̂ is the same under both models: λ's posterior sits at 0.
# The teacher reads as teaching, and the two models disagree about their skill.
#
# Under `maxent`, the teacher looks *more* expert than they are. A teacher in this model
# exaggerates: the actions that display θ are mostly the ones θ prefers anyway, so showing
# sharpens the choices. `maxent` can only explain sharper choices by a smaller β. The teaching
# model puts part of the sharpening on λ and reads β nearer the truth.
#
# λ̂ is well below the teacher's λ = 1, and its interval, on the grid, misses it. θ* lies between
# the set's directions, so no hypothesis's informativeness is the teacher's own, and a weaker λ
# fits best. Over the benchmark's teachers read as teaching, λ̂/λ* has a median near 1 but a wide
# spread ([Performance](../../performance/#teaching-or-doing)).
#
# Real teachers may also take planned detours. Those would look like noise, and this per-action
# model does not produce them; [the docs](../../teaching/#why-the-per-action-form) say why.

# %% [markdown]
# ## The evidence against `maxent`
#
# `compare-models` puts the teaching model beside the others. Its Bayes factor against `maxent`
# is the evidence for teaching. The held-out check asks the same question of episodes the fit
# did not see.

# %%
expertise_irl("compare-models", "zones30", "--demos", "teacher.csv", "--models", "maxent,pedagogical",
              "--betas", betas, "--out", "compare.json")
cmp = json.loads((work / "compare.json").read_text())
for m in cmp["models"]:
    print(f"{m['model']:12s} log evidence {m['log_evidence']:8.1f}   held-out log-lik / action "
          f"{m['heldout_log_likelihood_per_action']:.4f}   β̂ {m['beta_hat']:.3f}")

# %% [markdown]
# ## The walks
#
# The teacher's episodes on the map, beside the teaching model's posterior of β and θ.

# %%
expertise_irl("plot", "teacher.json", "--map", "zones30", "--demos", "teacher.csv", "--out", "teacher.png")
display(Image(filename=work / "teacher.png", width=860))
