"""The claims of Secs. VI-B to VI-E (the ``conditions`` study), every one computed from the rows.

Ids of the first claims (VI-B, VI-C-cosine, VI-C-regret, VI-D-*, VI-E-group, VI-E-regret) are kept as
they were; the rest (per-group orderings of Figs. 2, 4 and 5, Fig. 3, the VI-D cosine, VI-E's margin
and every cell of Tables I and II) were added after them.
"""

from __future__ import annotations

import numpy as np

from ...hypotheses import GROUP_NAMES as GROUPS
from . import claim_kinds as K
from . import claims as C
from .stats import METRICS, level, paired
from .tables import factor_rows, pearson_table

PERSON = ["environment", "run", "k", "group", "truth"]
V2 = {"theta_k_truth_similarity": "Similarity between θ*_out and Θ_k",
      "theta_k_diversity": "Similarity within Θ_k",
      "beta_set_distance": "Min. distance between β*_out and B"}
T2 = {"episodes": "No. episodes", "n_hypotheses": "Cardinality of Ψ_k", "n_states": "No. states"}
#: VI-E: the mean regret that counts as "near 0", and the episode counts of the VI-E claims.
REGRET_NEAR_ZERO = 0.05
GROUP_AT, REGRET_AT = 5, 10
#: Fig. 3 is judged from this episode count (the first of its counts in steps of 5) to the last (from 1
#: where the last is not beyond it).
FIG3_FROM = 5
#: VI-E: "good performance after 15 episodes; the improvement at 20 within the margin of error at 15".
MARGIN_COUNTS = (15, 20)
#: The id part and the name of each metric in a table cell claim.
COLUMNS = {"cosine_similarity": ("cosine", METRICS["cosine_similarity"]),
           "expertise_distance": ("beta", METRICS["expertise_distance"]),
           "policy_regret": ("regret", METRICS["policy_regret"])}
TABLE1 = {V2["theta_k_truth_similarity"]: ("0.57†", "−0.45†", "0.05"),
          V2["theta_k_diversity"]: ("−0.06", "−0.03", "−0.12"),
          V2["beta_set_distance"]: ("0.0001", "0.58†", "−0.33†")}
TABLE2 = {T2["episodes"]: ("0.39†", "−0.26†", "−0.27†"),
          T2["n_hypotheses"]: ("−0.09†", "0.02", "0.06†"),
          T2["n_states"]: ("−0.02", "0.03", "0.01")}


def paper_cells(table: dict) -> dict:
    """{(row label, metric): paper's cell} from {row label: (cosine, distance, regret)}."""
    return {(row, m): cell for row, cells in table.items() for m, cell in zip(METRICS, cells, strict=True)}


def groups_of(frame) -> list[str]:
    present = set(frame["group_true"])
    return [g for g in GROUPS if g in present]


def table1(rows, n: int):
    out_n = rows[(rows["truth"] == "out_of_set") & (rows["condition"] == "full") & (rows["episodes"] == n)]
    missing = {c: "needs study version 2" for c in V2}
    return pearson_table(
        "table1", "Table I: out-of-set metrics vs the composition of the hypothesis set",
        f"Out-of-set rows (truth = out_of_set), Full set, episodes = {n}, all k ({len(out_n)} rows).",
        factor_rows(out_n, V2, missing))


def table2(rows, n: int):
    full_in = rows[(rows["truth"] == "in_set") & (rows["condition"] == "full") & (rows["episodes"] <= n)]
    return pearson_table(
        "table2", "Table II: in-set metrics vs episodes, cardinality and states",
        f"In-set Full-set rows at every episode count 1..{n}, all k ({len(full_in)} rows).",
        factor_rows(full_in, T2))


def _pairs(frame, metric, a, b):
    return paired(frame, PERSON, "condition", metric, a, b, keep=("group_true",))


def claims_b(rows, inset_n, n: int, n_low: int) -> list[C.ClaimResult]:
    """VI-B (Figs. 2 and 3)."""
    p = _pairs(inset_n, "expertise_distance", "full", "fixed_theta")
    out = [C.ordering_claim(
        "VI-B", "VI-B", f"Full-set β distance below Fixed θ's (in-set, {n} episodes)",
        "Full below Fixed θ (Fig. 2)", p["full"], p["fixed_theta"], "Full", "Fixed θ", "|β* − β̂|",
        claimed="below", who="in-set people")]
    for g in ("high", "medium"):
        q = p[p["group_true"] == g]
        out.append(C.ordering_claim(
            f"VI-B-{g}", "VI-B", f"Full-set β distance below Fixed θ's in the {g} group (in-set, {n} "
            "episodes; Fig. 2: \"more apparent in the high and medium expertise instances\")",
            "Full below Fixed θ (Fig. 2)", q["full"], q["fixed_theta"], "Full", "Fixed θ", "|β* − β̂|",
            claimed="below", who=f"in-set {g}-expertise people"))
    low = inset_n[inset_n["group_true"] == "low"]
    for cond, name in (("full", "Full"), ("fixed_theta", "Fixed θ")):
        sub = low[low["condition"] == cond]
        out.append(C.share_claim(
            f"VI-B-low-group-{cond}", "VI-B", f"{name}: low-expertise people recognised as low (β̂ in the "
            f"low group; in-set, {n} episodes)", "both approaches find low expertise (Fig. 2)",
            (sub["group_hat"] == "low").to_numpy(), f"in-set low-expertise people under {name} have "
            f"group_hat = low at {n} episodes"))
    return out + fig3_claims(rows, n_low)


def fig3_claims(rows, n_low: int) -> list[C.ClaimResult]:
    """Fig. 3: low-expertise in-set people from :data:`FIG3_FROM` to ``n_low`` episodes."""
    low = rows[(rows["truth"] == "in_set") & (rows["group_true"] == "low")]
    start = FIG3_FROM if n_low > FIG3_FROM else 1
    out = []
    for cond in ("full", "fixed_theta"):
        sub = low[(low["condition"] == cond) & low["episodes"].isin([start, n_low])]
        p = paired(sub, PERSON, "episodes", "expertise_distance", n_low, start)
        a, b = p[n_low] if len(p) else [], p[start] if len(p) else []
        text = f"low expertise, in-set, {start} → {n_low} episodes"
        if cond == "full":
            out.append(C.ordering_claim(
                "VI-B-fig3-full", "VI-B", f"Full-set β distance improves with episodes (Fig. 3; {text})",
                "improves with episodes (Fig. 3)", a, b, f"at {n_low}", f"at {start}", "|β* − β̂|",
                claimed="below", who="low-expertise people"))
        else:
            out.append(K.no_effect_claim(
                "VI-B-fig3-fixed_theta", "VI-B", f"Fixed-θ β distance does not improve with episodes "
                f"(Fig. 3; {text})", "no improvement (Fig. 3)", a, b, f"at {n_low}", f"at {start}",
                "|β* − β̂|", ruled_out="below", who="low-expertise people"))
    return out


def claims_c(inset_n, n: int) -> list[C.ClaimResult]:
    """VI-C (Figs. 4 and 5)."""
    p = _pairs(inset_n, "cosine_similarity", "full", "fixed_beta")
    out = [C.ordering_claim(
        "VI-C-cosine", "VI-C", f"Full-set cosine above Fixed β's (in-set, {n} episodes)",
        "Full above Fixed β (Fig. 4)", p["full"], p["fixed_beta"], "Full", "Fixed β", "cosine similarity",
        claimed="above", who="in-set people")]
    r = _pairs(inset_n, "policy_regret", "fixed_beta", "full")
    out.append(C.ratio_claim(
        "VI-C-regret", "VI-C", f"Fixed-β regret ≈ 2 orders of magnitude above the Full set's "
        f"(in-set, {n} episodes)", "≈ 100× (2 orders)", r["fixed_beta"], r["full"], "Fixed β", "Full",
        "regret", 100.0, orders=2, paired=True, who="in-set people", clusters=level(r, "environment"),
        groups=r["group_true"].to_numpy()))
    for g in groups_of(inset_n):
        q = p[p["group_true"] == g]
        out.append(C.ordering_claim(
            f"VI-C-cosine-{g}", "VI-C", f"Full-set cosine above Fixed β's in the {g} group (in-set, {n} "
            "episodes; Fig. 4: \"across all expertise levels\")", "Full above Fixed β (Fig. 4)", q["full"],
            q["fixed_beta"], "Full", "Fixed β", "cosine similarity", claimed="above",
            who=f"in-set {g}-expertise people"))
    full = inset_n[inset_n["condition"] == "full"]
    low, rest = full[full["group_true"] == "low"], full[full["group_true"].isin(["high", "medium"])]
    out.append(K.difference_claim(
        "VI-C-cosine-low-lower", "VI-C", "Full-set cosine lower in the low group than in the high and "
        f"medium groups (in-set, {n} episodes; Fig. 4)", "decrease for low expertise (Fig. 4)",
        low["cosine_similarity"], rest["cosine_similarity"], "low", "high and medium", "cosine similarity",
        claimed="below", clusters=(low["environment"], rest["environment"]), who="in-set people"))
    for g in groups_of(inset_n):
        q = r[r["group_true"] == g]
        out.append(C.ordering_claim(
            f"VI-C-regret-{g}", "VI-C", f"Full-set regret below Fixed β's in the {g} group (in-set, {n} "
            "episodes; Fig. 5: \"better for all expertise levels\")", "Full below Fixed β (Fig. 5)",
            q["full"], q["fixed_beta"], "Full", "Fixed β", "regret", claimed="below",
            who=f"in-set {g}-expertise people"))
    v = float(low["policy_regret"].mean()) if len(low) else np.nan
    out.append(C.threshold_claim(
        "VI-C-regret-low-near-0", "VI-C", f"Full-set regret near 0 for low expertise (in-set, {n} episodes; "
        f"mean ≤ {REGRET_NEAR_ZERO:g}; Fig. 5)", "near 0 (Fig. 5)", v, {"low": v} if len(low) else {},
        REGRET_NEAR_ZERO, "Full-set regret of low-expertise people", len(low)))
    return out


def claims_d(rows, n: int) -> list[C.ClaimResult]:
    """VI-D (Fig. 6): out of set against in set, Full set at the largest k."""
    kmax = int(rows["k"].max())
    at_k = rows[(rows["condition"] == "full") & (rows["k"] == kmax) & (rows["episodes"] == n)]
    inn, outt = at_k[at_k["truth"] == "in_set"], at_k[at_k["truth"] == "out_of_set"]
    out = []
    for metric, name, x in (("expertise_distance", "β distance", 3.0), ("policy_regret", "regret", 6.0)):
        out.append(C.ratio_claim(
            f"VI-D-{metric}", "VI-D", f"out-of-set {name} ≈ {x:g}× in-set (Full, k = {kmax}, {n} episodes)",
            f"≈ {x:g}×", outt[metric], inn[metric], "out of set", "in set", name, x, paired=False,
            who="out-of-set and in-set people", clusters=(outt["environment"], inn["environment"]),
            groups=(outt["group_true"], inn["group_true"])))
    out.append(K.difference_claim(
        "VI-D-cosine_similarity", "VI-D", f"out-of-set cosine below in-set (Full, k = {kmax}, {n} episodes)",
        "decrease (Fig. 6)", outt["cosine_similarity"], inn["cosine_similarity"], "out of set", "in set",
        "cosine similarity", claimed="below", clusters=(outt["environment"], inn["environment"]),
        groups=(outt["group_true"], inn["group_true"])))
    return out


def claims_e(rows, n: int) -> list[C.ClaimResult]:
    """VI-E (Fig. 7): the right group after 5 episodes, regret near 0 by 10, cosine by 15."""
    full_in = rows[(rows["truth"] == "in_set") & (rows["condition"] == "full")]
    at = min(GROUP_AT, n)
    p = paired(full_in.assign(right=(full_in["group_hat"] == full_in["group_true"]).astype(float)),
               PERSON, "episodes", "right", 1, at, keep=("group_true",))
    g5 = full_in[full_in["episodes"] == at]
    per = ", ".join(f"{g} {p.loc[p['group_true'] == g, at].mean():.0%}" for g in groups_of(p))
    mass = (f"; by the other reading, posterior mass on β*'s group above 1/2 (p_group_true > 0.5): "
            f"{np.mean(g5['p_group_true'] > 0.5):.0%}" if "p_group_true" in g5.columns and len(g5) else "")
    out = [K.share_gain_claim(
        "VI-E-group", "VI-E", f"the right expertise group for most in-set people after ≈ {GROUP_AT} "
        f"episodes, learnt from the episodes (Full; at {at} against 1 episode; the group of the "
        "posterior-mean β̂)", "most instances by 5 episodes", p[1].to_numpy() > 0.5, p[at].to_numpy() > 0.5,
        "in-set people have group_hat = group_true", (1, at), detail=f" (per group: {per}){mass}")]
    at = min(REGRET_AT, n)
    r10 = full_in[full_in["episodes"] == at]
    by_group = {g: float(r10.loc[r10["group_true"] == g, "policy_regret"].mean()) for g in groups_of(r10)}
    out.append(C.threshold_claim(
        "VI-E-regret", "VI-E", f"regret ≈ 0 by ≈ {REGRET_AT} episodes in every group (Full, in-set; mean "
        f"at {at} episodes ≤ {REGRET_NEAR_ZERO:g})", "near 0 at ≈ 10 episodes (Fig. 7)",
        float(r10["policy_regret"].mean()) if len(r10) else np.nan, by_group, REGRET_NEAR_ZERO,
        f"regret at {at} episodes", len(r10)))
    a, b = MARGIN_COUNTS
    out.append(K.margin_claim(
        "VI-E-cosine-15", "VI-E", f"cosine from {a} to {b} episodes within the margin of error at {a} in "
        "every group (Full, in-set; Fig. 7)", "improvement at 20 within the margin at 15",
        full_in, "cosine_similarity", MARGIN_COUNTS, groups_of(full_in), "cosine similarity"))
    return out


def table_claims(t1, t2, n: int) -> list[C.ClaimResult]:
    """Every cell of Tables I and II."""
    c1 = K.table_claims(t1, paper_cells(TABLE1), {V2[f]: f"T1-{f}" for f in V2}, "VI-D", "Table I",
                        {r: f"the out-of-set Full-set rows at {n} episodes, all k" for r in TABLE1}, COLUMNS)
    c2 = K.table_claims(t2, paper_cells(TABLE2), {T2[f]: f"T2-{f}" for f in T2}, "VI-E", "Table II",
                        {r: f"the in-set Full-set rows at episode counts 1..{n}, all k" for r in TABLE2},
                        COLUMNS)
    return c1 + c2


def claims(rows, n: int, n_low: int | None = None, tables=None) -> list[C.ClaimResult]:
    """The claims of Secs. VI-B to VI-E, from the rows (``n``: the config's episode count; ``n_low``:
    the low-expertise people's, default the rows' largest; ``tables``: Tables I and II if built)."""
    n_low = int(rows["episodes"].max()) if n_low is None else n_low
    inset_n = rows[(rows["truth"] == "in_set") & (rows["episodes"] == n)]
    t1, t2 = tables or (table1(rows, n), table2(rows, n))
    return [*claims_b(rows, inset_n, n, n_low), *claims_c(inset_n, n), *claims_d(rows, n),
            *claims_e(rows, n), *table_claims(t1, t2, n)]
