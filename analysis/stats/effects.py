"""Effect sizes with confidence intervals: partial eta squared (noncentral F) and, per pair of
levels, the mean difference and Cohen's d_z (noncentral t). Issue 21; not in the thesis.

Intervals come from inverting the noncentral F and t distributions (Steiger & Fouladi 1997;
Steiger 2004; Cumming & Finch 2001), as R's ``effectsize`` and ``MBESS`` packages compute
them; no bootstrap, so every figure is deterministic and reproducible in R
(``tests/r/oracle.R``).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy import optimize, stats

from analysis.stats._numbers import _is_rounding

# Root-finding tolerance on the noncentrality parameter: far below the 1e-6 the R oracle
# checks, far above double rounding.
_XTOL = 1e-12
ETA_CI_METHOD = "noncentral F (Steiger 2004), uncorrected dfs"
DZ_CI_METHOD = "noncentral t (Steiger & Fouladi 1997; Cumming & Finch 2001)"


def _bracket_root(f, start: float) -> float:
    """The root of a decreasing ``f`` on [0, inf) with f(0) > 0: doubles ``hi`` until f < 0."""
    hi = max(start, 1.0)
    while f(hi) > 0.0:
        hi *= 2.0
        if hi > 1e8:  # pragma: no cover - only for F or t beyond any real data
            return math.nan
    return float(optimize.brentq(f, 0.0, hi, xtol=_XTOL, rtol=4 * np.finfo(float).eps))


def ncp_interval_f(F: float, df1: float, df2: float, level: float) -> tuple[float, float]:
    """The two-sided ``level`` confidence interval of the noncentrality lambda of an F.

    lambda_low solves P(F'(df1, df2, lambda) <= F) = (1 + level) / 2, lambda_high solves it
    for (1 - level) / 2; a bound is 0 when even lambda = 0 leaves F too small.
    """
    upper_tail = (1.0 + level) / 2.0

    def bound(target: float) -> float:
        if stats.f.cdf(F, df1, df2) <= target:
            return 0.0

        def f(lam: float) -> float:
            cdf = stats.ncf.cdf(F, df1, df2, lam)
            return (cdf if math.isfinite(cdf) else 0.0) - target  # NaN only far in the tail

        return _bracket_root(f, F * df1)

    return bound(upper_tail), bound(1.0 - upper_tail)


def partial_eta_squared_ci(F: float | None, df1: float, df2: float, *, level: float) -> dict:
    """Partial eta squared from F with its noncentral-F interval.

    ::

        np2 = F df1 / (F df1 + df2)
        [lambda_low, lambda_high] = ncp_interval_f(F, df1, df2, level)
        np2 bound = lambda / (lambda + df1 + df2 + 1)

    Parameters
    ----------
    F : float or None
        The ANOVA's F (None: undefined, every field None).
    df1, df2 : float
        Its degrees of freedom (uncorrected).
    level : float
        Two-sided confidence level, e.g. 0.90 (Steiger 2004: 1 - 2 alpha matches the one-sided
        F test).

    Returns
    -------
    dict
        ``value``, ``ci_low``, ``ci_high``, ``ci_level``, ``method``.

    Notes
    -----
    In R: ``effectsize::F_to_eta2(F, df1, df2, ci = level, alternative = "two.sided")``
    (the same bound conversion), or by hand with ``uniroot`` on ``pf(F, df1, df2, ncp)``, as
    ``tests/r/oracle.R`` does.
    """
    out = {"value": None, "ci_low": None, "ci_high": None, "ci_level": level}
    out["method"] = ETA_CI_METHOD
    if F is None or not math.isfinite(F):
        return out
    low, high = ncp_interval_f(F, df1, df2, level)
    out["value"] = F * df1 / (F * df1 + df2)
    out["ci_low"] = low / (low + df1 + df2 + 1.0)
    out["ci_high"] = high / (high + df1 + df2 + 1.0)
    return out


def ncp_interval_t(t: float, df: float, level: float) -> tuple[float, float]:
    """The two-sided ``level`` interval of the noncentrality delta of a t with ``df``.

    delta_low solves P(T'(df, delta) <= t) = (1 + level) / 2, delta_high solves it for
    (1 - level) / 2 (P decreases in delta; the bounds are symmetric in the sign of t).
    """
    if t < 0.0:
        low, high = ncp_interval_t(-t, df, level)
        return -high, -low
    upper_tail = (1.0 + level) / 2.0

    def bound(target: float) -> float:
        def f(delta: float) -> float:
            cdf = stats.nct.cdf(t, df, delta)
            if not math.isfinite(cdf):  # far tails, where scipy's nct gives NaN: 0 or 1
                cdf = 0.0 if delta > t else 1.0
            return cdf - target

        step = 1.0
        while f(t - step) < 0.0:  # widen geometrically: stops near the root
            step *= 2.0
        lo, step = t - step, 1.0
        while f(t + step) > 0.0:
            step *= 2.0
        hi = t + step
        return float(optimize.brentq(f, lo, hi, xtol=_XTOL, rtol=4 * np.finfo(float).eps))

    return bound(upper_tail), bound(1.0 - upper_tail)


def _pair_effect(a: str, b: str, d: np.ndarray, y: np.ndarray, level: float) -> dict:
    n = d.size
    diff = float(d.mean())
    sd = float(np.std(d, ddof=1))
    t_crit = float(stats.t.ppf((1.0 + level) / 2.0, n - 1))
    se = sd / math.sqrt(n)
    row = {"a": a, "b": b, "n": n, "diff": diff, "sd_diff": sd}
    row.update(ci_low=diff - t_crit * se, ci_high=diff + t_crit * se)
    row.update(dz=None, dz_ci_low=None, dz_ci_high=None)
    if not _is_rounding(sd, y, squared=False):
        dz = diff / sd
        low, high = ncp_interval_t(dz * math.sqrt(n), n - 1, level)
        row.update(dz=dz, dz_ci_low=low / math.sqrt(n), dz_ci_high=high / math.sqrt(n))
    return row


def pair_effects(y: np.ndarray, levels: tuple[str, ...], *, level: float = 0.95) -> list[dict]:
    """Per pair of levels (a before b): the mean difference and Cohen's d_z, with CIs.

    With d_i = y_ia - y_ib over the n complete subjects::

        diff = mean(d),  CI = diff -/+ t_{(1 + level)/2, n-1} sd(d) / sqrt(n)
        d_z  = mean(d) / sd(d)                                       (Cohen 1988)
        CI(d_z) = [delta_low, delta_high] / sqrt(n),  delta from ncp_interval_t(d_z sqrt(n))

    Parameters
    ----------
    y : np.ndarray
        (n, k) complete-case wide table [dv unit].
    levels : tuple of str
        (k,) level labels.
    level : float
        Confidence level of both intervals (1 - alpha).

    Returns
    -------
    list of dict
        One per pair: ``a, b, n, diff, sd_diff, ci_low, ci_high`` [dv unit], ``dz,
        dz_ci_low, dz_ci_high`` (None when sd(d) is 0).

    Notes
    -----
    In R: ``t.test(x, y, paired = TRUE)$conf.int`` and
    ``MBESS::ci.sm(ncp = t, N = n, conf.level = level)`` (or ``uniroot`` on ``pt(t, n - 1,
    ncp)``, as ``tests/r/oracle.R`` does).
    """
    return [
        _pair_effect(levels[i], levels[j], y[:, i] - y[:, j], y, level)
        for i, j in itertools.combinations(range(y.shape[1]), 2)
    ]
