"""The claim kinds beyond :mod:`.claims`' five: table cells, claims that something does not happen,
a share that grows with episodes, an unpaired difference of means, a claim judged at every episode
count, and a change within a margin. Their rules are in :data:`.claims.RULES`."""

from __future__ import annotations

import numpy as np

from ...errors import plural
from .claims import (
    ALPHA,
    DIFFERS,
    EXCLUDED,
    INCONCLUSIVE,
    MIN_BOOTSTRAP_N,
    NO_DATA,
    NOT_JUDGED,
    NOT_REPRODUCED,
    PLAIN,
    REPRODUCED,
    RULED_OUT,
    UNSURE,
    VERDICTS,
    WITHHELD,
    ClaimResult,
    _differs_why,
    ci_against,
    correlation_judgement,
    finite_pairs,
    paired_test,
    rank_test_text,
    strip_prefix,
)
from .ratios import ratio_extras
from .stats import cluster_difference_ci, fisher_ci, fmt, fmt_p, mean_ci


# ----------------------------------------------------------------------------- table cells
def parse_cell(text: str) -> tuple[float, bool]:
    """The paper's cell ``"−0.45†"`` as (ρ, significant)."""
    t = text.strip()
    return float(t.rstrip("†").replace("−", "-")), t.endswith("†")


def cell_judgement(paper_rho: float, paper_sig: bool, rho: float, p: float,
                   n: int = 0) -> tuple[str, str, tuple[float, float]]:
    """The table-cell rule (:data:`.claims.RULES` ``"table-cell"``): (verdict, why kind, Fisher-z 95% CI
    of ρ over ``n`` rows; without ``n`` no CI, and a non-significant ρ against a † is inconclusive)."""
    if not (np.isfinite(rho) and np.isfinite(p)):
        return NO_DATA, PLAIN, (np.nan, np.nan)
    if paper_sig:
        return correlation_judgement(rho, p, n, np.sign(paper_rho), paper_rho)
    ci = fisher_ci(rho, n)
    if not p < ALPHA:
        return REPRODUCED, PLAIN, ci
    same = np.sign(rho) == np.sign(paper_rho) and rho != 0
    return (DIFFERS if same else NOT_REPRODUCED), PLAIN, ci


def cell_verdict(paper_rho: float, paper_sig: bool, rho: float, p: float, n: int = 0) -> str:
    """The table-cell rule's verdict (:func:`cell_judgement`)."""
    return cell_judgement(paper_rho, paper_sig, rho, p, n)[0]


def cell_claim(id, section, table: str, row: str, column: str, paper: str, cell,
               rows_text: str) -> ClaimResult:
    """One cell of a Pearson table (``cell``: a record with rho, p, n and cell (its text)) against the
    paper's ``paper`` (e.g. ``"0.57†"``)."""
    paper_rho, paper_sig = parse_cell(paper)
    rho, p, n, text = float(cell["rho"]), float(cell["p"]), int(cell["n"]), str(cell["cell"])
    claim = f"{table}, row “{row}”, column “{column}”"
    ours = f"ρ = {text} (n = {n}, p = {fmt_p(p)})"
    verdict, kind, ci = cell_judgement(paper_rho, paper_sig, rho, p, n)
    if verdict == NO_DATA:
        return ClaimResult(id, section, claim, paper, ours, NO_DATA, f"ρ is undefined over {rows_text} "
                           f"({text}, n = {n}).", "table-cell", n, rho, p=p, number=f"ρ = {text}")
    sig = p < ALPHA
    same = np.sign(rho) == np.sign(paper_rho) and rho != 0
    against = ci_against(ci, paper_rho if paper_sig else None, f"the paper's {paper.rstrip('†')}")
    why = (f"our ρ over {rows_text} is {text} (n = {n}, p = {fmt_p(p)}; {against}): "
           f"{'the paper’s' if same else 'not the paper’s'} sign, "
           f"{'significant' if sig else 'not significant'} where the paper's {paper} is "
           f"{'significant' if paper_sig else 'not'}.")
    why = _differs_why(why, verdict, kind)
    return ClaimResult(id, section, claim, paper, ours, verdict, why, "table-cell", n, rho, ci[0], ci[1],
                       p=p, number=f"ρ = {text} (n = {n})")


def table_claims(table, paper: dict, ids: dict, section: str, table_title: str, rows_text: dict,
                 columns: dict) -> list[ClaimResult]:
    """A claim per cell of ``table`` (a :class:`.parts.Table` from :func:`.tables.pearson_table`).

    ``paper``: {(row label, metric): paper's cell}; ``ids``: {row label: the id's row part};
    ``rows_text``: {row label: the rows it is computed over}; ``columns``: {metric: (id part, name)}.
    """
    out = []
    for rec in table.data.to_dict("records"):
        key = (rec["row"], rec["metric"])
        if key not in paper:
            continue
        part, name = columns[rec["metric"]]
        out.append(cell_claim(f"{ids[rec['row']]}-{part}", section, table_title, rec["row"], name,
                              paper[key], rec, rows_text[rec["row"]]))
    return out


# ----------------------------------------------------------------------- "does not happen"
def no_effect_claim(id, section, claim, paper, a, b, a_name, b_name, quantity, *, ruled_out="below",
                    who="pairs", judged=True) -> ClaimResult:
    """``a`` (paired with ``b``) is claimed *not* to be ``ruled_out`` ("below"/"above") ``b``."""
    a, b = finite_pairs(a, b)
    n = len(a)
    if n == 0:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no paired {who} to compare.",
                           "no-effect", 0)
    t = paired_test(a, b, ruled_out)
    if t.sign > 0:  # the mean in the direction the claim rules out
        verdict = NOT_REPRODUCED if t.p_toward < ALPHA else DIFFERS
    else:
        verdict = DIFFERS if t.p_toward < ALPHA else REPRODUCED
    verdict = verdict if judged else NOT_JUDGED
    actual = "below" if t.mean_d < 0 else "above" if t.mean_d > 0 else "equal to"
    ours = f"{a_name} {fmt(a.mean())} vs {b_name} {fmt(b.mean())}"
    why = (f"mean {quantity} is {fmt(a.mean())} for {a_name} and {fmt(b.mean())} for {b_name} over {n} "
           f"paired {who}: {a_name} is {actual} {b_name} (the claim rules out {ruled_out}); "
           f"{rank_test_text(t, a_name, b_name, ruled_out)}.")
    why = _differs_why(why, verdict, UNSURE)
    return ClaimResult(id, section, claim, paper, f"{ours} (n = {n}, p = {fmt_p(t.p_toward)})", verdict, why,
                       "no-effect", n, t.mean_d, p=t.p_toward, number=f"{ours} (n = {n})")


# -------------------------------------------------------------------- a share that grows
def mcnemar_greater(before, after) -> tuple[int, int, float]:
    """Exact one-sided McNemar test that ``after`` (bool per unit) is True more often than ``before``:
    (gains, losses, p), p the binomial tail of the gains among the discordant units (NaN if none)."""
    from scipy import stats

    before, after = np.asarray(before, dtype=bool), np.asarray(after, dtype=bool)
    gains, losses = int((after & ~before).sum()), int((before & ~after).sum())
    if gains + losses == 0:
        return gains, losses, float("nan")
    return gains, losses, float(stats.binomtest(gains, gains + losses, 0.5, alternative="greater").pvalue)


def share_gain_claim(id, section, claim, paper, before, after, what: str, at: tuple[int, int],
                     detail: str = "") -> ClaimResult:
    """The share of True in ``after`` is claimed above 1/2 and above ``before``'s (paired per unit)."""
    from scipy import stats

    before, after = np.asarray(before, dtype=bool), np.asarray(after, dtype=bool)
    n = len(after)
    if n == 0:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {what}.", "share-gain", 0)
    k, k0 = int(after.sum()), int(before.sum())
    share, share0 = k / n, k0 / n
    p_half = float(stats.binomtest(k, n, 0.5, alternative="greater").pvalue)
    gains, losses, p_gain = mcnemar_greater(before, after)
    if share <= 0.5 or share <= share0:
        verdict = NOT_REPRODUCED
    elif p_half < ALPHA and np.isfinite(p_gain) and p_gain < ALPHA:
        verdict = REPRODUCED
    else:
        verdict = DIFFERS
    ours = f"{share0:.0%} ({k0}/{n}) at {at[0]} → {share:.0%} ({k}/{n}) at {at[1]} episodes"
    why = (f"{k} of {n} {what} at {at[1]} episodes, {share:.0%}{detail}; one-sided binomial test against "
           f"1/2: p = {fmt_p(p_half)}. At {plural(at[0], 'episode')} {k0} of {n}, {share0:.0%}: {gains} "
           f"people go from wrong to right and {losses} from right to wrong; exact one-sided McNemar "
           f"test p = {fmt_p(p_gain)}.")
    why = _differs_why(why, verdict, UNSURE)
    return ClaimResult(id, section, claim, paper, f"{ours} (McNemar p = {fmt_p(p_gain)})", verdict, why,
                       "share-gain", n, share, p=p_gain, number=ours)


# --------------------------------------------------------------- an unpaired difference
def difference_claim(id, section, claim, paper, a, b, a_name, b_name, quantity, *, claimed="below",
                     clusters=None, groups=None, who="people") -> ClaimResult:
    """``mean(a)`` is claimed ``claimed`` ("below"/"above") ``mean(b)``; ``a`` and ``b`` are different
    units. ``clusters``/``groups``: pairs (a's, b's) of map and expertise-group labels."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    ka, kb = np.isfinite(a), np.isfinite(b)
    a, b = a[ka], b[kb]
    if not len(a) or not len(b):
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {a_name} or {b_name}.",
                           "difference", 0)
    d = float(a.mean() - b.mean())
    few = min(len(a), len(b)) < MIN_BOOTSTRAP_N
    if clusters is not None:  # maps first, then the people within them
        cl = (np.asarray(clusters[0], dtype=object)[ka], np.asarray(clusters[1], dtype=object)[kb])
        maps = len(set(cl[0]) | set(cl[1]))
        how = f"two-stage cluster bootstrap over {maps} maps, then the {who} within each"
    else:  # one "map": each side's people on their own
        cl = (np.zeros(len(a)), np.zeros(len(b)))
        how = f"bootstrap over {len(a)} and {len(b)} {who}, each side on its own"
    ci = (np.nan, np.nan) if few else cluster_difference_ci(a, b, cl, paired=False)
    right = d < 0 if claimed == "below" else d > 0
    claimed_side, other_side = (ci[1] < 0, ci[0] > 0) if claimed == "below" else (ci[0] > 0, ci[1] < 0)
    verdict = (REPRODUCED if right and claimed_side else NOT_REPRODUCED if not right and other_side
               else DIFFERS)
    adj = ""
    if groups is not None:
        ga, gb = np.asarray(groups[0], dtype=object)[ka], np.asarray(groups[1], dtype=object)[kb]
        ex = ratio_extras(a, b, ga, gb, paired=False)
        adj = f"; mix-adjusted {a_name} / {b_name} {ex.adjusted_text()}" if ex.adjusted_how else ""
    ci_text = f"[{fmt(ci[0])}, {fmt(ci[1])}]" if not few else f"[n/a: n < {MIN_BOOTSTRAP_N}]"
    side = (f"no CI from fewer than {MIN_BOOTSTRAP_N} {who} on a side" if few
            else "the CI excludes 0 on the claimed side" if claimed_side
            else "the CI excludes 0 on the other side" if other_side else "the CI includes 0")
    ours = f"{a_name} {fmt(a.mean())} vs {b_name} {fmt(b.mean())}: {fmt(d)} {ci_text}"
    why = (f"mean {quantity} is {fmt(a.mean())} for {a_name} (n = {len(a)}) and {fmt(b.mean())} for {b_name} "
           f"(n = {len(b)}): difference {fmt(d)}, 95% CI {ci_text} ({how}); "
           f"{'the claimed' if right else 'not the claimed'} side, {side}{adj}.")
    why = _differs_why(why, verdict, UNSURE)
    return ClaimResult(id, section, claim, paper, f"{ours} (n = {len(a)} / {len(b)})", verdict, why,
                       "difference", min(len(a), len(b)), d, ci[0], ci[1], number=f"{fmt(d)} {ci_text}")


# ---------------------------------------------------------------- judged at every count
#: How bad a verdict is, for "the worst of them".
_WORST = {NOT_REPRODUCED: 0, NO_DATA: 1, DIFFERS: 2, REPRODUCED: 3, WITHHELD: 4, NOT_JUDGED: 5}
assert set(_WORST) == set(VERDICTS)


def _kind(why: str) -> str:
    """The why-prefix kind a "differs" ``why`` carries."""
    return UNSURE if why.startswith(INCONCLUSIVE) else RULED_OUT if why.startswith(EXCLUDED) else PLAIN


def every_count_claim(id, section, claim, paper, parts: list[tuple[int, ClaimResult]]) -> ClaimResult:
    """One claim judged at several episode counts by the rule of its ``parts``: the worst verdict of the
    judged counts (a count without rows does not hide them; n/a only if no count is judged)."""
    if not parts:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, "no episode count to judge.",
                           "every-count", 0)
    judged = [(e, c) for e, c in parts if c.verdict in (REPRODUCED, DIFFERS, NOT_REPRODUCED)]
    worst_count, worst = min(judged or parts, key=lambda cp: _WORST[cp[1].verdict])
    missing = [str(e) for e, c in parts if c.verdict == NO_DATA]
    inner = parts[0][1].rule
    ours = "; ".join(f"{e}: {c.number or c.ours} ({c.verdict})" for e, c in parts)
    why = " ".join(f"At {e} episodes: {strip_prefix(c.why)}" for e, c in parts)
    skipped = (f"; n/a at {', '.join(missing)} episodes, not counted" if missing and judged else "")
    why = f"worst at {worst_count} episodes ({worst.verdict}){skipped}. " + why
    why = _differs_why(why, worst.verdict, _kind(worst.why))
    return ClaimResult(id, section, claim, paper, ours, worst.verdict, why, f"every-count:{inner}",
                       sum(c.n for _, c in parts), worst.value, p=worst.p,
                       number="; ".join(f"{e}: {c.number or c.ours}" for e, c in parts))


# --------------------------------------------------------------------- within a margin
def margin_claim(id, section, claim, paper, frame, metric: str, counts: tuple[int, int], groups: list[str],
                 quantity: str) -> ClaimResult:
    """The change of the mean ``metric`` from ``counts[0]`` to ``counts[1]`` episodes is claimed to be
    within the 95% CI half-width at ``counts[0]`` in every expertise group (``frame``: rows with
    ``episodes``, ``group_true`` and ``metric``)."""
    a_n, b_n = counts
    per, n, short = {}, 0, []
    for g in groups:
        sub = frame[frame["group_true"] == g]
        ca = mean_ci(sub.loc[sub["episodes"] == a_n, metric])
        cb = mean_ci(sub.loc[sub["episodes"] == b_n, metric])
        if ca.n >= 2 and cb.n:
            per[g] = (cb.mean - ca.mean, ca.half)
            n += ca.n
        else:
            short.append(f"{g} ({ca.n} at {a_n}, {cb.n} at {b_n})")
    if short or not per:
        what = (f"too few rows in {', '.join(short)}: every group needs 2 at {a_n} episodes (for the "
                f"CI) and 1 at {b_n}." if short else f"no rows at {a_n} and {b_n} episodes.")
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, what, "margin", n)
    allc = (mean_ci(frame.loc[frame["episodes"] == a_n, metric]), mean_ci(frame.loc[frame["episodes"] == b_n,
                                                                                    metric]))
    overall = (allc[1].mean - allc[0].mean, allc[0].half)
    inside = [g for g, (d, h) in per.items() if abs(d) <= h]
    if len(inside) == len(per):
        verdict = REPRODUCED
    else:
        verdict = DIFFERS if abs(overall[0]) <= overall[1] else NOT_REPRODUCED
    text = ", ".join(f"{g} {fmt(d)} (± {fmt(h)})" for g, (d, h) in per.items())
    why = (f"change of the mean {quantity} from {a_n} to {b_n} episodes (± the 95% CI half-width at {a_n}): "
           f"{text}; all groups {fmt(overall[0])} (± {fmt(overall[1])}); "
           + ("every group within its margin." if verdict == REPRODUCED
              else f"outside: {', '.join(g for g in per if g not in inside)}."))
    return ClaimResult(id, section, claim, paper, text, verdict, why, "margin", n, overall[0],
                       number=text)
