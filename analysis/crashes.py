"""Sec. 7.5's clearance results: Table 7.10 (clearance mean/SD per participant and mode, a
crashed trial 0/0 "due to the crash of the robot, the clearance is assumed to be zero") and
Fig. 7.44b (the clearance distribution per mode over all trials except the crashed ones).

The clearance is the trial outcome's ``lrf_clearance`` (:mod:`tasks.clearance`: the laser's
minimum range from the robot's centre); whether a trial crashed is the trial frame's
``crashed`` column (:mod:`analysis.data.frames`). Shown only for protocols whose main
trials end on a collision (``end_on_collision``), the Sec. 7.5 kind (docs/decisions.md).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

CRASH_NOTE = "Due to the crash of the robot, the clearance is assumed to be zero."


def _outcomes(trial_table: pd.DataFrame) -> dict[int, dict]:
    return {
        int(i): (o if isinstance(o, dict) else {})
        for i, o in zip(trial_table["id"], trial_table["outcome"], strict=True)
    }


def table_7_10(trials: pd.DataFrame, trial_table: pd.DataFrame) -> pd.DataFrame:
    """One row per counted main trial (``trials``: the trial frame, with ``crashed``):
    participant, mode, crashed, mean_m, std_m.

    A crashed trial's mean and SD are 0 (Table 7.10); a trial without ``lrf_clearance``
    (a database from before it was stored) has NaN.
    """
    outcomes = _outcomes(trial_table)
    rows = []
    for pid, mode, tid, crash in zip(
        trials["participant"], trials["mode"], trials["trial_id"], trials["crashed"],
        strict=True,
    ):  # fmt: skip
        lrf = outcomes.get(int(tid), {}).get("lrf_clearance") or {}
        crash = bool(crash)
        mean = 0.0 if crash else _number(lrf.get("mean_m"))
        std = 0.0 if crash else _number(lrf.get("std_m"))
        rows.append({"participant": pid, "mode": mode, "crashed": crash,
                     "mean_m": mean, "std_m": std})  # fmt: skip
    return pd.DataFrame(rows, columns=["participant", "mode", "crashed", "mean_m", "std_m"])


def _number(value: object) -> float:
    return float(value) if isinstance(value, int | float) else math.nan


def html_rows(table: pd.DataFrame, modes: tuple[str, ...]) -> list[dict]:
    """Table 7.10's layout: per participant a "mean/SD" cell per mode, "0/0*" if crashed."""
    out = []
    for pid, g in table.groupby("participant", sort=True):
        cells = []
        for mode in modes:
            r = g[g["mode"] == mode]
            if r.empty:
                cells.append("")
            elif bool(r["crashed"].iloc[-1]):
                cells.append("0/0*")
            else:
                m, s = float(r["mean_m"].iloc[-1]), float(r["std_m"].iloc[-1])
                cells.append("n/a" if math.isnan(m) else f"{m:.3f}/{s:.3f}")
        out.append({"participant": pid, "cells": cells})
    return out


def distribution(
    trials: pd.DataFrame, trial_table: pd.DataFrame, edges: np.ndarray
) -> pd.DataFrame:
    """Tick counts per clearance bin and mode, crashed trials left out (Fig. 7.44b).

    Index: the bins' lower edges [m] (``edges``, the last bin open); one column per mode.
    """
    outcomes = _outcomes(trial_table)
    by_mode: dict[str, np.ndarray] = {}
    for mode, tid, crash in zip(trials["mode"], trials["trial_id"], trials["crashed"],
                                strict=True):  # fmt: skip
        counts = by_mode.setdefault(mode, np.zeros(len(edges)))
        hist = (outcomes.get(int(tid), {}).get("lrf_clearance") or {}).get("histogram")
        if not crash and hist is not None and len(hist) == len(edges):
            counts += np.asarray(hist, dtype=float)
    return pd.DataFrame(by_mode, index=pd.Index(edges, name="bin_low_m"))
