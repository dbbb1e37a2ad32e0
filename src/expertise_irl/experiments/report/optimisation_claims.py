"""The claims of Sec. VII (the ``optimisation`` study), every one computed from the rows.

VII-B (Fig. 8) and VII-D keep the ids they had; VII-B's Table I reading, VII-C (Fig. 9, from 20
episodes on) and every cell of Table IV were added after them.
"""

from __future__ import annotations

from . import claim_kinds as K
from . import claims as C
from .conditions_claims import COLUMNS, paper_cells
from .stats import level, paired
from .tables import factor_rows, pearson_table

PERSON = ["environment", "instance"]
KEY = [*PERSON, "episodes"]
JUDGED = "birl_box"
RESCALED = f"{JUDGED}_rescaled"
#: VII-C: "as soon as the number of observations reaches 20 episodes ... equally good or better".
FROM_EPISODES = 20
T4 = {"episodes": "No. of episodes", "n_states": "No. of states",
      "mean_episode_length": "Average episode length", "beta_true": "True expertise level"}
TABLE4 = {T4["episodes"]: ("0.18†", "−0.22†", "−0.36†"),
          T4["n_states"]: ("−0.07", "0.13†", "−0.01"),
          T4["mean_episode_length"]: ("−0.12†", "0.31†", "−0.13†"),
          T4["beta_true"]: ("−0.11†", "0.32†", "−0.28†")}


def matched(rows, a: str, b: str, column: str):
    """``a`` and ``b``'s ``column`` on the same (environment, instance, episodes), with β*'s group."""
    return paired(rows, KEY, "method", column, a, b, keep=("group_true",))


def table4(rows):
    box = rows[rows["method"] == JUDGED]
    return pearson_table(
        "table4", "Table IV: Algorithm 1's metrics vs episodes, states, episode length and β*",
        f"`{JUDGED}` rows at every episode count ({len(box)} rows).", factor_rows(box, T4))


def _ratio(id, claim, paper, p, a, b, quantity, target, *, judged, who="instances", withheld=None,
           units=None):
    return C.ratio_claim(id, "VII-B" if id.startswith("VII-B") else "VII-D", claim, paper, p[a], p[b], a, b,
                         quantity, target, paired=True, who=who, judged=judged, withheld=withheld,
                         clusters=level(p, "environment"), groups=p["group_true"].to_numpy(), units=units)


def claims_b(at_e, e: int, m: str, rescaled=None) -> list[C.ClaimResult]:
    """VII-B (Fig. 8) for method ``m`` against the discrete set (judged where ``m`` is Algorithm 1)."""
    import pandas as pd

    judged = m == JUDGED
    tag = "" if judged else f" [{m}]"
    paper = {"beta": "≈ 1.5×", "regret": "≈ 2.5×"} if judged else {"beta": "— (ours)", "regret": "— (ours)"}
    out = [_ratio(f"VII-B-beta-{m}", f"β distance 1.5× better than the discrete set (discrete / {m}, {e} "
                  f"episodes){tag}", paper["beta"], matched(at_e, "discrete", m, "expertise_distance"),
                  "discrete", m, "|β* − β̂|", 1.5, judged=judged)]
    if judged and rescaled is not None and len(rescaled):
        both = pd.concat([at_e, rescaled], ignore_index=True)
        out.append(_ratio(f"VII-B-beta-{RESCALED}", "β distance 1.5× better than the discrete set (discrete "
                          f"/ {JUDGED} with β̂/‖θ̂‖₁, {e} episodes) [{RESCALED}]", "— (ours)",
                          matched(both, "discrete", RESCALED, "expertise_distance"), "discrete", RESCALED,
                          "|β* − β̂/‖θ̂‖₁|", 1.5, judged=False))
    out.append(_ratio(f"VII-B-regret-{m}", f"regret 2.5× better than the discrete set (discrete / {m}, {e} "
                      f"episodes){tag}", paper["regret"], matched(at_e, "discrete", m, "policy_regret"),
                      "discrete", m, "regret", 2.5, judged=judged))
    p = matched(at_e, m, "discrete", "cosine_similarity")
    out.append(C.ordering_claim(
        f"VII-B-cosine-{m}", "VII-B", f"cosine above the discrete set's ({m} vs discrete, {e} episodes){tag}",
        "0.90 vs 0.88" if judged else "— (ours)", p[m], p["discrete"], m, "discrete", "cosine similarity",
        claimed="above", who="instances", judged=judged))
    return out


def claim_b_table1(at_e, e: int) -> C.ClaimResult:
    """VII-B's reading of Table I's first row: the discrete set's cosine grows with θ*'s similarity to Θ_k."""
    disc = at_e[at_e["method"] == "discrete"]
    x = disc.get("theta_k_truth_similarity", disc["cosine_similarity"] * float("nan"))
    return C.correlation_claim(
        "VII-B-table1", "VII-B", f"the discrete set's cosine grows with the similarity between θ* and Θ_k "
        f"(discrete, {e} episodes)", "ρ = 0.57†", x, disc["cosine_similarity"], "similarity of θ* to Θ_k",
        "the discrete set's cosine", claimed="positive", paper_rho=0.57)


def claims_c(rows) -> list[C.ClaimResult]:
    """VII-C (Fig. 9): Algorithm 1 at least as good as the discrete set from 20 episodes on."""
    counts = sorted(int(c) for c in rows["episodes"].unique() if c >= FROM_EPISODES)
    parts = {"regret": [], "beta": [], "cosine": []}
    for c in counts:
        at = rows[rows["episodes"] == c]
        for metric, part in (("policy_regret", "regret"), ("expertise_distance", "beta")):
            p = matched(at, JUDGED, "discrete", metric)
            parts[part].append((c, C.ordering_claim(
                "", "VII-C", "", "", p[JUDGED], p["discrete"], JUDGED, "discrete", COLUMNS[metric][1].lower(),
                claimed="below", who="instances")))
        p = matched(at, JUDGED, "discrete", "cosine_similarity")
        parts["cosine"].append((c, K.no_effect_claim(
            "", "VII-C", "", "", p[JUDGED], p["discrete"], JUDGED, "discrete", "cosine similarity",
            ruled_out="below", who="instances")))
    since = f"every episode count from {FROM_EPISODES} on ({JUDGED}; Fig. 9)"
    better, equal = "better from 20 episodes on (Fig. 9)", "equally good from 20 episodes on (Fig. 9)"
    return [
        K.every_count_claim("VII-C-regret", "VII-C", f"Algorithm 1's regret below the discrete set's at "
                            f"{since}", better, parts["regret"]),
        K.every_count_claim("VII-C-beta", "VII-C", f"Algorithm 1's β distance below the discrete set's at "
                            f"{since}", better, parts["beta"]),
        K.every_count_claim("VII-C-cosine", "VII-C", f"Algorithm 1's cosine not below the discrete set's at "
                            f"{since}", equal, parts["cosine"])]


def claim_d(rows, shared: str | None) -> C.ClaimResult:
    """VII-D: the discrete set ≈ 4× faster than Algorithm 1 (withheld where tasks shared the machine)."""
    p = matched(rows, JUDGED, "discrete", "wall_time_s")
    withheld = None
    if shared:
        withheld = (f"{shared} (Sec. VII-D compares the methods on one processor); a sweep run "
                    "with `--workers 1` can judge it.")
    return _ratio("VII-D", f"discrete ≈ 4× faster than Algorithm 1 ({JUDGED} / discrete mean wall time, all "
                  "episode counts)", "≈ 4×", p, JUDGED, "discrete", "wall time (s)", 4.0, judged=True,
                  who="(environment, instance, episode count) rows", withheld=withheld,
                  units=level(p, "instance"))


def table_claims(t4) -> list[C.ClaimResult]:
    """Every cell of Table IV."""
    return K.table_claims(t4, paper_cells(TABLE4), {T4[f]: f"T4-{f}" for f in T4}, "VII-C", "Table IV",
                          {r: f"the `{JUDGED}` rows at every episode count" for r in TABLE4}, COLUMNS)


def claims(rows, e: int, methods: list[str], shared: str | None = None, rescaled=None,
           t4=None) -> list[C.ClaimResult]:
    """The Sec. VII claims at ``e`` episodes. ``shared``: why the tasks' timings shared the machine
    (VII-D is then not judged); ``rescaled``: Algorithm 1's rows with β̂ on θ*'s scale (not judged)."""
    at_e = rows[rows["episodes"] == e]
    out = []
    for m in [x for x in methods if x != "discrete"]:
        out += claims_b(at_e, e, m, rescaled if m == JUDGED else None)
    if JUDGED in methods and "discrete" in methods:
        out.append(claim_d(rows, shared))
        out.append(claim_b_table1(at_e, e))
        out += claims_c(rows)
        out += table_claims(t4 if t4 is not None else table4(rows))
    return out
