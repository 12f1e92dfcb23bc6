"""A session's LSL: what the session engine calls (:class:`SessionLsl`) and how a session
starts it (:class:`LslPlan`): pylsl loaded, the protocol's required streams checked before
anything is started, the outlets opened and the recorder started once the session row
exists.

Every marker and state sample of a tick carries the one ``local_clock()`` taken when the
tick happened (:meth:`SessionLsl.tick`); events outside a tick (a pause, an answer given
between ticks, the session's and phases' starts and ends) are stamped when they happen. A
``sync`` marker every simulated second, stamped with its tick's clock, gives an XDF import
its anchors (:mod:`study.lsl.xdf`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
from sqlalchemy.engine import Engine

from study.lsl import runtime
from study.lsl.outlets import STATE_CHANNELS, OutletNames, SessionOutlets, marker
from study.lsl.recorder import StreamRecorder
from study.lsl.settings import LslSettings, RecordSpec

SYNC_EVERY_TICKS = 20  # a sync marker every simulated second
_TRIAL_KEYS = ("phase", "ordinal", "attempt", "scenario")


class SessionLsl:
    """The engine's side of a session's LSL: markers, state samples, the tick's clock and
    the recorder's trial context. Built by :meth:`LslPlan.started`."""

    def __init__(
        self,
        lsl: ModuleType,
        participant: str,
        *,
        outlets: SessionOutlets | None,
        recorder: StreamRecorder | None,
        mode_names: bool,
    ) -> None:
        self.lsl, self.participant = lsl, participant
        self.outlets, self.recorder, self.mode_names = outlets, recorder, mode_names
        self.trial_id: int | None = None
        self.tick_index: int | None = None  # the last tick simulated (its sample's tick)
        self.t = 0.0  # [s] simulated time of the last tick
        self.stamp: float | None = None  # [s] local_clock of the tick being simulated
        self._row = np.zeros(len(STATE_CHANNELS))

    def clock(self) -> float:
        """[s] LSL's clock now."""
        return float(self.lsl.local_clock())

    # ------------------------------------------------------------------ markers

    def _push(
        self,
        kind: str,
        detail: Mapping[str, Any],
        stamp: float | None = None,
        t: float | None = None,
    ) -> None:
        if self.outlets is None:
            return
        when = self.t if t is None else t
        text = marker(kind, self.participant, self.trial_id, self.tick_index, when, detail)
        self.outlets.push_event(text, stamp if stamp is not None else self.clock())

    def session_event(self, kind: str, **detail: Any) -> None:
        """An event of the session (outside trials), stamped now."""
        self._push(kind, detail)

    def recorder_event(self, kind: str, detail: dict[str, Any]) -> None:
        """A recorded stream lost or found (called from the recorder's thread)."""
        self._push(kind, detail)

    def begin_trial(self, trial_id: int, values: Mapping[str, Any]) -> None:
        """The trial's row exists: its ``trial_started`` marker."""
        self.trial_id, self.tick_index, self.t, self.stamp = trial_id, None, 0.0, None
        detail = {k: values[k] for k in _TRIAL_KEYS if k in values}
        if self.mode_names:
            detail["mode"] = values.get("mode", "")
        self._push("trial_started", detail)
        if self.recorder is not None:
            self.recorder.set_trial(trial_id, 0.0)

    def trial_event(self, t: float, kind: str, detail: Mapping[str, Any]) -> None:
        """An event of the running trial (``TrialWriter``'s listener): stamped with the
        tick's clock inside a tick, else now."""
        self._push(kind, detail, self.stamp, t)

    def end_trial(self) -> None:
        """The trial is over (stored or aborted)."""
        self.trial_id, self.stamp = None, None
        if self.recorder is not None:
            self.recorder.set_trial(None, 0.0)

    # ------------------------------------------------------------------ ticks

    def tick(self, tick: int, t: float) -> float:
        """The clock of tick ``tick`` at simulated time ``t``, taken now (once per tick)."""
        self.tick_index, self.t = tick, t
        self.stamp = self.clock()
        if self.recorder is not None:
            self.recorder.set_trial(self.trial_id, t)
        return self.stamp

    def state(self, record: Any, twist: np.ndarray) -> None:
        """The tick's state sample (``study.types.TickRecord``, the robot-frame twist),
        and the sync marker every simulated second; ends the tick."""
        stamp = self.stamp
        if self.outlets is not None and stamp is not None:
            row = self._row
            row[0], row[1] = record.tick, record.t
            row[2:5] = record.pose.x, record.pose.y, record.pose.yaw
            row[5:8] = twist
            row[8:11] = record.u
            row[11:14] = record.v
            row[14] = record.beta
            code, new = self.outlets.code(record.label)
            row[15] = code
            if new:
                self._push("label_code", {"code": code, "label": record.label}, stamp)
            self.outlets.push_state(row, stamp)
            if record.tick % SYNC_EVERY_TICKS == 0:
                self._push("sync", {}, stamp)
        self.stamp = None

    def close(self) -> None:
        """Stop the recorder (its last samples written) and close the outlets."""
        try:
            if self.recorder is not None:
                self.recorder.stop()
        finally:
            if self.outlets is not None:
                self.outlets.close()


@dataclass(frozen=True, slots=True)
class LslPlan:
    """What a session does with LSL: its settings, outlets on or off, recording on or off."""

    settings: LslSettings
    outlets: bool
    record: bool

    @classmethod
    def of(cls, settings: LslSettings, *, enable: bool | None, record: bool) -> LslPlan | None:
        """The plan for a session: ``enable`` None follows the protocol's ``[lsl]``, True
        opens the outlets even without one (``asa run --lsl``), False switches LSL off;
        ``record`` False records none of the lab's streams (``asa synth``). None: no LSL."""
        if enable is False or (enable is None and not settings.enabled):
            return None
        outlets = settings.outlets or not settings.enabled
        recording = record and settings.records
        if not outlets and not recording:
            return None
        return cls(settings, outlets, recording)

    def check(self) -> list[tuple[Any, RecordSpec]]:
        """Load pylsl and find the lab's streams to record; ``ValueError`` (one line)
        naming the first required stream that is not there."""
        lsl = runtime.pylsl()
        if not self.record:
            return []
        found: list[tuple[Any, RecordSpec]] = []
        for spec in self.settings.record:
            wait = self.settings.resolve_timeout_s if spec.required else 0.5
            infos = lsl.resolve_bypred(spec.predicate(), 1, wait)
            if not infos and spec.required:
                raise ValueError(
                    f"[[lsl.record]]: the required stream with {spec.label()} is not on the "
                    f"network (waited {wait:g} s); start it, or set required = false"
                )
            found += [(info, spec) for info in _distinct(infos)]
        return found

    @contextlib.contextmanager
    def started(
        self,
        engine: Engine,
        session_id: int,
        participant: str,
        machine: str,
        found: Sequence[tuple[Any, RecordSpec]],
    ) -> Iterator[SessionLsl]:
        """The outlets opened and the recorder running for the session's duration."""
        lsl = runtime.pylsl()
        outlets = SessionOutlets(lsl, OutletNames(machine)) if self.outlets else None
        if outlets is not None and self.settings.wait_for_consumers_s > 0:
            outlets.events.wait_for_consumers(self.settings.wait_for_consumers_s)
        link = SessionLsl(
            lsl, participant, outlets=outlets, recorder=None, mode_names=self.settings.mode_names
        )
        if self.record:
            link.recorder = StreamRecorder(
                lsl, engine, session_id, self.settings.record, on_event=link.recorder_event
            )
            link.recorder.start(found)
        try:
            yield link
        finally:
            link.close()


def _distinct(infos: Sequence[Any]) -> list[Any]:
    seen: set[str] = set()
    out = []
    for info in infos:
        if info.uid() not in seen:
            seen.add(info.uid())
            out.append(info)
    return out
