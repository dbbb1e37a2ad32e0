"""Claims of the paper and the rules that judge them, computed from the rows (never written by hand).

Every claim gives a :class:`ClaimResult`: the paper's number, ours, a verdict and one sentence
built from the numbers. The verdict rules (also printed in each report):

- ordering ("A below B"): *reproduced* if the mean paired difference has the claimed sign and a
  two-sided Wilcoxon signed-rank test gives p < 0.05; *differs* if the sign is right but p ≥ 0.05
  (inconclusive); *not reproduced* if the sign is wrong (or every difference is zero).
- ratio ("≈ X×"): the ratio of means with a 95% percentile-bootstrap CI (paired where the rows
  pair; two-stage, maps then the people or instances within them, where the rows carry their map),
  beside the per-group, mix-adjusted and median ratios (:mod:`.ratios`). *reproduced* if the ratio
  is within [X/1.5, 1.5·X] and the CI excludes 1 on the claimed side; *differs* if the CI excludes
  1 on the claimed side but the ratio is outside the band (right direction, wrong size), or if the
  CI includes 1 or cannot be computed (inconclusive); *not reproduced* if the whole CI lies on the
  other side of 1.
  "≈ m orders of magnitude" uses the log band [10^(m−0.5), 10^(m+0.5)] instead.
- share ("most"): *reproduced* if the share is above 1/2 and a one-sided binomial test against 1/2
  gives p < 0.05; *differs* if above 1/2 with p ≥ 0.05 (inconclusive); *not reproduced* if at most 1/2.
- threshold ("≈ 0 by n episodes"): *reproduced* if the mean is at most the threshold in every group;
  *differs* if the mean over all groups is but some group's is not; *not reproduced* otherwise.
- correlation ("ρ > 0, significant"): as ordering, with Pearson's p in place of Wilcoxon's.
- table-cell, no-effect, share-gain, difference, every-count, margin (:mod:`.claim_kinds`): see
  :data:`RULES`.

The why of an inconclusive *differs* starts with "inconclusive:" (:data:`INCONCLUSIVE`).

A claim is *not judged (ours)* where the number is for one of our methods, beside the paper's,
and *not judged* where the rows cannot judge it (the "why" says why, e.g. timings taken while
other tasks shared the machine).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from ...errors import plural
from .ratios import ratio_extras
from .stats import BOOTSTRAP_SEED, RESAMPLES, cluster_ratio_ci, fmt, fmt_p, ratio_ci, wilcoxon_p

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
             "own; where the rows carry their map (`environment`) the bootstrap is two-stage: the maps "
             "are drawn with replacement first, then the people or instances within each drawn map, "
             "so that people who share a map are not counted as independent). Beside the pooled ratio "
             "each ratio claim gives the ratio per expertise group of β*, a mix-adjusted ratio "
             "(unpaired sides: the numerator's people reweighted to the denominator's group mix; "
             "paired: each group weighted equally) and the ratio of medians; the verdict is on the "
             "pooled ratio, the paper's. "
             f"Reproduced if the ratio lies within [X/{BAND}, {BAND}·X] and the CI excludes 1 on "
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
    "table-cell": "Table cells (one claim per cell of Tables I–IV): our Pearson ρ and p over the rows the "
                  "table names, with n, against the paper's cell. Where the paper's cell has † (p < "
                  "0.05): reproduced if our ρ has its sign and p < 0.05; differs if the sign is the "
                  "paper's but p ≥ 0.05 (inconclusive); not reproduced if the sign is the other. Where "
                  "the paper's cell has no †: reproduced if our p ≥ 0.05, whatever the sign (the sign of "
                  "a correlation the paper found not significant is not a finding; with a small n this "
                  "is easy to pass, so read it with n); differs if p < 0.05 with the paper's sign (a "
                  "correlation the paper did not find significant, in its direction); not reproduced if "
                  "p < 0.05 with the other sign. A cell our rows cannot compute (a constant factor, a "
                  "missing column) is n/a (no data).",
    "no-effect": "Claims that something does not happen (no improvement; not worse): the mean paired "
                 "difference and a two-sided Wilcoxon signed-rank test. Reproduced if the difference is "
                 "not in the direction the claim rules out (or is zero); differs if it is but p ≥ 0.05 "
                 "(inconclusive); not reproduced if it is with p < 0.05.",
    "share-gain": "Share claims that episodes bring about (most people right after n episodes): each "
                  "person right or wrong at 1 episode and at n, paired. Reproduced if the share at n "
                  "is above 1/2 with a one-sided binomial p < 0.05 and above the share at 1 with an "
                  "exact one-sided McNemar test p < 0.05 (the binomial tail of the people who go from "
                  "wrong to right among those who change); not reproduced if the share at n is at most "
                  "1/2 or at most the share at 1; differs otherwise (inconclusive).",
    "difference": "Unpaired orderings (A below/above B, different people): the difference of means with "
                  "a 95% percentile-bootstrap CI (two-stage by map where the rows carry `environment`). "
                  "Reproduced if the difference has the claimed sign and the CI excludes 0; differs if "
                  "the sign is right but the CI includes 0 (inconclusive); not reproduced if the sign is "
                  "wrong.",
    "every-count": "Claims made for every episode count from some count on: judged at each count by the "
                   "rule named beside this one; the verdict is the worst of them (not reproduced, then "
                   "differs, then reproduced), so that every count must pass.",
    "margin": "Margin claims (the change from n to m episodes is within the margin of error at n): per "
              "expertise group, the change of the mean against the half-width of the 95% Student-t CI "
              "at n. Reproduced if every group's change is within its half-width; differs if the change "
              "over all groups is but some group's is not; not reproduced otherwise.",
}


def rule_kinds(rule: str) -> list[str]:
    """The rules a claim's ``rule`` names (``"every-count:ordering"`` names two)."""
    return rule.split(":")


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
    p: float = float("nan")  # the test's p, where the rule uses a test
    median_ratio: float = float("nan")  # ratio claims: median(num) / median(den)
    adjusted_ratio: float = float("nan")  # ratio claims: mix-adjusted (see ratios.ratio_extras)
    group_ratios: str = ""  # ratio claims: the ratio of means per expertise group of β*
    number: str = ""  # our number in a few characters (for the claim × protocol matrix)

    def record(self) -> dict:
        return asdict(self)

    def with_(self, **changes) -> ClaimResult:
        return replace(self, **changes)


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
                       "ordering", n, mean_d, p=p, number=f"{ours_text} (n = {n})")


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


def _sides(x, paired: bool):
    """Labels of both sides: an array (paired: one for both) or a pair (num's, den's)."""
    if x is None:
        return None, None
    return (x, x) if paired else (x[0], x[1])


def _keep(mask, *labels):
    return [None if x is None else np.asarray(x, dtype=object)[mask] for x in labels]


def _ratio_ci(num, den, clusters, units, *, paired: bool, few: bool) -> tuple[tuple[float, float], int]:
    """The ratio's 95% CI and the number of maps it resampled first (0: none, an iid bootstrap)."""
    if clusters[0] is None:
        return ((np.nan, np.nan) if few else ratio_ci(num, den, paired=paired)), 0
    maps = len(set(clusters[0]) | set(clusters[1]))
    if few:
        return (np.nan, np.nan), maps
    ci = cluster_ratio_ci(num, den, clusters if not paired else clusters[0], paired=paired,
                          units=units if not paired else units[0])
    return ci, maps


def _bootstrap_text(n: int, n_num: int, n_den: int, who: str, *, paired: bool, maps: int) -> str:
    """How the ratio's CI was drawn, for its why."""
    if not maps:
        return (f"paired bootstrap over {n} {who}" if paired
                else f"bootstrap over {n_num} and {n_den} {who}, each side on its own")
    first = (f"two-stage cluster bootstrap: the {plural(maps, 'map')} drawn with replacement, then within "
             "each ")
    if paired:
        return first + f"drawn map its pairs ({n} {who} in all)"
    return first + f"drawn map each side's people on its own ({n_num} and {n_den} {who} in all)"


def _ratio_side_text(ci_side: str, target: float, few: bool) -> str:
    return {"claimed": "the CI excludes 1 on the claimed side",
            "other": f"the CI lies {'at or below' if target > 1 else 'at or above'} 1, against the claim",
            "includes": "the CI includes 1",
            "undefined": (f"no CI from fewer than {MIN_BOOTSTRAP_N} rows" if few
                          else "the CI is undefined")}[ci_side]


def ratio_claim(id, section, claim, paper, num, den, num_name, den_name, quantity, target,
                *, paired: bool, who: str, orders: float | None = None, judged: bool = True,
                withheld: str | None = None, clusters=None, groups=None, units=None) -> ClaimResult:
    """``mean(num) / mean(den)`` is claimed to be about ``target`` (``10**orders`` if ``orders``).

    ``paired``: ``num[i]`` and ``den[i]`` are one unit (``who``, e.g. "in-set people") under both
    sides; pairs with a NaN are dropped. Otherwise the sides are independent samples of ``who``.
    ``judged=False``: one of our methods (verdict :data:`NOT_JUDGED`); ``withheld``: why the rows
    cannot judge the claim (verdict :data:`WITHHELD`). ``clusters`` (the map of each row), ``units``
    (the unit of each row within its map) and ``groups`` (β*'s expertise group): an array for both
    sides where paired, else a pair (num's, den's). With ``clusters`` the CI is the two-stage
    cluster bootstrap (:func:`.stats.cluster_ratio_ci`); with ``groups`` the claim also gives the
    ratio per group, mix-adjusted and of medians (:func:`.ratios.ratio_extras`).
    """
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    (cn, cd), (gn, gd), (un, ud) = (_sides(x, paired) for x in (clusters, groups, units))
    if paired:
        keep = np.isfinite(num) & np.isfinite(den)
        num, den = num[keep], den[keep]
        cn, gn, un = _keep(keep, cn, gn, un)
        cd, gd, ud = cn, gn, un
    else:
        kn, kd = np.isfinite(num), np.isfinite(den)
        num, den = num[kn], den[kd]
        cn, gn, un = _keep(kn, cn, gn, un)
        cd, gd, ud = _keep(kd, cd, gd, ud)
    n = min(len(num), len(den))
    rule = "ratio" if orders is None else "magnitude"
    if n == 0:
        return ClaimResult(id, section, claim, paper, "n/a", NO_DATA, f"no rows for {num_name} or "
                           f"{den_name}.", rule, 0)
    mn, md = float(num.mean()), float(den.mean())
    ratio = mn / md if md != 0 else (np.inf if mn > 0 else np.nan)
    few = n < MIN_BOOTSTRAP_N
    ci, maps = _ratio_ci(num, den, (cn, cd), (un, ud), paired=paired, few=few)
    extras = ratio_extras(num, den, gn, gd, paired=paired)
    lo, hi = ratio_band(target, orders)
    ci_text = (f"[{fmt(ci[0])}, {fmt(ci[1])}]" if np.all(np.isfinite(ci))
               else f"[n/a: n < {MIN_BOOTSTRAP_N}]" if few else "[n/a]")
    counts = f"n = {n} pair{'s' if n != 1 else ''}" if paired else f"n = {len(num)} / {len(den)}"
    ours = (f"{fmt(ratio)}× {ci_text} ({num_name} {fmt(mn)} / {den_name} {fmt(md)}, {counts}); "
            + extras.ours_text())
    if withheld:
        verdict = WITHHELD
    else:
        verdict = ratio_verdict(ratio, target, ci, (lo, hi)) if judged else NOT_JUDGED
    where = ("inside" if lo <= ratio <= hi else "outside") if np.isfinite(ratio) else "undefined for"
    around = f"{fmt(target)}× ({orders:g} orders of magnitude, log band)" if orders is not None \
        else f"{fmt(target)}×"
    kind = _bootstrap_text(n, len(num), len(den), who, paired=paired, maps=maps)
    ci_side = _ci_side(ci, target)
    side = _ratio_side_text(ci_side, target, few)
    unsure = bool(np.isfinite(ratio)) and ci_side in ("includes", "undefined")
    if unsure and verdict != DIFFERS:
        side += ": inconclusive"  # a number beside the judged ones, or withheld: said at the end
    why = (f"mean {quantity} is {fmt(mn)} for {num_name} and {fmt(md)} for {den_name}: ratio "
           f"{fmt(ratio)}, 95% CI {ci_text} ({kind}); {where} the band [{fmt(lo)}, {fmt(hi)}] around "
           f"{around}; {side}. " + extras.why_text(num_name, den_name))
    why = _inconclusive(why, unsure and verdict == DIFFERS)
    if withheld:
        why += f" Not judged: {withheld}"
    return ClaimResult(id, section, claim, paper, ours, verdict, why, rule, n, ratio, ci[0], ci[1],
                       median_ratio=extras.medians, adjusted_ratio=extras.adjusted,
                       group_ratios=extras.group_text(), number=f"{fmt(ratio)}× {ci_text}")


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
    return ClaimResult(id, section, claim, paper, f"{share:.0%} ({k}/{n})", verdict, why, "share", n, share,
                       p=p, number=f"{share:.0%} ({k}/{n})")


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
    return ClaimResult(id, section, claim, paper, ours, verdict, why, "threshold", n, overall,
                       number=f"{fmt(overall)} ({groups})")


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
                       "correlation", cell.n, cell.rho, p=cell.p, number=f"ρ = {cell.text} (n = {cell.n})")


def claims_frame(claims: list[ClaimResult]):
    import pandas as pd

    cols = list(ClaimResult.__dataclass_fields__)
    return pd.DataFrame([c.record() for c in claims], columns=cols)
