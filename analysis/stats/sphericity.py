"""Sphericity: Mauchly's test and the Greenhouse-Geisser correction (thesis Sec. 7.6.2)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats._numbers import _ZERO_ULPS, _check_alpha, _clean, _number
from analysis.stats.anova import _anova
from analysis.stats.design import repeated_measures


def _orthonormal_contrasts(k: int) -> np.ndarray:
    """(k, k - 1) normalised Helmert contrasts: orthonormal columns, each orthogonal to 1."""
    contrasts = np.zeros((k, k - 1))
    for j in range(1, k):
        contrasts[:j, j - 1] = 1.0
        contrasts[j, j - 1] = -float(j)
        contrasts[:, j - 1] /= math.sqrt(j * (j + 1))
    return contrasts


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
