"""The protocol's ``[lsl]`` table: which Lab Streaming Layer outlets a session opens and
which of the lab's streams it records (DESIGN.md, "The lab's clock"). Plain data, read
without pylsl.

``[lsl]`` outlets (true), mode_names (false), resolve_timeout_s (2.0),
wait_for_consumers_s (0: how long the session waits, before its first event, for a
consumer of its event stream such as LabRecorder), and
``[[lsl.record]]`` tables with type, name and/or source_id (at least one) and required
(true): every stream that matches all the given properties is recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim.fields import FieldReader

MAX_RECORD = 32  # [[lsl.record]] tables
MAX_RESOLVE_S = 60.0  # [s] the longest wait for a required stream
MAX_WAIT_S = 600.0  # [s] the longest wait for a consumer of the event stream
OFFSET_EVERY_S = 5.0  # [s] between two clock offsets of a recorded stream (LabRecorder's)
_PROPERTIES = ("type", "name", "source_id")


@dataclass(frozen=True, slots=True)
class RecordSpec:
    """One ``[[lsl.record]]`` entry: the lab's streams that match every property given."""

    type: str = ""  # LSL content type, e.g. "Gaze", "EEG"; "" matches any
    name: str = ""  # stream name; "" matches any
    source_id: str = ""  # the device's source id; "" matches any
    required: bool = True  # no session starts without it

    def predicate(self) -> str:
        """The LSL XPath predicate of the properties given (``resolve_bypred``)."""
        parts = [f"{key}='{getattr(self, key)}'" for key in _PROPERTIES if getattr(self, key)]
        return " and ".join(parts)

    def label(self) -> str:
        """How the experimenter names it: ``type 'Gaze', name 'Tobii'``."""
        return ", ".join(f"{k} {getattr(self, k)!r}" for k in _PROPERTIES if getattr(self, k))

    def matches(self, stream_type: str, name: str, source_id: str) -> bool:
        """Whether a stream with these properties is one of this entry's."""
        given = {"type": stream_type, "name": name, "source_id": source_id}
        return all(getattr(self, k) in ("", given[k]) for k in _PROPERTIES)


@dataclass(frozen=True, slots=True)
class LslSettings:
    """The session's LSL: outlets on or off, the mode's name in the markers, the lab's
    streams to record. ``enabled`` is False without an ``[lsl]`` table."""

    enabled: bool = False
    outlets: bool = True  # the event (markers) and state streams
    mode_names: bool = False  # the active mode's name in trial_started markers
    resolve_timeout_s: float = 2.0  # [s] wait for each required stream before refusing
    wait_for_consumers_s: float = 0.0  # [s] wait for a recorder of the events before starting
    record: tuple[RecordSpec, ...] = ()

    @property
    def records(self) -> bool:
        """Whether the session records any of the lab's streams."""
        return self.enabled and bool(self.record)


def boolean(r: FieldReader, key: str, default: bool) -> bool:
    """A true/false field (as :func:`study.engine.protocol.readers.boolean`, which this
    module cannot import: the protocol's types import this module)."""
    r.used.add(key)
    value = r.data.get(key, default)
    if not isinstance(value, bool):
        raise r.fail(key, f"must be true or false, got {value!r}")
    return value


def _record(r: FieldReader) -> RecordSpec:
    values = {}
    for key in _PROPERTIES:
        value = r.string(key, "")
        if "'" in value or '"' in value:
            raise r.fail(key, f"must not contain quotes, got {value!r}")
        values[key] = value
    if not any(values.values()):
        raise r.fail("type", "give at least one of type, name or source_id")
    spec = RecordSpec(**values, required=boolean(r, "required", True))
    r.finish()
    return spec


def lsl_settings(r: FieldReader, present: bool) -> LslSettings:
    """The ``[lsl]`` table read by ``r`` (``present``: the protocol has one)."""
    if not present:
        r.finish()
        return LslSettings()
    records = tuple(_record(t) for t in r.tables("record"))
    if len(records) > MAX_RECORD:
        raise r.fail("record", f"at most {MAX_RECORD} [[lsl.record]] tables, got {len(records)}")
    s = LslSettings(
        enabled=True,
        outlets=boolean(r, "outlets", True),
        mode_names=boolean(r, "mode_names", False),
        resolve_timeout_s=r.number("resolve_timeout_s", 2.0, positive=True, maximum=MAX_RESOLVE_S),
        wait_for_consumers_s=r.number(
            "wait_for_consumers_s", 0.0, non_negative=True, maximum=MAX_WAIT_S
        ),
        record=records,
    )
    r.finish()
    return s
