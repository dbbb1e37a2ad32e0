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
# # Infer a person from a recording
#
# A participant tele-operated a robot across a warehouse floor while a tracker logged its
# position ten times a second. From that one log we want two things: **what they wanted**
# (the weights θ of their reward over the floor's features: short paths, keeping out of
# restricted areas, driving along the roads) and **how expert they are** (the temperature β
# of their policy: small β means they reliably pick the best move for their goals).
#
# The recording is participant P04 of the study bundled with the package
# (`expertise_irl/userstudy/example/`). The participants are simulated, so we know the truth
# and can check the answer at the end. This page was executed when the site was built; the
# source is a [jupytext](https://jupytext.readthedocs.io) file, `docs/tutorials/infer-a-recording.py`,
# that opens as a notebook (`jupytext --to ipynb`) or runs as a script.
#
# We use the command line, as you would on your own data, and read its outputs with pandas.

# %%
import json
import os
import shutil
import subprocess
import sys
import tempfile
from importlib.resources import files
from pathlib import Path

import pandas as pd
from IPython.display import Image, display

import expertise_irl as ei

EXAMPLE = Path(str(files("expertise_irl.userstudy") / "example"))
work = Path(tempfile.mkdtemp(prefix="expertise-irl-tutorial-"))
for name in ["spec-b.txt", "spec-b.toml", "recordings/P04.csv", "truth.csv"]:
    shutil.copy(EXAMPLE / name, work)


def expertise_irl(*args: str, expect: int = 0) -> None:
    """Run ``expertise-irl ARGS`` in ``work``, print what it says, check its exit code."""
    exe = Path(sys.executable).with_name("expertise-irl")  # installed beside this Python
    command = [str(exe) if exe.exists() else "expertise-irl", *args]
    env = {k: v for k, v in os.environ.items()
           if k not in ("FORCE_COLOR", "CLICOLOR_FORCE", "MPLBACKEND")}
    env.update(NO_COLOR="1", TERM="dumb", COLUMNS="90")  # plain text, no animation
    proc = subprocess.run(command, cwd=work, capture_output=True, text=True, env=env)
    print((proc.stdout + proc.stderr).strip())
    assert proc.returncode == expect, f"exit code {proc.returncode}, expected {expect}"


sorted(p.name for p in work.iterdir())

# %% [markdown]
# ## The task: a floor plan
#
# `spec-b.txt` is the floor plan, one character per 0.5 m cell (`#` shelving, `x` restricted,
# `> < ^ v` roads with their direction, `S` the start, `G` the goals), and `spec-b.toml` beside
# it says it is a warehouse (`world = "warehouse"`, `cell_size`, the discount `gamma`). Its
# features are `length` (each move costs 1, a turn 2, the goal pays a bonus), `restricted`
# and `road`. The whole format is in [User studies](../../user-studies/#floor-plans).

# %%
print((work / "spec-b.toml").read_text())
expertise_irl("render", "spec-b.txt", "--out", "plan.png")
display(Image(filename=work / "plan.png", width=720))

# %% [markdown]
# ## The recording
#
# A recording is a CSV of `episode,t,x,y`: seconds and metres, as the robot's tracker wrote
# them. P04 drove one episode.

# %%
rec = pd.read_csv(work / "P04.csv")
print(f"{len(rec)} samples over {rec.t.max():.0f} s, "
      f"x from {rec.x.min():.2f} to {rec.x.max():.2f} m, y from {rec.y.min():.2f} to {rec.y.max():.2f} m")
rec.head()

# %% [markdown]
# ## From samples to moves
#
# Inference needs moves from cell to cell. `discretise` resamples the recording at 1 Hz (the
# paper's rate), maps each kept sample to its cell, splits diagonal steps and checks that
# consecutive cells are neighbours. This recording has a hole: the tracker dropped out for a
# few seconds while the robot moved on, and by default that is an error naming the row:

# %%
expertise_irl("discretise", "spec-b.txt", "--recording", "P04.csv", "--out", "demos.csv", expect=2)

# %% [markdown]
# `--fill-gaps` joins the two ends of a gap by a shortest free path and counts what it filled,
# so nothing is changed silently. The figure shows every sample (grey), the samples kept at
# the ticks (rings), the cells of the path (blue) and the filled cells (orange).

# %%
expertise_irl("discretise", "spec-b.txt", "--recording", "P04.csv", "--out", "demos.csv", "--fill-gaps")
display(Image(filename=work / "demos.png", width=720))
pd.read_csv(work / "demos.csv").head()

# %% [markdown]
# ## Joint inference
#
# The discrete-set method (the paper's Eq. 13) scores every hypothesis (θ, β) of a grid:
# `--thetas paper-real` is the paper's 19 preference directions over three features and
# `--betas paper-real` its five temperatures, 0.1 to 10. Each hypothesis is solved by soft
# value iteration once, and the posterior is exact on the grid (uniform prior). The example's
# people act by `maxent-relative` (noisy people still head for the goal; see
# [The model](../../model/#observation-models)), so we infer with that model.

# %%
expertise_irl("infer", "spec-b.txt", "--demos", "demos.csv", "--thetas", "paper-real",
              "--betas", "paper-real", "--model", "maxent-relative", "--out", "result.json")

# %% [markdown]
# The result is a JSON document: the posterior means β̂ and θ̂, the expertise group, the
# marginals and every hypothesis with its log-likelihood and probability.

# %%
result = json.loads((work / "result.json").read_text())
print("β̂ =", round(result["beta_hat"], 3), "→", result["expertise_group"], "expertise")
theta_hat = dict(zip(result["feature_names"], result["theta_hat"], strict=True))
print("θ̂ =", {name: round(t, 3) for name, t in theta_hat.items()})
print("most probable hypothesis:", result["map"])
beta = result["marginals"]["beta"]
pd.DataFrame({"β": beta["values"], "P(β | demonstrations)": beta["probabilities"]}).round(4)

# %% [markdown]
# ## Reading the figure
#
# `plot` draws any result. Left, the map with the path (one dot per visited cell). Then the
# marginal posterior of β (bars over the grid; low β = expert) and of each θ component, with
# the posterior mean dashed.

# %%
expertise_irl("plot", "result.json", "--map", "spec-b.txt", "--demos", "demos.csv", "--out", "result.png")
display(Image(filename=work / "result.png"))

# %% [markdown]
# How to read it:
#
# - **β.** Almost all the mass sits on one grid value. That says which grid value explains the
#   path best, not that β is known to three digits: the grid has nothing between its values.
# - **θ.** The θ marginals are wider. One episode on one floor plan says much about the
#   trade-off the person made, and less about each weight alone. Several different θ's
#   produce the same path here.
#
# ## Against the truth
#
# The example's people are simulated, so `truth.csv` holds what generated P04's recording:

# %%
truth = pd.read_csv(work / "truth.csv").set_index("participant").loc["P04"]
print(f"β* = {truth.beta}, β̂ = {result['beta_hat']:.3g}")
print("θ* =", truth.drop("beta").to_dict())

# %%
theta_true = truth[["theta_length", "theta_restricted", "theta_road"]].to_numpy(float)
print(f"cosine similarity of θ̂ and θ*: {ei.cosine_similarity(theta_true, result['theta_hat']):.2f}")

# %% [markdown]
# - **β.** β* = 0.8 is not on the grid. The posterior puts its mass on 0.3, the grid value
#   that explains this path best, and P04 lands in the medium-expertise group, as the truth
#   does (the groups split at β = 0.21 and 2.24). A finer grid gets closer: `expertise-irl study`
#   uses `--betas auto`, 16 values chosen from the map's own reward scale.
# - **θ.** θ̂ puts weight on `restricted`, which P04 does not care about (θ* = 0). Their path
#   had no reason to enter a restricted area: the shortest way to the goal runs along the
#   roads, away from both red zones. So this one episode cannot tell a person who avoids
#   restricted areas from one who ignores them, and the posterior spreads over both. More
#   episodes, or tasks where avoiding the zones costs something, would separate them.
#
# Next: [a whole study from a folder](../user-study/), or [the model](../../model/) behind
# these numbers.

# %% [markdown]
# The files above were written to a temporary folder, removed here.

# %%
shutil.rmtree(work)
