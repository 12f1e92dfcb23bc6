"""The planned analysis of one metric: descriptives, ANOVA, sphericity, gate and LSD.

Thesis Sec. 7.6.2: Fisher's LSD only after the ANOVA rejects the null at alpha.
"""

from __future__ import annotations

import pandas as pd

from analysis.stats._numbers import _check_alpha, _clean, _number
from analysis.stats.anova import _anova, _anova_dict
from analysis.stats.design import RepeatedMeasures, _descriptives, repeated_measures
from analysis.stats.posthoc import _lsd_paired, _lsd_pooled
from analysis.stats.sphericity import _gg, _mauchly

GATES: tuple[str, ...] = ("auto", "uncorrected", "greenhouse_geisser")


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
    _check_gate(gate)
    if gate == "greenhouse_geisser" or (gate == "auto" and sphericity["violated"]):
        return "greenhouse_geisser"
    return "uncorrected"


def _check_gate(gate: str) -> None:
    if gate not in GATES:
        raise ValueError(f"gate {gate!r} is not allowed; choose one of {', '.join(GATES)}")


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
    _check_gate(gate)
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    y = data.y
    anova = _anova(y)
    sphericity = _mauchly(y, alpha=sphericity_alpha)
    eps, p_gg = _gg(y)
    anova_out = _anova_dict(anova)
    gg_out = {"eps": _number(eps), "p": _number(p_gg)}
    notes = [*data.warnings, *_degenerate_notes(anova.ss_error, sphericity, y.shape)]
    p = gate_p(anova_out, sphericity, gg_out, gate=gate)
    significant = p is not None and p < alpha
    paired, pooled = _posthoc(data, alpha, notes) if significant else ([], [])
    return _clean(
        {
            "n_subjects": int(y.shape[0]),
            "levels": list(data.levels),
            "descriptives": _described(data, within),
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


def _degenerate_notes(ss_error: float, sphericity: dict, shape: tuple[int, int]) -> list[str]:
    """The warning of a zero error term or a singular contrast covariance, if any."""
    if ss_error == 0.0:
        return [
            "SS_error is 0 (every subject's scores differ by the same constants between "
            "levels): F, its p and the sphericity test are undefined; no significance test"
        ]
    if sphericity["W"] == 0.0:
        return [
            f"the covariance of the level differences is singular ({shape[0]} subjects, "
            f"{shape[1]} levels): Mauchly's W = 0 and sphericity counts as violated"
        ]
    return []


def _posthoc(
    data: RepeatedMeasures, alpha: float, notes: list[str]
) -> tuple[list[dict], list[dict]]:
    """Both LSD forms as JSON-safe pair lists; appends a note when a paired SD is 0."""
    paired = _pairs(_lsd_paired(data.y, data.levels, alpha))
    pooled = _pairs(_lsd_pooled(data.y, data.levels, alpha))
    if any(pair["t"] is None for pair in paired):
        notes.append("some paired differences have SD 0: their t and p are undefined")
    return paired, pooled


def _described(data: RepeatedMeasures, within: str) -> dict[str, dict]:
    """{level: {mean, sd, se, n}} of the complete cases, as plain Python numbers."""
    table = _descriptives(data, within)
    return {
        level: {
            "mean": float(row["mean"]),
            "sd": float(row["sd"]),
            "se": float(row["se"]),
            "n": int(row["n"]),
        }
        for level, row in table.iterrows()
    }
