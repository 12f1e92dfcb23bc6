"""APA-style text of the statistics: p-values, the omnibus tests with their effect sizes and
intervals, the pairs, the mixed model (APA Publication Manual, 7th ed., Sec. 6.36-6.46).
Issue 21; the thesis (Sec. 7.6.2) reports F and p only.

Significance is always decided on the unrounded p; the text never shows a rounded p that
lands on the other side of alpha (p = .04996 is written "= .04996"-like, never "= .050").
"""

from __future__ import annotations

import math

__all__ = ["apa_friedman", "apa_mixed", "apa_order", "apa_pair", "apa_rm_anova", "format_p"]


def _no_leading_zero(text: str) -> str:
    if text.startswith("0."):
        return text[1:]
    if text.startswith("-0."):
        return "-" + text[2:]
    return text


def format_p(p: float | None, *, alpha: float | None = None) -> str:
    """APA p: ``"< .001"``, ``"= .026"``, or ``"n/a"`` when undefined (None or NaN).

    With ``alpha``, a p whose three-decimal rounding would reach alpha from below (e.g.
    0.04996 -> ".050") gets as many more decimals as keep it below (".04996").
    """
    if p is None or not math.isfinite(p):
        return "n/a"
    if p < 0.001:
        return "< .001"
    digits = 3
    while alpha is not None and p < alpha <= round(p, digits) and digits < 12:
        digits += 1
    return "= " + _no_leading_zero(f"{p:.{digits}f}")


def _num(value: float | None, digits: int = 2, *, zero: bool = True) -> str:
    if value is None or not math.isfinite(value):
        return "n/a"
    text = f"{value:.{digits}f}"
    return text if zero else _no_leading_zero(text)


def _ci(low: float | None, high: float | None, level: float, *, zero: bool = True) -> str:
    return f"{100 * level:g}% CI [{_num(low, zero=zero)}, {_num(high, zero=zero)}]"


def apa_rm_anova(result: dict, *, alpha: float = 0.05) -> str:
    """The RM-ANOVA with both eta squared, e.g. ``"F(2, 34) = 25.76, p < .001, eta_p^2 =
    .60, 90% CI [.41, .70], eta_G^2 = .31"``; Greenhouse-Geisser dfs when the gate used them.
    """
    anova, gg = result["anova"], result["greenhouse_geisser"]
    df1, df2 = anova["df_effect"], anova["df_error"]
    if anova["F"] is None:
        return f"F({df1}, {df2}) undefined (SS_error = 0)"
    corrected = result["p_gate_source"] == "greenhouse_geisser" and (gg["eps"] or 1.0) < 1.0
    dfs = f"{gg['eps'] * df1:.2f}, {gg['eps'] * df2:.2f}" if corrected else f"{df1}, {df2}"
    np2 = result["effect_sizes"]["np2"]
    return (
        f"F({dfs}) = {anova['F']:.2f}, p {format_p(result['p_gate'], alpha=alpha)}, "
        f"eta_p^2 = {_num(np2['value'], zero=False)}, "
        f"{_ci(np2['ci_low'], np2['ci_high'], np2['ci_level'], zero=False)}, "
        f"eta_G^2 = {_num(anova['ng2'], zero=False)}"
        + (" (Greenhouse-Geisser)" if corrected else "")
    )


def apa_friedman(friedman: dict, *, alpha: float = 0.05) -> str:
    """Friedman's test with Kendall's W, e.g. ``"chi2(2) = 12.20, p = .002, W = .61"``."""
    if friedman["chi2"] is None:
        return f"chi2({friedman['df']}) undefined (every subject's ranks tied)"
    return (
        f"chi2({friedman['df']}) = {friedman['chi2']:.2f}, "
        f"p {format_p(friedman['p'], alpha=alpha)}, W = {_num(friedman['kendall_w'], zero=False)}"
    )


def apa_pair(effect: dict, test: dict | None, *, level: float, alpha: float = 0.05) -> str:
    """One pair: the mean difference and d_z with their CIs, and its test when it ran.

    ``effect``: a row of :func:`analysis.stats.effects.pair_effects`; ``test``: the row of the
    planned post-hoc family (t, df, p) or of the Wilcoxon-Holm tests (V, p), or None.
    """
    text = (
        f"{effect['a']} - {effect['b']}: M_diff = {_num(effect['diff'])}, "
        f"{_ci(effect['ci_low'], effect['ci_high'], level)}, d_z = {_num(effect['dz'])}, "
        f"{_ci(effect['dz_ci_low'], effect['dz_ci_high'], level)}"
    )
    if test is None:
        return text
    if "V" in test:
        statistic = f"V = {_num(test['V'], 1)}"
    else:
        statistic = f"t({test['df']}) = {_num(test['t'])}"
    return f"{text}; {statistic}, p {format_p(test['p'], alpha=alpha)}"


def apa_mixed(mixed: dict, *, alpha: float = 0.05) -> str:
    """The likelihood-ratio test of mode in the mixed model, e.g. ``"chi2(2) = 9.10, p = .011
    (likelihood ratio, ML; 35 observations of 12 participants)"``."""
    lrt = mixed["lrt"]
    where = f"{mixed['n_obs']} observations of {mixed['n_subjects']} participants"
    if lrt["chi2"] is None:
        return f"likelihood-ratio test undefined ({where})"
    return (
        f"chi2({lrt['df']}) = {lrt['chi2']:.2f}, p {format_p(lrt['p'], alpha=alpha)} "
        f"(likelihood ratio, ML; {where})"
    )


def apa_order(order: dict, *, alpha: float = 0.05) -> str:
    """Position and mode x position likelihood-ratio tests on one line."""
    parts = []
    for name, label in (("position", "position"), ("mode_x_position", "mode x position")):
        lrt = order[name]
        if lrt["chi2"] is None:
            parts.append(f"{label}: undefined")
        else:
            parts.append(
                f"{label}: chi2({lrt['df']}) = {lrt['chi2']:.2f}, "
                f"p {format_p(lrt['p'], alpha=alpha)}"
            )
    return "; ".join(parts)
