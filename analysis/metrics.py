"""The metric table of the study report: what each per-trial metric is, and its long frame.

Thesis Sec. 7.6.2 (Figs. 7.50-7.52): primary-task completion time, collisions and score;
secondary-task answer time and errors with the baseline as a fourth level; the NASA-TLX.
Sec. 7.5 (Fig. 7.44, Table 7.10): clearance to obstacles. The assistance and recognition
metrics describe the modes themselves (spec section 7, issue 7); the recognition metric is
descriptive only (:attr:`Metric.descriptive`, :mod:`analysis.recognition`).

Each :class:`Metric` names a column of :attr:`analysis.data.Frames.trials`; its names match
``study.engine.protocol.METRICS`` where the protocol knows the metric (``score_s``, ``tlx_raw``...),
so the protocol's ``[analysis] metrics`` pick from this table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.data import BASELINE, Frames, secondary_metrics
from questionnaires import nasa_tlx


@dataclass(frozen=True, slots=True)
class Metric:
    """One per-trial metric.

    Attributes
    ----------
    name : column of the trial frame (and key of results.json).
    label : axis label with unit.
    group : "primary", "clearance", "assistance", "secondary", "workload" or "recognition".
    baseline : a secondary-task metric: the baseline block is a further level.
    lower_is_better : direction of a good result, None when neither.
    description : one sentence for the report.
    descriptive : described per mode, never tested: no repeated-measures ANOVA (the
        recognition metric exists for the modes with task recognition only, one level).
    zero_in : levels in which the metric is 0 by construction (no assistance in manual
        control): described in Table 1, left out of the test.
    """

    name: str
    label: str
    group: str
    baseline: bool = False
    lower_is_better: bool | None = True
    description: str = ""
    descriptive: bool = False
    zero_in: tuple[str, ...] = ()


_TLX_SUBSCALES = tuple(
    Metric(
        f"tlx_{s.id}",
        f"TLX {s.title} (0-100)",
        "workload",
        description=f"NASA-TLX rating of {s.title.lower()} (0 = {s.low}, 100 = {s.high}).",
    )
    for s in nasa_tlx.SUBSCALES
)

METRICS: tuple[Metric, ...] = (
    Metric(
        "completion_time_s",
        "Completion time [s]",
        "primary",
        description="Time from the start to the return to A (thesis Fig. 7.50a).",
    ),
    Metric(
        "collisions",
        "Collisions [count]",
        "primary",
        description="Debounced contact episodes during the trial (Fig. 7.50b).",
    ),
    Metric(
        "score_s",
        "Score [s]",
        "primary",
        description="Completion time plus the protocol's penalty per collision (Fig. 7.50c).",
    ),
    Metric(
        "path_length_m",
        "Path length [m]",
        "primary",
        description="Distance driven by the robot.",
    ),
    Metric(
        "clearance_mean_m",
        "Mean clearance [m]",
        "clearance",
        lower_is_better=False,
        description="Mean over ticks of the distance to the nearest obstacle.",
    ),
    Metric(
        "clearance_std_m",
        "SD of clearance [m]",
        "clearance",
        lower_is_better=None,
        description="Standard deviation over the trial's samples of the clearance.",
    ),
    Metric(
        "clearance_min_m",
        "Minimum clearance [m]",
        "clearance",
        lower_is_better=False,
        description="Smallest distance to an obstacle in the trial (Sec. 7.5, Table 7.10).",
    ),
    Metric(
        "assist_share",
        "Share of time assisted",
        "assistance",
        lower_is_better=None,
        description="Share of ticks with assistance weight beta > 0.05.",
        zero_in=("manual",),
    ),
    Metric(
        "beta_mean",
        "Mean beta",
        "assistance",
        lower_is_better=None,
        description="Mean assistance weight beta over the trial's ticks.",
        zero_in=("manual",),
    ),
    Metric(
        "secondary_answer_time_s",
        "Answer time [s]",
        "secondary",
        baseline=True,
        description="Mean time to answer a question, answered questions only (Fig. 7.51a).",
    ),
    Metric(
        "secondary_errors",
        "Errors [count]",
        "secondary",
        baseline=True,
        description="Questions answered wrongly or not at all (Fig. 7.51b).",
    ),
    Metric(
        "secondary_misses",
        "Unanswered questions [count]",
        "secondary",
        baseline=True,
        description="Questions left unanswered (timed out or the trial ended).",
    ),
    Metric(
        "secondary_error_rate",
        "Error rate",
        "secondary",
        baseline=True,
        description="Errors divided by the questions shown.",
    ),
    Metric(
        "tlx_raw",
        "NASA-TLX raw (0-100)",
        "workload",
        description="Unweighted mean of the six NASA-TLX ratings (Fig. 7.52).",
    ),
    Metric(
        "tlx_weighted",
        "NASA-TLX weighted (0-100)",
        "workload",
        description="NASA-TLX weighted by the 15 pairwise comparisons.",
    ),
    *_TLX_SUBSCALES,
    Metric(
        "recognition_accuracy",
        "Recognition accuracy",
        "recognition",
        lower_is_better=False,
        description=(
            "Synthetic participants: share of labelled ticks whose recognised task and "
            "target equal the true intention (described in 'Recognition in the loop')."
        ),
        descriptive=True,
    ),
)
BY_NAME: dict[str, Metric] = {m.name: m for m in METRICS}


def ordered_metrics(planned: tuple[str, ...]) -> tuple[Metric, ...]:
    """The protocol's planned metrics first (in its order), then the rest of the table
    (descriptive metrics included: the caller leaves them out of the tests)."""
    first = [BY_NAME[n] for n in planned if n in BY_NAME]
    return tuple(first + [m for m in METRICS if m not in first])


def _baseline_values(frames: Frames, metric: str) -> pd.DataFrame:
    q = frames.questions[frames.questions["mode"] == BASELINE]
    if q.empty:
        return pd.DataFrame(columns=["participant", "mode", "position", "value"])
    values = secondary_metrics(q, "participant")
    return pd.DataFrame(
        {
            "participant": values["participant"].astype(str),
            "mode": BASELINE,
            "position": -1,
            "value": values[metric].to_numpy(dtype=float),
        }
    )


def long_frame(frames: Frames, metric: Metric | str, *, baseline: bool = True) -> pd.DataFrame:
    """The long frame ``analysis.stats.analyse`` takes for one metric.

    Parameters
    ----------
    frames : the study's tidy frames.
    metric : a :class:`Metric` or its name.
    baseline : add the baseline level for a secondary-task metric (the protocol's
        ``secondary_baseline_level``).

    Returns
    -------
    pandas.DataFrame
        Columns ``participant``, ``mode``, ``position`` (-1 for the baseline) and ``value``
        (float, NaN where missing), one row per counted main trial (and baseline block),
        modes in :attr:`Frames.modes` order then the baseline; levels with no value at
        all are left out.
    """
    m = BY_NAME[metric] if isinstance(metric, str) else metric
    t = frames.trials
    out = pd.DataFrame(
        {
            "participant": t["participant"].astype(str),
            "mode": t["mode"],
            "position": t["position"].astype(int),
            "value": t[m.name].astype(float) if m.name in t else np.nan,
        }
    )
    levels = list(frames.modes)
    if m.baseline and baseline:
        base = _baseline_values(frames, m.name)
        if len(base):
            base = base[base["participant"].isin(set(out["participant"]))]
            out = pd.concat([out, base], ignore_index=True)
            levels.append(BASELINE)
    has = out.groupby("mode")["value"].apply(lambda v: v.notna().any())
    levels = [lv for lv in levels if bool(has.get(lv, False))]
    out = out[out["mode"].isin(levels)]
    rank = {lv: i for i, lv in enumerate(levels)}
    out = out.assign(_r=out["mode"].map(rank)).sort_values(["_r", "participant"], kind="stable")
    return out.drop(columns="_r").reset_index(drop=True)
