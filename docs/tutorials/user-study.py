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
# # A user study from a folder
#
# A study is a folder: floor plans, one recording per participant and task, and a
# **manifest** that says who did what. `expertise-irl study` infers every participant
# (θ and β, jointly over all their tasks), checks the fit, and writes the tables and figures.
# Here we run it on the study bundled with the package, add a grouping column to compare
# two cohorts, and fit the participants as one **population** of β.
#
# This page was executed when the site was built. The source is the jupytext file
# `docs/tutorials/user-study.py`.

# %%
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from importlib.resources import files
from pathlib import Path

import pandas as pd
from IPython.display import Image, Markdown, display
from scipy.stats import spearmanr

EXAMPLE = Path(str(files("expertise_irl.userstudy") / "example"))
work = Path(tempfile.mkdtemp(prefix="expertise-irl-tutorial-"))
shutil.copytree(EXAMPLE, work / "study")


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


sorted(p.relative_to(work).as_posix() for p in (work / "study").rglob("*") if p.is_file())

# %% [markdown]
# ## The manifest
#
# One row per task: `participant,map,recording`, paths relative to the manifest. P07 drove
# two floor plans, so they have two rows, and their posterior is the product over both tasks.
# Any other column is carried into the tables. We add `cohort`, a made-up grouping for this
# tutorial: say the first four came from a trained group and the others were first-time
# drivers.

# %%
manifest = pd.read_csv(work / "study" / "manifest.csv")
trained = {"P01", "P02", "P03", "P07"}
manifest["cohort"] = ["trained" if p in trained else "novice" for p in manifest.participant]
manifest.to_csv(work / "study" / "manifest.csv", index=False)
display(manifest)

# %% [markdown]
# ## Run the study
#
# - `--fill-gaps`: P04's recording has a gap (see [the first tutorial](../infer-a-recording/)).
# - `--model maxent-relative`: the model the simulated people act by.
# - `--betas paper-real`: the paper's five temperatures keep this page quick. The default,
#   `--betas auto`, picks 16 values from the floor plans' reward scale and resolves the
#   experts better, at about twice the time.
# - `--group-by cohort`: compare β between the cohorts (Mann–Whitney).
# - `--population`: fit the participants as one population, log β ~ Normal(μ, σ²) per cohort,
#   and re-estimate each person under it ([the population model](../../population/)).
# - `--figures none`: skip the per-participant figures; `study.png` is always drawn.
#
# Participants who share a floor plan share one solve. The run is resumable: the same command
# on the same folder reuses the finished work.

# %%
expertise_irl("study", "study/manifest.csv", "--out", "out", "--fill-gaps", "--model", "maxent-relative",
              "--betas", "paper-real", "--group-by", "cohort", "--population", "--figures", "none")

# %% [markdown]
# ## The participants
#
# `study.csv` has one row per participant: β̂ (posterior mean) with its 90% interval, θ̂,
# the expertise-group probabilities, the path counts of the paper's Table V and more. The
# people are simulated, so we can put the truth beside the estimates.

# %%
out = work / "out"
study = pd.read_csv(out / "study.csv")
truth = pd.read_csv(work / "study" / "truth.csv").rename(columns={"beta": "beta_true"})
table = study.merge(truth[["participant", "beta_true"]], on="participant").sort_values("beta_true")
columns = ["participant", "cohort", "beta_true", "beta_hat", "beta_q05", "beta_q95",
           "theta_length", "theta_restricted", "theta_road", "path_length", "optimal_path_length"]
table[columns].round(3)

# %%
rho = spearmanr(table.beta_true, table.beta_hat).statistic
print(f"Spearman ρ between β* and β̂: {rho:.2f}")

# %% [markdown]
# `study.png` puts everyone on one axis: β̂ with its 90% interval against the expertise-group
# boundaries, and θ̂ as a heat map. The three most expert people (β* 0.1 to 0.3) all drove
# the optimal path, so their data cannot order them: their intervals overlap and reach the
# grid's smallest value, and the study warns that they may be more expert than the grid allows.

# %%
display(Image(filename=out / "study.png"))

# %% [markdown]
# ## Comparing the cohorts
#
# With `--group-by`, `study.md` compares β̂ between the groups. Two groups of four are few
# people, so read the p-value with that in mind.


# %%
def section(title: str) -> str:
    """The section of study.md under the heading ``## title``."""
    text = (out / "study.md").read_text()
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert match, f"no section {title!r} in study.md"
    return match.group(1).strip()


display(Markdown(section("β by cohort")))

# %% [markdown]
# ## The population of β
#
# Each participant alone says little about how expert the cohort is. The population model
# learns, from everyone at once, each cohort's typical β (exp μ) and how much people differ
# (σ of log β). Then it estimates each person under their cohort's population. Everything is
# in `population.json`; here is the group comparison:

# %%
population = json.loads((out / "population.json").read_text())
for group, values in population["population_beta"].items():
    typical, spread = values["median_beta"], values["sigma_log_beta"]
    print(f"{group} (n = {values['n']}): typical β, exp μ = {typical['mean']:.2g} "
          f"[90% {typical['q05']:.2g} to {typical['q95']:.2g}]; spread σ of log β = {spread['mean']:.2g}")
for c in population["comparisons"]:
    print(f"P(μ_{c['a']} < μ_{c['b']}) = {c['p_mu_a_lt_mu_b']:.3f}: "
          f"{c['a']}'s typical β is {c['beta_ratio_median']:.1f}× {c['b']}'s")

# %% [markdown]
# `population.png` draws each cohort's fitted population of β and, per participant, the 90%
# interval alone (light) and pooled (dark); on the right, the population mean of θ.

# %%
display(Image(filename=out / "population.png"))

# %% [markdown]
# The same numbers in words, with the held-out comparison and any sampler warnings, are in
# the study's report:

# %%
display(Markdown(section("Population (--population)")))

# %% [markdown]
# What to take from it:
#
# - **Cohorts.** The novices' typical β is several times the trained drivers'. The
#   population fit says so (P(μ_novice < μ_trained) is small), and so does the Mann–Whitney
#   test on the β̂'s above.
# - **Pooling.** Compare the light and dark bars. Pooling narrows the intervals of people
#   whose own data leave β open, and moves the estimates little where a person's path is
#   already decisive on this coarse grid.
# - **Few people.** With four people per cohort the populations are wide, and NUTS may report
#   a few divergent transitions. [The population model](../../population/) says what they
#   mean and when to worry.
#
# Next: every option of `study` and its outputs are in [User studies](../../user-studies/), and
# the model behind the population in [A population model](../../population/).

# %% [markdown]
# The files above were written to a temporary folder, removed here.

# %%
shutil.rmtree(work)
