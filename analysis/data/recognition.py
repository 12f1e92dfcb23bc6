"""In-the-loop recognition counts per counted trial and true task type (thesis Sec. 7.2.2,
7.4; issue 16).

A tick is *labelled* when the synthetic driver reported the task it was executing (sample
``true_task`` not empty). Of the labelled ticks, the recognised task type (the tick's label
translated by the trial's stored ``label_tasks``) matches the true task, or matches it and
the recognised target matches the true target, or is null (no label, or a label that names
no task type). The session engine stores these counts in ``trial.outcome["recognition"]``;
for a trial written before it did, they are re-derived here from the samples and the
trial's ``label_tasks`` (whatever the labels are: primitive ids or task types).

The assistance measures of issue 40 (assist precision and coverage, confident-wrong time,
the deciles of each trial's labelled time; definitions in ``study.engine.recognition`` and
docs/decisions.md) come from the stored ``outcome["recognition"]["assist"]`` and
``["deciles"]`` when the trial stored them, else from the samples (their blend weight
``beta`` and simulated time ``t``) of trials with ``label_tasks``, else they are missing.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import pandas as pd

COUNTS: tuple[str, ...] = ("labelled_ticks", "task_matches", "task_target_matches", "null_ticks")
# share of the labelled ticks -> the count it is made of
SHARES: dict[str, str] = {
    "loop_task_match": "task_matches",
    "loop_task_target_match": "task_target_matches",
    "loop_null_rate": "null_ticks",
}
COLUMNS: tuple[str, ...] = ("trial_id", "task", *COUNTS, "source")

# as study.engine.recognition (the session engine's tally), which analysis may not import
CONFIDENT_BETA = 0.5  # a blend weight at or above this is assistance the driver feels
DECILES = 10
# per (trial, true task): of its labelled ticks, those assisted (beta >= CONFIDENT_BETA),
# assisted with the right task and target, assisted on a wrong target
TASK_ASSIST: tuple[str, ...] = ("assist_ticks", "assist_correct_ticks", "confident_wrong_ticks")
# per trial: every tick scored with its blend weight (counts, then seconds)
TRIAL_ASSIST: tuple[str, ...] = (
    "ticks",
    "assist_labelled_ticks",
    "assist_all_ticks",
    "assist_correct_ticks",
    "assist_unlabelled_ticks",
    "assist_covered_ticks",
    "confident_wrong_ticks",
    "seconds",
    "confident_wrong_s",
    "confident_wrong_longest_s",
)
# per (trial, decile of its labelled ticks in time order)
DECILE_COUNTS: tuple[str, ...] = (
    "labelled_ticks",
    "task_matches",
    "task_target_matches",
    "assist_ticks",
)


def recognition_counts(
    trial_ids: Iterable[int],
    outcomes: Iterable[Any],
    samples: pd.DataFrame,
    *,
    source: str = "study",
) -> pd.DataFrame:
    """The recognition counts of each trial that has them, per true task type.

    Parameters
    ----------
    trial_ids : the trials' ids.
    outcomes : their stored outcomes (dict or None), in the same order.
    samples : the sample table (at least ``trial_id``, ``label``, ``target``,
        ``true_task``, ``true_target``); only the rows of trials without a stored
        ``recognition`` entry but with ``label_tasks`` are used.
    source : the database or folder read, named in errors.

    Returns
    -------
    pandas.DataFrame
        :data:`COLUMNS`: one row per (trial, true task type) with at least one labelled
        tick; ``source`` is ``"outcome"`` (stored by the session engine) or ``"samples"``
        (re-derived). Trials of modes without task recognition (no ``label_tasks``) and
        trials without a true intention (human participants) have no rows.

    Raises
    ------
    ValueError
        A stored ``recognition`` entry without integer counts per task (naming ``source``
        and the trial).
    """
    stored: list[dict[str, Any]] = []
    fallback: dict[int, dict[str, str]] = {}
    for tid, outcome in zip(trial_ids, outcomes, strict=True):
        o = outcome if isinstance(outcome, dict) else {}
        if isinstance(o.get("recognition"), dict):
            stored += _stored_rows(int(tid), o["recognition"], source)
        elif isinstance(o.get("label_tasks"), dict):
            fallback[int(tid)] = {str(k): str(v) for k, v in o["label_tasks"].items()}
    frames = [pd.DataFrame(stored, columns=list(COLUMNS)), sample_counts(samples, fallback)]
    frames = [f for f in frames if len(f)]
    if not frames:
        return _empty()
    out = pd.concat(frames, ignore_index=True)
    out = out[out["labelled_ticks"] > 0]
    out = out.astype({c: int for c in ("trial_id", *COUNTS)})
    return out.sort_values(["trial_id", "task"], kind="stable").reset_index(drop=True)


def _empty() -> pd.DataFrame:
    text = ("task", "source")
    return pd.DataFrame({c: pd.Series(dtype=object if c in text else int) for c in COLUMNS})


def _stored_rows(
    trial_id: int, recognition: Mapping[str, Any], source: str
) -> list[dict[str, Any]]:
    """The rows of one trial's ``outcome["recognition"]`` (its ``per_task`` counts)."""
    where = f"{source}: trial {trial_id}"
    per_task = recognition.get("per_task")
    if not isinstance(per_task, dict):
        raise ValueError(
            f"{where}: field 'outcome.recognition.per_task' is missing or not an object"
        )
    rows = []
    for task, counts in per_task.items():
        values = [counts.get(k) if isinstance(counts, dict) else None for k in COUNTS]
        if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in values):
            raise ValueError(
                f"{where}: field 'outcome.recognition.per_task.{task}' must hold "
                f"the counts {', '.join(COUNTS)} as integers >= 0"
            )
        row = {"trial_id": trial_id, "task": str(task)}
        row.update(zip(COUNTS, values, strict=True))
        rows.append({**row, "source": "outcome"})
    return rows


def sample_counts(
    samples: pd.DataFrame, label_tasks: Mapping[int, Mapping[str, str]]
) -> pd.DataFrame:
    """The recognition counts re-derived from the samples of the trials in ``label_tasks``.

    Parameters
    ----------
    samples : the sample table (``trial_id``, ``label``, ``target``, ``true_task``,
        ``true_target``; text columns with "" for none).
    label_tasks : trial id -> that trial's {label -> task type}; a label not in it, and
        the empty label, recognise nothing (a null tick).

    Returns
    -------
    pandas.DataFrame
        :data:`COLUMNS` with ``source`` ``"samples"``, one row per (trial, true task) with
        at least one labelled tick.
    """
    s = samples[samples["trial_id"].isin(list(label_tasks)) & (samples["true_task"] != "")]
    if s.empty:
        return _empty()
    task = pd.Series("", index=s.index, dtype=object)
    for tid, table in label_tasks.items():
        rows = s["trial_id"] == tid
        task[rows] = s.loc[rows, "label"].map(dict(table)).fillna("")
    null = (task == "").to_numpy()
    same = ~null & (task == s["true_task"]).to_numpy()
    both = same & (s["target"] == s["true_target"]).to_numpy()
    work = pd.DataFrame(
        {
            "trial_id": s["trial_id"].astype(int).to_numpy(),
            "task": s["true_task"].astype(str).to_numpy(),
            "labelled_ticks": np.ones(len(s), dtype=int),
            "task_matches": same.astype(int),
            "task_target_matches": both.astype(int),
            "null_ticks": null.astype(int),
        }
    )
    out = work.groupby(["trial_id", "task"], as_index=False, sort=True)[list(COUNTS)].sum()
    return out.assign(source="samples")[list(COLUMNS)]


def shares(counts: pd.DataFrame) -> pd.DataFrame:
    """:data:`SHARES` of count rows: each count over ``labelled_ticks`` (NaN without any).

    Parameters
    ----------
    counts : rows with the :data:`COUNTS` columns (any other columns kept).

    Returns
    -------
    pandas.DataFrame
        ``counts`` with the three share columns added (floats in [0, 1]).
    """
    n = counts["labelled_ticks"].astype(float)
    n = n.where(n > 0)
    return counts.assign(**{share: counts[count] / n for share, count in SHARES.items()})


def per_trial(counts: pd.DataFrame) -> pd.DataFrame:
    """The counts of :func:`recognition_counts` summed over task types, with their shares.

    Returns
    -------
    pandas.DataFrame
        One row per trial: ``trial_id``, :data:`COUNTS`, :data:`SHARES`, ``source``.
    """
    if counts.empty:
        return shares(counts.drop(columns="task"))
    summed = counts.groupby("trial_id", as_index=False, sort=True).agg(
        **{c: (c, "sum") for c in COUNTS}, source=("source", "first")
    )
    return shares(summed)
