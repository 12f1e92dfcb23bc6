"""One-way repeated-measures ANOVA: sums of squares, F, p and effect sizes (thesis Sec. 7.6.2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats._numbers import _is_rounding, _number
from analysis.stats.design import repeated_measures


@dataclass(frozen=True, slots=True)
class _Anova:
    F: float  # NaN when SS_error is 0
    df_effect: int
    df_error: int
    p_unc: float
    ss_effect: float
    ss_subjects: float
    ss_error: float
    ms_error: float
    np2: float
    ng2: float


def _anova(y: np.ndarray) -> _Anova:
    n, k = y.shape
    grand = y.mean()
    subject_means = y.mean(axis=1)
    level_means = y.mean(axis=0)
    ss_total = float(np.sum((y - grand) ** 2))
    ss_effect = float(n * np.sum((level_means - grand) ** 2))
    ss_subjects = float(k * np.sum((subject_means - grand) ** 2))
    residual = y - subject_means[:, None] - level_means[None, :] + grand
    ss_error = float(np.sum(residual**2))  # subject x level interaction = the error term
    if _is_rounding(ss_error, y, squared=True):
        ss_error = 0.0
    df_effect, df_error = k - 1, (n - 1) * (k - 1)
    ms_error = ss_error / df_error
    if ss_error > 0.0:
        F = (ss_effect / df_effect) / ms_error
        p_unc = float(stats.f.sf(F, df_effect, df_error))
    else:
        F = p_unc = math.nan
    np2 = ss_effect / (ss_effect + ss_error) if ss_effect + ss_error > 0.0 else math.nan
    ng2 = ss_effect / ss_total if ss_total > 0.0 else math.nan
    return _Anova(
        F=float(F),
        df_effect=df_effect,
        df_error=df_error,
        p_unc=p_unc,
        ss_effect=ss_effect,
        ss_subjects=ss_subjects,
        ss_error=ss_error,
        ms_error=ms_error,
        np2=float(np2),
        ng2=float(ng2),
    )


def rm_anova(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> dict:
    """One-way repeated-measures ANOVA (univariate approach, sphericity assumed).

    With y_ij the score of subject i = 1..n at level j = 1..k, row means y_i., column means
    y_.j and grand mean y..::

        SS_effect   = n * sum_j (y_.j - y..)^2                      df_effect = k - 1
        SS_subjects = k * sum_i (y_i. - y..)^2
        SS_error    = sum_ij (y_ij - y_i. - y_.j + y..)^2           df_error = (n-1)(k-1)
        F = (SS_effect / df_effect) / MS_error,   MS_error = SS_error / df_error
        p_unc = P(F(df_effect, df_error) > F)
        np2 = SS_effect / (SS_effect + SS_error)                    partial eta squared
        ng2 = SS_effect / (SS_effect + SS_subjects + SS_error)      generalised eta squared

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.

    Returns
    -------
    dict
        ``F``, ``df_effect``, ``df_error`` (int), ``p_unc``, ``ss_effect``, ``ss_error``,
        ``ms_error`` (in the dv's unit squared), ``np2``, ``ng2``. ``F`` and ``p_unc`` are
        None when SS_error is 0; ``np2``/``ng2`` None when their denominators are 0.

    Notes
    -----
    The error term is the subject x level interaction (Maxwell & Delaney 2004, ch. 11).
    The generalised eta squared is Olejnik & Algina (2003), Table 2, for a design with one
    manipulated within factor and no measured factors; pingouin's ``rm_anova`` reports it as
    ``ng2``. In R: ``summary(aov(dv ~ within + Error(subject / within), df))``, or
    ``afex::aov_ez(subject, dv, df, within = within, anova_table = list(correction = "none",
    es = c("pes", "ges")))``; in SPSS: GLM Repeated Measures, "Sphericity Assumed" rows.
    """
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _anova_dict(_anova(data.y))


def _anova_dict(anova: _Anova) -> dict:
    return {
        "F": _number(anova.F),
        "df_effect": anova.df_effect,
        "df_error": anova.df_error,
        "p_unc": _number(anova.p_unc),
        "ss_effect": anova.ss_effect,
        "ss_error": anova.ss_error,
        "ms_error": anova.ms_error,
        "np2": _number(anova.np2),
        "ng2": _number(anova.ng2),
    }
