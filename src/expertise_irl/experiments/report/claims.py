"""Claims of the paper and the rules that judge them, computed from the rows (never written by hand).

Every claim gives a :class:`ClaimResult`: the paper's number, ours, a verdict and one sentence
built from the numbers. Paired values within 1e-9 (relative) of each other are ties, zero differences
(:func:`.stats.paired_differences`). The verdict rules (also printed in each report, :data:`RULES`):

- ordering ("A below B"): the mean paired difference and a one-sided Wilcoxon signed-rank test in
  each direction. *reproduced* if the mean has the claimed sign and the test in the claimed direction
  gives p < 0.05; *not reproduced* if the mean has the other sign and the test in that direction gives
  p < 0.05, or if every pair is a tie; *differs* (inconclusive) otherwise: not significant, or the
  mean and the rank test disagree.
- ratio ("≈ X×"): the ratio of means with a 95% percentile-bootstrap CI (paired where the rows
  pair; two-stage, maps then the people or instances within them, where the rows carry their map),
  beside the per-group, mix-adjusted and median ratios (:mod:`.ratios`). *reproduced* if the ratio
  is within [X/1.5, 1.5·X] and the CI excludes 1 on the claimed side; *differs* if the CI excludes
  1 on the claimed side but the ratio is outside the band (right direction, wrong size); where the
  CI includes 1, *differs*, inconclusive if the CI also overlaps the band and "the rows exclude the
  paper's value" if it does not; *differs* (inconclusive) without a CI; *not reproduced* if the whole
  CI lies on the other side of 1; *n/a (no data)* where the ratio is 0 / 0.
  "≈ m orders of magnitude" uses the log band [10^(m−0.5), 10^(m+0.5)] instead.
- share ("most"): *reproduced* if the share is above 1/2 and a one-sided binomial test against 1/2
  gives p < 0.05; *differs* if above 1/2 with p ≥ 0.05 (inconclusive); *not reproduced* if at most 1/2.
- threshold ("≈ 0 by n episodes"): *reproduced* if the mean is at most the threshold in every group;
  *differs* if the mean over all groups is but some group's is not; *not reproduced* otherwise.
- correlation ("ρ > 0, significant"): *reproduced* if Pearson's ρ has the claimed sign with p < 0.05;
  *not reproduced* if it has the other sign with p < 0.05; *differs* if p ≥ 0.05, inconclusive if the
  Fisher-z 95% CI of ρ includes the paper's ρ, else "the rows exclude the paper's value".
- table-cell, no-effect, share-gain, difference, every-count, margin (:mod:`.claim_kinds`): see
  :data:`RULES`.

The why of an inconclusive *differs* starts with "inconclusive:" (:data:`INCONCLUSIVE`); that of a
*differs* whose CI includes the null but rules out the paper's value with "the rows exclude the
paper's value:" (:data:`EXCLUDED`).

A claim is *not judged (ours)* where the number is for one of our methods, beside the paper's,
and *not judged* where the rows cannot judge it (the "why" says why, e.g. timings taken while
other tasks shared the machine).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import NamedTuple

import numpy as np

from ...errors import plural
from .ratios import ratio_extras
from .stats import (
    BOOTSTRAP_SEED,
    MIN_BOOTSTRAP_N,
    RESAMPLES,
    TIE_ATOL,
    TIE_RTOL,
    cluster_ratio_ci,
    fisher_ci,
    fmt,
    fmt_p,
    paired_differences,
    ratio_ci,
    wilcoxon_p,
)

ALPHA = 0.05
BAND = 1.5
#: Half-width, in orders of magnitude, of the band of "≈ m orders of magnitude" claims.
LOG_HALF_BAND = 0.5
REPRODUCED, DIFFERS, NOT_REPRODUCED = "reproduced", "differs", "not reproduced"
NOT_JUDGED, WITHHELD, NO_DATA = "not judged (ours)", "not judged", "n/a (no data)"
#: Every verdict a claim can get.
VERDICTS = (REPRODUCED, DIFFERS, NOT_REPRODUCED, NOT_JUDGED, WITHHELD, NO_DATA)
#: What a verdict means beyond its rule (printed under the rules where the verdict occurs).
VERDICT_NOTES = {
    DIFFERS: "differs: either the rows cannot tell (not significant, a CI that includes both the null "
             "and the paper's value, a mean and a rank test that disagree, or too few rows for a CI), "
             "and then its why starts with \"inconclusive:\"; or the rows include no effect but rule "
             "out the paper's value (its CI lies outside the paper's band or misses the paper's ρ), and "
             "then its why starts with \"the rows exclude the paper's value:\"; or the direction is "
             "right but not the claimed size (for threshold claims: some group above the threshold).",
    NOT_JUDGED: "not judged (ours): the same number for one of our methods, beside the paper's; the "
                "paper makes no claim about it.",
    WITHHELD: "not judged: the rows cannot judge this claim; the why says what is missing.",
    NO_DATA: "n/a (no data): the sweep has no rows for it (or too few, or a ratio of 0 / 0).",
}
_TIES = (f"pairs equal within {TIE_RTOL:g} relative (+ {TIE_ATOL:g}) are ties, zero differences, "
         "dropped from the test and counted as 0 in the mean")

RULES = {
    "ordering": "Ordering claims (A below/above B): the mean paired difference and one-sided Wilcoxon "
                "signed-rank tests (scipy.stats.wilcoxon) in each direction; " + _TIES + ". Reproduced "
                "if the mean difference has the claimed sign and the test in the claimed direction "
                "gives p < 0.05; not reproduced if the mean has the other sign and the test in that "
                "direction gives p < 0.05, or if every pair is a tie; differs otherwise (inconclusive: "
                "not significant either way, or the mean and the rank test point different ways).",
    "ratio": f"Ratio claims (≈ X×): our ratio of means, with a 95% percentile-bootstrap CI "
             f"({RESAMPLES} resamples, numpy Generator seed {BOOTSTRAP_SEED}; rows that pair, the same "
             "people or instances under both, are resampled as pairs, other rows each side on its "
             "own; where the rows carry their map (`environment`) the bootstrap is two-stage: the maps "
             "are drawn with replacement first, then the people or instances within each drawn map, "
             "so that people who share a map are not counted as independent). Beside the pooled ratio "
             "each ratio claim gives the ratio per expertise group of β* with its n, a mix-adjusted "
             "ratio (unpaired sides: the numerator's people reweighted to the denominator's group mix; "
             "paired: each group weighted equally; n/a where a group has fewer than "
             f"{MIN_BOOTSTRAP_N} people or instances on a side) and the ratio of medians (n/a where "
             "the denominator's median is below 1e-9); the verdict is on the pooled ratio, the paper's. "
             f"Reproduced if the ratio lies within the band [X/{BAND}, {BAND}·X] and the CI excludes 1 "
             "on the claimed side; differs if the CI excludes 1 on the claimed side but the ratio is "
             "outside the band (right direction, wrong size); where the CI includes 1: differs, "
             "inconclusive if the CI also overlaps the band, and \"the rows exclude the paper's "
             "value\" if it lies wholly outside the band; not reproduced if the whole CI lies on the "
             "other side of 1 (its nearer bound at 1 or past it). With fewer than "
             f"{MIN_BOOTSTRAP_N} rows on a side (too few for a two-sided Wilcoxon test to reach "
             "p < 0.05) there is no CI and the claim is inconclusive (differs). A ratio of 0 / 0 (both "
             "means 0) is undefined: n/a (no data).",
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
                   "sign with p < 0.05; not reproduced if it has the other sign with p < 0.05; differs "
                   "if p ≥ 0.05, whatever the sign: inconclusive if the Fisher-z 95% CI of ρ "
                   "(tanh(atanh ρ ± 1.96/√(n − 3))) includes the paper's ρ, and \"the rows exclude "
                   "the paper's value\" if it does not.",
    "table-cell": "Table cells (one claim per cell of Tables I–IV): our Pearson ρ and p over the rows the "
                  "table names, with n and the Fisher-z 95% CI of ρ, against the paper's cell. Where "
                  "the paper's cell has † (p < 0.05): reproduced if our ρ has its sign and p < 0.05; not "
                  "reproduced if our ρ has the other sign and p < 0.05; differs if p ≥ 0.05, whatever "
                  "the sign: inconclusive if our CI includes the paper's ρ, and \"the rows exclude the "
                  "paper's value\" if it does not. Where the paper's cell has no †: reproduced if our "
                  "p ≥ 0.05, whatever the sign (the sign of a correlation the paper found not "
                  "significant is not a finding; with a small n this is easy to pass, so read it with "
                  "n); differs if p < 0.05 with the paper's sign (a correlation the paper did not find "
                  "significant, in its direction); not reproduced if p < 0.05 with the other sign. A "
                  "cell our rows cannot compute (a constant factor, a missing column) is n/a (no data).",
    "no-effect": "Claims that something does not happen (no improvement; not worse): the mean paired "
                 "difference and a one-sided Wilcoxon signed-rank test in the direction the claim "
                 "rules out; " + _TIES + ". Not reproduced if the mean difference is in that direction "
                 "and the test gives p < 0.05; differs (inconclusive) if the mean is in that direction "
                 "with p ≥ 0.05, or if it is not but the test gives p < 0.05 (the mean and the rank "
                 "test disagree); reproduced otherwise (the mean not in that direction, or zero, and "
                 "the test not significant).",
    "share-gain": "Share claims that episodes bring about (most people right after n episodes): each "
                  "person right or wrong at 1 episode and at n, paired. Reproduced if the share at n "
                  "is above 1/2 with a one-sided binomial p < 0.05 and above the share at 1 with an "
                  "exact one-sided McNemar test p < 0.05 (the binomial tail of the people who go from "
                  "wrong to right among those who change); not reproduced if the share at n is at most "
                  "1/2 or at most the share at 1; differs otherwise (inconclusive).",
    "difference": "Unpaired orderings (A below/above B, different people): the difference of means with "
                  "a 95% percentile-bootstrap CI (two-stage by map where the rows carry `environment`). "
                  "Reproduced if the difference has the claimed sign and the CI excludes 0; not "
                  "reproduced if it has the other sign and the CI excludes 0 on that side; differs "
                  "(inconclusive) otherwise: a CI that includes 0, or no CI, with fewer than "
                  f"{MIN_BOOTSTRAP_N} people on a side.",
    "every-count": "Claims made for every episode count from some count on: judged at each count by the "
                   "rule named beside this one; the verdict is the worst of the judged counts (not "
                   "reproduced, then differs, then reproduced), so that every count must pass. A count "
                   "without rows (n/a) is named in the why but does not hide the others' verdicts; the "
                   "claim is n/a (no data) only if no count is judged.",
    "margin": "Margin claims (the change from n to m episodes is within the margin of error at n): per "
              "expertise group, the change of the mean against the half-width of the 95% Student-t CI "
              "at n. Reproduced if every group's change is within its half-width; differs if the change "
              "over all groups is but some group's is not; not reproduced otherwise. A group the claim "
              "names with fewer than 2 rows at n or none at m makes the claim n/a (no data).",
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


#: How the why of a "differs" begins where the rows cannot tell (not significant, a CI that includes both
#: the null and the paper's value, too few rows), so that the claims table tells it from "right
#: direction, wrong size".
INCONCLUSIVE = "inconclusive: "
#: How the why of a "differs" begins where the CI includes the null but rules out the paper's value.
EXCLUDED = "the rows exclude the paper's value: "
#: Why-prefix kinds of a "differs" (:func:`_differs_why`): none, inconclusive, the paper's value excluded.
PLAIN, UNSURE, RULED_OUT = "", "inconclusive", "excluded"


def _inconclusive(why: str, inconclusive: bool) -> str:
    return INCONCLUSIVE + why if inconclusive else why


def _differs_why(why: str, verdict: str, kind: str) -> str:
    """``why`` with the prefix a "differs" of ``kind`` takes (none for other verdicts)."""
    if verdict != DIFFERS:
        return why
    return {UNSURE: INCONCLUSIVE, RULED_OUT: EXCLUDED}.get(kind, "") + why


def strip_prefix(why: str) -> str:
    """``why`` without the prefix of an inconclusive or excluding "differs"."""
    return why.removeprefix(INCONCLUSIVE).removeprefix(EXCLUDED)


class PairedTest(NamedTuple):
    """A paired comparison toward one direction ("below"/"above"): the mean difference (ties at 0), the
    number of ties, the sign of the mean (+1: toward, −1: the other way, 0: none) and the one-sided
    Wilcoxon p toward and the other way (NaN where every pair is a tie)."""

    mean_d: float
    ties: int
    sign: int
    p_toward: float
    p_away: float

    @property
    def all_ties(self) -> bool:
        return bool(np.isnan(self.p_toward) and np.isnan(self.p_away))

    def agree(self) -> bool:
        """False where the mean points one way and the rank test is significant the other way (or the
        mean is 0 and the rank test significant)."""
        if self.sign > 0:
            return not self.p_away < ALPHA
        if self.sign < 0:
            return not self.p_toward < ALPHA
        return not (self.p_toward < ALPHA or self.p_away < ALPHA)


def paired_test(a, b, toward: str) -> PairedTest:
    """``a`` against ``b`` (paired) toward ``toward``: see :class:`PairedTest`."""
    d = paired_differences(a, b)
    mean_d = float(d.mean()) if len(d) else float("nan")
    less, greater = wilcoxon_p(a, b, "less"), wilcoxon_p(a, b, "greater")
    sign = int(np.sign(mean_d)) * (-1 if toward == "below" else 1)
    p_toward, p_away = (less, greater) if toward == "below" else (greater, less)
    return PairedTest(mean_d, int((d == 0).sum()), sign, p_toward, p_away)


def _opposite(direction: str) -> str:
    return "above" if direction == "below" else "below"


def rank_test_text(t: PairedTest, a_name: str, b_name: str, toward: str) -> str:
    """The one-sided tests of ``t`` in words."""
    if t.all_ties:
        return "every pair is a tie, nothing to test"
    ties = f" ({plural(t.ties, 'tie')} dropped)" if t.ties else ""
    return (f"one-sided Wilcoxon p = {fmt_p(t.p_toward)} for {a_name} {toward} {b_name} and "
            f"{fmt_p(t.p_away)} for {a_name} {_opposite(toward)} {b_name}{ties}"
            + ("" if t.agree() else "; the mean and the rank test point different ways"))


def ordering_verdict(t: PairedTest) -> str:
    """The ordering rule on a :class:`PairedTest` toward the claimed direction."""
    if t.all_ties:
        return NOT_REPRODUCED
    if t.sign > 0 and t.p_toward < ALPHA:
        return REPRODUCED
    if t.sign < 0 and t.p_away < ALPHA:
        return NOT_REPRODUCED
    return DIFFERS


def finite_pairs(a, b) -> tuple[np.ndarray, np.ndarray]:
    """``a`` and ``b`` (paired, same order) as float arrays without the pairs where either is NaN/inf."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    return a[keep], b[keep]


def ordering_claim(id, section, claim, paper, a, b, a_name, b_name, quantity, *, claimed="below",
                   who="pairs", judged=True) -> ClaimResult:
    """``a`` (paired with ``b``, same order) is claimed to be ``claimed`` ("below"/"above") ``b``."""
    a, b = finite_pairs(a, b)
    n = len(a)
    ours_text = f"{a_name} {fmt(a.mean()) if n else 'n/a'} vs {b_name} {fmt(b.mean()) if n else 'n/a'}"
    if n == 0:
        return ClaimResult(id, section, claim, paper, ours_text, NO_DATA, f"no paired {who} to compare.",
                           "ordering", 0)
    t = paired_test(a, b, claimed)
    verdict = ordering_verdict(t) if judged else NOT_JUDGED
    actual = "below" if t.mean_d < 0 else "above" if t.mean_d > 0 else "equal to"
    why = (f"mean {quantity} is {fmt(a.mean())} for {a_name} and {fmt(b.mean())} for {b_name} over {n} "
           f"paired {who}: {a_name} is {actual} {b_name}, {'as' if t.sign > 0 else 'not as'} claimed; "
           f"{rank_test_text(t, a_name, b_name, claimed)}.")
    why = _differs_why(why, verdict, UNSURE)
    return ClaimResult(id, section, claim, paper, ours_text + f" (n = {n}, p = {fmt_p(t.p_toward)})", verdict,
                       why, "ordering", n, t.mean_d, p=t.p_toward, number=f"{ours_text} (n = {n})")


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


def ratio_judgement(ratio: float, target: float, ci: tuple[float, float],
                    band: tuple[float, float] | None = None) -> tuple[str, str]:
    """The ratio rule: (verdict, why kind) of ``ratio`` and its 95% ``ci`` against ≈ ``target``."""
    lo, hi = band or ratio_band(target)
    if np.isnan(ratio):
        return NO_DATA, PLAIN  # 0 / 0
    side = _ci_side(ci, target)
    if side == "claimed":
        return (REPRODUCED if lo <= ratio <= hi else DIFFERS), PLAIN
    if side == "other":
        return NOT_REPRODUCED, PLAIN
    if side == "includes" and (ci[1] < lo or ci[0] > hi):
        return DIFFERS, RULED_OUT  # the CI includes 1 but misses the band
    return DIFFERS, UNSURE  # includes 1 and overlaps the band, or no CI


def ratio_verdict(ratio: float, target: float, ci: tuple[float, float],
                  band: tuple[float, float] | None = None) -> str:
    """The ratio rule's verdict (:func:`ratio_judgement`)."""
    return ratio_judgement(ratio, target, ci, band)[0]


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


def _ratio_side_text(ci, target: float, kind: str, verdict: str, few: bool) -> str:
    """Where the CI lies against 1 (and, where it includes 1, against the band), for the why."""
    ci_side = _ci_side(ci, target)
    text = {"claimed": "the CI excludes 1 on the claimed side",
            "other": f"the CI lies {'at or below' if target > 1 else 'at or above'} 1, against the claim",
            "includes": "the CI includes 1",
            "undefined": (f"no CI from fewer than {MIN_BOOTSTRAP_N} rows" if few
                          else "the CI is undefined")}[ci_side]
    if kind == RULED_OUT:
        return text + " but lies wholly outside the band: the rows rule out the paper's size"
    if kind == UNSURE:
        text += " and overlaps the band" if ci_side == "includes" else ""
        text += "" if verdict == DIFFERS else ": inconclusive"  # beside the judged ones, or withheld
    return text


def _finite_sides(num, den, paired: bool, clusters, groups, units):
    """``num``, ``den`` without NaNs and each side's (clusters, groups, units) labels to match."""
    (cn, cd), (gn, gd), (un, ud) = (_sides(x, paired) for x in (clusters, groups, units))
    if paired:
        keep = np.isfinite(num) & np.isfinite(den)
        num, den = num[keep], den[keep]
        cn, gn, un = _keep(keep, cn, gn, un)
        return num, den, (cn, cn), (gn, gn), (un, un)
    kn, kd = np.isfinite(num), np.isfinite(den)
    cn, gn, un = _keep(kn, cn, gn, un)
    cd, gd, ud = _keep(kd, cd, gd, ud)
    return num[kn], den[kd], (cn, cd), (gn, gd), (un, ud)


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
    num, den, (cn, cd), (gn, gd), (un, ud) = _finite_sides(
        np.asarray(num, dtype=np.float64), np.asarray(den, dtype=np.float64), paired, clusters, groups, units)
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
    judged_verdict, kind = ratio_judgement(ratio, target, ci, (lo, hi))
    verdict = WITHHELD if withheld else judged_verdict if judged else NOT_JUDGED
    where = ("inside" if lo <= ratio <= hi else "outside") if np.isfinite(ratio) else "undefined for"
    around = f"{fmt(target)}× ({orders:g} orders of magnitude, log band)" if orders is not None \
        else f"{fmt(target)}×"
    how = _bootstrap_text(n, len(num), len(den), who, paired=paired, maps=maps)
    side = (_ratio_side_text(ci, target, kind, verdict, few) if np.isfinite(ratio)
            else "both means are 0: the ratio is undefined (0 / 0)")
    why = (f"mean {quantity} is {fmt(mn)} for {num_name} and {fmt(md)} for {den_name}: ratio "
           f"{fmt(ratio)}, 95% CI {ci_text} ({how}); {where} the band [{fmt(lo)}, {fmt(hi)}] around "
           f"{around}; {side}. " + extras.why_text(num_name, den_name))
    why = _differs_why(why, verdict, kind)
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


def correlation_judgement(rho: float, p: float, n: int, sign: float,
                          paper_rho: float | None = None) -> tuple[str, str, tuple[float, float]]:
    """(verdict, why kind, Fisher-z 95% CI) of ρ (``p``, over ``n`` rows) against a claim of ``sign``
    (+1/−1), significant, and where given the paper's ``paper_rho`` (:data:`RULES` "correlation")."""
    ci = fisher_ci(rho, n)
    if p < ALPHA:
        return (REPRODUCED if np.sign(rho) == np.sign(sign) else NOT_REPRODUCED), PLAIN, ci
    if paper_rho is not None and np.all(np.isfinite(ci)) and not ci[0] <= paper_rho <= ci[1]:
        return DIFFERS, RULED_OUT, ci
    return DIFFERS, UNSURE, ci


def ci_against(ci: tuple[float, float], value: float | None, what: str) -> str:
    """"Fisher-z 95% CI [a, b], which includes/excludes ``what``" for a why."""
    if not np.all(np.isfinite(ci)):
        return "Fisher-z 95% CI n/a"
    text = f"Fisher-z 95% CI [{fmt(ci[0])}, {fmt(ci[1])}]"
    if value is None:
        return text
    return text + f", which {'includes' if ci[0] <= value <= ci[1] else 'excludes'} {what}"


def correlation_claim(id, section, claim, paper, x, y, factor, metric, *, claimed="positive",
                      paper_rho: float | None = None) -> ClaimResult:
    """Pearson ρ of ``x`` and ``y`` is claimed to be ``claimed`` ("positive"/"negative") and significant
    (``paper_rho``: the paper's ρ, which a non-significant ρ's CI may rule out)."""
    from .tables import format_rho, pearson_cell

    cell = pearson_cell(x, y)
    if not np.isfinite(cell.rho):
        return ClaimResult(id, section, claim, paper, cell.text, NO_DATA,
                           f"ρ of {factor} and {metric} is undefined ({cell.text}, n = {cell.n}).",
                           "correlation", cell.n)
    sign = 1.0 if claimed == "positive" else -1.0
    verdict, kind, ci = correlation_judgement(cell.rho, cell.p, cell.n, sign, paper_rho)
    sign_right = np.sign(cell.rho) == sign
    paper_text = f"the paper's {fmt(paper_rho)}" if paper_rho is not None else ""
    why = (f"ρ of {factor} and {metric} is {format_rho(cell.rho, 1.0)} over {cell.n} rows "
           f"({'the claimed' if sign_right else 'not the claimed'} sign), p = {fmt_p(cell.p)}"
           f"{'' if cell.p < ALPHA else ', not significant'}; "
           f"{ci_against(ci, paper_rho, paper_text)}.")
    why = _differs_why(why, verdict, kind)
    return ClaimResult(id, section, claim, paper, f"ρ = {cell.text} (n = {cell.n})", verdict, why,
                       "correlation", cell.n, cell.rho, ci[0], ci[1], p=cell.p,
                       number=f"ρ = {cell.text} (n = {cell.n})")


def claims_frame(claims: list[ClaimResult]):
    import pandas as pd

    cols = list(ClaimResult.__dataclass_fields__)
    return pd.DataFrame([c.record() for c in claims], columns=cols)
