"""How large a regret can be per expertise group: the regret (Eq. 17, at β*) of a θ drawn uniformly from
the grid (``random_theta_regret``), beside the Full set's, in the ``conditions`` report."""

from __future__ import annotations

import numpy as np

from ...hypotheses import GROUP_NAMES as GROUPS
from .parts import Section, Table
from .stats import fmt

COLUMN = "random_theta_regret"
TRUTHS = {"in_set": "in set", "out_of_set": "out of set"}


def _row(truth, g, sub) -> dict:
    full, rand = sub["policy_regret"], sub[COLUMN]
    ratio = full.mean() / rand.mean() if rand.mean() > 0 else np.nan
    return {"truth": truth, "group_true": g, "people": len(sub), "full_regret_mean": float(full.mean()),
            "full_regret_median": float(full.median()), "random_theta_regret_mean": float(rand.mean()),
            "random_theta_regret_median": float(rand.median()), "full_over_random": float(ratio)}


def random_theta_table(rows, n: int) -> Table | None:
    """Full-set rows at ``n`` episodes, per truth and expertise group: the Full set's regret beside a
    random θ's; None where the rows lack :data:`COLUMN`."""
    import pandas as pd

    if COLUMN not in rows.columns:
        return None
    at = rows[(rows["condition"] == "full") & (rows["episodes"] == n)]
    data = [_row(t, g, sub) for t in TRUTHS for g in GROUPS
            for sub in [at[(at["truth"] == t) & (at["group_true"] == g) & at[COLUMN].notna()]] if len(sub)]
    if not data:
        return None
    data = pd.DataFrame(data)
    display = pd.DataFrame({
        "truth": data["truth"].map(TRUTHS), "group_true": data["group_true"], "people": data["people"],
        "Full set regret: mean (median)": [f"{fmt(a)} ({fmt(b)})" for a, b in zip(
            data["full_regret_mean"], data["full_regret_median"], strict=True)],
        "random θ regret: mean (median)": [f"{fmt(a)} ({fmt(b)})" for a, b in zip(
            data["random_theta_regret_mean"], data["random_theta_regret_median"], strict=True)],
        "Full / random": data["full_over_random"].map(lambda x: f"{fmt(x)}×" if np.isfinite(x) else "n/a")})
    return Table("random_theta_regret", "Regret of a random θ per expertise group",
                 f"Full-set rows at episodes = {n}: each person's regret (Eq. 17, at β*) of the Full set's θ̂ "
                 "and of a θ drawn uniformly from the grid (`random_theta_regret`), per truth and expertise "
                 "group of β*.", display, data)


def random_theta_section(rows, n: int) -> Section | None:
    """The table and a sentence on what it says of the regret ratios; None without the column."""
    table = random_theta_table(rows, n)
    if table is None:
        return None
    inset = table.data[table.data["truth"] == "in_set"]
    parts = ", ".join(f"{g} {fmt(v)}" for g, v in zip(inset["group_true"], inset["random_theta_regret_mean"],
                                                       strict=True))
    text = ("The regret of Eq. 17 is measured on the soft values at β*, which for a large β* are dominated "
            "by the entropy term, so its scale shrinks with β* whatever the estimate: ")
    text += (f"a θ drawn at random from the grid costs in-set people a mean regret of {parts}. A ratio of "
             "regrets pooled over the groups (claims VI-C and VI-D) is therefore weighted towards the groups "
             "where regret can be large." if parts else "see the table.")
    return Section("Regret of a random θ", text, table)
