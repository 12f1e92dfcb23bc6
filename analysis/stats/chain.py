"""The planned analysis of one metric: descriptives, ANOVA, sphericity, gate and LSD.

Thesis Sec. 7.6.2: Fisher's LSD only after the ANOVA rejects the null at alpha.
"""

from __future__ import annotations

import pandas as pd

from analysis.stats import apa
from analysis.stats._numbers import _check_alpha, _clean, _number
from analysis.stats.anova import _anova, _anova_dict
from analysis.stats.assumptions import normality, outliers
from analysis.stats.design import RepeatedMeasures, _descriptives, repeated_measures
from analysis.stats.effects import DZ_CI_METHOD, pair_effects, partial_eta_squared_ci
from analysis.stats.mixed import cells, mixed_model, order_effects
from analysis.stats.nonparametric import TESTS, choose_test, friedman, wilcoxon_holm
from analysis.stats.posthoc import _adjusted, _lsd_paired, _lsd_pooled
from analysis.stats.sphericity import _gg, _mauchly

GATES: tuple[str, ...] = ("auto", "uncorrected", "greenhouse_geisser")
POSTHOC: tuple[str, ...] = ("lsd_paired", "lsd_pooled", "holm", "bonferroni")
# Whether a post-hoc family runs only after the omnibus test rejects: "auto" gates Fisher's
# LSD (protected by the omnibus test, thesis Sec. 7.6.2) and not Holm or Bonferroni (which
# control the family-wise error on their own); "omnibus" gates every family, "none" none.
POSTHOC_GATES: tuple[str, ...] = ("auto", "omnibus", "none")
# Steiger (2004): a two-sided 1 - 2 alpha interval of eta squared matches the F test.
ETA_CI_LEVEL_OF_ALPHA = "1 - 2 alpha"


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


def posthoc_gated(family: str, posthoc_gate: str = "auto") -> bool:
    """Whether the post-hoc ``family`` runs only when the omnibus test rejects.

    ``family`` is one of :data:`POSTHOC` or ``"wilcoxon_holm"`` (Friedman's pairs);
    ``posthoc_gate`` one of :data:`POSTHOC_GATES`. With ``"auto"`` only the LSD forms are
    gated: Fisher's LSD controls the family-wise error (for three levels) only behind the
    omnibus test (Fisher 1935; thesis Sec. 7.6.2), Holm (1979) and Bonferroni control it on
    their own. In R: emmeans' ``pairs(..., adjust = "holm")`` is not conditional on any F.
    """
    if posthoc_gate not in POSTHOC_GATES:
        raise ValueError(
            f"posthoc_gate {posthoc_gate!r} is not allowed; choose one of "
            f"{', '.join(POSTHOC_GATES)}"
        )
    if posthoc_gate == "auto":
        return family.startswith("lsd")
    return posthoc_gate == "omnibus"


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
    test: str = "rm_anova",
    posthoc: str = "lsd_paired",
    posthoc_gate: str = "auto",
    order: str | None = None,
    mixed: bool = True,
    decisions_only: bool = False,
) -> dict:
    """The whole analysis of one metric: the thesis's chain and issue 21's additions.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.
    alpha : float
        Significance level of the gated ANOVA, the post-hoc pairs, Friedman and the LRTs;
        CI level 1 - alpha (eta squared: 1 - 2 alpha, Steiger 2004).
    gate : {"auto", "uncorrected", "greenhouse_geisser"}
        Which p decides significance of the RM-ANOVA, see :func:`gate_p`.
    sphericity_alpha : float
        Mauchly's p below which sphericity counts as violated (the auto gate).
    test : {"rm_anova", "friedman", "auto"}
        The planned omnibus test (see :func:`analysis.stats.nonparametric.choose_test`);
        both are computed, the planned one leads.
    posthoc : {"lsd_paired", "lsd_pooled", "holm", "bonferroni"}
        The planned post-hoc family of the RM-ANOVA path (every family is computed).
    posthoc_gate : {"auto", "omnibus", "none"}
        Which post-hoc families wait for their omnibus test to reject, see
        :func:`posthoc_gated` (the RM-ANOVA's families behind its gate, Friedman's
        Wilcoxon-Holm pairs behind Friedman's test).
    order : str, optional
        Column of each cell's position in the subject's order (1, 2, ...): enables the order
        checks and the position covariate of the mixed model.
    mixed : bool
        Fit the mixed model (statsmodels MixedLM; about a second per metric).
    decisions_only : bool
        Only what decides the planned tests, by the same code: descriptives, the ANOVA,
        sphericity, the gate, the planned post-hoc family and (when planned) Friedman with
        its Wilcoxon-Holm pairs; ``effect_sizes``, ``pairs``, ``assumptions``, ``mixed``,
        ``order`` and ``apa`` are None, the unplanned families empty, ``friedman`` None
        unless planned. For resampled studies (power analysis, issue 22): about five
        times faster.

    Returns
    -------
    dict
        JSON-safe (plain Python numbers, None instead of NaN). The thesis's keys:
        ``n_subjects``, ``levels``, ``descriptives`` {level: {mean, sd, se, n}}, ``anova``
        (see :func:`rm_anova`), ``sphericity`` (see :func:`mauchly`), ``greenhouse_geisser``
        {eps, p}, ``p_gate``, ``p_gate_source``, ``significant`` (the RM-ANOVA's gate),
        ``posthoc`` {ran, gated, posthoc_gate, lsd_paired, lsd_pooled, holm, bonferroni}
        (``ran``/``gated``: the planned family; a gated family's list is empty unless
        ``significant``; holm/bonferroni rows add ``p_unc``), ``warnings``,
        ``dropped_subjects``. Issue 21's keys are documented in docs/algorithms.md
        ("Issue 21 keys"): ``planned``, ``posthoc_planned``, ``posthoc_warning``,
        ``effect_sizes``, ``pairs``, ``assumptions``, ``friedman``, ``mixed``, ``order``,
        ``apa``.

    Notes
    -----
    R reproduces every figure: ``tests/r/oracle.R`` (afex, lme4, base R).
    In SPSS: GLM Repeated Measures with Descriptive statistics and Compare main effects (LSD).
    """
    _check_options(alpha, sphericity_alpha, gate, test, posthoc)
    gated = posthoc_gated(posthoc, posthoc_gate)
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    families = (posthoc,) if decisions_only else POSTHOC
    result = _thesis_chain(
        data, within, alpha=alpha, gate=gate, sphericity_alpha=sphericity_alpha,
        families=families, planned=posthoc, posthoc_gate=posthoc_gate,
    )  # fmt: skip
    if not gated and posthoc.startswith("lsd"):
        result["warnings"].append(_UNPROTECTED_LSD)
    if decisions_only:
        return _clean(
            _decisions(
                data, result, alpha=alpha, test=test, posthoc=posthoc, posthoc_gate=posthoc_gate
            )
        )
    notes = result["warnings"]
    result.update(_additions(data, result, alpha=alpha, posthoc=posthoc, notes=notes))
    planned, reason = choose_test(data.y, requested=test)
    result["friedman"] = _friedman_block(data, alpha, posthoc_gate)
    result["planned"] = _planned(result, planned, test, reason, alpha)
    if planned == "rm_anova":
        notes.extend(_assumption_notes(result["assumptions"], result["posthoc_warning"]))
    frame = cells(df, dv=dv, within=within, subject=subject, order=order)
    result["mixed"] = _mixed_block(frame, data, alpha) if mixed else None
    result["order"] = _order_block(frame, data, alpha) if order is not None else None
    result["apa"] = _apa(result, alpha)
    return _clean(result)


def _check_options(
    alpha: float, sphericity_alpha: float, gate: str, test: str, posthoc: str
) -> None:
    _check_alpha(alpha)
    _check_alpha(sphericity_alpha, "sphericity_alpha")
    _check_gate(gate)
    if test not in TESTS:
        raise ValueError(f"test {test!r} is not allowed; choose one of {', '.join(TESTS)}")
    if posthoc not in POSTHOC:
        raise ValueError(f"posthoc {posthoc!r} is not allowed; choose one of {', '.join(POSTHOC)}")


_UNPROTECTED_LSD = (
    "Fisher's LSD without the omnibus gate (posthoc_gate = none) does not control the "
    "family-wise error rate"
)


def _decisions(
    data: RepeatedMeasures,
    result: dict,
    *,
    alpha: float,
    test: str,
    posthoc: str,
    posthoc_gate: str,
) -> dict:
    """``result`` (the thesis chain) with the planned test, the rest of the keys None."""
    planned, reason = choose_test(data.y, requested=test)
    friedman = _friedman_block(data, alpha, posthoc_gate) if planned == "friedman" else None
    result["friedman"] = friedman
    result["planned"] = _planned(result, planned, test, reason, alpha)
    result.update(
        posthoc_planned=posthoc,
        posthoc_warning=lsd_warning(posthoc, data.y.shape[1]),
        effect_sizes=None, pairs=None, assumptions=None, mixed=None, order=None, apa=None,
    )  # fmt: skip
    return result


def _thesis_chain(
    data: RepeatedMeasures,
    within: str,
    *,
    alpha: float,
    gate: str,
    sphericity_alpha: float,
    families: tuple[str, ...] = POSTHOC,
    planned: str = "lsd_paired",
    posthoc_gate: str = "auto",
) -> dict:
    """Descriptives, ANOVA, sphericity, GG, gate and the post-hoc ``families`` (thesis
    7.6.2; the others empty): a family gated by ``posthoc_gate`` only when the gate
    passes."""
    y = data.y
    anova = _anova(y)
    sphericity = _mauchly(y, alpha=sphericity_alpha)
    eps, p_gg = _gg(y)
    anova_out = _anova_dict(anova)
    gg_out = {"eps": _number(eps), "p": _number(p_gg)}
    notes = [*data.warnings, *_degenerate_notes(anova.ss_error, sphericity, y.shape)]
    p = gate_p(anova_out, sphericity, gg_out, gate=gate)
    significant = p is not None and p < alpha
    runs = tuple(f for f in families if significant or not posthoc_gated(f, posthoc_gate))
    pairs = _posthoc(data, alpha, notes, runs) if runs else {}
    pairs = {name: pairs.get(name, []) for name in POSTHOC}
    gated = posthoc_gated(planned, posthoc_gate)
    return {
        "n_subjects": int(y.shape[0]),
        "levels": list(data.levels),
        "descriptives": _described(data, within),
        "anova": anova_out,
        "sphericity": sphericity,
        "greenhouse_geisser": gg_out,
        "p_gate": p,
        "p_gate_source": gate_source(sphericity, gate=gate),
        "significant": bool(significant),
        "posthoc": {
            "ran": bool(significant or not gated),
            "gated": gated,
            "posthoc_gate": posthoc_gate,
            **pairs,
        },
        "warnings": notes,
        "dropped_subjects": list(data.dropped_subjects),
    }


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


_FAMILIES = {
    "lsd_paired": lambda y, levels, alpha: _lsd_paired(y, levels, alpha),
    "lsd_pooled": lambda y, levels, alpha: _lsd_pooled(y, levels, alpha),
    "holm": lambda y, levels, alpha: _adjusted(y, levels, alpha, "holm"),
    "bonferroni": lambda y, levels, alpha: _adjusted(y, levels, alpha, "bonferroni"),
}


def _posthoc(
    data: RepeatedMeasures, alpha: float, notes: list[str], families: tuple[str, ...] = POSTHOC
) -> dict[str, list[dict]]:
    """The post-hoc ``families`` as JSON-safe pair lists; a note when a paired SD is 0."""
    out = {name: _pairs(_FAMILIES[name](data.y, data.levels, alpha)) for name in families}
    paired = out.get("lsd_paired", out.get("holm", out.get("bonferroni", [])))
    if any(pair["t"] is None for pair in paired):
        notes.append("some paired differences have SD 0: their t and p are undefined")
    return out


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


def _eta_level(alpha: float) -> float:
    """The CI level of eta squared: 1 - 2 alpha (Steiger 2004), or 1 - alpha from alpha .25."""
    return 1.0 - 2.0 * alpha if alpha < 0.25 else 1.0 - alpha


def lsd_warning(posthoc: str, k: int) -> str | None:
    """The warning when Fisher's LSD is planned with more than three levels, else None."""
    if posthoc.startswith("lsd") and k > 3:
        return (
            f"Fisher's LSD ({posthoc}) protects the family-wise error rate only for three "
            f"levels; with {k} levels use holm or bonferroni"
        )
    return None


def _additions(
    data: RepeatedMeasures, result: dict, *, alpha: float, posthoc: str, notes: list[str]
) -> dict:
    """Effect sizes with CIs, per-pair effects, assumption checks, the planned family."""
    anova = result["anova"]
    np2 = partial_eta_squared_ci(
        anova["F"], anova["df_effect"], anova["df_error"], level=_eta_level(alpha)
    )
    ng2 = {"value": anova["ng2"], "ci_low": None, "ci_high": None, "ci_level": None}
    ng2["method"] = "point estimate (Olejnik & Algina 2003); no interval"
    sphericity = result["sphericity"]
    return {
        "posthoc_planned": posthoc,
        "posthoc_warning": lsd_warning(posthoc, data.y.shape[1]),
        "effect_sizes": {
            "np2": np2,
            "ng2": ng2,
            "pair_ci_level": 1.0 - alpha,
            "dz_ci_method": DZ_CI_METHOD,
        },
        "pairs": pair_effects(data.y, data.levels, level=1.0 - alpha),
        "assumptions": {
            "normality": normality(data.y, data.levels, alpha=alpha),
            "outliers": outliers(data.y, data.levels, data.subjects),
            "sphericity": {"violated": sphericity["violated"], "p": sphericity["p"]},
        },
    }


def _friedman_block(data: RepeatedMeasures, alpha: float, posthoc_gate: str = "auto") -> dict:
    """Friedman's test, Kendall's W and the Wilcoxon-Holm pairs (when Friedman rejects, or
    always when Holm is not gated, see :func:`posthoc_gated`)."""
    out = friedman(data.y)
    significant = out["p"] is not None and out["p"] < alpha
    gated = posthoc_gated("wilcoxon_holm", posthoc_gate)
    ran = significant or not gated
    pairs = wilcoxon_holm(data.y, data.levels, alpha=alpha) if ran else []
    out.update(
        significant=significant,
        posthoc={"ran": ran, "gated": gated, "wilcoxon_holm": pairs},
    )
    return out


def _planned(result: dict, planned: str, requested: str, reason: str, alpha: float) -> dict:
    """Which omnibus test leads, why, and its verdict."""
    other = "friedman" if planned == "rm_anova" else "rm_anova"
    if planned == "rm_anova":
        p, significant = result["p_gate"], result["significant"]
    else:
        p, significant = result["friedman"]["p"], result["friedman"]["significant"]
    return {
        "test": planned,
        "other": other,
        "requested": requested,
        "reason": reason,
        "p": p,
        "significant": bool(significant),
        "alpha": alpha,
    }


def _assumption_notes(assumptions: dict, lsd_note: str | None) -> list[str]:
    """Warnings of the RM-ANOVA path's failed assumption checks (and the LSD warning)."""
    notes = [lsd_note] if lsd_note else []
    failed = [p for p in assumptions["normality"]["pairs"] if p["violated"]]
    if failed:
        listed = ", ".join(
            f"{p['a']} - {p['b']} (W = {p['W']:.3f}, p {apa.format_p(p['p'])})" for p in failed
        )
        notes.append(f"Shapiro-Wilk rejects normal paired differences for {listed}")
    outlying = assumptions["outliers"]
    if outlying["count"]:
        listed = ", ".join(
            f"{o['subject']} in {o['level']} (t = {o['t']:.2f})" for o in outlying["items"][:5]
        )
        notes.append(
            f"{outlying['count']} outlier(s), |studentised residual| > "
            f"{outlying['limit']:g}: {listed}"
        )
    return notes


def _mixed_block(frame: pd.DataFrame, data: RepeatedMeasures, alpha: float) -> dict:
    out = mixed_model(frame, list(data.levels))
    out["significant"] = out["lrt"]["p"] is not None and out["lrt"]["p"] < alpha
    out["lrt"]["significant"] = out["significant"]
    return out


def _order_block(frame: pd.DataFrame, data: RepeatedMeasures, alpha: float) -> dict:
    out = order_effects(frame, list(data.levels))
    for key in ("position", "mode_x_position"):
        out[key]["significant"] = out[key]["p"] is not None and out[key]["p"] < alpha
    return out


def _apa(result: dict, alpha: float) -> dict:
    """APA lines: each omnibus test, the planned one, every pair, the mixed model, order."""
    lines = {
        "rm_anova": apa.apa_rm_anova(result, alpha=alpha),
        "friedman": apa.apa_friedman(result["friedman"], alpha=alpha),
    }
    lines["planned"] = lines[result["planned"]["test"]]
    if result["planned"]["test"] == "rm_anova":
        tests = result["posthoc"][result["posthoc_planned"]]
    else:
        tests = result["friedman"]["posthoc"]["wilcoxon_holm"]
    by_pair = {(t["a"], t["b"]): t for t in tests}
    level = result["effect_sizes"]["pair_ci_level"]
    lines["pairs"] = [
        apa.apa_pair(e, by_pair.get((e["a"], e["b"])), level=level, alpha=alpha)
        for e in result["pairs"]
    ]
    mixed, order = result["mixed"], result["order"]
    lines["mixed"] = apa.apa_mixed(mixed, alpha=alpha) if mixed else None
    lines["order"] = apa.apa_order(order, alpha=alpha) if order else None
    return lines
