"""How much the data pin θ down: the MAP's log-likelihood minus the truth's, per instance (``map`` rows
with ``log_likelihood_truth`` and ``log_likelihood_hat``), in nats and per action."""

from __future__ import annotations

import numpy as np

from .parts import Section, Table
from .stats import fmt

COLUMNS = ("log_likelihood_truth", "log_likelihood_hat")
METHOD = "map"
STATS = ("median", "q1", "q3", "min", "max")


def _summary(x) -> dict:
    x = np.asarray(x, dtype=np.float64)
    q1, med, q3 = np.quantile(x, [0.25, 0.5, 0.75])
    return {"median": float(med), "q1": float(q1), "q3": float(q3), "min": float(x.min()),
            "max": float(x.max())}


def gap_table(rows) -> Table | None:
    """Per episode count, the gap's median, quartiles, min and max over the instances, in nats and per
    action (``n_pairs``); None where the rows lack the columns or have no ``map`` rows with them."""
    import pandas as pd

    if not all(c in rows.columns for c in COLUMNS):
        return None
    m = rows[(rows["method"] == METHOD) & rows[list(COLUMNS)].notna().all(axis=1)]
    if not len(m):
        return None
    gap = m["log_likelihood_hat"] - m["log_likelihood_truth"]
    m = m.assign(gap_nats=gap, gap_per_action=gap / m["n_pairs"])
    data = []
    for e, sub in m.groupby("episodes", sort=True):
        rec = {"episodes": int(e), "instances": len(sub), "actions_median": float(sub["n_pairs"].median())}
        rec.update({f"nats_{k}": v for k, v in _summary(sub["gap_nats"]).items()})
        rec.update({f"per_action_{k}": v for k, v in _summary(sub["gap_per_action"]).items()})
        data.append(rec)
    data = pd.DataFrame(data)

    def spread(prefix):
        return [f"{fmt(r[f'{prefix}_median'])} [{fmt(r[f'{prefix}_q1'])}, {fmt(r[f'{prefix}_q3'])}] "
                f"({fmt(r[f'{prefix}_min'])} to {fmt(r[f'{prefix}_max'])})" for r in data.to_dict("records")]

    display = pd.DataFrame({"episodes": data["episodes"], "instances": data["instances"],
                            "actions (median)": data["actions_median"].map(fmt),
                            "gap, nats": spread("nats"), "gap, nats per action": spread("per_action")})
    return Table("identifiability_gap", "Identifiability gap: MAP minus truth log-likelihood",
                 f"`{METHOD}` rows: log P(Ξ | θ̂, β̂) − log P(Ξ | θ*, β*) per instance (log_likelihood_hat − "
                 "log_likelihood_truth), in nats and divided by the instance's actions (n_pairs); median "
                 "[quartiles] (min to max) over the instances at each episode count.", display, data)


def gap_section(rows) -> Section | None:
    table = gap_table(rows)
    if table is None:
        return None
    last = table.data.iloc[-1]
    below = int((rows.loc[rows["method"] == METHOD, "log_likelihood_hat"]
                 < rows.loc[rows["method"] == METHOD, "log_likelihood_truth"]).sum())
    text = ("An estimate fitted to the data (the MAP, under a weak prior close to the maximum-likelihood "
            "one) is expected to score at least as well as the truth on those data, so a positive gap "
            "proves nothing by itself; its size says how flat the likelihood is around the truth. At "
            f"{int(last['episodes'])} episodes the MAP's log-likelihood exceeds the truth's by a median "
            f"{fmt(last['nats_median'])} nats over a median {fmt(last['actions_median'])} actions "
            f"({fmt(last['per_action_median'])} nats per action; range {fmt(last['nats_min'])} to "
            f"{fmt(last['nats_max'])} nats over {int(last['instances'])} instances): a θ̂ whose likelihood "
            "is within a few nats of the truth's is about as well supported by the data. "
            f"{below} of the `{METHOD}` rows have a negative gap (the MAP scores below the truth: the "
            "prior pulled it away or the optimiser stopped short).")
    return Section("Identifiability gap", text, table)
