"""One-way repeated-measures statistics: descriptives, ANOVA, sphericity, Greenhouse-Geisser
and Fisher's LSD, for one metric measured once per participant and level (thesis Sec. 7.6.2:
"the repeated measures ANOVA ... After a null hypothesis is rejected by ANOVA, Fisher's Least
Significant Difference (LSD) is applied for pairwise comparison ... the significant level is
0.05"; spec/algorithms.md, "Analysis").

Every public function takes a long-format DataFrame (one row per subject and level) and the
names of its three columns; :func:`analyse` runs the whole chain and returns the JSON object of
``asa stats --json`` (one per metric in the report). The arithmetic is numpy/scipy written out
from the formulas, so each number can be read against its reference; the tests compare it with
statsmodels' ``AnovaRM``, pingouin 0.7 and independent re-implementations.

Decisions where the spec is silent
----------------------------------
- **Complete cases.** Subjects lacking any level are removed (listwise deletion, as SPSS GLM
  and R's ``mlm`` do) and named in a warning; a cell whose value is NaN counts as missing.
  Descriptives are computed on the same complete cases as the test, so the table and the
  F agree (SPSS prints its GLM descriptives the same way).
- **Duplicate (subject, level) rows are averaged**, with a warning saying how many cells and
  giving an example, as afex's ``aov_ez`` does ("More than one observation per cell,
  aggregating the data using mean"). A per-trial or per-question export (several secondary
  questions per trial) is the usual cause, and its cell mean is what the analyst wants;
  NaN rows inside a cell are skipped, the cell is missing only when all its rows are.
- **Labels are strings.** Levels and subjects are compared and reported as ``str(value)``, in
  order of first appearance; two values with the same string (``1`` and ``"1"``) are an error.
- **Zero error variance.** When every subject's scores differ by the same constants
  (SS_error = 0 up to rounding, judged against the data's magnitude), F = MS_effect / 0 is
  infinite or 0/0: F, p and the corrected p are ``None`` (JSON null), the gate fails and a
  warning says why; partial eta squared is 1 when SS_effect > 0. Mauchly's test is then
  undefined (W, chi2, p ``None``, ``violated`` False). Likewise an LSD pair whose standard
  error is 0 has t and p ``None`` and is not significant. Nothing returned is NaN or infinite.
- **Singular contrast covariance** (fewer subjects than levels, or exactly collinear
  differences) with SS_error > 0: W = 0 and p = 0 as R's ``mauchly.test`` gives in the limit,
  chi2 ``None`` (infinite); sphericity counts as violated, so the auto gate uses the
  Greenhouse-Geisser p.
- **Two levels.** Sphericity holds trivially: W = 1, chi2 = 0 on 0 df, p = 1, not violated;
  epsilon = 1. (R's formula has 0 df there; pingouin 0.7 returns W and chi2 NaN, 1 df, p 1.)
- **Gate.** ``"auto"`` uses the Greenhouse-Geisser p when Mauchly's p < ``sphericity_alpha``
  (0.05, independent of the test's ``alpha``), otherwise the uncorrected p; ``"uncorrected"``
  and ``"greenhouse_geisser"`` force one of them (afex's default is always GG). Post-hoc tests
  run only when the gated p < alpha.
- **LSD confidence level** is 1 - alpha (95 % at alpha = .05), as SPSS ties the two.
- **Mauchly versus pingouin.** pingouin 0.7's ``sphericity`` uses R's chi-square, correction
  factor rho and second-order term (``w2`` with the number of levels k, as R has it), and
  agrees with this module to rounding (checked in the tests for k = 3..5). The installed 0.7.0
  takes log W from ``slogdet``; releases that dropped eigenvalues below a fixed 0.001 gave
  wrong W for small-variance data (pingouin issue #478). It differs only in degenerate cases:
  two levels (above), and a singular covariance, where it returns W = 0 with chi2 = inf (and
  divides by zero with n = 2 subjects) rather than W = 0 with chi2 None. SPSS prints the same
  p as R (Field's Bushtucker data: W = .136, chi2(5) = 11.41, p = .047, reproduced in the
  tests; the first-order chi-square alone would give p = .044).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

__all__ = [
    "GATES",
    "RepeatedMeasures",
    "analyse",
    "descriptives",
    "gate_p",
    "gate_source",
    "greenhouse_geisser",
    "lsd_paired",
    "lsd_pooled",
    "mauchly",
    "repeated_measures",
    "rm_anova",
]

GATES: tuple[str, ...] = ("auto", "uncorrected", "greenhouse_geisser")
PAIR_COLUMNS: tuple[str, ...] = (
    *("a", "b", "diff", "t", "df", "p"),
    *("ci_low", "ci_high", "significant"),
)

# A sum of squares or an SD below this many ulps of the data's magnitude is rounding, not data.
_ZERO_ULPS = 64.0


@dataclass(frozen=True, slots=True)
class RepeatedMeasures:
    """The complete-case wide table of a one-way within-subject design.

    Attributes
    ----------
    y : np.ndarray
        (n, k) dependent variable, one row per complete subject, one column per level, in the
        dv's own unit.
    levels : tuple of str
        (k,) level labels in order of first appearance.
    subjects : tuple of str
        (n,) complete subjects in order of first appearance.
    dropped_subjects : tuple of str
        Subjects removed because they lack a value for some level.
    warnings : tuple of str
        Human-readable notes on what was dropped or averaged.
    """

    y: np.ndarray  # (n, k) [dv unit]
    levels: tuple[str, ...]
    subjects: tuple[str, ...]
    dropped_subjects: tuple[str, ...]
    warnings: tuple[str, ...]


# --------------------------------------------------------------------------------------------
# Long frame -> complete wide table
# --------------------------------------------------------------------------------------------


def _labels(column: pd.Series, name: str) -> pd.Series:
    """Labels of an id column as strings; empty cells and string collisions are errors."""
    missing = column.isna()
    if missing.any():
        row = column.index[np.flatnonzero(missing.to_numpy())[0]]
        raise ValueError(f"column {name!r}: row {row} is empty; every row needs a {name}")
    as_text = column.map(str)
    originals = pd.DataFrame({"text": as_text, "value": column.map(repr)}).drop_duplicates()
    clash = originals["text"].duplicated(keep=False)
    if clash.any():
        values = ", ".join(originals.loc[clash, "value"].head(4))
        raise ValueError(
            f"column {name!r}: values {values} read as the same label; make the labels distinct"
        )
    return as_text


def _numeric_dv(column: pd.Series, name: str) -> np.ndarray:
    """The dv as float64; NaN means a missing cell, anything else non-numeric is an error."""
    if pd.api.types.is_bool_dtype(column):
        values = column.astype(float)
    else:
        values = pd.to_numeric(column, errors="coerce")
    bad = values.isna() & column.notna()
    if bad.any():
        row = column.index[np.flatnonzero(bad.to_numpy())[0]]
        raise ValueError(
            f"column {name!r}: row {row}: {column.loc[row]!r} is not a number "
            f"(the dependent variable must be numeric; leave a cell empty if it is missing)"
        )
    out = values.to_numpy(dtype=float)
    infinite = np.isinf(out)
    if infinite.any():
        row = column.index[np.flatnonzero(infinite)[0]]
        raise ValueError(f"column {name!r}: row {row}: {column.loc[row]!r} is not finite")
    return out


def _quoted(labels: list[str] | tuple[str, ...]) -> str:
    return ", ".join(repr(label) for label in labels)


def repeated_measures(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> RepeatedMeasures:
    """Validate a long-format frame and reshape it to the complete-case wide table.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format: one row per subject and level (several rows per cell are averaged).
    dv, within, subject : str
        Columns holding the dependent variable (numeric; NaN = missing), the within-subject
        factor and the subject id.

    Returns
    -------
    RepeatedMeasures
        The (n, k) table of complete subjects, the labels, who was dropped and why.

    Raises
    ------
    ValueError
        A column is missing (the message lists the available ones), the dv is not numeric
        (naming the first offending row and value), an id cell is empty, there are fewer than
        two levels, or fewer than two subjects have every level.

    Notes
    -----
    In R: ``aggregate(dv ~ subject + within, df, mean)`` then ``reshape(..., direction =
    "wide")`` and ``na.omit``; in SPSS the data are entered wide, one column per level, and
    GLM drops incomplete cases.
    """
    if not isinstance(df, pd.DataFrame):
        raise TypeError(f"expected a pandas DataFrame, got {type(df).__name__}")
    names = {"dv": dv, "within": within, "subject": subject}
    available = ", ".join(repr(str(c)) for c in df.columns) or "none"
    for role, column in names.items():
        if column not in df.columns:
            raise ValueError(
                f"column {column!r} ({role}) not found; available columns: {available}"
            )
    if len(set(names.values())) < 3:
        raise ValueError(
            f"dv, within and subject must be three different columns, got {dv!r}, {within!r}, "
            f"{subject!r}"
        )

    long = pd.DataFrame(
        {
            "subject": _labels(df[subject], subject),
            "level": _labels(df[within], within),
            "y": _numeric_dv(df[dv], dv),
        }
    )
    levels = tuple(pd.unique(long["level"]))
    if len(levels) < 2:
        found = _quoted(levels) if levels else "none"
        raise ValueError(
            f"column {within!r}: only {len(levels)} level ({found}); a repeated-measures "
            f"ANOVA needs at least two"
        )
    subjects_all = tuple(pd.unique(long["subject"]))

    notes: list[str] = []
    rows_per_cell = long.groupby(["subject", "level"], sort=False).size()
    repeated = rows_per_cell[rows_per_cell > 1]
    if len(repeated):
        (who, where), count = next(iter(repeated.items())), int(repeated.iloc[0])
        notes.append(
            f"{len(repeated)} (subject, level) cell(s) had more than one row; each was "
            f"replaced by the mean of its rows (e.g. subject {who!r}, level {where!r}: "
            f"{count} rows)"
        )
    cell_means = long.groupby(["subject", "level"], sort=False)["y"].mean()
    wide = cell_means.unstack("level").reindex(index=list(subjects_all), columns=list(levels))

    incomplete = wide.isna().any(axis=1)
    dropped = tuple(str(s) for s in wide.index[incomplete.to_numpy()])
    if dropped:
        details = []
        for who in dropped:
            lacking = [str(level) for level in levels if pd.isna(wide.loc[who, level])]
            details.append(f"{who!r} (no {_quoted(lacking)})")
        notes.append(
            f"listwise deletion: dropped {len(dropped)} subject(s) lacking a value for some "
            f"level: {'; '.join(details)}"
        )
    complete = wide.loc[~incomplete.to_numpy()]
    if len(complete) < 2:
        raise ValueError(
            f"only {len(complete)} subject(s) in column {subject!r} have a {dv!r} value for "
            f"every level of {within!r} ({_quoted(levels)}); need at least two"
            + (f" (dropped: {_quoted(dropped)})" if dropped else "")
        )
    y = complete.to_numpy(dtype=float)
    y.setflags(write=False)
    return RepeatedMeasures(
        y=y,
        levels=tuple(str(level) for level in levels),
        subjects=tuple(str(s) for s in complete.index),
        dropped_subjects=dropped,
        warnings=tuple(notes),
    )


# --------------------------------------------------------------------------------------------
# Cores on the (n, k) table
# --------------------------------------------------------------------------------------------


def _is_rounding(value: float, y: np.ndarray, *, squared: bool) -> bool:
    """Whether ``value`` (an SD, or a sum of squares over y's cells) is rounding noise."""
    scale = _ZERO_ULPS * np.finfo(float).eps * float(np.max(np.abs(y)))
    if squared:
        return value <= y.size * scale**2
    return value <= scale


def _number(value: float) -> float | None:
    """A plain float, or None for NaN and infinities (JSON has neither)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _orthonormal_contrasts(k: int) -> np.ndarray:
    """(k, k - 1) normalised Helmert contrasts: orthonormal columns, each orthogonal to 1."""
    contrasts = np.zeros((k, k - 1))
    for j in range(1, k):
        contrasts[:j, j - 1] = 1.0
        contrasts[j, j - 1] = -float(j)
        contrasts[:, j - 1] /= math.sqrt(j * (j + 1))
    return contrasts


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


def _mauchly(y: np.ndarray, *, alpha: float) -> dict:
    n, k = y.shape
    d = k - 1
    if d == 1:
        return {"W": 1.0, "chi2": 0.0, "dof": 0, "p": 1.0, "violated": False}
    dof = d * (d + 1) // 2 - 1
    if _anova(y).ss_error == 0.0:
        return {"W": None, "chi2": None, "dof": dof, "p": None, "violated": False}
    contrasts = _orthonormal_contrasts(k)
    cov = contrasts.T @ np.cov(y, rowvar=False, ddof=1) @ contrasts  # (d, d)
    eig = np.linalg.eigvalsh(cov)
    if eig.min() <= eig.max() * d * np.finfo(float).eps * _ZERO_ULPS:
        return {"W": 0.0, "chi2": None, "dof": dof, "p": 0.0, "violated": True}
    # W = det(S_c) / (tr(S_c) / d)^d  (Mauchly 1940), in logs for accuracy.
    log_w = float(np.sum(np.log(eig)) - d * math.log(eig.sum() / d))
    nu = n - 1  # residual df of the covariance matrix
    rho = 1.0 - (2 * d**2 + d + 2) / (6 * d * nu)  # Anderson (2003) Sec. 10.7; R's rho
    chi2 = -nu * rho * log_w
    # Second-order term as R's code has it: 3 * k with k the number of levels (not d).
    w2_numerator = (d + 2) * (d - 1) * (d - 2) * (2 * d**3 + 6 * d**2 + 3 * k + 2)
    w2 = w2_numerator / (288 * (nu * d * rho) ** 2)
    p1 = stats.chi2.sf(chi2, dof)
    p2 = stats.chi2.sf(chi2, dof + 4)
    p = float(np.clip(p1 + w2 * (p2 - p1), 0.0, 1.0))
    return {"W": math.exp(log_w), "chi2": chi2, "dof": dof, "p": p, "violated": p < alpha}


def _gg_epsilon(y: np.ndarray) -> float:
    """Box's epsilon; NaN when the double-centred covariance is 0."""
    k = y.shape[1]
    if k == 2:
        return 1.0
    centring = np.eye(k) - np.full((k, k), 1.0 / k)
    cov = centring @ np.cov(y, rowvar=False, ddof=1) @ centring  # double-centred (k, k)
    trace = float(np.trace(cov))
    if _anova(y).ss_error == 0.0 or trace <= 0.0:
        return math.nan
    # eps = tr(S_dc)^2 / ((k - 1) tr(S_dc^2))   (Box 1954; Greenhouse & Geisser 1959)
    eps = trace**2 / ((k - 1) * float(np.sum(cov * cov)))
    return float(np.clip(eps, 1.0 / (k - 1), 1.0))


def _gg(y: np.ndarray) -> tuple[float, float]:
    anova = _anova(y)
    eps = _gg_epsilon(y)
    if math.isnan(eps) or math.isnan(anova.F):
        return eps, math.nan
    p = float(stats.f.sf(anova.F, eps * anova.df_effect, eps * anova.df_error))
    return eps, p


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


def _check_alpha(alpha: float, name: str = "alpha") -> None:
    if not (isinstance(alpha, int | float) and 0.0 < float(alpha) < 1.0):
        raise ValueError(f"{name} must be a number strictly between 0 and 1, got {alpha!r}")


# --------------------------------------------------------------------------------------------
# Public functions on long frames
# --------------------------------------------------------------------------------------------


def descriptives(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> pd.DataFrame:
    """Mean, SD, SE and n of the dv per level, on the complete cases.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.

    Returns
    -------
    pandas.DataFrame
        Indexed by level (first-appearance order, index name ``within``), columns ``mean``,
        ``sd`` (ddof = 1), ``se`` = sd / sqrt(n), ``n`` (complete subjects), in the dv's unit.

    Notes
    -----
    In R: ``aggregate(dv ~ within, wide_complete, function(x) c(mean(x), sd(x),
    sd(x) / sqrt(length(x))))``; in SPSS: GLM Repeated Measures, Options > Descriptive
    statistics (SPSS prints SD, not SE).
    """
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _descriptives(data, within)


def _descriptives(data: RepeatedMeasures, within: str) -> pd.DataFrame:
    n = data.y.shape[0]
    sd = data.y.std(axis=0, ddof=1)
    frame = pd.DataFrame(
        {"mean": data.y.mean(axis=0), "sd": sd, "se": sd / math.sqrt(n), "n": n},
        index=pd.Index(list(data.levels), name=within),
    )
    return frame


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


def mauchly(df: pd.DataFrame, *, dv: str, within: str, subject: str, alpha: float = 0.05) -> dict:
    """Mauchly's test of sphericity, as R's ``mauchly.test`` computes it.

    With S_c the (d, d) sample covariance (ddof = 1) of the k levels projected on d = k - 1
    orthonormal contrasts, nu = n - 1 and p = k::

        W    = det(S_c) / (tr(S_c) / d)^d                                 (Mauchly 1940)
        rho  = 1 - (2 d^2 + d + 2) / (6 d nu)
        chi2 = -nu * rho * log(W),   dof = d (d + 1) / 2 - 1
        w2   = (d+2)(d-1)(d-2)(2 d^3 + 6 d^2 + 3 p + 2) / (288 (nu d rho)^2)
        p    = P1 + w2 (P2 - P1),   P1 = P(chi2_dof > chi2),  P2 = P(chi2_{dof+4} > chi2)

    (Anderson 2003, Sec. 10.7; the second-order term w2 is written as R's code has it, with the
    number of levels p = k.)
    W does not depend on which orthonormal contrasts are used.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.
    alpha : float
        Level below which sphericity counts as violated.

    Returns
    -------
    dict
        ``W``, ``chi2``, ``dof`` (int), ``p``, ``violated`` (p < alpha). Two levels: W = 1,
        chi2 = 0, dof = 0, p = 1, not violated. SS_error = 0: W, chi2, p None, not violated.
        Singular S_c (n <= d or collinear differences): W = 0, chi2 None, p = 0, violated.

    Notes
    -----
    In R: ``fit <- lm(as.matrix(wide) ~ 1); mauchly.test(fit, X = ~1)`` (``idata`` defaults to
    the levels); ``chi2`` is R's internal statistic ``z``, which R does not print. In SPSS:
    GLM Repeated Measures, "Mauchly's Test of Sphericity" (same W, chi-square and p).
    pingouin 0.7: ``pingouin.sphericity(df, dv, within, subject)`` (same numbers for k >= 3).
    """
    _check_alpha(alpha)
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _clean(_mauchly(data.y, alpha=alpha))


def greenhouse_geisser(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> dict:
    """Greenhouse-Geisser epsilon and the corrected p of the repeated-measures F.

    With S the (k, k) covariance matrix of the levels (ddof = 1), H = I - J / k and the
    double-centred S_dc = H S H::

        eps = tr(S_dc)^2 / ((k - 1) * tr(S_dc^2))         (Box 1954), 1/(k-1) <= eps <= 1
        p   = P(F(eps (k - 1), eps (n - 1)(k - 1)) > F)  (Greenhouse & Geisser 1959)

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.

    Returns
    -------
    dict
        ``eps`` and ``p`` (None when SS_error is 0). Two levels: eps = 1, p = p_unc.

    Notes
    -----
    In R: ``afex::aov_ez(subject, dv, df, within = within)`` (GG by default) or
    ``car::Anova(fit, idata = idata, idesign = ~within, type = 3)`` then ``summary(...)``
    "GG eps" and "Pr(>F[GG])"; in SPSS: "Greenhouse-Geisser" row of "Tests of
    Within-Subjects Effects". pingouin 0.7: ``pingouin.epsilon(df, dv, within, subject)``.
    """
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    eps, p = _gg(data.y)
    return {"eps": _number(eps), "p": _number(p)}


def gate_p(
    anova: dict,
    sphericity: dict,
    gg: dict,
    *,
    gate: str = "auto",
) -> float | None:
    """The p that decides whether the effect is significant and post-hoc tests run.

    Parameters
    ----------
    anova, sphericity, gg : dict
        Outputs of :func:`rm_anova`, :func:`mauchly` and :func:`greenhouse_geisser`.
    gate : {"auto", "uncorrected", "greenhouse_geisser"}
        ``"auto"``: the Greenhouse-Geisser p when ``sphericity["violated"]`` (Mauchly's
        p < its alpha, 0.05 by default), else the uncorrected p. The other two force one.

    Returns
    -------
    float or None
        None when the chosen p is undefined (SS_error = 0).

    Notes
    -----
    SPSS prints both rows and leaves the choice to the analyst; this is the common rule
    (e.g. Field 2009, ch. 13). afex always corrects (``correction = "GG"``).
    """
    source = gate_source(sphericity, gate=gate)
    return gg["p"] if source == "greenhouse_geisser" else anova["p_unc"]


def gate_source(sphericity: dict, *, gate: str = "auto") -> str:
    """Which p :func:`gate_p` takes: ``"greenhouse_geisser"`` or ``"uncorrected"``."""
    if gate not in GATES:
        raise ValueError(f"gate {gate!r} is not allowed; choose one of {', '.join(GATES)}")
    if gate == "greenhouse_geisser" or (gate == "auto" and sphericity["violated"]):
        return "greenhouse_geisser"
    return "uncorrected"


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


# --------------------------------------------------------------------------------------------
# The whole chain
# --------------------------------------------------------------------------------------------


def _clean(value):
    """Recursively turn numpy scalars into Python ones and NaN/inf into None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return _number(value)
    return value


def _pairs(frame: pd.DataFrame) -> list[dict]:
    return _clean(frame.to_dict(orient="records"))


def analyse(
    df: pd.DataFrame,
    *,
    dv: str,
    within: str,
    subject: str,
    alpha: float = 0.05,
    gate: str = "auto",
    sphericity_alpha: float = 0.05,
) -> dict:
    """Descriptives, repeated-measures ANOVA, sphericity, GG, gate and LSD for one metric.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.
    alpha : float
        Significance level of the gated ANOVA and of the LSD pairs; CI level 1 - alpha.
    gate : {"auto", "uncorrected", "greenhouse_geisser"}
        Which p decides significance, see :func:`gate_p`.
    sphericity_alpha : float
        Mauchly's p below which sphericity counts as violated (the auto gate).

    Returns
    -------
    dict
        JSON-safe (plain Python numbers, None instead of NaN), keys ``n_subjects``,
        ``levels``, ``descriptives`` {level: {mean, sd, se, n}}, ``anova`` (see
        :func:`rm_anova`), ``sphericity`` (see :func:`mauchly`), ``greenhouse_geisser``
        {eps, p}, ``p_gate``, ``p_gate_source`` ("uncorrected" or "greenhouse_geisser":
        which p the gate used), ``significant``, ``posthoc`` {ran, lsd_paired, lsd_pooled}
        (pair lists empty unless ``significant``), ``warnings`` (list of str) and
        ``dropped_subjects`` (list of str).

    Notes
    -----
    In R, the same chain: ``afex::aov_ez`` (ANOVA, GG), ``mauchly.test`` and per-pair
    ``t.test(paired = TRUE)``; ``tests/r/rm_stats.R`` writes this object from base R.
    In SPSS: GLM Repeated Measures with Descriptive statistics and Compare main effects (LSD).
    """
    _check_alpha(alpha)
    _check_alpha(sphericity_alpha, "sphericity_alpha")
    if gate not in GATES:
        raise ValueError(f"gate {gate!r} is not allowed; choose one of {', '.join(GATES)}")
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    y = data.y
    notes = list(data.warnings)

    anova = _anova(y)
    sphericity = _mauchly(y, alpha=sphericity_alpha)
    eps, p_gg = _gg(y)
    anova_out = _anova_dict(anova)
    gg_out = {"eps": _number(eps), "p": _number(p_gg)}
    if anova.ss_error == 0.0:
        notes.append(
            "SS_error is 0 (every subject's scores differ by the same constants between "
            "levels): F, its p and the sphericity test are undefined; no significance test"
        )
    elif sphericity["W"] == 0.0:
        notes.append(
            f"the covariance of the level differences is singular ({y.shape[0]} subjects, "
            f"{y.shape[1]} levels): Mauchly's W = 0 and sphericity counts as violated"
        )
    p = gate_p(anova_out, sphericity, gg_out, gate=gate)
    significant = p is not None and p < alpha
    if significant:
        paired = _pairs(_lsd_paired(y, data.levels, alpha))
        pooled = _pairs(_lsd_pooled(y, data.levels, alpha))
        if any(pair["t"] is None for pair in paired):
            notes.append("some paired differences have SD 0: their t and p are undefined")
    else:
        paired, pooled = [], []

    table = _descriptives(data, within)
    described = {
        level: {
            "mean": float(row["mean"]),
            "sd": float(row["sd"]),
            "se": float(row["se"]),
            "n": int(row["n"]),
        }
        for level, row in table.iterrows()
    }
    return _clean(
        {
            "n_subjects": int(y.shape[0]),
            "levels": list(data.levels),
            "descriptives": described,
            "anova": anova_out,
            "sphericity": sphericity,
            "greenhouse_geisser": gg_out,
            "p_gate": p,
            "p_gate_source": gate_source(sphericity, gate=gate),
            "significant": bool(significant),
            "posthoc": {"ran": bool(significant), "lsd_paired": paired, "lsd_pooled": pooled},
            "warnings": notes,
            "dropped_subjects": list(data.dropped_subjects),
        }
    )
