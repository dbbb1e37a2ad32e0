"""The share of episodes that hit the step cap, per expertise group, and what it touches."""

from __future__ import annotations

from .parts import Section, Table
from .stats import GROUPS


def last_rows(frame, person: list[str]):
    """Each person's row at their largest episode count."""
    idx = frame.groupby(person, sort=False, observed=True)["episodes"].idxmax()
    return frame.loc[idx.to_numpy()]


def capped_section(last, effect: str, *, by: list[str] | None = None, model: str | None = None,
                   max_steps: int | None = None, name: str = "capped") -> Section:
    """``last``: one row per person (their largest episode count), with ``n_capped`` and ``episodes``.

    ``effect`` (sentences built by the study from its numbers) says which results the cap moves.
    """
    import pandas as pd

    by = list(by or [])
    keys = [*by, "group_true"]
    rows = []
    for key, g in last.groupby(keys, sort=False, observed=True):
        key = key if isinstance(key, tuple) else (key,)
        eps, cap = int(g["episodes"].sum()), int(g["n_capped"].sum())
        rows.append({**dict(zip(keys, key, strict=True)), "people": len(g), "episodes": eps,
                     "capped": cap, "share_capped": cap / eps if eps else float("nan")})
    data = pd.DataFrame(rows, columns=[*keys, "people", "episodes", "capped", "share_capped"])
    order = {g: i for i, g in enumerate(GROUPS)}
    data = data.sort_values([*by, "group_true"], key=lambda s: s.map(order) if s.name == "group_true" else s,
                            kind="stable").reset_index(drop=True)
    display = data.copy()
    display["share_capped"] = display["share_capped"].map(lambda x: f"{x:.0%}")
    cap = f"{max_steps} actions" if max_steps else "the step cap"
    table = Table(name, "Episodes that hit the step cap", f"Per expertise group of β* (group_true), each "
                  f"person's episodes up to their largest episode count; capped = ended after {cap} "
                  "without reaching the goal.", display, data)
    shares_all = capped_shares(last)
    share = {g: shares_all[g] for g in GROUPS if g in shares_all}
    shares = ", ".join(f"{g} {share[g]:.0%}" for g in share)
    model_text = ("the paper's model (maxent)" if model in (None, "maxent")
                  else f"the {model} model (not the paper's maxent)")
    text = (f"Share of episodes that hit the cap ({cap}) per expertise group: {shares}. Under {model_text} "
            "a person is paid for randomness and the goal is worth 0 once reached, so simulated people "
            "whose β is large next to their weights prefer to keep moving and rarely reach the goal "
            "(DESIGN §1). ")
    heavy = [g for g in share if share[g] >= 0.5]
    if heavy:
        names = heavy[0] if len(heavy) == 1 else ", ".join(heavy[:-1]) + " and " + heavy[-1]
        text += (f"Here most {names}-expertise episodes are capped: those demonstrations stop at the cap "
                 f"({cap}) without reaching the goal; they are not goal-directed paths. ")
    else:
        text += "Here no group has most of its episodes capped. "
    text += effect
    return Section("Capped episodes", text.strip(), table)


def capped_shares(last, by: str = "group_true") -> dict[str, float]:
    """Share of capped episodes per value of ``by`` (each person at their largest episode count)."""
    s = last.groupby(by, observed=True)[["n_capped", "episodes"]].sum()
    return {g: float(s.loc[g, "n_capped"] / s.loc[g, "episodes"]) for g in s.index}
