"""The share of episodes that hit the step cap, per expertise group, and what it touches."""

from __future__ import annotations

from ...hypotheses import GROUP_NAMES as GROUPS
from .parts import Section, Table


def last_rows(frame, person: list[str]):
    """Each person's row at their largest episode count."""
    idx = frame.groupby(person, sort=False, observed=True)["episodes"].idxmax()
    return frame.loc[idx.to_numpy()]


TRUTH_PEOPLE = {"in_set": "in-set people", "out_of_set": "out-of-set people"}


def population(key: dict) -> str:
    """How a sentence names the people of one ``by`` key: "in-set people", "the conditions study's
    out-of-set people", or "all people" (no key); "..., under the `fixed` protocol" where the key holds
    ``goal_reward_mode``."""
    source = key.get("source")
    truth = TRUTH_PEOPLE.get(key.get("truth"), "people")
    who = f"the {source} study's {truth}" if source else truth if key.get("truth") else "all people"
    mode = key.get("goal_reward_mode")
    return f"{who} under the `{mode}` protocol" if mode else who


def cap_text(max_steps, by_value=None) -> str | None:
    """``"500 actions"``; ``max_steps`` may map the first ``by`` column's values to their caps."""
    if isinstance(max_steps, dict):
        if by_value is not None:
            max_steps = max_steps.get(by_value)
        else:
            caps = {v for v in max_steps.values() if v}
            if len(caps) != 1:
                given = [(k, int(v)) for k, v in max_steps.items() if v]
                return (", ".join(f"{v}{' actions' if i == 0 else ''} for {k}"
                                  for i, (k, v) in enumerate(given)) or None)
            max_steps = caps.pop()
    return f"{int(max_steps)} actions" if max_steps else None


def capped_section(last, effect: str, *, by: list[str] | None = None, model: str | None = None,
                   max_steps: int | dict | None = None, name: str = "capped",
                   everyone: str = "all people") -> Section:
    """``last``: one row per person (their largest episode count), with ``n_capped`` and ``episodes``.

    The shares are given per value of ``by`` (e.g. per truth: in-set and out-of-set people apart),
    each population named, so that ``effect`` (sentences built by the study from its numbers, which
    say which results the cap moves) can name the same population. ``max_steps``: the cap, or a
    dict from the values of ``by[0]`` to their caps; unknown (None): the text says "the cap".
    ``everyone``: how the text names the people where there is no ``by``.
    """
    import pandas as pd

    by = list(by or [])
    if "goal_reward_mode" in last.columns and "goal_reward_mode" not in by:
        by = ["goal_reward_mode", *by]  # the protocol: the shares are stated per protocol
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
    cap = cap_text(max_steps)
    ended = f"ended at the cap ({cap})" if cap else "ended at the step cap (`max_steps`)"
    table = Table(name, "Episodes that hit the step cap", "Per "
                  + (f"{', '.join(by)} and " if by else "") + "expertise group of β* (group_true), each "
                  f"person's episodes up to their largest episode count; capped = {ended} without "
                  "reaching the goal.", display, data)
    pops = []  # (name, {group: share})
    for key, g in (data.groupby(by, sort=False) if by else [((), data)]):
        key = dict(zip(by, key if isinstance(key, tuple) else (key,), strict=True))
        share = dict(zip(g["group_true"], g["share_capped"], strict=True))
        named = population(key) if set(key) - {"goal_reward_mode"} else everyone
        if key.get("goal_reward_mode") and named == everyone:
            named = f"{everyone} under the `{key['goal_reward_mode']}` protocol"
        pops.append((named, share))
    text = (f"An episode that hits {f'the cap ({cap})' if cap else 'the cap'} ends without reaching the "
            "goal: it is not a goal-directed path. ")
    text += " ".join(population_sentence(who, share) for who, share in pops) + " "
    fixed = "goal_reward_mode" in last.columns and set(last["goal_reward_mode"]) == {"fixed"}
    text += FIXED_NOTE if fixed else MODEL_NOTE
    text += " " if model in (None, "maxent") else f" This sweep's people follow the `{model}` model instead. "
    text += effect
    return Section("Capped episodes", text.strip(), table)


#: Why episodes are capped under the paper's model, and where the README says more.
MODEL_NOTE = ("Under the paper's model (maxent) a person is paid for randomness and the goal is worth 0 "
              "once reached, so simulated people whose β is large next to their weights prefer to keep "
              "moving and rarely reach the goal (see the README, 'A property of the model worth "
              "knowing').")


#: The same under the ``fixed`` protocol, where entering the goal pays outside θ·φ.
FIXED_NOTE = ("Under the `fixed` protocol entering the goal pays a constant reward outside θ·φ, so every "
              "person has a reason to finish whatever their θ; the cap is a safeguard, and the shares say "
              "how often it still ends a walk.")


def population_sentence(who: str, share: dict[str, float]) -> str:
    """One sentence on one population's capped shares, e.g. "For in-set people, most episodes are
    capped at medium (99%) and low (100%) expertise, at most half at high (30%)."."""
    heavy = [g for g, v in share.items() if v > 0.5]
    light = [g for g in share if g not in heavy]
    listed = ", ".join(f"{g} {v:.0%}" for g, v in share.items())

    def groups(gs):
        return _and([f"{g} ({share[g]:.0%})" for g in gs])

    if not heavy:
        return f"For {who}, no expertise group has most of its episodes capped ({listed})."
    if light:
        return (f"For {who}, most episodes are capped at {groups(heavy)} expertise, at most half at "
                f"{groups(light)}.")
    if len(heavy) == len(GROUPS):
        return f"For {who}, most episodes are capped at every expertise level ({listed})."
    return f"For {who}, most episodes are capped at {groups(heavy)} expertise."


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def capped_shares(last, by: str = "group_true") -> dict[str, float]:
    """Share of capped episodes per value of ``by`` (each person at their largest episode count)."""
    s = last.groupby(by, observed=True)[["n_capped", "episodes"]].sum()
    return {g: float(s.loc[g, "n_capped"] / s.loc[g, "episodes"]) for g in s.index}
