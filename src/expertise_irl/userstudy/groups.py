"""``expertise-irl study --group-by COLUMN``: participants' β compared across the groups of a
manifest column.

Input: the rows of ``study.csv`` as dicts, one per participant, each with the manifest column
(the participant's value, a string) and ``beta_hat``, ``beta_geomean`` and ``beta_median`` (numbers
or the strings a CSV gives back). Rules:

- **Groups**: a participant's value with surrounding whitespace removed; an empty value (or a
  missing key) is a group of its own, named ``"(empty)"``. Groups are listed sorted by name.
- **Per group** (:func:`group_summaries`): ``n``, the participants with a usable ``beta_hat`` (a
  finite number > 0), and ``n_missing``, those without one (a participant whose inference failed,
  say; left out of every statistic). Of ``beta_hat``: the median and the interquartile range
  (``beta_hat_q25``, ``beta_hat_q75``, ``beta_hat_iqr`` = q75 − q25, by :func:`numpy.quantile`'s
  linear interpolation). Of ``beta_geomean``: the geometric mean over the participants
  (exp of the mean of log), and of ``beta_median``: the median over the participants; each over
  the participants for whom that value is usable (``None`` if none is).
- **Tests** (:func:`group_tests`) compare ``beta_hat``: with exactly two groups, one two-sided
  Mann–Whitney U test (:func:`scipy.stats.mannwhitneyu`): the exact distribution of U for small
  samples without ties; with ties, the exact permutation distribution of U (every split of the
  pooled β̂ into groups of these sizes, ties as they are) while there are at most
  :data:`EXACT_SPLITS` splits, since the normal approximation is far too small for small tied
  samples (3 against 3, all tied within a group: 0.047 where the exact p is 0.1); beyond that the
  normal approximation with tie correction (``method`` names which); with more than two, every pair,
  and the p-values Holm-adjusted over the pairs that were tested (``p_holm``; with two groups
  ``p_holm`` = ``p``). ``U`` is the statistic of the pair's first group (the number of (a, b) pairs
  with a's β̂ > b's, ties counting ½), and the effect size is the rank-biserial correlation ``r =
  2U/(n_a·n_b) − 1`` = P(a > b) − P(a < b), in [−1, 1]: positive when the first group's β̂ tend to
  be larger (less expert). A pair with a group of fewer than :data:`MIN_PER_GROUP` participants is
  not tested: its entry carries a ``note`` instead of numbers. One group (or none) gives no test.
- An unknown column raises :class:`~expertise_irl.errors.InputError` naming the available
  ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from itertools import combinations
from typing import Any

import numpy as np

from ..errors import InputError

EMPTY = "(empty)"
#: The U test needs at least this many participants in each group of a pair.
MIN_PER_GROUP = 2
#: With ties, the U test enumerates every split of the pooled values up to this many splits.
EXACT_SPLITS = 200_000


def _check_column(rows: Sequence[Mapping[str, Any]], column: str, columns: Sequence[str] | None) -> None:
    if columns is None:
        columns = sorted({k for r in rows for k in r})
    if column not in columns:
        raise InputError(f"--group-by {column}: no such manifest column "
                         f"(columns: {', '.join(columns) if columns else 'none'})")


def _number(x: Any) -> float | None:
    """A usable β (finite, > 0) from a number or a CSV string, else None."""
    if x is None:
        return None
    if isinstance(x, str):
        x = x.strip()
        if not x:
            return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) and v > 0 else None


def group_name(value: Any) -> str:
    """A participant's group: the value stripped, or ``"(empty)"`` when there is none."""
    s = "" if value is None else str(value).strip()
    return s or EMPTY


def _groups(rows, column) -> dict[str, list[Mapping[str, Any]]]:
    out: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        out.setdefault(group_name(r.get(column)), []).append(r)
    return dict(sorted(out.items()))


def _values(members, key: str) -> np.ndarray:
    vals = [_number(r.get(key)) for r in members]
    return np.array([v for v in vals if v is not None], dtype=np.float64)


def group_summaries(rows: Sequence[Mapping[str, Any]], column: str,
                    columns: Sequence[str] | None = None) -> list[dict]:
    """One dict per group (sorted by name): ``group``, ``n``, ``n_missing``, ``beta_hat_median``,
    ``beta_hat_q25``, ``beta_hat_q75``, ``beta_hat_iqr``, ``beta_geomean_geomean``,
    ``beta_median_median`` (rules in the module docstring).

    ``columns``: the manifest's columns (for the error on an unknown ``column``); default: every
    key of the rows.
    """
    _check_column(rows, column, columns)
    out = []
    for name, members in _groups(rows, column).items():
        b = _values(members, "beta_hat")
        geo = _values(members, "beta_geomean")
        med = _values(members, "beta_median")
        q25, q50, q75 = (float(x) for x in np.quantile(b, [0.25, 0.5, 0.75])) if b.size else (None,) * 3
        out.append({
            "group": name,
            "n": int(b.size),
            "n_missing": len(members) - int(b.size),
            "beta_hat_median": q50,
            "beta_hat_q25": q25,
            "beta_hat_q75": q75,
            "beta_hat_iqr": None if q25 is None else q75 - q25,
            "beta_geomean_geomean": float(np.exp(np.log(geo).mean())) if geo.size else None,
            "beta_median_median": float(np.median(med)) if med.size else None,
        })
    return out


def holm_adjusted(p: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment: sorted ascending, p_(i) · (m − i + 1) (i from 1), made
    non-decreasing by a running maximum and capped at 1; returned in the input's order."""
    p = np.asarray(p, dtype=np.float64)
    m = len(p)
    order = np.argsort(p, kind="stable")
    adj = np.minimum(1.0, np.maximum.accumulate(p[order] * (m - np.arange(m))))
    out = np.empty(m)
    out[order] = adj
    return out.tolist()


def u_test(xa: np.ndarray, xb: np.ndarray) -> tuple[float, float, str]:
    """``(U of xa, two-sided p, method)`` of the Mann–Whitney U test (rules in the module docstring)."""
    from scipy.stats import PermutationMethod, mannwhitneyu

    pooled = np.concatenate([xa, xb])
    ties = np.unique(pooled).size < pooled.size
    if not ties and min(xa.size, xb.size) <= 8:
        method, how = "exact", "exact"
    elif ties and math.comb(pooled.size, xa.size) <= EXACT_SPLITS:
        method, how = PermutationMethod(n_resamples=np.inf), "exact permutation (ties)"
    else:
        method, how = "asymptotic", "normal approximation"
    res = mannwhitneyu(xa, xb, alternative="two-sided", method=method)
    p = float(res.pvalue)
    return float(res.statistic), min(1.0, p) if math.isfinite(p) else 1.0, how


def group_tests(rows: Sequence[Mapping[str, Any]], column: str,
                columns: Sequence[str] | None = None) -> list[dict]:
    """Mann–Whitney U tests of ``beta_hat`` between the groups (every pair, in name order).

    Each entry: ``groups`` (a, b), ``n`` (n_a, n_b), and either ``U``, ``p``, ``p_holm``,
    ``effect`` (the rank-biserial r; > 0: a's β̂ larger), ``larger`` (the name of the group whose
    β̂ tend to be larger, None when r = 0) and ``note`` None, or, when a group has fewer than
    :data:`MIN_PER_GROUP` participants, those numbers None and ``note`` saying why.
    ``adjustment``: ``"none"`` (one pair) or ``"holm"``; ``method``: how p was computed
    (:func:`u_test`), None when not tested.
    """
    _check_column(rows, column, columns)
    beta = {name: _values(members, "beta_hat") for name, members in _groups(rows, column).items()}
    pairs = list(combinations(beta, 2))
    adjustment = "holm" if len(pairs) > 1 else "none"
    out: list[dict] = []
    for a, b in pairs:
        xa, xb = beta[a], beta[b]
        entry: dict[str, Any] = {"groups": (a, b), "n": (int(xa.size), int(xb.size)), "U": None, "p": None,
                                 "p_holm": None, "effect": None, "larger": None, "note": None,
                                 "adjustment": adjustment, "method": None}
        small = [g for g, x in ((a, xa), (b, xb)) if x.size < MIN_PER_GROUP]
        if small:
            sizes = ", ".join(f"{g} has {beta[g].size}" for g in small)
            entry["note"] = (f"{a} vs {b}: not tested; the Mann–Whitney U test needs at least "
                             f"{MIN_PER_GROUP} participants per group ({sizes})")
        else:
            u, p, how = u_test(xa, xb)
            r = 2.0 * u / (xa.size * xb.size) - 1.0
            entry.update(U=u, p=p, method=how, effect=r,
                         larger=a if r > 0 else b if r < 0 else None)
        out.append(entry)
    tested = [e for e in out if e["p"] is not None]
    for e, ph in zip(tested, holm_adjusted([e["p"] for e in tested]), strict=True):
        e["p_holm"] = ph
    return out


def _sig_or_dash(x: float | None) -> str:
    """``x`` to 3 significant figures; a dash for None (no usable β̂ in the group)."""
    return "–" if x is None else f"{x:.3g}"


def _test_words(e: dict) -> str:
    if e["note"] is not None:
        return e["note"]
    a, b = e["groups"]
    na, nb = e["n"]
    if e["larger"] is None:
        direction = f"{a} and {b}: neither group's β̂ tend to be larger"
    else:
        smaller = b if e["larger"] == a else a
        direction = f"{e['larger']}'s β̂ tend to be larger (less expert) than {smaller}'s"
    p = f"p = {e['p']:.3g}, {e['method']}"
    if e["adjustment"] == "holm":
        p += f", Holm-adjusted p = {e['p_holm']:.3g}"
    return (f"{direction} (two-sided Mann–Whitney U = {e['U']:.3g}, {p}; rank-biserial r = "
            f"{e['effect']:+.2f} for {a} against {b}; n = {na} and {nb})")


def group_markdown(rows: Sequence[Mapping[str, Any]], column: str,
                   columns: Sequence[str] | None = None) -> str:
    """The ``study.md`` section ``## β by <column>``: the summaries as a table, then the test(s)
    in words (direction, p, effect size)."""
    summ = group_summaries(rows, column, columns)
    tests = group_tests(rows, column, columns)
    lines = [f"## β by {column}", "",
             "| group | n | median β̂ | IQR of β̂ (q25–q75) | geometric mean of the participants' β geomean |",
             "|---|---|---|---|---|"]
    for s in summ:
        n = f"{s['n']}" + (f" (+{s['n_missing']} without β̂)" if s["n_missing"] else "")
        iqr = ("–" if s["beta_hat_q25"] is None
               else f"{_sig_or_dash(s['beta_hat_q25'])}–{_sig_or_dash(s['beta_hat_q75'])}")
        lines.append(f"| {s['group']} | {n} | {_sig_or_dash(s['beta_hat_median'])} | {iqr} | "
                     f"{_sig_or_dash(s['beta_geomean_geomean'])} |")
    lines.append("")
    if not tests:
        lines.append(f"Only one group of {column}: nothing to compare.")
    else:
        if len(tests) > 1:
            lines.append(f"Every pair of groups compared by a two-sided Mann–Whitney U test on β̂; "
                         f"p-values Holm-adjusted over the {sum(e['p'] is not None for e in tests)} "
                         "pairs tested. r > 0: the first group's β̂ tend to be larger.")
            lines.append("")
        lines.extend(f"- {_test_words(e)}." if len(tests) > 1 else f"{_test_words(e)}." for e in tests)
    return "\n".join(lines) + "\n"
