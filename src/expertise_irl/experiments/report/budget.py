"""Algorithm 1's budget ablation in the `optimisation` report: the Sec. VII claims judged again on
each budget's rows.

A sweep with ``birl_budgets`` has, beside ``birl_box`` (one chain of ``birl_iterations``, the study
as the paper describes it), methods ``birl_box@<budget>``: ``birl_chains`` chains pooled, run for
that many iterations each or until their split R-hat is below ``birl_rhat``. For each budget the
claims that judge Algorithm 1 are computed again with that budget's rows in ``birl_box``'s place
(the same people, episodes and discrete rows), giving one column of verdicts per budget, and the
budget's chain diagnostics (iterations run, R-hat reached) beside them.
"""

from __future__ import annotations

import numpy as np

from .optimisation_claims import JUDGED, claims, table4
from .parts import Section, Table
from .stats import fmt

#: What a budget's method name starts with.
PREFIX = f"{JUDGED}@"


def budget_methods(rows) -> list[str]:
    """The ablation's methods present in ``rows``: the additive β lattice's first, then the log-spaced
    one's (``:log``), each in increasing budget (``rhat`` last)."""
    names = {m for m in rows["method"].unique() if str(m).startswith(PREFIX)}

    def key(m: str):
        budget = m[len(PREFIX):]
        base = budget.removesuffix(":log")
        return budget.endswith(":log"), base == "rhat", int(base) if base.isdigit() else 0

    return sorted(names, key=key)


def _as_judged(rows, method: str):
    """``rows`` with ``method``'s rows as ``birl_box``'s (the other Algorithm 1 budgets dropped)."""
    keep = rows[~rows["method"].astype(str).str.startswith(JUDGED) | (rows["method"] == method)]
    return keep.assign(method=keep["method"].replace({method: JUDGED}))


def _diagnostics(rows, method: str) -> str:
    sub = rows[rows["method"] == method]
    if method == JUDGED:
        return f"1 chain × {int(sub['birl_iterations'].max()) if 'birl_iterations' in sub else 1000:,} it."
    rhat = sub["max_rhat"].to_numpy(dtype=float)
    med = float(np.nanmedian(rhat)) if (~np.isnan(rhat)).any() else float("nan")
    shown = "∞ (a chain never moved)" if med == float("inf") else fmt(med)
    return (f"{int(sub['birl_chains'].max())} chains × {int(np.median(sub['birl_iterations'])):,} it. "
            f"(median); R-hat < 1.01 in {np.mean(rhat < 1.01):.0%}, median R-hat {shown}")


def budget_section(rows, e: int, shared: str | None) -> Section | None:
    """The ablation (see the module docstring); None when the rows hold no budget methods."""
    import pandas as pd

    extra = budget_methods(rows)
    if not extra or "discrete" not in set(rows["method"]):
        return None
    columns, order = {}, []
    budgets = [JUDGED, *extra] if JUDGED in set(rows["method"]) else extra
    for m in budgets:
        judged = _as_judged(rows, m)
        results = claims(judged, e, ["discrete", JUDGED], shared, None, table4(judged))
        for c in results:
            if c.id not in columns:
                order.append(c.id)
                columns[c.id] = {"claim": c.id, "paper": c.paper}
            columns[c.id][m] = f"{c.verdict} ({c.number or c.ours})"
    data = pd.DataFrame([columns[i] for i in order])
    diag = pd.DataFrame([{"claim": "chains", "paper": "“run 4 times”",
                          **{m: _diagnostics(rows, m) for m in budgets}}])
    data = pd.concat([diag, data], ignore_index=True)
    text = (f"Algorithm 1's claims judged again with each budget's rows in `{JUDGED}`'s place (the same "
            f"instances, episode counts and discrete rows): `{JUDGED}` is one chain of the paper's 1,000 "
            "iterations, the study as printed; `" + "`, `".join(extra) + "` are independent chains pooled, "
            "for that many iterations each or (`@rhat`) until their split R-hat over β and θ/‖θ‖₁ is below "
            "the config's `birl_rhat`; a budget ending in `:log` runs on the log-spaced β lattice (each step "
            "multiplying β by the config's `birl_beta_ratio`). The first row gives each budget's chains and "
            "the R-hat they reached.")
    table = Table("budget_ablation", "Algorithm 1's budget: a verdict per budget", "Verdict (our number) of "
                  "each claim that judges Algorithm 1, per budget.", data, data)
    return Section("Algorithm 1's budget", text, table)
