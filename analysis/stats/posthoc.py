"""Fisher's Least Significant Difference, paired and pooled forms (thesis Sec. 7.6.2)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats._numbers import _check_alpha, _is_rounding
from analysis.stats.anova import _anova
from analysis.stats.design import repeated_measures

PAIR_COLUMNS: tuple[str, ...] = (
    *("a", "b", "diff", "t", "df", "p"),
    *("ci_low", "ci_high", "significant"),
)


def _pair_row(a, b, diff, se, df, alpha, y) -> dict:
    t_crit = float(stats.t.ppf(1.0 - alpha / 2.0, df))
    if _is_rounding(se, y, squared=False):
        t = p = math.nan
    else:
        t = diff / se
        p = float(2.0 * stats.t.sf(abs(t), df))
    return {
        "a": a,
        "b": b,
        "diff": float(diff),
        "t": float(t),
        "df": int(df),
        "p": p,
        "ci_low": float(diff - t_crit * se),
        "ci_high": float(diff + t_crit * se),
        "significant": bool(p < alpha),
    }


def _lsd_paired(y: np.ndarray, levels: tuple[str, ...], alpha: float) -> pd.DataFrame:
    n, k = y.shape
    rows = []
    for i, j in itertools.combinations(range(k), 2):
        d = y[:, i] - y[:, j]
        se = float(np.std(d, ddof=1)) / math.sqrt(n)  # SE of the mean paired difference
        rows.append(_pair_row(levels[i], levels[j], d.mean(), se, n - 1, alpha, y))
    return pd.DataFrame(rows, columns=list(PAIR_COLUMNS))


def _lsd_pooled(y: np.ndarray, levels: tuple[str, ...], alpha: float) -> pd.DataFrame:
    n, k = y.shape
    anova = _anova(y)
    se = math.sqrt(2.0 * anova.ms_error / n)  # Fisher's LSD: SE = sqrt(2 MS_error / n)
    means = y.mean(axis=0)
    rows = [
        _pair_row(levels[i], levels[j], means[i] - means[j], se, anova.df_error, alpha, y)
        for i, j in itertools.combinations(range(k), 2)
    ]
    return pd.DataFrame(rows, columns=list(PAIR_COLUMNS))


def lsd_paired(
    df: pd.DataFrame, *, dv: str, within: str, subject: str, alpha: float = 0.05
) -> pd.DataFrame:
    """Fisher's LSD, paired form: a paired t-test per pair of levels, uncorrected.

    For levels a before b (level order), with d_i = y_ia - y_ib over the n complete subjects::

        diff = mean(d),  SE = sd(d) / sqrt(n),  t = diff / SE,  df = n - 1
        p = 2 P(T_df > |t|),  CI = diff -/+ t_{1 - alpha/2, df} SE

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.
    alpha : float
        Significance level; the CI level is 1 - alpha.

    Returns
    -------
    pandas.DataFrame
        One row per pair, columns ``a, b, diff, t, df, p, ci_low, ci_high, significant``;
        t and p NaN when SE = 0.

    Notes
    -----
    Equals SPSS's GLM Repeated Measures "Pairwise Comparisons" with "Compare main effects",
    adjustment LSD(none). In R: ``t.test(wide[[a]], wide[[b]], paired = TRUE)`` per pair, or
    ``pairwise.t.test(df$dv, df$within, paired = TRUE, p.adjust.method = "none")`` (p only).
    pingouin 0.7: ``pairwise_tests(..., within=..., subject=..., padjust="none")``.
    """
    _check_alpha(alpha)
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _lsd_paired(data.y, data.levels, alpha)


def lsd_pooled(
    df: pd.DataFrame, *, dv: str, within: str, subject: str, alpha: float = 0.05
) -> pd.DataFrame:
    """Fisher's LSD, classic form: the ANOVA's MS_error and error df for every pair.

    For levels a before b (level order)::

        diff = mean_a - mean_b,  SE = sqrt(2 MS_error / n),  t = diff / SE,
        df = df_error = (n - 1)(k - 1),  p = 2 P(T_df > |t|),  CI = diff -/+ t_{1-alpha/2,df} SE

    (Fisher 1935; Maxwell & Delaney 2004, ch. 11: valid under sphericity, since every pair
    then has the difference variance 2 MS_error.)

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.
    alpha : float
        Significance level; the CI level is 1 - alpha.

    Returns
    -------
    pandas.DataFrame
        One row per pair, columns ``a, b, diff, t, df, p, ci_low, ci_high, significant``;
        t and p NaN when MS_error = 0.

    Notes
    -----
    In R: ``agricolae::LSD.test(aov(dv ~ within + subject, df), "within", p.adj = "none")``
    (the additive two-way model has the same MS_error and df); SPSS offers it only for
    between-subject factors (Post Hoc > LSD), via UNIANOVA with subject as a random factor.
    """
    _check_alpha(alpha)
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _lsd_pooled(data.y, data.levels, alpha)


ADJUSTED_COLUMNS: tuple[str, ...] = (*PAIR_COLUMNS, "p_unc")


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's (1979) step-down adjusted p-values, in the input order (R: ``p.adjust(p, "holm")``).

    With the m finite p-values sorted ascending p_(1) <= ... <= p_(m)::

        p_holm_(i) = min(1, max_{j <= i} (m - j + 1) p_(j))

    NaN (an undefined test) stays NaN and does not count in m, as in R.
    """
    p = np.asarray(p, dtype=float)
    out = np.full(p.size, np.nan)
    finite = np.flatnonzero(np.isfinite(p))
    m = finite.size
    order = finite[np.argsort(p[finite], kind="stable")]
    out[order] = np.minimum(1.0, np.maximum.accumulate((m - np.arange(m)) * p[order]))
    return out


def bonferroni(p: np.ndarray) -> np.ndarray:
    """Bonferroni's adjusted p-values min(1, m p), m the number of finite p (R's ``p.adjust``)."""
    p = np.asarray(p, dtype=float)
    return np.minimum(1.0, np.isfinite(p).sum() * p)


def _adjusted(y: np.ndarray, levels: tuple[str, ...], alpha: float, method: str) -> pd.DataFrame:
    """Paired t-tests with Holm or Bonferroni p and Bonferroni (simultaneous) CIs."""
    n, k = y.shape
    m = k * (k - 1) // 2
    frame = _lsd_paired(y, levels, alpha / m)  # CI at 1 - alpha / m
    raw = frame["p"].to_numpy(dtype=float)
    adjusted = holm(raw) if method == "holm" else bonferroni(raw)
    frame = frame.assign(p_unc=raw, p=adjusted, significant=adjusted < alpha)
    return frame[list(ADJUSTED_COLUMNS)]


def paired_adjusted(
    df: pd.DataFrame,
    *,
    dv: str,
    within: str,
    subject: str,
    method: str,
    alpha: float = 0.05,
) -> pd.DataFrame:
    """Paired t-tests for every pair of levels with Holm or Bonferroni adjusted p-values.

    Same t, df and difference as :func:`lsd_paired`; ``p`` is adjusted over the m = k(k-1)/2
    pairs (``p_unc`` keeps the raw one); the CI is Bonferroni's simultaneous interval,
    ``diff -/+ t_{1 - alpha / (2 m), n - 1} SE``, for both methods (Holm has no matching
    interval; emmeans falls back to Bonferroni for ``confint(..., adjust = "holm")`` too).

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.
    method : {"holm", "bonferroni"}
    alpha : float
        Family-wise significance level.

    Returns
    -------
    pandas.DataFrame
        Columns ``a, b, diff, t, df, p, ci_low, ci_high, significant, p_unc``.

    Notes
    -----
    In R: ``pairwise.t.test(df$dv, df$within, paired = TRUE, p.adjust.method = method)``;
    pingouin 0.7: ``pairwise_tests(..., padjust="holm")``.
    """
    _check_alpha(alpha)
    if method not in ("holm", "bonferroni"):
        raise ValueError(f"method {method!r} is not allowed; choose holm or bonferroni")
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _adjusted(data.y, data.levels, alpha, method)
