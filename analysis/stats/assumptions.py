"""Assumption checks of the repeated-measures ANOVA: normality of the paired differences
(Shapiro-Wilk) and outliers (externally studentised residuals beyond |3|). Issue 21; not in
the thesis (Sec. 7.6.2 checks sphericity only, see :mod:`analysis.stats.sphericity`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy import stats

from analysis.stats._numbers import _is_rounding
from analysis.stats.anova import _anova

OUTLIER_LIMIT = 3.0  # |studentised residual| beyond which an observation is flagged
NORMALITY_METHOD = "Shapiro-Wilk on each pair's paired differences"
OUTLIER_METHOD = (
    "externally studentised residuals of the additive model dv ~ subject + level, "
    f"|t| > {OUTLIER_LIMIT:g}"
)


def _shapiro(d: np.ndarray, y: np.ndarray) -> tuple[float | None, float | None]:
    """(W, p) of Shapiro-Wilk, or (None, None) below 3 values or for constant d."""
    if d.size < 3 or _is_rounding(float(np.ptp(d)), y, squared=False):
        return None, None
    result = stats.shapiro(d)
    return float(result.statistic), float(result.pvalue)


def normality(y: np.ndarray, levels: tuple[str, ...], *, alpha: float = 0.05) -> dict:
    """Shapiro-Wilk test of the paired differences of every pair of levels.

    The paired t-tests (LSD paired, Holm, Bonferroni) assume the differences y_a - y_b are
    normal; for k = 2 this is also the ANOVA's assumption.

    Parameters
    ----------
    y : np.ndarray
        (n, k) complete-case wide table [dv unit].
    levels : tuple of str
        (k,) labels.
    alpha : float
        p below which normality counts as violated.

    Returns
    -------
    dict
        ``method``; ``pairs``: [{a, b, W, p, violated}] (W and p None when n < 3 or the
        differences are constant; violated then False); ``violated`` (any pair).

    Notes
    -----
    In R: ``shapiro.test(wide[, a] - wide[, b])`` (Royston 1995, algorithm AS R94, which scipy
    implements too).
    """
    pairs = []
    for i, j in itertools.combinations(range(y.shape[1]), 2):
        w, p = _shapiro(y[:, i] - y[:, j], y)
        violated = p is not None and p < alpha
        pairs.append({"a": levels[i], "b": levels[j], "W": w, "p": p, "violated": violated})
    return {
        "method": NORMALITY_METHOD,
        "pairs": pairs,
        "violated": any(pair["violated"] for pair in pairs),
    }


def studentised_residuals(y: np.ndarray) -> np.ndarray | None:
    """(n, k) externally studentised residuals of the additive model subject + level.

    ::

        e_ij = y_ij - y_i. - y_.j + y..,  h = (n + k - 1) / (n k)  (every leverage)
        s_(ij)^2 = (SS_error - e_ij^2 / (1 - h)) / (df_error - 1)
        t_ij = e_ij / (s_(ij) sqrt(1 - h))

    None when SS_error is 0 or df_error < 2 (the deleted variance is undefined).
    In R: ``rstudent(lm(dv ~ subject + level, long))``.
    """
    n, k = y.shape
    anova = _anova(y)
    df_error = anova.df_error
    if anova.ss_error == 0.0 or df_error < 2:
        return None
    e = y - y.mean(axis=1)[:, None] - y.mean(axis=0)[None, :] + y.mean()
    h = (n + k - 1) / (n * k)
    deleted = (anova.ss_error - e**2 / (1.0 - h)) / (df_error - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = e / np.sqrt(np.maximum(deleted, 0.0) * (1.0 - h))
    return t


def outliers(
    y: np.ndarray, levels: tuple[str, ...], subjects: tuple[str, ...], *, limit: float = 3.0
) -> dict:
    """Observations whose externally studentised residual exceeds ``limit`` in size.

    Parameters
    ----------
    y : np.ndarray
        (n, k) complete-case wide table [dv unit].
    levels, subjects : tuple of str
        (k,) and (n,) labels.
    limit : float
        The flagging threshold (3).

    Returns
    -------
    dict
        ``method``, ``limit``, ``max_abs`` (the largest |t|, None when undefined), ``count``
        and ``items``: [{subject, level, value, t}] sorted by |t| descending.
    """
    t = studentised_residuals(y)
    out = {"method": OUTLIER_METHOD, "limit": limit, "max_abs": None, "count": 0, "items": []}
    if t is None:
        return out
    size = np.where(np.isfinite(t), np.abs(t), math.inf)
    out["max_abs"] = float(size.max())
    items = [
        {"subject": subjects[i], "level": levels[j], "value": float(y[i, j]), "t": float(t[i, j])}
        for i, j in zip(*np.nonzero(size > limit), strict=True)
    ]
    items.sort(key=lambda item: -abs(item["t"]))
    out.update(count=len(items), items=items)
    return out
