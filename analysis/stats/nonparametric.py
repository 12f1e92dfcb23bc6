"""The non-parametric path: Friedman's test with Kendall's W, Wilcoxon signed-rank pairs with
Holm's correction, and the rule that picks it (``test = "auto"``). Issue 21; not in the thesis.

Both tests are written as R's ``friedman.test`` and ``wilcox.test`` compute them (ties,
zeros, exact or normal p), so ``tests/r/oracle.R`` reproduces every number.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy import stats

from analysis.stats.posthoc import holm

TESTS: tuple[str, ...] = ("rm_anova", "friedman", "auto")
# "Many ties" for test = "auto": whole-number data whose distinct values are at most this
# share of the observations (half of them repeat a value seen before). Counts that are
# mostly zero and rating items (1..7 answered by 10+ people) qualify; times do not.
TIE_SHARE = 0.5
_EXACT_BELOW = 50  # R's wilcox.test: exact p for n < 50 without ties or zeros


def friedman(y: np.ndarray) -> dict:
    """Friedman's rank test of k related samples, with Kendall's W.

    With r_ij the rank of y_ij within subject i (mid-ranks for ties), R_j = sum_i r_ij and
    t the sizes of the tie groups within rows::

        chi2 = 12 sum_j (R_j - n (k + 1) / 2)^2 / (n k (k + 1) - sum (t^3 - t) / (k - 1))
        df = k - 1,  p = P(chi2_df > chi2)
        W = chi2 / (n (k - 1))                      (Kendall's W, tie-corrected)

    Parameters
    ----------
    y : np.ndarray
        (n, k) complete-case wide table.

    Returns
    -------
    dict
        ``chi2``, ``df``, ``p``, ``kendall_w``, ``n`` (None for chi2, p and W when every
        row is tied throughout).

    Notes
    -----
    In R: ``friedman.test(wide)``; W as ``rstatix::friedman_effsize`` (chi2 / (n (k - 1))).
    scipy: ``friedmanchisquare`` (k >= 3 only).
    """
    n, k = y.shape
    ranks = np.apply_along_axis(stats.rankdata, 1, y)
    ties = 0.0
    for row in ranks:
        _, counts = np.unique(row, return_counts=True)
        ties += float(np.sum(counts**3 - counts))
    denominator = n * k * (k + 1) - ties / (k - 1)
    out = {"chi2": None, "df": k - 1, "p": None, "kendall_w": None, "n": n}
    if denominator <= 0.0:
        return out
    chi2 = 12.0 * float(np.sum((ranks.sum(axis=0) - n * (k + 1) / 2.0) ** 2)) / denominator
    out.update(chi2=chi2, p=float(stats.chi2.sf(chi2, k - 1)), kendall_w=chi2 / (n * (k - 1)))
    return out


def _signrank_counts(n: int) -> np.ndarray:
    """(n (n + 1) / 2 + 1,) number of sign patterns of n untied ranks giving each V."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for i in range(1, n + 1):
        counts[i:] = counts[i:] + counts[:-i].copy()
    return counts


def wilcoxon(d: np.ndarray) -> dict:
    """Wilcoxon's signed-rank test of paired differences d against 0, two-sided, as R does.

    Zeros are dropped (Wilcoxon's method); V = sum of the ranks of |d| (mid-ranks) where
    d > 0. Exact p when fewer than 50 differences remain and none are tied or zero, else the
    normal approximation with the tie-corrected variance and a continuity correction::

        z = (V - m (m + 1) / 4 - sign * 0.5) / sqrt(m (m + 1)(2 m + 1) / 24 - sum(t^3 - t) / 48)

    Returns
    -------
    dict
        ``V``, ``n`` (nonzero differences), ``p``, ``method`` ("exact" or "normal"); V and p
        None when every difference is 0.

    Notes
    -----
    In R: ``wilcox.test(x, y, paired = TRUE)`` (``exact = NULL, correct = TRUE``).
    """
    zeros = bool(np.any(d == 0.0))
    d = d[d != 0.0]
    m = d.size
    if m == 0:
        return {"V": None, "n": 0, "p": None, "method": "normal"}
    ranks = stats.rankdata(np.abs(d))
    v = float(ranks[d > 0].sum())
    _, counts = np.unique(ranks, return_counts=True)
    tied = bool(np.any(counts > 1))
    if m < _EXACT_BELOW and not tied and not zeros:
        dist = _signrank_counts(m) / 2.0**m
        # R: psignrank(V - 1, m, lower.tail = FALSE) above the centre, psignrank(V, m) below
        p = dist[int(v) :].sum() if v > m * (m + 1) / 4.0 else dist[: int(v) + 1].sum()
        return {"V": v, "n": m, "p": min(2.0 * float(p), 1.0), "method": "exact"}
    z = v - m * (m + 1) / 4.0
    sigma = math.sqrt(m * (m + 1) * (2 * m + 1) / 24.0 - float(np.sum(counts**3 - counts)) / 48.0)
    z = (z - math.copysign(0.5, z) * (z != 0.0)) / sigma
    p = 2.0 * min(stats.norm.cdf(z), stats.norm.sf(z))
    return {"V": v, "n": m, "p": float(p), "method": "normal"}


def wilcoxon_holm(y: np.ndarray, levels: tuple[str, ...], *, alpha: float = 0.05) -> list[dict]:
    """Wilcoxon signed-rank tests of every pair of levels, Holm-adjusted over the pairs.

    Returns
    -------
    list of dict
        One per pair (a before b): ``a, b, V, n, method, p_unc, p`` (Holm), ``significant``
        (p < alpha), ``median_diff`` (median of y_a - y_b, in the dv's unit).

    Notes
    -----
    In R: ``wilcox.test(wide[, a], wide[, b], paired = TRUE)`` per pair, then
    ``p.adjust(p, "holm")``.
    """
    rows = []
    for i, j in itertools.combinations(range(y.shape[1]), 2):
        d = y[:, i] - y[:, j]
        test = wilcoxon(d)
        rows.append({"a": levels[i], "b": levels[j], "median_diff": float(np.median(d)), **test})
    raw = np.array([np.nan if r["p"] is None else r["p"] for r in rows])
    adjusted = holm(raw)
    for row, p in zip(rows, adjusted, strict=True):
        row["p_unc"] = row.pop("p")
        row["p"] = None if math.isnan(p) else float(p)
        row["significant"] = row["p"] is not None and row["p"] < alpha
    return rows


def choose_test(values: np.ndarray, *, requested: str = "auto") -> tuple[str, str]:
    """The planned omnibus test of a metric: ("rm_anova" | "friedman", why).

    ``requested`` "rm_anova" or "friedman" is taken as is. "auto" plans Friedman when every
    value is a whole number and the distinct values are at most :data:`TIE_SHARE` of the
    observations (counts with many ties, e.g. mostly zero collisions, and single rating
    items); else the RM-ANOVA.

    Parameters
    ----------
    values : np.ndarray
        The metric's observed values (any shape; NaN ignored).
    requested : {"rm_anova", "friedman", "auto"}
    """
    if requested not in TESTS:
        raise ValueError(f"test {requested!r} is not allowed; choose one of {', '.join(TESTS)}")
    if requested != "auto":
        return requested, "requested"
    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    whole = x.size > 0 and bool(np.all(x == np.round(x)))
    distinct = np.unique(x).size
    if whole and distinct <= TIE_SHARE * x.size:
        return "friedman", (
            f"auto: whole numbers with many ties ({distinct} distinct values in {x.size} "
            f"observations, at most {TIE_SHARE:g} of them): Friedman"
        )
    kind = "not all whole numbers" if not whole else f"{distinct} distinct values in {x.size}"
    return "rm_anova", f"auto: {kind}: RM-ANOVA"
