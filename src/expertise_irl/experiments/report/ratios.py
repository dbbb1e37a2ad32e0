"""What a ratio of means hides: the ratio per expertise group, mix-adjusted, of medians, and how much
of the numerator's mean one unit supplies (beside the pooled ratio a ratio claim is judged on)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...hypotheses import GROUP_NAMES
from .stats import MIN_BOOTSTRAP_N, fmt

#: A denominator's median below this is at 0: the ratio of medians is n/a, not a huge number.
MEDIAN_FLOOR = 1e-9


@dataclass(frozen=True)
class RatioExtras:
    """``by_group``: {group: (ratio of means, n num, n den)}; ``adjusted``: the mix-adjusted ratio and
    ``adjusted_how`` the sentence that says how (``adjusted_note``: why it is withheld, NaN then);
    ``medians``: median(num) / median(den) (NaN where median(den) is below :data:`MEDIAN_FLOOR`);
    ``top_share``: the largest single value's share of the numerator's sum."""

    by_group: dict
    adjusted: float
    adjusted_how: str
    medians: float
    median_num: float
    median_den: float
    top_share: float
    adjusted_note: str = ""
    paired: bool = False

    def _n(self, a: int, b: int) -> str:
        return f"n = {a}" if self.paired else f"n = {a}/{b}"

    def group_text(self) -> str:
        """``"high 69× (n = 25/30), medium 6.1× (n = 30/30)"`` (empty where there are no groups)."""
        return ", ".join(f"{g} {fmt(r) + '×' if np.isfinite(r) else 'n/a'} ({self._n(a, b)})"
                         for g, (r, a, b) in self.by_group.items())

    def adjusted_text(self) -> str:
        """``"1.8× (how)"``, ``"n/a (why)"`` or empty (no groups)."""
        if np.isfinite(self.adjusted):
            return f"{fmt(self.adjusted)}× ({self.adjusted_how})"
        return f"n/a ({self.adjusted_note})" if self.adjusted_note else ""

    def medians_text(self) -> str:
        if np.isfinite(self.medians):
            return f"{fmt(self.medians)}×"
        return "n/a (median at 0)" if abs(self.median_den) < MEDIAN_FLOOR else "n/a"

    def ours_text(self) -> str:
        """The short form for a claim's "ours"."""
        parts = [f"per group {self.group_text()}"] if self.by_group else []
        if np.isfinite(self.adjusted):
            parts.append(f"mix-adjusted {fmt(self.adjusted)}×")
        elif self.adjusted_note:
            parts.append("mix-adjusted n/a")
        parts.append(f"ratio of medians {self.medians_text()}")
        return "; ".join(parts)

    def why_text(self, num_name: str, den_name: str) -> str:
        """The sentence for a claim's why."""
        out = "Beside the pooled ratio: "
        if self.by_group:
            out += f"per expertise group of β* {self.group_text()}; "
        if self.adjusted_text():
            out += f"mix-adjusted {self.adjusted_text()}; "
        out += (f"ratio of medians {self.medians_text()} ({num_name} {fmt(self.median_num)} / {den_name} "
                f"{fmt(self.median_den)}); the largest single {num_name} value is "
                f"{self.top_share:.0%} of the {num_name} sum.")
        return out


def _ratio(a: float, b: float) -> float:
    if not (np.isfinite(a) and np.isfinite(b)):
        return float("nan")
    return a / b if b != 0 else (float("inf") if a > 0 else float("nan"))


def _order(groups) -> list[str]:
    present = {str(g) for g in groups}
    return [g for g in GROUP_NAMES if g in present] + sorted(present - set(GROUP_NAMES))


def _adjusted(num, den, gn, gd, by_group: dict, paired: bool) -> tuple[float, str, str]:
    """(mix-adjusted ratio, how, why withheld) over the groups both sides hold."""
    small = [f"{g} ({a}/{b})" for g, (_, a, b) in by_group.items() if min(a, b) < MIN_BOOTSTRAP_N]
    both = [g for g in by_group if (gn == g).any() and (gd == g).any()]
    if paired:
        w = {g: 1.0 / len(both) for g in both}
        how = "each expertise group weighted equally"
    else:
        w = {g: float((gd == g).sum()) for g in both}
        s = sum(w.values())
        w = {g: v / s for g, v in w.items()} if s else {}
        mix = ", ".join(f"{g} {v:.0%}" for g, v in w.items())
        how = f"the numerator's units reweighted to the denominator's group mix ({mix})"
    if small:
        return float("nan"), how, (f"fewer than {MIN_BOOTSTRAP_N} units on a side in "
                                   f"{', '.join(small)}")
    if not w:
        return float("nan"), how, ""
    return _ratio(sum(w[g] * num[gn == g].mean() for g in w), sum(w[g] * den[gd == g].mean() for g in w)), \
        how, ""


def ratio_extras(num, den, groups_num=None, groups_den=None, *, paired: bool) -> RatioExtras:
    """The numbers beside a pooled ratio of means (``num``, ``den`` without NaNs).

    Paired (the same units on both sides): the mix is the same on both sides, so the mix-adjusted
    ratio is stratified with equal weight per group, sum_g mean(num_g) / sum_g mean(den_g), the
    ratio a sample with as many units in each group would give. Unpaired: ``num``'s units are
    reweighted to ``den``'s group mix, sum_g w_g mean(num_g) / sum_g w_g mean(den_g) with w_g the
    share of ``den``'s units in group g, over the groups both sides hold. The mix-adjusted ratio is
    withheld (NaN, with the reason) where any group has fewer than :data:`.stats.MIN_BOOTSTRAP_N`
    units on a side; the ratio of medians where the denominator's median is below
    :data:`MEDIAN_FLOOR`.
    """
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    med_n, med_d = (float(np.median(x)) if len(x) else np.nan for x in (num, den))
    total = float(num.sum())
    top = float(num.max() / total) if len(num) and total > 0 else float("nan")
    by_group, adjusted, how, note = {}, float("nan"), "", ""
    if groups_num is not None and len(num) and len(den):
        gn = np.asarray(groups_num, dtype=str)
        gd = gn if paired else np.asarray(groups_den, dtype=str)
        for g in _order([*gn, *gd]):
            a, b = num[gn == g], den[gd == g]
            by_group[g] = (_ratio(a.mean(), b.mean()) if len(a) and len(b) else float("nan"), len(a), len(b))
        adjusted, how, note = _adjusted(num, den, gn, gd, by_group, paired)
    medians = _ratio(med_n, med_d) if not abs(med_d) < MEDIAN_FLOOR else float("nan")
    return RatioExtras(by_group, adjusted, how, medians, med_n, med_d, top, note, paired)
