"""Claims of the paper and the rules that judge them, computed from the rows (never written by hand).

Every claim gives a :class:`ClaimResult`: the paper's number, ours, a verdict and one sentence
built from the numbers. The verdict rules (also printed in each report):

- ordering ("A below B"): *reproduced* if the mean paired difference has the claimed sign and a
  two-sided Wilcoxon signed-rank test gives p < 0.05; *differs* if the sign is right but p ≥ 0.05
  (inconclusive); *not reproduced* if the sign is wrong (or every difference is zero).
- ratio ("≈ X×"): the ratio of means with a 95% percentile-bootstrap CI (paired where the rows
  pair). *reproduced* if the ratio is within [X/1.5, 1.5·X] and the CI excludes 1 on the claimed
  side; *differs* if the CI excludes 1 on the claimed side but the ratio is outside the band (right
  direction, wrong size), or if the CI includes 1 or cannot be computed (inconclusive); *not
  reproduced* if the whole CI lies on the other side of 1.
  "≈ m orders of magnitude" uses the log band [10^(m−0.5), 10^(m+0.5)] instead.
- share ("most"): *reproduced* if the share is above 1/2 and a one-sided binomial test against 1/2
  gives p < 0.05; *differs* if above 1/2 with p ≥ 0.05 (inconclusive); *not reproduced* if at most 1/2.
- threshold ("≈ 0 by n episodes"): *reproduced* if the mean is at most the threshold in every group;
  *differs* if the mean over all groups is but some group's is not; *not reproduced* otherwise.
- correlation ("ρ > 0, significant"): as ordering, with Pearson's p in place of Wilcoxon's.

The why of an inconclusive *differs* starts with "inconclusive:" (:data:`INCONCLUSIVE`).

A claim is *not judged (ours)* where the number is for one of our methods, beside the paper's,
and *not judged* where the rows cannot judge it (the "why" says why, e.g. timings taken while
other tasks shared the machine).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .stats import BOOTSTRAP_SEED, RESAMPLES, fmt, fmt_p, ratio_ci, wilcoxon_p

ALPHA = 0.05
BAND = 1.5
#: The fewest rows per side a ratio's bootstrap CI is computed from: the fewest pairs with which the
#: ordering rule's two-sided Wilcoxon test can reach p < 0.05 (2 / 2**6). With fewer the CI is n/a.
MIN_BOOTSTRAP_N = 6
#: Half-width, in orders of magnitude, of the band of "≈ m orders of magnitude" claims.
LOG_HALF_BAND = 0.5
REPRODUCED, DIFFERS, NOT_REPRODUCED = "reproduced", "differs", "not reproduced"
NOT_JUDGED, WITHHELD, NO_DATA = "not judged (ours)", "not judged", "n/a (no data)"
#: Every verdict a claim can get.
VERDICTS = (REPRODUCED, DIFFERS, NOT_REPRODUCED, NOT_JUDGED, WITHHELD, NO_DATA)
#: What a verdict means beyond its rule (printed under the rules where the verdict occurs).
VERDICT_NOTES = {
    DIFFERS: "differs: either the rows cannot tell (not significant, a CI that includes 1, or too few "
             "rows for a CI), and then its why starts with \"inconclusive:\"; or the direction is right "
             "but not the claimed size (for threshold claims: some group above the threshold).",
    NOT_JUDGED: "not judged (ours): the same number for one of our methods, beside the paper's; the "
                "paper makes no claim about it.",
    WITHHELD: "not judged: the rows cannot judge this claim; the why says what is missing.",
    NO_DATA: "n/a (no data): the sweep has no rows for it.",
}

RULES = {
    "ordering": "Ordering claims (A below/above B): reproduced if the mean paired difference has the "
                "claimed sign and a two-sided Wilcoxon signed-rank test (scipy.stats.wilcoxon) gives "
                "p < 0.05; differs if the sign is right but p ≥ 0.05 (inconclusive); not reproduced if "
                "the sign is wrong or every difference is zero.",
    "ratio": f"Ratio claims (≈ X×): our ratio of means, with a 95% percentile-bootstrap CI "
             f"({RESAMPLES} resamples, numpy Generator seed {BOOTSTRAP_SEED}; rows that pair, the same "
             "people or instances under both, are resampled as pairs, other rows each side on its "
             f"own). Reproduced if the ratio lies within [X/{BAND}, {BAND}·X] and the CI excludes 1 on "
             "the claimed side; differs if the CI excludes 1 on the claimed side but the ratio is "
             "outside the band (right direction, wrong size), or if the CI includes 1 (inconclusive); "
             "not reproduced if the whole CI lies on the other side of 1 (its nearer bound at 1 or past "
             "it). With fewer than "
             f"{MIN_BOOTSTRAP_N} rows on a side (too few for the ordering rule's Wilcoxon test to reach "
             "p < 0.05) there is no CI and the claim is inconclusive (differs).",
    "magnitude": f"Order-of-magnitude claims (≈ m orders of magnitude): as ratio claims, with a band of "
                 f"{LOG_HALF_BAND:g} orders either side on a log scale, [10^(m−{LOG_HALF_BAND:g}), "
                 f"10^(m+{LOG_HALF_BAND:g})] (for 2 orders: {10 ** 1.5:.1f}× to {10 ** 2.5:.0f}×).",
    "share": "Share claims (most people): reproduced if the share is above 1/2 and a one-sided "
             "binomial test against 1/2 gives p < 0.05; differs if it is above 1/2 with p ≥ 0.05 "
             "(inconclusive); not reproduced if it is at most 1/2.",
    "threshold": "Threshold claims (≈ 0 by n episodes): reproduced if the mean is at most the "
                 "threshold in every expertise group; differs if the mean over all groups is but "
                 "some group's is not; not reproduced otherwise.",
    "correlation": "Correlation claims (ρ of a given sign): reproduced if Pearson's ρ has the claimed "
                   "sign with p < 0.05; differs if the sign is right but p ≥ 0.05 (inconclusive); not "
                   "reproduced if the sign is wrong.",
}


@dataclass(frozen=True)
class ClaimResult:
    id: str
    section: str
    claim: str
    paper: str
    ours: str
    verdict: str
    why: str
    rule: str
    n: int
    value: float = float("nan")  # the number the verdict is about (difference, ratio, share, ...)
    ci_low: float = float("nan")  # its 95% CI, where the rule uses one (ratio claims)
    ci_high: float = float("nan")

    def record(self) -> dict:
        return asdict(self)


#: How the why of a "differs" begins where the rows cannot tell (not significant, a CI that includes 1,
#: too few rows), so that the claims table tells it from "right direction, wrong size".
INCONCLUSIVE = "inconclusive: "


def _inconclusive(why: str, inconclusive: bool) -> str:
    return INCONCLUSIVE + why if inconclusive else why


def _ordering_verdict(sign_right: bool, p: float) -> str:
    if not sign_right:
        return NOT_REPRODUCED
    return REPRODUCED if np.isfinite(p) and p < ALPHA else DIFFERS


def ordering_claim(id, section, claim, paper, a, b, a_name, b_name, quantity, *, claimed="below",
                   who="pairs", judged=True) -> ClaimResult:
    """``a`` (paired with ``b``, same order) is claimed to be ``claimed`` ("below"/"above") ``b``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    n = len(a)
    ours_text = f"{a_name} {fmt(a.mean()) if n else 'n/a'} vs {b_name} {fmt(b.mean()) if n else 'n/a'}"
    if n == 0:
        return ClaimResult(id, section, claim, paper, ours_text, NO_DATA, f"no paired {who} to compare.",
                           "ordering", 0)
    d = a - b
    mean_d = float(d.mean())
    p = wilcoxon_p(d)
    sign_right = mean_d < 0 if claimed == "below" else mean_d > 0
    verdict = _ordering_verdict(sign_right, p) if judged else NOT_JUDGED
    actual = "below" if mean_d < 0 else "above" if mean_d > 0 else "equal to"
    if np.isfinite(p):
        test = f"Wilcoxon p = {fmt_p(p)}" + (" < 0.05" if p < ALPHA else " ≥ 0.05, not significant")
    else:
        test = "Wilcoxon test undefined"
    why = (f"mean {quantity} is {fmt(a.mean())} for {a_name} and {fmt(b.mean())} for {b_name} over {n} "
           f"paired {who}: {a_name} is {actual} {b_name}, {'as' if sign_right else 'not as'} claimed; "
           f"{test}.")
    why = _inconclusive(why, verdict == DIFFERS)
    return ClaimResult(id, section, claim, paper, ours_text + f" (n = {n}, p = {fmt_p(p)})", verdict, why,
                       "ordering", n, mean_d)


def ratio_band(target: float, orders: float | None = None) -> tuple[float, float]:
    """The band a ratio claim's ratio must lie in: [X/1.5, 1.5·X], or a log band for ``orders``."""
    if orders is not None:
        return 10 ** (orders - LOG_HALF_BAND), 10 ** (orders + LOG_HALF_BAND)
    return target / BAND, target * BAND


def _ci_side(ci: tuple[float, float], target: float) -> str:
    """Where the CI lies against 1: "claimed" (all on ``target``'s side), "other" (its bound nearest
    the claim at or past 1), "includes" (1 inside it) or "undefined"."""
    lo, hi = ci
    if np.isnan(lo) or np.isnan(hi):
        return "undefined"
    if target > 1:
        return "claimed" if lo > 1 else "other" if hi <= 1 else "includes"
    return "claimed" if hi < 1 else "other" if lo >= 1 else "includes"


def ratio_verdict(ratio: float, target: float, ci: tuple[float, float],
                  band: tuple[float, float] | None = None) -> str:
    """The ratio rule: ``ratio`` and its 95% ``ci`` against a claim of ≈ ``target``."""
    lo, hi = band or ratio_band(target)
    if np.isnan(ratio):
        return NOT_REPRODUCED
    side = _ci_side(ci, target)
    if side == "claimed":
        return REPRODUCED if lo <= ratio <= hi else DIFFERS
    return NOT_REPRODUCED if side == "other" else DIFFERS  # includes 1 or undefined: inconclusive


def ratio_claim(id, section, claim, paper, num, den, num_name, den_name, quantity, target,
                *, paired: bool, who: str, orders: float | None = None, judged: bool = True,
                withheld: str | None = None) -> ClaimResult:
    """``mean(num) / mean(den)`` is claimed to be about ``target`` (``10**orders`` if ``orders``).

    ``paired``: ``num[i]`` and ``den[i]`` are one unit (``who``, e.g. "in-set people") under both
    sides; pairs with a NaN are dropped. Otherwise the sides are independent samples of ``who``.
    ``judged=False``: one of our methods (verdict :data:`NOT_JUDGED`); ``withheld``: why the rows
    cannot judge the claim (verdict :data:`WITHHELD`).
    """
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    if paired:
        keep = np.isfinite(num) & np.isfinite(den)
        num, den = num[keep], den[keep]
    else:
        num, den = num[np.isfinite(num)], den[np.isfinite(den)]
    n = min(len(num), len(den))
    rule = "ratio" if orders is None else "magnitude"
    if n == 0:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {num_name} or "
                           f"{den_name}.", rule, 0)
    mn, md = float(num.mean()), float(den.mean())
    ratio = mn / md if md != 0 else (np.inf if mn > 0 else np.nan)
    few = n < MIN_BOOTSTRAP_N
    ci = (np.nan, np.nan) if few else ratio_ci(num, den, paired=paired)
    lo, hi = ratio_band(target, orders)
    ci_text = (f"[{fmt(ci[0])}, {fmt(ci[1])}]" if np.all(np.isfinite(ci))
               else f"[n/a: n < {MIN_BOOTSTRAP_N}]" if few else "[n/a]")
    counts = f"n = {n} pair{'s' if n != 1 else ''}" if paired else f"n = {len(num)} / {len(den)}"
    ours = (f"{fmt(ratio)}× {ci_text} ({num_name} {fmt(mn)} / {den_name} {fmt(md)}, {counts})")
    if withheld:
        verdict = WITHHELD
    else:
        verdict = ratio_verdict(ratio, target, ci, (lo, hi)) if judged else NOT_JUDGED
    where = ("inside" if lo <= ratio <= hi else "outside") if np.isfinite(ratio) else "undefined for"
    around = f"{fmt(target)}× ({orders:g} orders of magnitude, log band)" if orders is not None \
        else f"{fmt(target)}×"
    kind = (f"paired bootstrap over {n} {who}" if paired
            else f"bootstrap over {len(num)} and {len(den)} {who}, each side on its own")
    ci_side = _ci_side(ci, target)
    side = {"claimed": "the CI excludes 1 on the claimed side",
            "other": f"the CI lies {'at or below' if target > 1 else 'at or above'} 1, against the claim",
            "includes": "the CI includes 1",
            "undefined": (f"no CI from fewer than {MIN_BOOTSTRAP_N} rows" if few
                          else "the CI is undefined")}[ci_side]
    unsure = bool(np.isfinite(ratio)) and ci_side in ("includes", "undefined")
    if unsure and verdict != DIFFERS:
        side += ": inconclusive"  # a number beside the judged ones, or withheld: said at the end
    why = (f"mean {quantity} is {fmt(mn)} for {num_name} and {fmt(md)} for {den_name}: ratio "
           f"{fmt(ratio)}, 95% CI {ci_text} ({kind}); {where} the band [{fmt(lo)}, {fmt(hi)}] around "
           f"{around}; {side}.")
    why = _inconclusive(why, unsure and verdict == DIFFERS)
    if withheld:
        why += f" Not judged: {withheld}"
    return ClaimResult(id, section, claim, paper, ours, verdict, why, rule, n, ratio, ci[0], ci[1])


def share_claim(id, section, claim, paper, hits, what, *, detail: str = "") -> ClaimResult:
    """The share of True in ``hits`` is claimed to be above 1/2."""
    from scipy import stats

    hits = np.asarray(hits, dtype=bool)
    n, k = len(hits), int(hits.sum())
    if n == 0:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {what}.", "share", 0)
    share = k / n
    p = float(stats.binomtest(k, n, 0.5, alternative="greater").pvalue)
    if share <= 0.5:
        verdict = NOT_REPRODUCED
    else:
        verdict = REPRODUCED if p < ALPHA else DIFFERS
    why = (f"{k} of {n} {what}, {share:.0%}{detail}; "
           f"{'above' if share > 0.5 else 'not above'} one half, binomial p = {fmt_p(p)}.")
    why = _inconclusive(why, verdict == DIFFERS)
    return ClaimResult(id, section, claim, paper, f"{share:.0%} ({k}/{n})", verdict, why, "share", n, share)


def threshold_claim(id, section, claim, paper, overall, by_group: dict[str, float], threshold, quantity,
                    n: int) -> ClaimResult:
    """The mean ``quantity`` is claimed to be at most ``threshold`` in every group."""
    if n == 0 or not by_group:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {quantity}.",
                           "threshold", 0)
    over = [g for g, v in by_group.items() if not v <= threshold]
    if not over:
        verdict = REPRODUCED
    elif overall <= threshold:
        verdict = DIFFERS
    else:
        verdict = NOT_REPRODUCED
    groups = ", ".join(f"{g} {fmt(v)}" for g, v in by_group.items())
    ours = f"{fmt(overall)} overall ({groups})"
    why = (f"mean {quantity} is {groups} (all {fmt(overall)}); "
           + ("every group is at most " if not over else f"{', '.join(over)} above ")
           + f"the threshold {fmt(threshold)}.")
    return ClaimResult(id, section, claim, paper, ours, verdict, why, "threshold", n, overall)


def correlation_claim(id, section, claim, paper, x, y, factor, metric, *, claimed="positive") -> ClaimResult:
    """Pearson ρ of ``x`` and ``y`` is claimed to be ``claimed`` ("positive"/"negative") and significant."""
    from .tables import format_rho, pearson_cell

    cell = pearson_cell(x, y)
    if not np.isfinite(cell.rho):
        return ClaimResult(id, section, claim, paper, cell.text, NO_DATA,
                           f"ρ of {factor} and {metric} is undefined ({cell.text}, n = {cell.n}).",
                           "correlation", cell.n)
    sign_right = cell.rho > 0 if claimed == "positive" else cell.rho < 0
    verdict = _ordering_verdict(sign_right, cell.p)
    why = (f"ρ of {factor} and {metric} is {format_rho(cell.rho, 1.0)} over {cell.n} rows "
           f"({'the claimed' if sign_right else 'not the claimed'} sign), p = {fmt_p(cell.p)}.")
    why = _inconclusive(why, verdict == DIFFERS)
    return ClaimResult(id, section, claim, paper, f"ρ = {cell.text} (n = {cell.n})", verdict, why,
                       "correlation", cell.n, cell.rho)


def claims_frame(claims: list[ClaimResult]):
    import pandas as pd

    cols = list(ClaimResult.__dataclass_fields__)
    return pd.DataFrame([c.record() for c in claims], columns=cols)
