"""Two regrets side by side: the paper's Eq. 17 and the return regret, and how often they disagree.

Eq. 17 compares soft values of θ̂ and θ* at β*; the return regret (:func:`expertise_irl.metrics.
return_regret`) compares what the optimal policy for θ̂ earns under θ* with the best policy's.
Every report shows both (its means table) and this section: per group (a method or a condition),
the mean of each, and among the pairs of estimates of one person from the same episodes, the
share that the two regrets order differently.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from .parts import Section, Table
from .stats import fmt

#: The return regret's column in the rows (absent from rows written before it existed).
COLUMN = "return_regret"
#: Differences below this count as ties (both metrics are exact to far better than this).
TIE = 1e-9


def _disagreements(rows, same: list[str], by: str) -> tuple[int, int]:
    """(pairs ordered differently, pairs ordered by both) among rows equal on ``same``, across ``by``."""
    bad = total = 0
    for _, g in rows.groupby(same, sort=False, observed=True):
        if g[by].nunique() < 2:
            continue
        eq17, ret = g["policy_regret"].to_numpy(), g[COLUMN].to_numpy()
        for i, j in combinations(range(len(g)), 2):
            d1, d2 = eq17[i] - eq17[j], ret[i] - ret[j]
            if abs(d1) <= TIE or abs(d2) <= TIE or not (np.isfinite(d1) and np.isfinite(d2)):
                continue
            total += 1
            bad += (d1 > 0) != (d2 > 0)
    return bad, total


def regrets_section(rows, person: list[str], by: str) -> Section:
    """The section (see the module docstring) for ``rows`` of people keyed by ``person`` (with the
    episode count), compared across ``by``; says so when the rows predate the return regret."""
    import pandas as pd

    title = "Two regrets: Eq. 17 and the return regret"
    if COLUMN not in rows.columns or rows[COLUMN].isna().all():
        return Section(title, "These rows were written before the return regret existed (the column "
                              f"`{COLUMN}` is absent); run the sweep again to compare the two regrets.")
    records = []
    for key, g in rows.groupby(by, sort=False, observed=True):
        records.append({by: key, "eq17_mean": float(g["policy_regret"].mean()),
                        "return_regret_mean": float(g[COLUMN].mean()), "n": len(g)})
    data = pd.DataFrame(records)
    display = data.assign(eq17_mean=data["eq17_mean"].map(fmt),
                          return_regret_mean=data["return_regret_mean"].map(fmt)).rename(
        columns={"eq17_mean": "Eq. 17 (mean)", "return_regret_mean": "return regret (mean)"})
    bad, total = _disagreements(rows, [*person, "episodes"], by)
    share = f"{bad / total:.0%} ({bad} of {total})" if total else "no pairs to compare"
    text = (f"Among the pairs of estimates of one person from the same episodes (across `{by}`), "
            f"Eq. 17 and the return regret order {share} differently. The return regret is what acting on "
            "θ̂ costs under θ*: the return of θ̂'s optimal policy short of the best policy's, as a share of "
            "the uniform random policy's shortfall (0 best, 1 no better than random); Eq. 17 compares soft "
            "values of two rewards at β*, so an estimate whose policy earns more can have the larger Eq. 17.")
    table = Table(f"regrets_by_{by}", "Eq. 17 and the return regret", f"Per `{by}`, every row.", display,
                  data)
    return Section(title, text, table)
