"""In-the-loop recognition described per mode (thesis Sec. 7.2.2, 7.4; issue 16).

Only modes with task recognition have the measurement, so it is described, never tested:
per mode the labelled ticks (a synthetic driver reported its true task) and the shares of
them whose recognised task type matches the true one, whose task and target both match,
and that recognised nothing (null). Each share is given pooled over the mode's labelled
ticks, and as mean and SD (ddof = 1) over its trials; the same pooled shares per true task
type. The counts are those of :attr:`analysis.data.Frames.recognition`.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from analysis.data import Frames
from analysis.data.recognition import COUNTS, SHARES, per_trial

SHARE_LABELS: dict[str, str] = {
    "loop_task_match": "task match",
    "loop_task_target_match": "task + target match",
    "loop_null_rate": "null rate",
}


def _number(value: Any) -> float | None:
    """A plain float, or None for NaN (JSON has no NaN)."""
    value = float(value)
    return value if math.isfinite(value) else None


def _pooled(counts: pd.DataFrame) -> dict[str, Any]:
    """The summed counts of ``counts`` and their shares of the labelled ticks."""
    total = {c: int(counts[c].sum()) for c in COUNTS}
    n = total["labelled_ticks"]
    return {**total, **{s: (total[c] / n if n else None) for s, c in SHARES.items()}}


def describe(frames: Frames) -> dict[str, dict[str, Any]]:
    """The recognition of every mode with recognition data.

    Parameters
    ----------
    frames : the study's tidy frames.

    Returns
    -------
    dict
        Mode -> {``trials``, ``participants``, the four counts of
        :data:`analysis.data.recognition.COUNTS` and the three shares of
        :data:`analysis.data.recognition.SHARES` pooled over the mode's labelled ticks,
        ``per_trial`` {share -> {``mean``, ``sd``, ``n``} over trials}, ``per_task``
        {true task type -> counts and pooled shares}, ``sources`` {"outcome" | "samples" ->
        trials}}; modes in :attr:`Frames.modes` order, modes without data left out. JSON-safe
        (None where a share or SD is undefined).
    """
    rec = frames.recognition
    out: dict[str, dict[str, Any]] = {}
    for mode in frames.modes:
        counts = rec[rec["mode"] == mode]
        if counts.empty:
            continue
        trials = per_trial(counts)
        out[mode] = {
            "trials": len(trials),
            "participants": int(counts["participant"].nunique()),
            **_pooled(counts),
            "per_trial": {
                s: {
                    "mean": _number(trials[s].mean()),
                    "sd": _number(trials[s].std(ddof=1)),
                    "n": int(trials[s].notna().sum()),
                }
                for s in SHARES
            },
            "per_task": {str(task): _pooled(g) for task, g in counts.groupby("task", sort=True)},
            "sources": {str(k): int(v) for k, v in trials["source"].value_counts().items()},
        }
    return out


def recognition_tables(described: dict[str, dict[str, Any]]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``tables/recognition.csv`` and ``tables/recognition_per_task.csv``.

    Parameters
    ----------
    described : the object of :func:`describe`.

    Returns
    -------
    (per_mode, per_task) : pandas.DataFrame
        ``per_mode``: one row per mode: ``mode``, ``trials``, ``participants``, the counts,
        the pooled shares, ``<share>_trial_mean``, ``<share>_trial_sd``,
        ``trials_from_outcome`` and ``trials_from_samples``. ``per_task``: one row per mode
        and true task type: ``mode``, ``task``, the counts and the pooled shares.
    """
    modes, tasks = [], []
    for mode, d in described.items():
        row = {"mode": mode, "trials": d["trials"], "participants": d["participants"]}
        row.update({k: d[k] for k in (*COUNTS, *SHARES)})
        for s, stats in d["per_trial"].items():
            row[f"{s}_trial_mean"] = stats["mean"]
            row[f"{s}_trial_sd"] = stats["sd"]
        row["trials_from_outcome"] = d["sources"].get("outcome", 0)
        row["trials_from_samples"] = d["sources"].get("samples", 0)
        modes.append(row)
        tasks += [{"mode": mode, "task": task, **c} for task, c in d["per_task"].items()]
    per_mode_cols = ["mode", "trials", "participants", *COUNTS, *SHARES]
    per_mode_cols += [f"{s}_trial_{k}" for s in SHARES for k in ("mean", "sd")]
    per_mode_cols += ["trials_from_outcome", "trials_from_samples"]
    return (
        pd.DataFrame(modes, columns=per_mode_cols),
        pd.DataFrame(tasks, columns=["mode", "task", *COUNTS, *SHARES]),
    )


def _share(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def _mean_sd(stats: dict[str, Any]) -> str:
    if stats["mean"] is None:
        return "n/a"
    sd = "n/a" if stats["sd"] is None else f"{stats['sd']:.3f}"
    return f"{stats['mean']:.3f} \u00b1 {sd}"


def html_rows(described: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The report template's values: per mode its formatted figures and task rows.

    Returns
    -------
    list of dict
        Per mode: ``mode``, ``trials``, ``participants``, ``labelled``, ``from_samples``
        (trials re-derived from the samples), ``cells`` [(pooled, "mean +- sd")] in
        :data:`SHARE_LABELS` order, and ``tasks`` [{``task``, ``labelled``, ``shares``}].
    """
    rows = []
    for mode, d in described.items():
        rows.append(
            {
                "mode": mode,
                "trials": d["trials"],
                "participants": d["participants"],
                "labelled": d["labelled_ticks"],
                "from_samples": d["sources"].get("samples", 0),
                "cells": [(_share(d[s]), _mean_sd(d["per_trial"][s])) for s in SHARE_LABELS],
                "tasks": [
                    {
                        "task": task,
                        "labelled": c["labelled_ticks"],
                        "shares": [_share(c[s]) for s in SHARE_LABELS],
                    }
                    for task, c in d["per_task"].items()
                ],
            }
        )
    return rows


__all__ = ["SHARE_LABELS", "describe", "html_rows", "recognition_tables"]
