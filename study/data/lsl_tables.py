"""The lab's streams in the study database (revision 0004; DESIGN.md, "The lab's clock").

``lsl_stream`` one row per stream a session recorded or an XDF file brought in, with its
header (the stream's XML info) and the shift onto the session's clock of an imported file;
``lsl_chunk`` the samples as pulled, raw: their own timestamps [s, the stream's LSL clock]
and values as little-endian arrays (``float64``/``int64`` by channel, or JSON text for
string streams), in pull order; ``lsl_offset`` the clock offsets (``time_correction``: add
to a stream's timestamp to get the recording machine's ``local_clock()``) measured every
few seconds; ``lsl_gap`` the times a stream was lost and found again. A ``segment`` counts
a stream's connections: a stream that comes back is a new segment, with its own offsets.

Clocks: ``*_clock_s`` are the session machine's ``pylsl.local_clock()`` [s]; ``first_ts``,
``last_ts`` and the chunk's timestamps are the stream's own clock. Imported by
:mod:`study.data.storage`, which re-exports the models.
"""

from __future__ import annotations

import datetime as dt

from sqlalchemy import Float, ForeignKey, Index, Integer, LargeBinary, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from study.data.storage import Base, UTCDateTime, utc_now

STREAM_ORIGINS = ("recorded", "xdf")  # recorded live by a session; imported from XDF
SAMPLE_DTYPES = ("f8", "i8", "json")  # how a chunk's values are stored


class LslStream(Base):
    __tablename__ = "lsl_stream"
    __table_args__ = (Index("ix_lsl_stream_session", "session_id"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("session.id"))
    origin: Mapped[str] = mapped_column(String(16))  # STREAM_ORIGINS
    name: Mapped[str] = mapped_column(String(200))
    type: Mapped[str] = mapped_column(String(64))
    source_id: Mapped[str] = mapped_column(String(200), default="")
    hostname: Mapped[str] = mapped_column(String(200), default="")
    channel_count: Mapped[int] = mapped_column(Integer)
    nominal_srate: Mapped[float] = mapped_column(Float)  # [Hz]; 0: irregular
    channel_format: Mapped[str] = mapped_column(String(16))  # LSL's: float32, string, ...
    dtype: Mapped[str] = mapped_column(String(8))  # SAMPLE_DTYPES
    channels: Mapped[str] = mapped_column(Text, default="")  # labels, comma-separated
    required: Mapped[bool | None] = mapped_column()  # the protocol's; None for imports
    info_xml: Mapped[str] = mapped_column(Text, default="")  # the stream's header
    # [s] added after the offsets to reach the session's clock (an XDF file's, fitted
    # from the markers; 0 for a stream recorded by the session)
    clock_shift_s: Mapped[float] = mapped_column(Float, default=0.0)
    source: Mapped[str] = mapped_column(Text, default="")  # the XDF file of an import
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)


class LslChunk(Base):
    __tablename__ = "lsl_chunk"
    __table_args__ = (Index("ix_lsl_chunk_stream", "stream_id", "segment"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    stream_id: Mapped[int] = mapped_column(ForeignKey("lsl_stream.id"))
    segment: Mapped[int] = mapped_column(Integer, default=0)
    n: Mapped[int] = mapped_column(Integer)  # samples
    first_ts: Mapped[float] = mapped_column(Float)  # [s] stream clock
    last_ts: Mapped[float] = mapped_column(Float)
    received_clock_s: Mapped[float] = mapped_column(Float)  # [s] session clock, at the pull
    timestamps: Mapped[bytes] = mapped_column(LargeBinary)  # (n,) float64 LE [s]
    data: Mapped[bytes] = mapped_column(LargeBinary)  # (n, channels) as the stream's dtype


class LslOffset(Base):
    __tablename__ = "lsl_offset"
    __table_args__ = (Index("ix_lsl_offset_stream", "stream_id", "segment"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    stream_id: Mapped[int] = mapped_column(ForeignKey("lsl_stream.id"))
    segment: Mapped[int] = mapped_column(Integer, default=0)
    clock_s: Mapped[float] = mapped_column(Float)  # [s] session clock when measured
    offset_s: Mapped[float] = mapped_column(Float)  # [s] stream clock + offset = session clock


class LslGap(Base):
    __tablename__ = "lsl_gap"
    __table_args__ = (Index("ix_lsl_gap_stream", "stream_id"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    stream_id: Mapped[int] = mapped_column(ForeignKey("lsl_stream.id"))
    segment: Mapped[int] = mapped_column(Integer)  # the segment that ended
    start_clock_s: Mapped[float] = mapped_column(Float)  # [s] session clock: lost
    end_clock_s: Mapped[float | None] = mapped_column(Float)  # found again; None: never
    trial_id: Mapped[int | None] = mapped_column(ForeignKey("trial.id"))  # running when lost
