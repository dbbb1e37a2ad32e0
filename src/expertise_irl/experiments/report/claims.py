"""Claims of the paper and the rules that judge them, computed from the rows (never written by hand).

Every claim gives a :class:`ClaimResult`: the paper's number, ours, a verdict and one sentence
built from the numbers. The verdict rules (also printed in each report):

- ordering ("A below B"): *reproduced* if the mean paired difference has the claimed sign and a
  two-sided Wilcoxon signed-rank test gives p < 0.05; *differs* if the sign is right but p ≥ 0.05;
  *not reproduced* if the sign is wrong (or every difference is zero).
- ratio ("≈ X×"): *reproduced* if our ratio of means is within [X/1.5, 1.5·X]; *differs* if it is on
  the claimed side of 1 but outside that band; *not reproduced* otherwise.
- share ("most"): *reproduced* if the share is above 1/2 and a one-sided binomial test against 1/2
  gives p < 0.05; *differs* if above 1/2 with p ≥ 0.05; *not reproduced* if at most 1/2.
- threshold ("≈ 0 by n episodes"): *reproduced* if the mean is at most the threshold in every group;
  *differs* if the mean over all groups is but some group's is not; *not reproduced* otherwise.
- correlation ("ρ > 0, significant"): as ordering, with Pearson's p in place of Wilcoxon's.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .stats import fmt, fmt_p, wilcoxon_p

ALPHA = 0.05
BAND = 1.5
REPRODUCED, DIFFERS, NOT_REPRODUCED = "reproduced", "differs", "not reproduced"
NOT_JUDGED, NO_DATA = "not judged (ours)", "n/a (no data)"

RULES = {
    "ordering": "Ordering claims (A below/above B): reproduced if the mean paired difference has the "
                "claimed sign and a two-sided Wilcoxon signed-rank test (scipy.stats.wilcoxon) gives "
                "p < 0.05; differs if the sign is right but p ≥ 0.05; not reproduced if the sign is "
                "wrong or every difference is zero.",
    "ratio": f"Ratio claims (≈ X×): our ratio of means is reproduced if it lies within [X/{BAND}, "
             f"{BAND}·X]; differs if it is on the claimed side of 1 but outside that band; not "
             "reproduced otherwise.",
    "share": "Share claims (most people): reproduced if the share is above 1/2 and a one-sided "
             "binomial test against 1/2 gives p < 0.05; differs if it is above 1/2 with p ≥ 0.05; "
             "not reproduced if it is at most 1/2.",
    "threshold": "Threshold claims (≈ 0 by n episodes): reproduced if the mean is at most the "
                 "threshold in every expertise group; differs if the mean over all groups is but "
                 "some group's is not; not reproduced otherwise.",
    "correlation": "Correlation claims (ρ of a given sign): reproduced if Pearson's ρ has the claimed "
                   "sign with p < 0.05; differs if the sign is right but p ≥ 0.05; not reproduced if "
                   "the sign is wrong.",
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

    def record(self) -> dict:
        return asdict(self)


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
    return ClaimResult(id, section, claim, paper, ours_text + f" (n = {n}, p = {fmt_p(p)})", verdict, why,
                       "ordering", n, mean_d)


def ratio_verdict(ratio: float, target: float) -> str:
    if not np.isfinite(ratio):
        return NOT_REPRODUCED
    if target / BAND <= ratio <= target * BAND:
        return REPRODUCED
    if (target > 1 and ratio > 1) or (target < 1 and ratio < 1):
        return DIFFERS
    return NOT_REPRODUCED


def ratio_claim(id, section, claim, paper, num, den, num_name, den_name, quantity, target,
                *, judged=True) -> ClaimResult:
    """``mean(num) / mean(den)`` is claimed to be about ``target``."""
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    num, den = num[np.isfinite(num)], den[np.isfinite(den)]
    n = min(len(num), len(den))
    if n == 0:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {num_name} or "
                           f"{den_name}.", "ratio", 0)
    mn, md = float(num.mean()), float(den.mean())
    ratio = mn / md if md != 0 else (np.inf if mn > 0 else np.nan)
    lo, hi = target / BAND, target * BAND
    ours = f"{fmt(ratio)}× ({num_name} {fmt(mn)} / {den_name} {fmt(md)}, n = {len(num)} / {len(den)})"
    verdict = ratio_verdict(ratio, target) if judged else NOT_JUDGED
    where = ("inside" if lo <= ratio <= hi else "outside") if np.isfinite(ratio) else "undefined for"
    side = "above" if ratio > 1 else "below" if ratio < 1 else "at"
    why = (f"mean {quantity} is {fmt(mn)} for {num_name} and {fmt(md)} for {den_name}: ratio "
           f"{fmt(ratio)}, {where} the band [{fmt(lo)}, {fmt(hi)}] around {fmt(target)}× and {side} 1.")
    return ClaimResult(id, section, claim, paper, ours, verdict, why, "ratio", n, ratio)


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
    from .tables import pearson_cell

    cell = pearson_cell(x, y)
    if not np.isfinite(cell.rho):
        return ClaimResult(id, section, claim, paper, cell.text, NO_DATA,
                           f"ρ of {factor} and {metric} is undefined ({cell.text}, n = {cell.n}).",
                           "correlation", cell.n)
    sign_right = cell.rho > 0 if claimed == "positive" else cell.rho < 0
    verdict = _ordering_verdict(sign_right, cell.p)
    why = (f"ρ of {factor} and {metric} is {cell.rho:.2f} over {cell.n} rows "
           f"({'the claimed' if sign_right else 'not the claimed'} sign), p = {fmt_p(cell.p)}.")
    return ClaimResult(id, section, claim, paper, f"ρ = {cell.text} (n = {cell.n})", verdict, why,
                       "correlation", cell.n, cell.rho)


def claims_frame(claims: list[ClaimResult]):
    import pandas as pd

    cols = list(ClaimResult.__dataclass_fields__)
    return pd.DataFrame([c.record() for c in claims], columns=cols)
