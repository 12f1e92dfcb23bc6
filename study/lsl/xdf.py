"""``asa xdf import``: a LabRecorder XDF file into the study database, aligned with the
trials through this platform's event stream in it (DESIGN.md, "The lab's clock").

The file is read raw (pyxdf, no clock synchronisation, no dejitter): each stream keeps its
own timestamps and clock offsets. The markers of the participant's session, corrected by
their own offsets onto the recorder's clock, are paired with the ticks they were stamped
with (the ``sync`` markers: one per simulated second, stamped with the tick's clock,
which the tick's sample row stores); the median difference is the shift from the
recorder's clock to the session's, stored with every imported stream
(``lsl_stream.clock_shift_s``). The lab's streams are stored from 5 s before the session's
first marker to 5 s after its last; the platform's own two streams are not (the database
has them).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from analysis.data.streams import corrected
from study.data.storage import (
    LslChunk,
    LslOffset,
    LslStream,
    Participant,
    Sample,
    Trial,
    open_database,
    utc_now,
)
from study.lsl import runtime
from study.lsl.outlets import EVENT_NAME, EVENT_TYPE
from study.lsl.recorder import encode, stream_dtype

MARGIN_S = 5.0  # [s] of the lab's streams kept before and after the session's markers
CHUNK = 10_000  # samples per stored chunk
MAX_SPREAD_S = 0.005  # [s] the sync pairs' differences may spread at most this much


@dataclass(frozen=True, slots=True)
class ImportSummary:
    """What :func:`import_xdf` stored."""

    participant: str
    session_id: int
    clock_shift_s: float  # [s] recorder's clock -> session's clock
    pairs: int  # sync markers matched with ticks
    spread_ms: float  # [ms] max - min of the pairs' differences
    streams: tuple[tuple[str, int], ...]  # (name, samples stored)


def _corrected(stream: dict[str, Any]) -> np.ndarray:
    """A stream's timestamps on the recorder's clock (its offsets fitted as pyxdf does)."""
    return corrected(
        stream["time_stamps"], stream.get("clock_times", []), stream.get("clock_values", [])
    )


def _info(stream: dict[str, Any], key: str, default: str = "") -> str:
    value = stream["info"].get(key, [default])
    return str(value[0] if isinstance(value, list) and value else value or default)


def _ours(stream: dict[str, Any]) -> bool:
    return _info(stream, "source_id").startswith("asa-study/")


def _markers(streams: Sequence[dict[str, Any]], xdf: Path) -> list[tuple[float, dict]]:
    """This platform's markers in the file, on the recorder's clock, in time order."""
    out: list[tuple[float, dict]] = []
    for s in streams:
        if _info(s, "name") == EVENT_NAME and _info(s, "type") == EVENT_TYPE and _ours(s):
            for t, sample in zip(_corrected(s), s["time_series"], strict=True):
                try:
                    out.append((float(t), json.loads(sample[0])))
                except (json.JSONDecodeError, TypeError, IndexError):
                    continue
    if not out:
        raise ValueError(
            f"{xdf}: holds no '{EVENT_NAME}' stream of this platform; record the session's "
            "event outlet with LabRecorder (asa run --lsl)"
        )
    return sorted(out, key=lambda m: m[0])


def _participant(markers: list[tuple[float, dict]], wanted: str | None, xdf: Path) -> str:
    codes = sorted({str(m.get("participant")) for _, m in markers if m.get("participant")})
    if wanted is not None:
        if wanted not in codes:
            raise ValueError(
                f"--participant: {wanted} has no markers in {xdf}; it holds "
                f"{', '.join(codes) or 'none'}"
            )
        return wanted
    if len(codes) != 1:
        raise ValueError(f"--participant: {xdf} holds the sessions of {', '.join(codes)}; name one")
    return codes[0]


def _trial_keys(markers: list[tuple[float, dict]]) -> dict[int, tuple[str, int, int]]:
    """Marker trial id -> (phase, ordinal, attempt), from the trial_started markers."""
    keys = {}
    for _, m in markers:
        if m.get("event") == "trial_started" and m.get("trial") is not None:
            keys[int(m["trial"])] = (str(m.get("phase")), int(m["ordinal"]), int(m["attempt"]))
    return keys


def _db_trials(s: Session, code: str, db: str | Path) -> dict[tuple[str, int, int], list[Trial]]:
    person = s.scalars(select(Participant).where(Participant.code == code)).first()
    if person is None:
        raise ValueError(f"--participant: {code} is not a participant of {db}")
    out: dict[tuple[str, int, int], list[Trial]] = {}
    for t in s.scalars(select(Trial).where(Trial.participant_id == person.id).order_by(Trial.id)):
        out.setdefault((t.phase, t.ordinal, t.attempt), []).append(t)
    return out


def _pairs(
    s: Session,
    markers: list[tuple[float, dict]],
    code: str,
    db: str | Path,
) -> tuple[np.ndarray, int]:
    """(session clock - recorder clock) of every sync marker matched with its tick, and
    the session of those ticks."""
    keys = _trial_keys(markers)
    trials = _db_trials(s, code, db)
    diffs: list[float] = []
    sessions: set[int] = set()
    for t, m in markers:
        if m.get("event") != "sync" or m.get("trial") is None or m.get("tick") is None:
            continue
        key = keys.get(int(m["trial"]))
        candidates = trials.get(key, []) if key is not None else []
        # the trial of that id where the ids are the file's own, else the latest of its key
        chosen = next((c for c in candidates if c.id == int(m["trial"])), None)
        chosen = chosen or (candidates[-1] if candidates else None)
        if chosen is None:
            continue
        clock = s.scalar(
            select(Sample.lsl_clock_s).where(
                Sample.trial_id == chosen.id, Sample.tick == int(m["tick"])
            )
        )
        if clock is not None:
            diffs.append(float(clock) - t)
            sessions.add(chosen.session_id)
    if not diffs:
        raise ValueError(
            f"{db}: none of participant {code}'s sync markers matches a tick with an LSL clock;"
            " was this database's session the one recorded?"
        )
    return np.asarray(diffs), max(sessions)


def _store(
    s: Session,
    stream: dict[str, Any],
    session_id: int,
    shift: float,
    window: tuple[float, float],
    source: str,
) -> int:  # noqa: E501
    """One lab stream of the file (its samples within ``window`` of the recorder's clock)."""
    ts = np.asarray(stream["time_stamps"], dtype=float)
    corrected = _corrected(stream)
    keep = (corrected >= window[0]) & (corrected <= window[1])
    fmt = _info(stream, "channel_format", "float32")
    dtype = stream_dtype(fmt)
    n_ch = int(_info(stream, "channel_count", "1"))
    values = stream["time_series"]
    values = (
        np.asarray(values, dtype=object) if dtype == "json" else np.asarray(values, dtype=float)
    ).reshape(len(ts), n_ch)[keep]
    row = LslStream(
        session_id=session_id, origin="xdf", name=_info(stream, "name"),
        type=_info(stream, "type"), source_id=_info(stream, "source_id"),
        hostname=_info(stream, "hostname"), channel_count=n_ch,
        nominal_srate=float(_info(stream, "nominal_srate", "0")), channel_format=fmt,
        dtype=dtype, channels=",".join(_labels(stream, n_ch)), required=None,
        info_xml=json.dumps(stream["info"], default=str), clock_shift_s=shift, source=source,
        created_at=utc_now(),
    )  # fmt: skip
    s.add(row)
    s.flush()
    _chunks(s, row.id, ts[keep], values, dtype)
    _offsets(s, row.id, stream)
    return int(keep.sum())


def _labels(stream: dict[str, Any], n_ch: int) -> list[str]:
    try:
        chans = stream["info"]["desc"][0]["channels"][0]["channel"]
        labels = [str(c["label"][0]) for c in chans]
    except (KeyError, IndexError, TypeError):
        labels = []
    return (labels + [f"ch{i}" for i in range(len(labels), n_ch)])[:n_ch]


def _chunks(s: Session, stream_id: int, ts: np.ndarray, values: np.ndarray, dtype: str) -> None:
    rows = []
    for i in range(0, len(ts), CHUNK):
        t, v = ts[i : i + CHUNK], values[i : i + CHUNK]
        rows.append(
            {
                "stream_id": stream_id,
                "segment": 0,
                "n": len(t),
                "first_ts": float(t[0]),
                "last_ts": float(t[-1]),
                "received_clock_s": float(t[-1]),
                "timestamps": t.astype("<f8").tobytes(),
                "data": encode(v, dtype),
            }
        )
    if rows:
        s.execute(LslChunk.__table__.insert(), rows)


def _offsets(s: Session, stream_id: int, stream: dict[str, Any]) -> None:
    rows = [
        {"stream_id": stream_id, "segment": 0, "clock_s": float(c), "offset_s": float(o)}
        for c, o in zip(stream.get("clock_times", []), stream.get("clock_values", []), strict=True)
    ]
    if rows:
        s.execute(LslOffset.__table__.insert(), rows)


def import_xdf(
    db: str | Path, xdf: str | Path, *, participant: str | None = None, force: bool = False
) -> ImportSummary:
    """Import LabRecorder's ``xdf`` file into ``db``, aligned with ``participant``'s trials.

    Raises
    ------
    ValueError
        (one line) no such file or not an XDF file, no marker stream of this platform in
        it, the participant missing or not named where the file holds several, no sync
        marker matching the database's ticks, markers that disagree with the ticks by
        more than 5 ms, or a file imported before for that session (unless ``force``).
    """
    path = Path(xdf)
    if not path.is_file():
        raise ValueError(f"--xdf: {xdf}: no such file")
    pyxdf = runtime.pyxdf()
    try:
        streams, _ = pyxdf.load_xdf(str(path), synchronize_clocks=False, dejitter_timestamps=False)
    except Exception as error:  # pyxdf raises OSError, ValueError, struct.error, ...
        raise ValueError(f"--xdf: {xdf}: not a readable XDF file ({error})") from None
    markers = _markers(streams, path)
    code = _participant(markers, participant, path)
    mine = [(t, m) for t, m in markers if m.get("participant") == code]
    source = f"{path.name} sha256:{hashlib.sha256(path.read_bytes()).hexdigest()}"
    engine = open_database(db, create=False, readonly=False)
    try:
        with Session(engine) as s, s.begin():
            diffs, session_id = _pairs(s, mine, code, db)
            spread = float(np.ptp(diffs))
            if spread > MAX_SPREAD_S:
                raise ValueError(
                    f"{xdf}: the markers of {code} disagree with the database's ticks by up "
                    f"to {spread * 1e3:.1f} ms (at most {MAX_SPREAD_S * 1e3:g}); is this the "
                    "session recorded in the file?"
                )
            _not_imported(s, session_id, source, force, xdf)
            shift = float(np.median(diffs))
            window = (mine[0][0] - MARGIN_S, mine[-1][0] + MARGIN_S)
            stored = tuple(
                (_info(st, "name"), _store(s, st, session_id, shift, window, source))
                for st in streams
                if not _ours(st)
            )
    finally:
        engine.dispose()
    return ImportSummary(code, session_id, shift, len(diffs), spread * 1e3, stored)


def _not_imported(s: Session, session_id: int, source: str, force: bool, xdf: Any) -> None:
    earlier = s.scalars(
        select(LslStream).where(LslStream.session_id == session_id, LslStream.source == source)
    ).first()
    if earlier is not None and not force:
        raise ValueError(
            f"--xdf: {xdf} was imported for session {session_id} already; pass --force to "
            "import it again"
        )
