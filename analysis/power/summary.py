"""From counted rejections to power curves: binomial confidence intervals, the smallest
sample size reaching the target power, the one-screen summary, and the bank's effect sizes
(issue 22)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from analysis.power.resample import OMNIBUS, PlannedTests

TARGET_POWER = 0.8
CI_LEVEL = 0.95


def clopper_pearson(k: int, n: int, level: float = CI_LEVEL) -> tuple[float, float]:
    """The exact (Clopper-Pearson 1934) interval of a binomial proportion ``k / n``.

    ``low = B^-1((1 - level)/2; k, n - k + 1)``, ``high = B^-1((1 + level)/2; k + 1, n - k)``
    (beta quantiles), 0 and 1 at the ends. In R: ``binom.test(k, n)$conf.int``.
    """
    if n <= 0:
        return (0.0, 1.0)
    tail = (1.0 - level) / 2.0
    low = 0.0 if k == 0 else float(stats.beta.ppf(tail, k, n - k + 1))
    high = 1.0 if k == n else float(stats.beta.ppf(1.0 - tail, k + 1, n - k))
    return low, high


def curve(counts: Mapping[int, tuple[int, int]], level: float = CI_LEVEL) -> list[dict]:
    """Size -> (rejections, studies) as points ``{n, rejections, studies, power, ci_low,
    ci_high}``, by size."""
    points = []
    for n in sorted(counts):
        k, total = counts[n]
        low, high = clopper_pearson(k, total, level)
        points.append(
            {
                "n": int(n),
                "rejections": int(k),
                "studies": int(total),
                "power": k / total if total else None,
                "ci_low": low,
                "ci_high": high,
            }
        )
    return points


def _crossing(sizes: Sequence[int], values: Sequence[float], target: float) -> float | None:
    """The size at which the piecewise-linear curve through (sizes, values) first reaches
    ``target``; None when it never does."""
    for i, (n, v) in enumerate(zip(sizes, values, strict=True)):
        if v >= target:
            if i == 0:
                return float(n)
            n0, v0 = sizes[i - 1], values[i - 1]
            return n0 + (target - v0) * (n - n0) / (v - v0)
    return None


def n_for_power(points: Sequence[dict], target: float = TARGET_POWER) -> dict:
    """The sample size at which a power curve reaches ``target``.

    ``n``: the curve through the simulated sizes, interpolated linearly and rounded up;
    ``low`` and ``high``: the same for the upper and the lower ends of the pointwise 95 %
    CIs (the Monte Carlo uncertainty; not that of the bank); ``simulated``: the smallest
    simulated size whose estimate reaches it. A value is None when the curve does not reach
    ``target`` within the simulated sizes (``beyond`` is then the largest size).
    ``at_most``: the smallest simulated size when it reaches the target already (the
    curve below it was not simulated: the N needed may be smaller), else None.
    """
    sizes = [p["n"] for p in points]

    def at(key: str) -> int | None:
        x = _crossing(sizes, [p[key] for p in points], target)
        return None if x is None else int(math.ceil(x - 1e-9))

    reached = [p["n"] for p in points if p["power"] >= target]
    return {
        "target": target,
        "n": at("power"),
        "low": at("ci_high"),
        "high": at("ci_low"),
        "simulated": reached[0] if reached else None,
        "beyond": None if reached else (max(sizes) if sizes else None),
        "at_most": sizes[0] if reached and reached[0] == sizes[0] else None,
    }


def describe_n(found: dict) -> str:
    """``"N = 12 [9, 15]"``; ``"N > 24"`` when the target is not reached, ``"N <= 6"``
    when the smallest simulated size reaches it already."""
    if found["n"] is None:
        return f"N > {found['beyond']}"
    if found.get("at_most") is not None:
        return f"N <= {found['at_most']}"
    high = "?" if found["high"] is None else f"{found['high']}"
    low = found["low"] if found["low"] is not None else found["n"]
    return f"N = {found['n']} [{low}, {high}]"


def summary_lines(metrics: Sequence[dict]) -> list[str]:
    """The one-screen summary: per metric and test, where it reaches the target power,
    e.g. ``"score_s: manual vs contextual_task reaches 0.8 at N = 12 [9, 15]"``."""
    lines = []
    for m in metrics:
        for t in m["tests"]:
            found = t["n_for_power"]
            name = "omnibus test" if t["test"] == OMNIBUS else t["test"]
            last = t["curve"][-1]
            verdict = (
                f"reaches {found['target']:g} at {describe_n(found)}"
                if found["n"] is not None
                else f"does not reach {found['target']:g} by N = {found['beyond']} "
                f"(power {last['power']:.2f} there)"
            )
            lines.append(f"{m['metric']}: {name} {verdict}")
    return lines


def bank_effects(outcomes: pd.DataFrame, planned: PlannedTests, metric: str) -> dict | None:
    """The effect sizes in the whole bank for ``metric``: descriptives, partial eta squared
    and each pair's mean difference and Cohen's d_z with their CIs
    (:func:`analysis.stats.analyse` on every bank participant); None when it cannot run."""
    frame = outcomes[outcomes["metric"] == metric]
    try:
        result = planned.analyse(frame, metric, mixed=False)
    except ValueError:
        return None
    return {
        "n": result["n_subjects"],
        "descriptives": result["descriptives"],
        "np2": result["effect_sizes"]["np2"],
        "pairs": result["pairs"],
        "planned_test": result["planned"]["test"],
        "p": result["planned"]["p"],
    }


def tally(
    batches: Sequence[tuple[int, dict[str, dict[str, np.ndarray]]]], planned: PlannedTests
) -> dict[str, dict[str, dict[int, tuple[int, int]]]]:
    """Sum batch results (size, :func:`analysis.power.resample.resample_batch` output) to
    metric -> test -> size -> (rejections, studies); also ``"_failed"`` per metric."""
    out: dict[str, dict[str, dict[int, tuple[int, int]]]] = {
        m: {key: {} for key in (*planned.keys(m), "_failed")} for m in planned.metrics
    }
    for n, result in batches:
        for metric, tests in result.items():
            for key, flags in tests.items():
                k, total = out[metric][key].get(n, (0, 0))
                out[metric][key][n] = (k + int(np.sum(flags)), total + int(flags.size))
    return out
