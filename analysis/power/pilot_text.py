"""The text of a power report computed from a pilot (``asa power --from-study``, issue 39):
the methods paragraph for a pre-registration, saying where every number came from, the
limitations, the pilot's fitted model as tables, and the spread of the power over the
pilot's bootstrap replicates. The figures and the summary table are those of
:mod:`analysis.power.report`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from analysis.methods import _GATES, _POSTHOC_WORDS, posthoc_gate_words
from analysis.stats.apa import _num

_MODEL_WORDS = {
    "mvn": (
        "a multivariate normal model of each participant's values across the levels (the "
        "levels' means and the participants' unstructured covariance across levels, "
        "estimated by the sample mean and covariance: the model of the repeated-measures "
        "ANOVA without assuming sphericity)"
    ),
    "lmm": (
        "a linear mixed model with the level as fixed effect and a random intercept per "
        "participant (variance components by REML on the complete balanced data: "
        "s_e^2 = MS_error, s_b^2 = max(0, (MS_subject - MS_error) / k))"
    ),
}


def _and(items) -> str:
    words = [str(i) for i in items]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _pilot_sentence(result: Mapping) -> str:
    pilot, p = result["pilot"], result["protocol"]
    kinds = ", ".join(f"{v} {k}" for k, v in pilot["kinds"].items())
    per_metric = "; ".join(
        f"{m} n = {f['n']} ({', '.join(f'{lv} M = {_num(mu)}, SD = {_num(sd)}' for lv, mu, sd in zip(f['levels'], f['mean'], f['sd'], strict=True))})"  # noqa: E501
        for m, f in pilot["fitted"].items()
    )
    return (
        f"The pilot study {p['name']} (protocol SHA-256 {p['sha256'][:12]}; database "
        f"{pilot['file']}) had {pilot['participants']} participants ({kinds}). For each "
        f"planned metric, its participants with a value in every level were fitted "
        f"{_MODEL_WORDS[result['settings']['model']]}: {per_metric}."
    )


def _simulation_sentence(result: Mapping) -> str:
    s = result["settings"]
    interest = s["interest"]
    sesoi = (
        " Because a pilot's effect sizes are noisy and, when selected for promise, biased "
        "upwards, power was also computed at the smallest effect size of interest stated "
        "before the analysis: the level means scaled about their grand mean so that the "
        "largest difference between two levels equals "
        + _and([f"{v:g} for {m}" for m, v in interest.items()])
        + " (the covariance the pilot's; as simr's fixef<-)."
        if interest
        else " No smallest effect size of interest was stated: the curves at the pilot's "
        "estimates inherit the pilot's noise and any upward bias of its effects."
    )
    return (
        f"For each sample size N = {_and(s['sizes'])}, S = {s['studies']} studies of N "
        "participants were simulated from the fitted model (parametric bootstrap, as R's "
        f"simr powerSim; seed {s['seed']}). The uncertainty of the pilot's estimates was "
        f"carried into a second set of curves: each simulated study took its model from one "
        f"of B = {s['draws']} bootstrap replicates of the pilot (its participants drawn "
        "with replacement, the model refitted), so that curve is the power expected over "
        "the pilot's uncertainty (assurance), and the spread of the replicates' power "
        f"(quantiles {s['spread'][0]:g} and {s['spread'][1]:g}, Monte Carlo error included) "
        f"is reported beside it." + sesoi
    )


def _analysis_sentence(result: Mapping) -> str:
    s = result["settings"]
    gate = s["posthoc_gate"]
    lsd = s["posthoc"].startswith("lsd")
    gated = gate == "omnibus" or (gate == "auto" and lsd)
    tests = _and([f"{m}: {t}" for m, t in s["tests"].items()])
    return (
        f"Each simulated study was analysed as the protocol plans, by the platform's own "
        f"analysis (asa-study {result['platform_version']}), at \u03b1 = {s['alpha']:g} "
        f"(planned omnibus tests {tests}; the repeated-measures ANOVA's correction: "
        f"{_GATES.get(s['gate'], s['gate'])}), pairs of levels by "
        f"{_POSTHOC_WORDS.get(s['posthoc'], s['posthoc'])} "
        + ("where the omnibus test rejected" if gated else posthoc_gate_words(s["posthoc"], gate))
        + f". Power is the share of the S studies rejecting, with exact Clopper\u2013Pearson "
        f"{100 * s['ci_level']:g} % intervals (Monte Carlo error); the N at which a test "
        f"reaches {s['target_power']:g} is the curve interpolated linearly between the "
        "simulated sizes and rounded up."
    )


def pilot_methods(result: Mapping) -> str:
    """The methods paragraph of a power analysis from a pilot: the pilot, the fitted model
    and its numbers, the simulation, the pilot's uncertainty, the effect of interest, the
    analysis and how power was counted."""
    return " ".join(
        [
            "Statistical power was estimated from pilot data by simulation.",
            _pilot_sentence(result),
            _simulation_sentence(result),
            _analysis_sentence(result),
        ]
    )


def pilot_limitations(result: Mapping) -> list[str]:
    """The limits of power from a pilot."""
    s, pilot = result["settings"], result["pilot"]
    smallest = min(f["n"] for f in pilot["fitted"].values())
    out = [
        f"A pilot of {smallest} complete participants estimates the covariance across "
        "levels poorly: the curves at the pilot's estimates can be far from the truth; read "
        "them beside the curves over the pilot's uncertainty and at the smallest effect of "
        "interest.",
        "The fitted model is normal: counts (collisions, errors) and ratings are simulated "
        "as continuous values, so a test planned on ranks (Friedman) is simulated on data "
        "without the ties the real measure has. For a count that is mostly zero (and a "
        "score that jumps with it) the normal model can overstate the power of small "
        "studies and understate that of larger ones (measured against resampling the same "
        "people: docs/results.md, issue 39); for such metrics prefer asa power on a "
        "population calibrated to the pilot (asa calibrate).",
        "The model has no order effects: counterbalancing is not simulated.",
        "The bootstrap replicates' spread includes the Monte Carlo error of the "
        f"{max(1, s['studies'] // s['draws'])} studies each replicate gets per N.",
    ]
    if "synthetic" in pilot["kinds"]:
        out.append(
            "Some of the pilot's participants are synthetic: their effects are the "
            "population model's, not people's."
        )
    return out


def pilot_settings_tables(result: Mapping) -> dict[str, list[tuple[str, str]]]:
    """(name, value) rows of the settings, the pilot, its fitted moments, the protocol and
    the timing, under the keys the template's settings section reads."""
    from analysis.power.report import _value_text

    def rows(entries: Mapping) -> list[tuple[str, str]]:
        return [(k, _value_text(k, v)) for k, v in entries.items()]

    pilot = {k: v for k, v in result["pilot"].items() if k != "fitted"}
    fitted: list[tuple[str, str]] = []
    for metric, f in result["pilot"]["fitted"].items():
        for key in ("n", "levels", "mean", "sd", "correlation"):
            fitted.append((f"{metric}.{key}", _value_text(key, _rounded(f[key]))))
    return {
        "protocol": rows(result["protocol"]),
        "settings": rows(result["settings"]),
        "bank": rows(pilot),
        "population": fitted,
        "timing": rows(result["timing"]),
    }


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return float(f"{value:.4g}")
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    return value


def spread_rows(result: Mapping) -> list[dict]:
    """Per metric over the pilot's uncertainty: each test's expected power and the spread
    of the replicates' power at every size (``"0.62 (0.31-0.88)"``)."""
    out = []
    for m in result["metrics"]:
        if m.get("variant") != "uncertain":
            continue
        tests = []
        for t in m["tests"]:
            by_n = {r["n"]: r for r in t.get("replicates", [])}
            cells = []
            for point in t["curve"]:
                r = by_n.get(point["n"])
                spread = "" if r is None else f" ({_num(r['low'])}\u2013{_num(r['high'])})"
                cells.append(f"{_num(point['power'])}{spread}")
            tests.append({"name": t["test"], "cells": cells})
        out.append({"metric": m["base_metric"], "label": m["label"], "tests": tests})
    return out
