"""The calibration report (issue 39): each fitted parameter with its interval, and the fit
of every moment (the pilot's value, its standard error, the calibrated bank's value)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from study.jobs.calibrate.fit import Problem, pilot_targets, simulated
from study.jobs.calibrate.moments import moment_names


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(float(v)) else None


def moment_rows(problem: Problem, estimate: np.ndarray) -> list[dict[str, Any]]:
    """One row per moment: name, target, se, simulated (at ``estimate``), z, whether it is
    fitted, and its metric's effective bank size."""
    targets = pilot_targets(problem)
    sims, ess = simulated(problem, estimate, np.ones(problem.bank_size()))
    fitted = set(problem.fitted_metrics())
    rows = []
    for metric, wide in problem.pilot.items():
        for j, name in enumerate(moment_names(wide)):
            t, se, m = targets[metric][j], problem.se[metric][j], sims[metric][j]
            z = (m - t) / se if se > 0 and math.isfinite(m - t) else math.nan
            rows.append({
                "moment": name, "metric": metric, "target": _num(t), "se": _num(se),
                "simulated": _num(m), "z": _num(z),
                "fitted": bool(metric in fitted and se > 0 and math.isfinite(t)),
                "bank_ess": round(ess[metric], 1),
            })  # fmt: skip
    return rows


def _fmt(v: float | None, digits: int = 3) -> str:
    return "n/a" if v is None else f"{v:.{digits}g}" if abs(v) >= 1000 else f"{v:.{digits}f}"


def report_lines(result: dict[str, Any]) -> list[str]:
    """The text report (the JSON's contents, one screen per part)."""
    st, se = result["study"], result["settings"]
    level = round(100 * se["level"])
    lines = [
        result["title"],
        f"study {st['file']}: {st['participants']} participants; bank {se['bank']}, "
        f"{se['replicates']} bootstrap replicates, {level} % intervals; {se['engine']}",
        "",
        f"{'parameter':<24}{'estimate':>10}  {f'{level} % interval':<20}{'base':>8}",
    ]
    for p in result["parameters"]:
        unit = f" [{p['unit']}]" if p["unit"] else ""
        interval = f"[{p['low']:.3f}, {p['high']:.3f}]"
        name = p["name"] + unit
        lines.append(f"{name:<24}{p['estimate']:>10.3f}  {interval:<20}{p['base']:>8.3f}")
    lines += ["", f"{'moment':<46}{'target':>10}{'SE':>9}{'simulated':>11}{'z':>7}  fitted"]
    for m in result["moments"]:
        z = "n/a" if m["z"] is None else f"{m['z']:+.2f}"
        lines.append(
            f"{m['moment']:<46}{_fmt(m['target']):>10}{_fmt(m['se']):>9}"
            f"{_fmt(m['simulated']):>11}{z:>7}  {'yes' if m['fitted'] else 'no'}"
        )
    t = result["timing"]
    lines += ["", f"bank {t['bank_s']:.0f} s, fit and bootstrap {t['fit_s']:.0f} s"]
    return lines
