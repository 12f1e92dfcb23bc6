"""What the report says around its statistics: Table 1, levels a metric is constant in by
construction, the synthetic-data banner, the glossary of the terms the page uses (issue
21), and the rows of the sample's experience, descriptives and pair tables (the
statistics themselves are :mod:`analysis.stats`).

Pure functions over the tidy frames and the ``analyse()`` objects; no I/O.
"""

from __future__ import annotations

import math

import pandas as pd

from analysis.data import Frames
from analysis.metrics import Metric
from analysis.tables import format_p
from questionnaires import experience as experience_q

SYNTHETIC_KINDS = ("synthetic", "scripted")  # participant kinds that are models, not people

SYNTHETIC_BANNER = (
    "Model output, not data about people: {n} of the {total} participants in this report "
    "are {what}. Their driving comes from a scripted controller, and their secondary-task "
    "slowdowns and NASA-TLX ratings are built into their model (docs/decisions.md, "
    "study/participants/population.py), so differences between modes in those measures "
    "show what the model assumes, not what people experience. Use such a report to check "
    "the platform and plan a study, never as a finding."
)

#: Every term the report uses that a reader may not know, explained once.
GLOSSARY: tuple[tuple[str, str], ...] = (
    (
        "gate",
        "the omnibus test that must reject the null at alpha before pairwise comparisons "
        "are made (Fisher's protected LSD); the protocol's `gate` chooses which p of the "
        "ANOVA decides: the uncorrected one, the Greenhouse-Geisser one, or the "
        "Greenhouse-Geisser one only when Mauchly's test rejects sphericity.",
    ),
    ("gated p", "the p-value of the ANOVA that the gate used (see gate)."),
    (
        "lsd_paired",
        "Fisher's LSD with a paired t-test per pair of levels (each pair's own error "
        "term, df = n - 1).",
    ),
    (
        "lsd_pooled",
        "Fisher's LSD with the ANOVA's pooled error term (MS_error and its df) for every "
        "pair, as SPSS's post hoc LSD after a repeated-measures ANOVA.",
    ),
    (
        "holm, bonferroni",
        "paired t-tests per pair with Holm's step-down or Bonferroni's adjustment of the "
        "p-values, which keep the family-wise error rate for any number of levels (LSD "
        "only for three); their intervals are Bonferroni's simultaneous ones.",
    ),
    (
        "eta_p^2, eta_G^2",
        "partial and generalised eta squared: the share of variance the factor explains, "
        "without and with the between-subject variance in the denominator.",
    ),
    (
        "Greenhouse-Geisser",
        "a correction of the ANOVA's degrees of freedom by epsilon (1 = sphericity holds) "
        "when the variances of the differences between levels are unequal.",
    ),
    (
        "planned / exploratory",
        "planned metrics are those the protocol's [analysis] metrics name before the "
        "study; the others are shown for exploration and need a correction for multiple "
        "tests before any claim.",
    ),
    (
        "by construction",
        "a level in which a metric cannot vary (no assistance in manual control, so its "
        "share of assisted time and its beta are 0): described, not tested.",
    ),
)


def constant_levels(metric: Metric, long: pd.DataFrame) -> list[str]:
    """Levels of ``long`` (``mode``, ``value``) in which ``metric`` is constant by
    construction (:attr:`Metric.zero_in`) and present in the data."""
    present = set(long["mode"])
    return [level for level in metric.zero_in if level in present]


def without_constant_levels(metric: Metric, long: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """The rows of ``long`` that go into the test, and the levels left out because the
    metric is constant in them by construction (only when two levels or more remain)."""
    out = constant_levels(metric, long)
    kept = long[~long["mode"].isin(out)]
    if not out or kept["mode"].nunique() < 2:
        return long, []
    return kept, out


def _m_sd(values: pd.Series, digits: int) -> str:
    """``"M (SD)"`` of ``values`` with ``digits`` decimals ("n/a" without values)."""
    v = values.dropna().astype(float)
    if v.empty:
        return "n/a"
    sd = float(v.std(ddof=1)) if len(v) > 1 else math.nan
    sd_text = f"{sd:.{digits}f}" if math.isfinite(sd) else "n/a"
    return f"{float(v.mean()):.{digits}f} ({sd_text})"


def _digits(values: pd.Series) -> int:
    """Decimals of a Table 1 row: 2, or 3 when every value of the metric is below 1."""
    v = values.dropna().astype(float).abs()
    return 3 if len(v) and float(v.max()) < 1 else 2


def table_one(longs: dict[str, tuple[Metric, pd.DataFrame]], levels: list[str]) -> pd.DataFrame:
    """Table 1: every metric as M (SD) per level.

    Parameters
    ----------
    longs : metric name -> (its :class:`Metric`, its long frame: ``participant``, ``mode``,
        ``value``), in report order.
    levels : the columns, in order (the modes, then the baseline if any metric has it).

    Returns
    -------
    pandas.DataFrame
        One row per metric: ``metric``, ``label``, ``n`` (participants with a value), one
        column per level (``"M (SD)"``, ``""`` where the metric has no such level) and
        ``note`` (``"0 by construction in manual"`` and the like).
    """
    rows = []
    for name, (metric, long) in longs.items():
        row = {"metric": name, "label": metric.label}
        row["n"] = int(long.dropna(subset=["value"])["participant"].nunique())
        digits = _digits(long["value"])  # one precision a row
        for level in levels:
            values = long.loc[long["mode"] == level, "value"]
            row[level] = _m_sd(values, digits) if len(values) else ""
        constant = constant_levels(metric, long)
        row["note"] = f"0 by construction in {', '.join(constant)}" if constant else ""
        rows.append(row)
    return pd.DataFrame(rows, columns=["metric", "label", "n", *levels, "note"])


def synthetic_banner(kinds: dict[str, int]) -> str:
    """The banner's text when any counted participant is a model (``kinds``: kind ->
    count of counted participants), else ``""``."""
    models = {k: v for k, v in kinds.items() if k in SYNTHETIC_KINDS and v}
    if not models:
        return ""
    n, total = sum(models.values()), sum(kinds.values())
    what = " and ".join(f"{k}" for k in models) + " participants"
    return SYNTHETIC_BANNER.format(n=n, total=total, what=what)


def _fmt(value: float | None, digits: int = 2) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.{digits}f}"


def experience_summary(frames: Frames, counted: set[str]) -> dict | None:
    r = frames.responses
    r = r[(r["instrument"] == experience_q.INSTRUMENT_ID) & r["participant"].isin(counted)]
    if r.empty:
        return None
    summaries, invalid = [], 0
    for _, g in r.groupby("participant"):
        answers = {
            item: (text if isinstance(text, str) and text else value)
            for item, value, text in zip(g["item"], g["value"], g["text"], strict=True)
        }
        answers = {
            k: int(v) if isinstance(v, float) and v.is_integer() else v for k, v in answers.items()
        }
        try:
            summaries.append(experience_q.summarise(answers))
        except ValueError:
            invalid += 1
    if not summaries:
        return None
    ages = [s["age"] for s in summaries if s["age"] is not None]
    hands: dict[str, int] = {}
    for s in summaries:
        key = s["handedness"] or "not given"
        hands[key] = hands.get(key, 0) + 1
    return {
        "n": len(summaries),
        "invalid": invalid,
        "age": (
            f"{sum(ages) / len(ages):.1f} (range {min(ages)}-{max(ages)}, n = {len(ages)})"
            if ages
            else "not given"
        ),
        "handedness": ", ".join(f"{k} {v}" for k, v in sorted(hands.items())),
        "experienced": {
            d: sum(bool(s[f"experienced_{d}"]) for s in summaries)
            for d in experience_q.EXPERIENCE_DOMAINS
        },
        "any_experience": sum(bool(s["any_experience"]) for s in summaries),
        "experience_mean": sum(s["experience_mean"] for s in summaries) / len(summaries),
    }


def pair_rows(pairs: list[dict], alpha: float) -> list[dict]:
    return [
        {
            "pair": f"{p['a']} - {p['b']}",
            "diff": _fmt(p["diff"], 3),
            "t": _fmt(p["t"]),
            "df": _fmt(p["df"], 0) if float(p["df"]).is_integer() else _fmt(p["df"]),
            "p": format_p(p["p"], alpha=alpha),
            "ci": f"[{_fmt(p['ci_low'], 3)}, {_fmt(p['ci_high'], 3)}]",
            "significant": p["significant"],
        }
        for p in pairs
    ]


def descriptive_rows(result: dict) -> list[dict]:
    return [
        {
            "level": level,
            "mean": _fmt(d["mean"], 3),
            "sd": _fmt(d["sd"], 3),
            "se": _fmt(d["se"], 3),
            "n": d["n"],
        }
        for level, d in result["descriptives"].items()
    ]


__all__ = [
    "GLOSSARY",
    "descriptive_rows",
    "experience_summary",
    "pair_rows",
    "SYNTHETIC_BANNER",
    "SYNTHETIC_KINDS",
    "constant_levels",
    "synthetic_banner",
    "table_one",
    "without_constant_levels",
]
