"""The assistance measures of the in-the-loop recognition per counted trial (issue 40): per
trial the ticks assisted with blend weight ``beta >= CONFIDENT_BETA`` and how many of them
assisted the driver's true task and target, the confident-wrong seconds and the longest
episode; per decile of the trial's labelled ticks (in time order) the task and task +
target matches and the assisted ticks; per true task type its assisted ticks.

Read from the trial's stored ``outcome["recognition"]`` (keys ``assist``, ``deciles`` and
the per-task counts) when the session engine stored them, else re-derived from the
trial's samples (``tick``, ``t``, ``beta``, ``label``, ``target``, ``true_task``,
``true_target``) and its ``label_tasks``; the definitions are those of
``study.engine.recognition`` (docs/decisions.md, "Recognition measures").
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from analysis.data.recognition import (
    CONFIDENT_BETA,
    DECILE_COUNTS,
    DECILES,
    TASK_ASSIST,
    TRIAL_ASSIST,
)

_FLOATS = ("seconds", "confident_wrong_s", "confident_wrong_longest_s")


@dataclass(frozen=True, slots=True)
class Assistance:
    """The assistance frames of counted trials.

    Attributes
    ----------
    per_task : ``trial_id``, ``task`` and :data:`TASK_ASSIST` (of that true task's
        labelled ticks).
    per_trial : ``trial_id``, :data:`TRIAL_ASSIST` (counts, and seconds of simulated time)
        and ``source`` ("outcome" or "samples").
    deciles : ``trial_id``, ``decile`` (0-9) and :data:`DECILE_COUNTS`.
    """

    per_task: pd.DataFrame
    per_trial: pd.DataFrame
    deciles: pd.DataFrame


def empty_assistance() -> Assistance:
    """Frames without rows, with their columns."""
    return Assistance(
        pd.DataFrame(columns=["trial_id", "task", *TASK_ASSIST]),
        pd.DataFrame(columns=["trial_id", *TRIAL_ASSIST, "source"]),
        pd.DataFrame(columns=["trial_id", "decile", *DECILE_COUNTS]),
    )


def assistance(
    trial_ids: Iterable[int],
    outcomes: Iterable[Any],
    samples: pd.DataFrame,
    *,
    source: str = "study",
) -> Assistance:
    """The assistance frames of every trial that has the measures.

    Parameters
    ----------
    trial_ids : the trials' ids.
    outcomes : their stored outcomes (dict or None), in the same order.
    samples : the sample table; the rows of trials with ``label_tasks`` whose outcome
        has no stored assistance measures are used.
    source : the database or folder read, named in errors.

    Returns
    -------
    Assistance
        Trials of modes without task recognition, and trials whose driver never reported
        an intention (human participants), have no rows.

    Raises
    ------
    ValueError
        A stored ``assist`` entry with a count that is not a number >= 0 (naming
        ``source``, the trial and the field).
    """
    per_task: list[dict] = []
    per_trial: list[dict] = []
    deciles: list[dict] = []
    derive: dict[int, dict[str, str]] = {}
    for tid, outcome in zip(trial_ids, outcomes, strict=True):
        o = outcome if isinstance(outcome, dict) else {}
        rec = o.get("recognition")
        tid = int(tid)
        if isinstance(rec, dict) and _stored(rec):
            _check(rec["assist"], f"{source}: trial {tid}")
            _from_outcome(tid, rec, per_task, per_trial, deciles)
        elif isinstance(o.get("label_tasks"), dict):
            derive[tid] = {str(k): str(v) for k, v in o["label_tasks"].items()}
    for tid, s in samples[samples["trial_id"].isin(list(derive))].groupby("trial_id"):
        _from_samples(
            int(tid), s.sort_values("tick"), derive[int(tid)], per_task, per_trial, deciles
        )
    if not per_trial:
        return empty_assistance()
    return Assistance(
        pd.DataFrame(per_task, columns=["trial_id", "task", *TASK_ASSIST]),
        pd.DataFrame(per_trial, columns=["trial_id", *TRIAL_ASSIST, "source"]),
        pd.DataFrame(deciles, columns=["trial_id", "decile", *DECILE_COUNTS]),
    )


def _stored(rec: Mapping[str, Any]) -> bool:
    """Whether a stored recognition carries the assistance measures (issue 40 on)."""
    assist = rec.get("assist")
    return isinstance(assist, dict) and bool(assist.get("ticks"))


def _check(assist: Mapping[str, Any], where: str) -> None:
    for key in TRIAL_ASSIST:
        v = assist.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not v >= 0:
            raise ValueError(
                f"{where}: field 'outcome.recognition.assist.{key}' must be a number >= 0, "
                f"got {v!r}"
            )


def _from_outcome(
    tid: int, rec: Mapping[str, Any], per_task: list, per_trial: list, deciles: list
) -> None:
    """The rows of one trial's stored recognition."""
    assist = rec["assist"]
    per_trial.append(
        {"trial_id": tid, **{k: assist.get(k, 0) for k in TRIAL_ASSIST}, "source": "outcome"}
    )
    for task, c in (rec.get("per_task") or {}).items():
        per_task.append(
            {"trial_id": tid, "task": str(task), **{k: c.get(k, 0) for k in TASK_ASSIST}}
        )
    for d, row in enumerate(rec.get("deciles") or ()):
        deciles.append({"trial_id": tid, "decile": d, **{k: row.get(k, 0) for k in DECILE_COUNTS}})


def _from_samples(
    tid: int,
    s: pd.DataFrame,
    label_tasks: Mapping[str, str],
    per_task: list,
    per_trial: list,
    deciles: list,
) -> None:
    """The rows of one trial re-derived from its samples ``s`` (in tick order), as the
    session engine's tally scores its ticks."""
    task = s["label"].map(dict(label_tasks)).fillna("").to_numpy(dtype=object)
    true_task = s["true_task"].to_numpy(dtype=object)
    wrong_target = (s["target"] != s["true_target"]).to_numpy()
    labelled = true_task != ""
    same = (task != "") & (task == true_task)
    both = same & ~wrong_target
    assisted = s["beta"].to_numpy(dtype=float) >= CONFIDENT_BETA
    wrong = assisted & wrong_target
    t = s["t"].to_numpy(dtype=float)
    dt = np.diff(t, prepend=0.0)  # [s] the first tick ends at t = dt
    runs = np.cumsum(~wrong)  # one run id per episode of consecutive wrong ticks
    longest = pd.Series(dt[wrong]).groupby(runs[wrong]).sum().max() if wrong.any() else 0.0
    per_trial.append(
        {
            "trial_id": tid,
            "ticks": len(s),
            "assist_labelled_ticks": int(labelled.sum()),
            "assist_all_ticks": int(assisted.sum()),
            "assist_correct_ticks": int((assisted & both & labelled).sum()),
            "assist_unlabelled_ticks": int((assisted & ~labelled).sum()),
            "assist_covered_ticks": int((assisted & labelled).sum()),
            "confident_wrong_ticks": int(wrong.sum()),
            "seconds": round(float(dt.sum()), 6),  # as the tally stores them
            "confident_wrong_s": round(float(dt[wrong].sum()), 6),
            "confident_wrong_longest_s": round(float(longest), 6),
            "source": "samples",
        }
    )
    for name in sorted(set(true_task[labelled])):
        rows = true_task == name
        per_task.append(
            {
                "trial_id": tid,
                "task": str(name),
                "assist_ticks": int((rows & assisted).sum()),
                "assist_correct_ticks": int((rows & assisted & both).sum()),
                "confident_wrong_ticks": int((rows & wrong).sum()),
            }
        )
    n = int(labelled.sum())
    part = DECILES * np.arange(n) // max(n, 1)  # labelled tick k of n in part 10 k / n
    for d in range(DECILES):
        at = part == d
        deciles.append(
            {
                "trial_id": tid,
                "decile": d,
                "labelled_ticks": int(at.sum()),
                "task_matches": int(same[labelled][at].sum()),
                "task_target_matches": int(both[labelled][at].sum()),
                "assist_ticks": int(assisted[labelled][at].sum()),
            }
        )


def pooled_measures(a: Mapping[str, float]) -> dict[str, float | None]:
    """The assistance measures of summed :data:`TRIAL_ASSIST` counts ``a`` (ratios of the
    pooled counts; None where a denominator is 0), as ``study.engine.recognition``'s
    ``assist_measures`` without its rounding.

    Returns
    -------
    dict
        ``assist_precision`` (right / assisted ticks, an assisted tick without a true task
        counted wrong), ``assist_precision_labelled``, ``assist_coverage`` (assisted /
        labelled ticks), ``assist_unlabelled_ticks``, ``confident_wrong_s_per_min`` [s per
        minute of trial], ``confident_wrong_longest_s`` [s].
    """

    def share(num: float, den: float) -> float | None:
        return float(num / den) if den else None

    labelled_assisted = a["assist_all_ticks"] - a["assist_unlabelled_ticks"]
    return {
        "assist_precision": share(a["assist_correct_ticks"], a["assist_all_ticks"]),
        "assist_precision_labelled": share(a["assist_correct_ticks"], labelled_assisted),
        "assist_coverage": share(a["assist_covered_ticks"], a["assist_labelled_ticks"]),
        "assist_unlabelled_ticks": int(a["assist_unlabelled_ticks"]),
        "confident_wrong_s_per_min": share(60.0 * a["confident_wrong_s"], a["seconds"]),
        "confident_wrong_longest_s": float(a["confident_wrong_longest_s"]),
    }
