"""``asa export --aligned``: the lab's streams, the ticks and the events of a study on the
session's clock (:func:`analysis.data.streams.align`), one CSV each, in ``<out>/aligned``.

Files: ``ticks.csv`` (trial_id, tick, t, session_clock_s), ``events.csv`` (the event table's
rows of trials with ticks, with session_clock_s), ``offsets.csv`` (the fitted clock offset
of every stream segment), and per stream ``stream-<id>-<name>.csv`` (segment, timestamp,
session_clock_s, trial_id, trial_t_s, one column per channel).
"""

from __future__ import annotations

import re
from pathlib import Path

from study.data.paths import refuse_existing


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "stream"


def export_aligned(db: str | Path, out: str | Path, *, force: bool = False) -> dict[str, int]:
    """Write the aligned CSV files into ``<out>/aligned``; returns file name -> rows.

    Raises ``ValueError`` for an existing file without ``force`` (nothing is written) or a
    study without LSL clocks (no tick stores one: no session ran with LSL).
    """
    from analysis.data import load_study
    from analysis.data.streams import align

    data = load_study(db)
    aligned = align(data.tables)
    if aligned.ticks.empty and not aligned.streams:
        raise ValueError(
            f"{db}: no tick has an LSL clock and no stream was recorded or imported; run the "
            "sessions with LSL ([lsl] in the protocol or asa run --lsl) or asa xdf import"
        )
    folder = Path(out) / "aligned"
    streams = data.tables.get("lsl_stream")
    frames = {
        "ticks.csv": aligned.ticks,
        "events.csv": aligned.events,
        "offsets.csv": aligned.offsets,
    }
    for sid, frame in aligned.streams.items():
        name = streams.loc[streams["id"] == sid, "name"].iloc[0] if streams is not None else ""
        frames[f"stream-{sid}-{_safe(str(name))}.csv"] = frame
    refuse_existing([folder / name for name in frames], force=force)
    folder.mkdir(parents=True, exist_ok=True)
    for name, frame in frames.items():
        frame.to_csv(folder / name, index=False)
    return {name: len(frame) for name, frame in frames.items()}
