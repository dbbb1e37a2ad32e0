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
# # Reproduce a figure of the paper
#
# The paper's Fig. 2 makes its first point: inferring expertise while **assuming** the
# person's preferences (the *Fixed θ* set) misjudges β, while inferring both (the *Full* set)
# does not. Here we rebuild that figure from scratch with the experiment engine, at the
# `smoke` scale. That is a handful of simulated people on small random maps, enough to run the
# whole pipeline in about a minute, not enough to conclude anything. The same commands with
# `--scale paper` give the paper's counts. The report we got at that scale is under
# [Reproduction results](../../reproduction/).
#
# This page was executed when the site was built. The source is the jupytext file
# `docs/tutorials/reproduce-a-figure.py`.

# %%
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd
from IPython.display import Image, display

from expertise_irl.experiments import load

work = Path(tempfile.mkdtemp(prefix="expertise-irl-tutorial-"))


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


# %% [markdown]
# ## The studies
#
# Each of the paper's experiments is a **study** with three scales. `experiment list` shows
# them, with the size of each sweep and the time it should take on this machine. Fig. 2 comes
# from `conditions` (paper Sec. VI-A): simulated people in the paper's three expertise groups,
# each inferred three ways. *Full* is the joint set Ψ_k = Θ_k × B. *Fixed θ* assumes one
# preference vector and infers β. *Fixed β* assumes one expertise and infers θ.

# %%
expertise_irl("experiment", "list")

# %% [markdown]
# ## Run the sweep
#
# One worker keeps the machine free for the rest of the build; the rows are the same for any
# number of workers, on a laptop or a Dask cluster (`--scheduler`). The sweep directory holds
# the config, one Parquet file of rows per task, their timings and a log of the runs. Running
# the same command again resumes: finished tasks are kept.

# %%
expertise_irl("experiment", "run", "conditions", "--out", "conditions", "--scale", "smoke", "--workers", "1")

# %%
expertise_irl("experiment", "status", "conditions")

# %% [markdown]
# ## The rows
#
# `expertise_irl.experiments.load` reads a sweep as a pandas DataFrame: one row per simulated
# person × condition × episode count, with the truth, the estimates and the paper's three
# metrics. Fig. 2 is the expertise distance |β* − β̂| of the in-set people (their truth is in
# the hypothesis set) after three episodes, Full against Fixed θ, per expertise group:

# %%
rows = load(work / "conditions")
print(f"{len(rows)} rows, {rows.columns.size} columns")
fig2 = rows[(rows.truth == "in_set") & (rows.episodes == 3)
            & rows.condition.isin(["full", "fixed_theta"])]
fig2.pivot_table(index="group_true", columns="condition", values="expertise_distance",
                 aggfunc=["mean", "count"]).reindex(["high", "medium", "low"]).round(3)

# %% [markdown]
# ## The report: figures, tables and the paper's claims
#
# `experiment report` builds, from the Parquet rows alone, the study's figures (PNG and PDF),
# its tables and `report.md`. The report sets each of the paper's claims beside our number,
# with a verdict.

# %%
expertise_irl("experiment", "report", "conditions")
report = work / "conditions" / "report"
sorted(p.name for p in (report / "figures").glob("*.png"))

# %%
display(Image(filename=report / "figures" / "fig2.png"))

# %% [markdown]
# Each violin is one method's |β* − β̂| over the people of a group (dot: median, bar: the
# middle half). Green is inferring θ and β together; orange is inferring β under an
# assumed θ. The paper's reading is that the joint set is closer for the high- and
# medium-expertise people, and that both find the low-expertise people to be low.
#
# The claims behind Fig. 2, as `claims.csv` has them. At `smoke` every test is on a handful of
# people, so a claim whose direction matches can still read *differs*: its *why* begins
# "inconclusive" when the test cannot decide. The report says at the top that this scale
# means nothing.

# %%
claims = pd.read_csv(report / "claims.csv")
with pd.option_context("display.max_colwidth", 90):
    display(claims[claims.paper.str.contains("Fig. 2", regex=False)][["claim", "ours", "verdict", "why"]])

# %% [markdown]
# ## At the paper's scale
#
# ```
# expertise-irl experiment run conditions --out runs/conditions --scale paper
# expertise-irl experiment report runs/conditions
# ```
#
# 600 simulated people in 30,000 rows; `experiment list` above says how long it takes here.
# The figures, tables and verdicts we got, under both goal-reward protocols, are in
# [Reproduction results](../../reproduction/). [Reproduce the paper](../../howto/reproduce-the-paper/)
# lists every study, and [Sweeps](../../experiments/) explains the sweep directory, the
# engine and running on Dask.

# %% [markdown]
# The files above were written to a temporary folder, removed here.

# %%
shutil.rmtree(work)
