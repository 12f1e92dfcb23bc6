"""A minimal XDF 1.0 writer for the tests, from the format's specification (the XDF
repository's "Specifications" page): the magic ``XDF:``, then chunks of
``[NumLengthBytes][Length][Tag (uint16)][Content]``, little-endian; tags 1 FileHeader,
2 StreamHeader, 3 Samples, 4 ClockOffset, 6 StreamFooter. Numeric samples are stored in
the stream's format, strings as a variable-length count and UTF-8 bytes; every sample
carries its timestamp. (The ``labrecorder`` package's 1.0.0rc0 wheel installs, but its
recording in this container wrote an empty file, so the tests write the file themselves.)
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

_FORMATS = {"float32": "<f4", "double64": "<f8", "int32": "<i4", "int16": "<i2", "int64": "<i8"}


@dataclass
class XdfStream:
    name: str
    type: str
    channel_format: str  # "float32", "double64", "string", ...
    nominal_srate: float
    source_id: str
    timestamps: np.ndarray  # (n,) [s] the stream's clock
    values: Sequence  # (n, channels): numbers, or strings
    labels: Sequence[str] = ()
    offsets: list[tuple[float, float]] = field(default_factory=list)  # (collection time, offset)
    hostname: str = "lab-pc"

    @property
    def channels(self) -> int:
        return len(self.values[0]) if len(self.values) else len(self.labels)


def _varlen(n: int) -> bytes:
    if n < 256:
        return bytes([1]) + struct.pack("<B", n)
    if n < 2**32:
        return bytes([4]) + struct.pack("<I", n)
    return bytes([8]) + struct.pack("<Q", n)


def _chunk(tag: int, content: bytes) -> bytes:
    return _varlen(len(content) + 2) + struct.pack("<H", tag) + content


def _header(sid: int, s: XdfStream) -> bytes:
    chans = "".join(f"<channel><label>{escape(lb)}</label></channel>" for lb in s.labels)
    xml = (
        f'<?xml version="1.0"?><info><name>{escape(s.name)}</name><type>{escape(s.type)}</type>'
        f"<channel_count>{s.channels}</channel_count><nominal_srate>{s.nominal_srate}"
        f"</nominal_srate><channel_format>{s.channel_format}</channel_format>"
        f"<source_id>{escape(s.source_id)}</source_id><version>1.1</version>"
        f"<created_at>0</created_at><uid>{escape(s.source_id)}-uid</uid>"
        f"<hostname>{escape(s.hostname)}</hostname>"
        f"<desc><channels>{chans}</channels></desc></info>"
    )
    return _chunk(2, struct.pack("<I", sid) + xml.encode())


def _samples(sid: int, s: XdfStream, lo: int, hi: int) -> bytes:
    body = bytearray(struct.pack("<I", sid) + _varlen(hi - lo))
    for i in range(lo, hi):
        body += bytes([8]) + struct.pack("<d", float(s.timestamps[i]))
        if s.channel_format == "string":
            for v in s.values[i]:
                raw = str(v).encode()
                body += _varlen(len(raw)) + raw
        else:
            body += np.asarray(s.values[i], dtype=_FORMATS[s.channel_format]).tobytes()
    return _chunk(3, bytes(body))


def _footer(sid: int, s: XdfStream) -> bytes:
    first = s.timestamps[0] if len(s.timestamps) else 0.0
    last = s.timestamps[-1] if len(s.timestamps) else 0.0
    offs = "".join(f"<offset><time>{t!r}</time><value>{v!r}</value></offset>" for t, v in s.offsets)
    xml = (
        f'<?xml version="1.0"?><info><first_timestamp>{first!r}</first_timestamp>'
        f"<last_timestamp>{last!r}</last_timestamp><sample_count>{len(s.timestamps)}"
        f"</sample_count><clock_offsets>{offs}</clock_offsets></info>"
    )
    return _chunk(6, struct.pack("<I", sid) + xml.encode())


def write_xdf(path: Path, streams: Sequence[XdfStream], *, per_chunk: int = 50) -> Path:
    """Write ``streams`` to ``path`` as LabRecorder would: headers, then samples and clock
    offsets interleaved, then footers."""
    out = bytearray(b"XDF:")
    out += _chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')
    for sid, s in enumerate(streams, start=1):
        out += _header(sid, s)
    for sid, s in enumerate(streams, start=1):
        for lo in range(0, len(s.timestamps), per_chunk):
            out += _samples(sid, s, lo, min(lo + per_chunk, len(s.timestamps)))
        for t, v in s.offsets:
            out += _chunk(4, struct.pack("<Idd", sid, t, v))
    for sid, s in enumerate(streams, start=1):
        out += _footer(sid, s)
    path.write_bytes(bytes(out))
    return path
