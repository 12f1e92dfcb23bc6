"""The report's section on the lab's streams (Lab Streaming Layer, DESIGN.md "The lab's
clock"): per participant and trial, which streams were recorded (or imported from XDF),
their samples in the trial, their gaps and the spread of their clock offsets; and one
recorded channel over a trial with the trial's events marked.

Descriptive only: the streams are the lab's, their analysis is the lab's.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from analysis.data.streams import Aligned, align
from analysis.figures import _figure

COLUMNS = ("participant", "phase", "ordinal", "mode", "trial_id", "stream", "origin",
           "samples", "rate_hz", "gaps", "gap_s", "offset_spread_ms")  # fmt: skip
OFFSET_WINDOW_S = 5.0  # [s] offsets measured this close to a trial count for its spread
MARKED = ("collision", "question_shown", "answer_given", "pause", "resume", "lsl_stream_lost",
          "lsl_stream_found", "region_entry", "region_exit")  # fmt: skip


def _trial_windows(aligned: Aligned) -> pd.DataFrame:
    """Per trial with ticks: its first and last tick's session clock [s]."""
    g = aligned.ticks.groupby("trial_id")["session_clock_s"]
    return pd.DataFrame({"start": g.min(), "end": g.max()})


def stream_table(tables: Mapping[str, pd.DataFrame], aligned: Aligned) -> pd.DataFrame:
    """One row per trial with ticks and stream of its session (see :data:`COLUMNS`)."""
    streams = tables.get("lsl_stream")
    if streams is None or streams.empty or aligned.ticks.empty:
        return pd.DataFrame(columns=list(COLUMNS))
    trials = tables["trial"].set_index("id")
    codes = tables["participant"].set_index("id")["code"]
    windows = _trial_windows(aligned)
    gaps = tables.get("lsl_gap", pd.DataFrame(columns=["stream_id", "start_clock_s",
                                                       "end_clock_s"]))  # fmt: skip
    offsets = tables.get("lsl_offset", pd.DataFrame(columns=["stream_id", "clock_s", "offset_s"]))
    rows = []
    for s in streams.itertuples():
        frame = aligned.streams[int(s.id)]
        for tid, w in windows.iterrows():
            trial = trials.loc[tid]
            if trial["session_id"] != s.session_id:
                continue
            n = int((frame["trial_id"] == tid).sum())
            g = gaps[gaps["stream_id"] == s.id]
            end = g["end_clock_s"].fillna(np.inf).to_numpy(float)
            start = g["start_clock_s"].to_numpy(float)
            inside = (start <= w["end"]) & (end >= w["start"])
            gap_s = np.minimum(end[inside], w["end"]) - np.maximum(start[inside], w["start"])
            # an import's offsets were measured on the recorder's clock: shifted to ours
            at = offsets["clock_s"] + float(s.clock_shift_s or 0.0)
            o = offsets[(offsets["stream_id"] == s.id)
                        & (at >= w["start"] - OFFSET_WINDOW_S)
                        & (at <= w["end"] + OFFSET_WINDOW_S)]  # fmt: skip
            duration = float(w["end"] - w["start"])
            rows.append({
                "participant": codes.get(trial["participant_id"], ""), "phase": trial["phase"],
                "ordinal": int(trial["ordinal"]), "mode": trial["mode"], "trial_id": int(tid),
                "stream": s.name, "origin": s.origin, "samples": n,
                "rate_hz": n / duration if duration > 0 else np.nan,
                "gaps": int(inside.sum()), "gap_s": float(gap_s.sum()),
                "offset_spread_ms": float(np.ptp(o["offset_s"])) * 1e3 if len(o) > 1 else np.nan,
            })  # fmt: skip
    return pd.DataFrame(rows, columns=list(COLUMNS))


def _numeric_channel(frame: pd.DataFrame) -> str | None:
    fixed = {"segment", "timestamp", "session_clock_s", "trial_id", "trial_t_s"}
    for column in frame.columns:
        if column not in fixed and pd.api.types.is_numeric_dtype(frame[column]):
            return str(column)
    return None


def channel_figure(tables: Mapping[str, pd.DataFrame], aligned: Aligned,
                   ) -> tuple[Figure, str] | None:  # fmt: skip
    """The first numeric channel of the first stream over the first main trial it has
    samples in (else any trial), the trial's events as vertical lines; None without."""
    trials = tables["trial"].set_index("id")
    for sid, frame in sorted(aligned.streams.items()):
        channel = _numeric_channel(frame)
        if channel is None:
            continue
        inside = frame[frame["trial_id"] >= 0]
        if inside.empty:
            continue
        main = [t for t in inside["trial_id"].unique() if trials.loc[t, "phase"] == "main"]
        tid = int(main[0] if main else inside["trial_id"].iloc[0])
        data = inside[inside["trial_id"] == tid]
        name = tables["lsl_stream"].set_index("id").loc[sid, "name"]
        fig = _figure(8.0, 3.2, left=0.08, bottom=0.16, top=0.88)
        ax = fig.add_subplot(1, 1, 1)
        ax.plot(data["trial_t_s"], data[channel], lw=0.8, color="#4C72B0")
        events = aligned.events[(aligned.events["trial_id"] == tid)
                                & aligned.events["kind"].isin(MARKED)]  # fmt: skip
        for i, (kind, g) in enumerate(events.groupby("kind")):
            for t in g["t"]:
                ax.axvline(t, color=f"C{(i + 1) % 10}", lw=0.8, ls="--")
            ax.plot([], [], color=f"C{(i + 1) % 10}", ls="--", label=kind)
        if not events.empty:
            ax.legend(loc="upper right", fontsize=7, frameon=False)
        ax.set_xlabel("trial time [s, simulated]")
        ax.set_ylabel(channel)
        trial = trials.loc[tid]
        title = f"{name}: {channel} over {trial['phase']} trial #{int(trial['ordinal'])} (id {tid})"
        ax.set_title(title, fontsize=9)
        return fig, title
    return None


def describe(
    tables: Mapping[str, pd.DataFrame],
) -> tuple[pd.DataFrame, tuple[Figure, str] | None] | None:  # noqa: E501
    """The section's table and figure, or None for a study without the lab's streams."""
    streams = tables.get("lsl_stream")
    if streams is None or streams.empty:
        return None
    aligned = align(tables)
    return stream_table(tables, aligned), channel_figure(tables, aligned)
