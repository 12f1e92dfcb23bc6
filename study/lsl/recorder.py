"""Recording the lab's streams into the study database, in a thread off the control loop
(DESIGN.md, "The lab's clock"), as LabRecorder does: the samples raw with their own
timestamps, the stream's header, and its clock offset (``time_correction``) every
:data:`~study.lsl.settings.OFFSET_EVERY_S` seconds.

Samples wait in the recorder's buffers and are written once a second, one transaction
for every stream. A stream that is lost (its outlet gone) ends its segment: a gap row, an
event, and a continuous resolver that connects it again (a new segment of the same stream
row) when it comes back; a stream of the protocol's that appears later is recorded from
then on.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

import numpy as np
from sqlalchemy import update
from sqlalchemy.engine import Engine

from study.data.storage import Event, LslChunk, LslGap, LslOffset, LslStream, utc_now
from study.lsl.settings import OFFSET_EVERY_S, RecordSpec

FLUSH_EVERY_S = 1.0  # [s] between two writes of the buffered samples
POLL_S = 0.02  # [s] between two pulls of every inlet (liblsl buffers between)
WATCH_EVERY_S = 0.25  # [s] between two looks at the resolvers (streams back, new ones)
MAX_CHUNK = 8192  # samples pulled at once
_INT_FORMATS = ("int8", "int16", "int32", "int64")
_INSERT_CHUNK = LslChunk.__table__.insert()
_INSERT_OFFSET = LslOffset.__table__.insert()


def stream_dtype(channel_format: str) -> str:
    """How a stream's values are stored: ``f8``, ``i8`` or ``json`` (strings)."""
    if channel_format == "string":
        return "json"
    return "i8" if channel_format in _INT_FORMATS else "f8"


def channel_labels(info: Any) -> list[str]:
    """The channel labels in a stream's description (``ch<i>`` where it has none)."""
    labels: list[str] = []
    ch = info.desc().child("channels").child("channel")
    while not ch.empty() and len(labels) < info.channel_count():
        labels.append(ch.child_value("label") or f"ch{len(labels)}")
        ch = ch.next_sibling("channel")
    return labels + [f"ch{i}" for i in range(len(labels), info.channel_count())]


def encode(values: np.ndarray, dtype: str) -> bytes:
    """A chunk's values (n, channels) as stored (:func:`decode` reads them)."""
    if dtype == "json":
        rows = [
            [v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v) for v in r]
            for r in values
        ]
        return json.dumps(rows, separators=(",", ":")).encode("utf-8")
    return np.ascontiguousarray(values, dtype="<" + dtype).tobytes()


@dataclass
class _Connection:
    """One inlet: a segment of a stream row, its buffers and its schedule."""

    stream_id: int
    spec: RecordSpec
    inlet: Any
    uid: str
    segment: int
    dtype: str
    channels: int
    identity: tuple[str, str, str, str]
    next_offset: float = 0.0  # [s] session clock
    times: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    lost: bool = False


class StreamRecorder:
    """Records the lab's streams of a session into ``engine`` (:meth:`start`, :meth:`stop`).

    Parameters
    ----------
    lsl : module
        pylsl (:func:`study.lsl.runtime.pylsl`).
    engine : Engine
        The study database.
    session_id : int
        The session the streams belong to.
    specs : sequence of RecordSpec
        The protocol's ``[[lsl.record]]`` entries.
    on_event : callable, optional
        ``(kind, detail)`` of a stream lost or found, for the event outlet.
    """

    def __init__(
        self,
        lsl: ModuleType,
        engine: Engine,
        session_id: int,
        specs: Sequence[RecordSpec],
        *,
        on_event: Callable[[str, dict[str, Any]], None] | None = None,
    ) -> None:
        self.lsl, self.engine, self.session_id = lsl, engine, session_id
        self.specs = tuple(specs)
        self.on_event = on_event
        self.connections: list[_Connection] = []
        self.rows: dict[tuple[str, str, str, str], tuple[int, int]] = {}  # -> (id, segments)
        self.dead: set[str] = set()  # uids of lost outlets (resolvers still list them a while)
        self.gaps: dict[int, int] = {}  # stream id -> its open gap's id
        self.trial: tuple[int | None, float] = (None, 0.0)  # the running trial, its time
        self.pending_offsets: list[dict[str, Any]] = []
        self.resolvers: list[Any] = []
        self.failure: BaseException | None = None
        self.cpu_s = 0.0  # [s] CPU time of the recording thread, known after stop()
        self.wall_s = 0.0  # [s] how long it ran, known after stop()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ control

    def start(self, found: Sequence[tuple[Any, RecordSpec]]) -> None:
        """Open an inlet on each stream ``found`` and record in a thread until :meth:`stop`."""
        for info, spec in found:
            self._try_connect(info, spec)
        self.resolvers = [self.lsl.ContinuousResolver(pred=s.predicate()) for s in self.specs]
        self._thread = threading.Thread(target=self._run, name="asa-lsl-recorder", daemon=True)
        self._thread.start()

    def set_trial(self, trial_id: int | None, t: float) -> None:
        """The trial running now and its time [s] (for the events of lost streams)."""
        self.trial = (trial_id, t)

    def stop(self) -> None:
        """Pull what is left, write it, close the inlets; re-raises a failure of the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        for c in self.connections:
            if not c.lost:
                c.inlet.close_stream()
        self.resolvers = []
        if self.failure is not None:
            raise RuntimeError(f"LSL recorder failed: {self.failure!r}") from self.failure

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        clock = self.lsl.local_clock
        next_flush = next_watch = started = clock()
        try:
            while not self._stop.is_set():
                now = clock()
                self._pull_all(now)
                self._offsets(now)
                if now >= next_watch:
                    self._watch()
                    next_watch = now + WATCH_EVERY_S
                if now >= next_flush:
                    self._flush()
                    next_flush = now + FLUSH_EVERY_S
                time.sleep(POLL_S)
            self._pull_all(clock())
            self._flush()
        except BaseException as error:  # a bug or the database: stop() re-raises it
            self.failure = error
        finally:
            self.cpu_s, self.wall_s = time.thread_time(), clock() - started

    def _pull_all(self, now: float) -> None:
        lost_error = self.lsl.util.LostError
        for c in self.connections:
            if c.lost:
                continue
            while True:
                try:
                    values, times = c.inlet.pull_chunk(0.0, MAX_CHUNK, as_numpy=True)
                except lost_error:
                    self._lost(c, now)
                    break
                if len(times) == 0:
                    break
                c.times.append(np.asarray(times, dtype=float))
                c.values.append(np.asarray(values).reshape(len(times), c.channels))
                if len(times) < MAX_CHUNK:
                    break

    def _offsets(self, now: float) -> None:
        errors = (self.lsl.util.LostError, self.lsl.util.TimeoutError)
        for c in self.connections:
            if c.lost or now < c.next_offset:
                continue
            try:
                offset = c.inlet.time_correction(timeout=1.0)
            except errors:
                c.next_offset = now + 1.0  # try again soon; a lost stream shows in its pull
                continue
            c.next_offset = now + OFFSET_EVERY_S
            self.pending_offsets.append(
                {
                    "stream_id": c.stream_id,
                    "segment": c.segment,
                    "clock_s": self.lsl.local_clock(),
                    "offset_s": float(offset),
                }
            )

    def _watch(self) -> None:
        """Connect the streams the resolvers list that are not recorded: back or new."""
        live = {c.uid for c in self.connections if not c.lost}
        for spec, resolver in zip(self.specs, self.resolvers, strict=True):
            for info in resolver.results():
                if info.uid() not in live and info.uid() not in self.dead:
                    if self._try_connect(info, spec):
                        live.add(info.uid())

    # ------------------------------------------------------------------ streams

    def _try_connect(self, info: Any, spec: RecordSpec) -> bool:
        """:meth:`_connect`, or False for a stream gone before its inlet opened (the
        resolvers offer it again if it comes back)."""
        try:
            self._connect(info, spec)
        except (self.lsl.util.LostError, self.lsl.util.TimeoutError):
            return False
        return True

    def _connect(self, info: Any, spec: RecordSpec) -> None:
        """An inlet on ``info``: a new stream row, or a new segment of the row of a stream
        with the same name, type, source id and host (one that came back)."""
        inlet = self.lsl.StreamInlet(info, max_buflen=360, recover=False)
        full = inlet.info(timeout=5.0)  # the header, with the description
        inlet.open_stream(timeout=5.0)
        identity = (full.name(), full.type(), full.source_id(), full.hostname())
        known = self.rows.get(identity)
        if known is None:
            stream_id, segment = self._insert_stream(full, spec), 0
        else:
            stream_id, segment = known[0], known[1]
            self._found(stream_id, identity)
        self.rows[identity] = (stream_id, segment + 1)
        self.connections.append(
            _Connection(
                stream_id,
                spec,
                inlet,
                full.uid(),
                segment,
                stream_dtype(_format_name(full)),
                full.channel_count(),
                identity,
            )
        )

    def _insert_stream(self, info: Any, spec: RecordSpec) -> int:
        fmt = _format_name(info)
        row = {
            "session_id": self.session_id,
            "origin": "recorded",
            "name": info.name(),
            "type": info.type(),
            "source_id": info.source_id(),
            "hostname": info.hostname(),
            "channel_count": info.channel_count(),
            "nominal_srate": info.nominal_srate(),
            "channel_format": fmt,
            "dtype": stream_dtype(fmt),
            "channels": ",".join(channel_labels(info)),
            "required": spec.required,
            "info_xml": info.as_xml(),
            "clock_shift_s": 0.0,
            "source": "",
            "created_at": utc_now(),
        }
        with self.engine.begin() as conn:
            return int(
                conn.execute(LslStream.__table__.insert().values(**row)).inserted_primary_key[0]
            )

    def _event(self, kind: str, identity: tuple[str, str, str, str], **detail: Any) -> dict:
        trial_id, t = self.trial
        body = {"stream": identity[0], "type": identity[1], "source_id": identity[2], **detail}
        return {
            "session_id": self.session_id,
            "trial_id": trial_id,
            "t": float(t),
            "kind": kind,
            "detail": body,
            "created_at": utc_now(),
        }

    def _lost(self, c: _Connection, now: float) -> None:
        """A stream gone: its segment ends, a gap opens (written at once), an event."""
        c.lost = True
        self.dead.add(c.uid)
        trial_id = self.trial[0]
        event = self._event("lsl_stream_lost", c.identity, segment=c.segment)
        with self.engine.begin() as conn:
            gap = conn.execute(
                LslGap.__table__.insert().values(
                    stream_id=c.stream_id,
                    segment=c.segment,
                    start_clock_s=now,
                    end_clock_s=None,
                    trial_id=trial_id,
                )
            )
            self.gaps[c.stream_id] = int(gap.inserted_primary_key[0])
            conn.execute(Event.__table__.insert().values(**event))
        if self.on_event is not None:
            self.on_event("lsl_stream_lost", event["detail"])

    def _found(self, stream_id: int, identity: tuple[str, str, str, str]) -> None:
        """A lost stream back: its gap closes, an event."""
        gap = self.gaps.pop(stream_id, None)
        event = self._event("lsl_stream_found", identity)
        with self.engine.begin() as conn:
            if gap is not None:
                conn.execute(
                    update(LslGap)
                    .where(LslGap.id == gap)
                    .values(end_clock_s=self.lsl.local_clock())
                )
            conn.execute(Event.__table__.insert().values(**event))
        if self.on_event is not None:
            self.on_event("lsl_stream_found", event["detail"])

    # ------------------------------------------------------------------ writing

    def _flush(self) -> None:
        """Every buffered sample (one chunk row per stream segment) and offset: one
        transaction."""
        now = self.lsl.local_clock()
        chunks = []
        for c in self.connections:
            if not c.times:
                continue
            times = np.concatenate(c.times)
            values = np.concatenate(c.values)
            c.times, c.values = [], []
            chunks.append(
                {
                    "stream_id": c.stream_id,
                    "segment": c.segment,
                    "n": len(times),
                    "first_ts": float(times[0]),
                    "last_ts": float(times[-1]),
                    "received_clock_s": now,
                    "timestamps": times.astype("<f8").tobytes(),
                    "data": encode(values, c.dtype),
                }
            )
        offsets, self.pending_offsets = self.pending_offsets, []
        if not chunks and not offsets:
            return
        with self.engine.begin() as conn:
            if chunks:
                conn.execute(_INSERT_CHUNK, chunks)
            if offsets:
                conn.execute(_INSERT_OFFSET, offsets)


def _format_name(info: Any) -> str:
    """LSL's name of a stream's channel format (``float32``, ``string``, ...)."""
    names = {
        1: "float32",
        2: "double64",
        3: "string",
        4: "int32",
        5: "int16",
        6: "int8",
        7: "int64",
    }
    return names.get(int(info.channel_format()), "undefined")
