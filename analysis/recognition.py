"""In-the-loop recognition described per mode (thesis Sec. 7.2.2, 7.4; issue 16).

Only modes with task recognition have the measurement, so it is described, never tested:
per mode the labelled ticks (a synthetic driver reported its true task) and the shares of
them whose recognised task type matches the true one, whose task and target both match,
and that recognised nothing (null). Each share is given pooled over the mode's labelled
ticks, and as mean and SD (ddof = 1) over its trials; the same pooled shares per true task
type. The counts are those of :attr:`analysis.data.Frames.recognition`.

The assistance the recognition drove (issue 40; :attr:`analysis.data.Frames.assistance`) is
described alike: assist precision (the share of the ticks with blend weight >= 0.5 that
assisted the true task and target, an assisted tick without a true task counted wrong),
assist coverage (the share of labelled ticks assisted so) and confident-wrong time (seconds
of such assistance on a wrong target per minute of trial, and the longest episode), pooled
as ratios of the mode's summed counts and as mean and SD over trials; per true task type;
and task and task + target match per decile of each trial's labelled time.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from analysis.data import Frames
from analysis.data.assistance import pooled_measures
from analysis.data.recognition import (
    COUNTS,
    DECILE_COUNTS,
    DECILES,
    SHARES,
    TASK_ASSIST,
    TRIAL_ASSIST,
    per_trial,
)

SHARE_LABELS: dict[str, str] = {
    "loop_task_match": "task match",
    "loop_task_target_match": "task + target match",
    "loop_null_rate": "null rate",
}
# the assistance measures described per trial too (mean, SD), with their labels
ASSIST_LABELS: dict[str, str] = {
    "assist_precision": "assist precision",
    "assist_coverage": "assist coverage",
    "confident_wrong_s_per_min": "confident-wrong [s/min]",
}
# the assistance measures of the pooled counts (analysis.data.assistance.pooled_measures)
ASSIST_POOLED: tuple[str, ...] = (
    "assist_precision",
    "assist_precision_labelled",
    "assist_coverage",
    "assist_unlabelled_ticks",
    "confident_wrong_s_per_min",
    "confident_wrong_longest_s",
)
# per true task type and per decile: share -> (numerator, denominator)
TASK_ASSIST_SHARES: dict[str, tuple[str, str]] = {
    "assist_coverage": ("assist_ticks", "labelled_ticks"),
    "assist_precision_labelled": ("assist_correct_ticks", "assist_ticks"),
    "confident_wrong_share": ("confident_wrong_ticks", "labelled_ticks"),
}
DECILE_SHARES: dict[str, tuple[str, str]] = {
    "loop_task_match": ("task_matches", "labelled_ticks"),
    "loop_task_target_match": ("task_target_matches", "labelled_ticks"),
    "assist_coverage": ("assist_ticks", "labelled_ticks"),
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


def _ratio(num: float, den: float) -> float | None:
    return float(num / den) if den else None


def _spread(values: pd.Series) -> dict[str, Any]:
    """Mean, SD (ddof = 1) and n of the defined values (JSON-safe: None for NaN)."""
    return {
        "mean": _number(values.mean()),
        "sd": _number(values.std(ddof=1)),
        "n": int(values.notna().sum()),
    }


def _assist(frames: Frames, trial_ids: set[int]) -> dict[str, Any]:
    """The assistance measures of the trials ``trial_ids``: pooled, per trial, per true
    task type and per decile; empty without any trial that has them."""
    a = frames.assistance
    trials = a.per_trial[a.per_trial["trial_id"].isin(trial_ids)]
    if trials.empty:
        return {}
    total = {k: trials[k].astype(float).sum() for k in TRIAL_ASSIST}
    total["confident_wrong_longest_s"] = float(trials["confident_wrong_longest_s"].max())
    each = pd.DataFrame([pooled_measures(r) for r in trials[list(TRIAL_ASSIST)].to_dict("records")])
    tasks = a.per_task[a.per_task["trial_id"].isin(set(trials["trial_id"]))]
    deciles = a.deciles[a.deciles["trial_id"].isin(set(trials["trial_id"]))]
    by_decile = deciles.groupby("decile")[list(DECILE_COUNTS)].sum()
    by_decile = by_decile.reindex(range(DECILES), fill_value=0)
    return {
        "assist_trials": len(trials),
        **pooled_measures(total),
        "confident_wrong_s": float(total["confident_wrong_s"]),
        "assist_per_trial": {m: _spread(each[m].astype(float)) for m in ASSIST_LABELS},
        "assist_per_task": {
            str(t): {k: int(g[k].sum()) for k in TASK_ASSIST}
            for t, g in tasks.groupby("task", sort=True)
        },
        "deciles": [
            {
                **{k: int(row[k]) for k in DECILE_COUNTS},
                **{s: _ratio(row[n], row[d]) for s, (n, d) in DECILE_SHARES.items()},
            }
            for _, row in by_decile.iterrows()
        ],
    }


def _task_rows(counts: pd.DataFrame, assist: dict[str, Any]) -> dict[str, Any]:
    """Per true task type: the pooled counts and shares, and its assistance (None where
    its trials have no assistance measures)."""
    out = {}
    for task, g in counts.groupby("task", sort=True):
        row = _pooled(g)
        c = assist.get("assist_per_task", {}).get(str(task))
        for k in TASK_ASSIST:
            row[k] = None if c is None else c[k]
        for share, (n, d) in TASK_ASSIST_SHARES.items():
            row[share] = None if c is None else _ratio(row[n], row[d])
        out[str(task)] = row
    return out


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
        {true task type -> counts and pooled shares, its assisted counts and the shares of
        :data:`TASK_ASSIST_SHARES`}, ``sources`` {"outcome" | "samples" -> trials}; the
        assistance: ``assist_trials`` (trials with the measures, 0 without), the measures
        of :data:`ASSIST_POOLED` and ``confident_wrong_s`` pooled, ``assist_per_trial``
        {measure of :data:`ASSIST_LABELS` -> mean, sd, n}, ``deciles`` (ten dicts: counts
        and :data:`DECILE_SHARES`)}; modes in :attr:`Frames.modes` order, modes without
        data left out. JSON-safe (None where a share or SD is undefined).
    """
    rec = frames.recognition
    out: dict[str, dict[str, Any]] = {}
    for mode in frames.modes:
        counts = rec[rec["mode"] == mode]
        if counts.empty:
            continue
        trials = per_trial(counts)
        assist = _assist(frames, set(trials["trial_id"].astype(int)))
        out[mode] = {
            "trials": len(trials),
            "participants": int(counts["participant"].nunique()),
            **_pooled(counts),
            "per_trial": {s: _spread(trials[s]) for s in SHARES},
            "per_task": _task_rows(counts, assist),
            "sources": {str(k): int(v) for k, v in trials["source"].value_counts().items()},
            "assist_trials": assist.get("assist_trials", 0),
            **{k: assist.get(k) for k in (*ASSIST_POOLED, "confident_wrong_s")},
            "assist_per_trial": assist.get("assist_per_trial", {}),
            "deciles": assist.get("deciles", []),
        }
    return out


def recognition_tables(
    described: dict[str, dict[str, Any]],
) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """``tables/recognition.csv``, ``tables/recognition_per_task.csv`` and
    ``tables/recognition_deciles.csv``.

    Parameters
    ----------
    described : the object of :func:`describe`.

    Returns
    -------
    (per_mode, per_task, per_decile) : pandas.DataFrame
        ``per_mode``: one row per mode: ``mode``, ``trials``, ``participants``, the counts,
        the pooled shares, ``<share>_trial_mean``, ``<share>_trial_sd``,
        ``trials_from_outcome`` and ``trials_from_samples``, then ``assist_trials``, the
        pooled assistance measures (:data:`ASSIST_POOLED`, ``confident_wrong_s``) and
        ``<measure>_trial_mean`` and ``_trial_sd`` of :data:`ASSIST_LABELS`.
        ``per_task``: one row per mode and true task type: ``mode``, ``task``, the counts
        and the pooled shares, the assisted counts and :data:`TASK_ASSIST_SHARES`.
        ``per_decile``: one row per mode and decile (1-10) of the trials' labelled time:
        ``mode``, ``decile``, the counts and :data:`DECILE_SHARES`.
    """
    modes, tasks, deciles = [], [], []
    for mode, d in described.items():
        row = {"mode": mode, "trials": d["trials"], "participants": d["participants"]}
        row.update({k: d[k] for k in (*COUNTS, *SHARES)})
        for s, stats in d["per_trial"].items():
            row[f"{s}_trial_mean"] = stats["mean"]
            row[f"{s}_trial_sd"] = stats["sd"]
        row["trials_from_outcome"] = d["sources"].get("outcome", 0)
        row["trials_from_samples"] = d["sources"].get("samples", 0)
        row.update({k: d[k] for k in ("assist_trials", *ASSIST_POOLED, "confident_wrong_s")})
        for m in ASSIST_LABELS:
            stats = d["assist_per_trial"].get(m, {})
            row[f"{m}_trial_mean"] = stats.get("mean")
            row[f"{m}_trial_sd"] = stats.get("sd")
        modes.append(row)
        tasks += [{"mode": mode, "task": task, **c} for task, c in d["per_task"].items()]
        deciles += [{"mode": mode, "decile": k + 1, **c} for k, c in enumerate(d["deciles"])]
    per_mode_cols = ["mode", "trials", "participants", *COUNTS, *SHARES]
    per_mode_cols += [f"{s}_trial_{k}" for s in SHARES for k in ("mean", "sd")]
    per_mode_cols += ["trials_from_outcome", "trials_from_samples"]
    per_mode_cols += ["assist_trials", *ASSIST_POOLED, "confident_wrong_s"]
    per_mode_cols += [f"{m}_trial_{k}" for m in ASSIST_LABELS for k in ("mean", "sd")]
    task_cols = ["mode", "task", *COUNTS, *SHARES, *TASK_ASSIST, *TASK_ASSIST_SHARES]
    decile_cols = ["mode", "decile", *DECILE_COUNTS, *DECILE_SHARES]
    return (
        pd.DataFrame(modes, columns=per_mode_cols),
        pd.DataFrame(tasks, columns=task_cols),
        pd.DataFrame(deciles, columns=decile_cols),
    )


def _share(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def _mean_sd(stats: dict[str, Any]) -> str:
    if not stats or stats["mean"] is None:
        return "n/a"
    sd = "n/a" if stats["sd"] is None else f"{stats['sd']:.3f}"
    return f"{stats['mean']:.3f} \u00b1 {sd}"


def _seconds(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"


def _assist_row(d: dict[str, Any]) -> dict[str, Any]:
    """A mode's assistance figures, formatted (``trials`` 0: not measured)."""
    spread = d["assist_per_trial"]
    return {
        "trials": d["assist_trials"],
        "cells": [(_share(d[m]), _mean_sd(spread.get(m, {}))) for m in ASSIST_LABELS],
        "labelled_precision": _share(d["assist_precision_labelled"]),
        "unlabelled": "n/a"
        if d["assist_unlabelled_ticks"] is None
        else d["assist_unlabelled_ticks"],
        "longest": _seconds(d["confident_wrong_longest_s"]),
        "deciles": [[_share(c[s]) for c in d["deciles"]] for s in DECILE_SHARES],
    }


def html_rows(described: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The report template's values: per mode its formatted figures and task rows.

    Returns
    -------
    list of dict
        Per mode: ``mode``, ``trials``, ``participants``, ``labelled``, ``from_samples``
        (trials re-derived from the samples), ``cells`` [(pooled, "mean +- sd")] in
        :data:`SHARE_LABELS` order, ``tasks`` [{``task``, ``labelled``, ``shares``, and
        ``assist`` the shares of :data:`TASK_ASSIST_SHARES`}], and ``assist``: ``trials``,
        ``cells`` [(pooled, "mean +- sd")] in :data:`ASSIST_LABELS` order,
        ``labelled_precision``, ``unlabelled``, ``longest`` and ``deciles`` (one list of
        ten per share of :data:`DECILE_SHARES`).
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
                        "assist": [_share(c[s]) for s in TASK_ASSIST_SHARES],
                    }
                    for task, c in d["per_task"].items()
                ],
                "assist": _assist_row(d),
            }
        )
    return rows


DECILE_LABELS: tuple[str, ...] = tuple(
    SHARE_LABELS[s] if s in SHARE_LABELS else "assist coverage" for s in DECILE_SHARES
)

__all__ = [
    "ASSIST_LABELS",
    "DECILE_LABELS",
    "SHARE_LABELS",
    "describe",
    "html_rows",
    "recognition_tables",
]
