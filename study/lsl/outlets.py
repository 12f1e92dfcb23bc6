"""The session's two outlets (DESIGN.md, "The lab's clock"): the study's events as
markers (one JSON string per event, irregular rate) and the robot's state at 20 Hz, each
sample stamped with the ``local_clock()`` of the tick it belongs to.

Stream names and source ids are stable for a machine (``asa-study/<machine>/events``), so
LabRecorder picks a restarted session up again. Channel labels, units and the codes of the
recognised task are in each stream's description.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from autonomy.reactive_bn import SITUATIONS
from autonomy.task_types import TASK_TYPES
from study import __version__

EVENT_NAME = "asa-study events"
EVENT_TYPE = "Markers"
STATE_NAME = "asa-study state"
STATE_TYPE = "RobotState"
STATE_HZ = 20.0  # [Hz] one sample per control tick
# (label, unit, what): the state stream's channels in order
STATE_CHANNELS: tuple[tuple[str, str, str], ...] = (
    ("tick", "count", "tick"),
    ("t", "s", "simulated trial time"),
    ("x", "m", "pose, map frame"),
    ("y", "m", "pose, map frame"),
    ("yaw", "rad", "pose, map frame"),
    ("twist_x", "m/s", "velocity, robot frame"),
    ("twist_y", "m/s", "velocity, robot frame"),
    ("twist_w", "rad/s", "velocity, robot frame"),
    ("u_x", "m/s", "participant's command"),
    ("u_y", "m/s", "participant's command"),
    ("u_w", "rad/s", "participant's command"),
    ("v_x", "m/s", "applied command"),
    ("v_y", "m/s", "applied command"),
    ("v_w", "rad/s", "applied command"),
    ("beta", "1", "blend weight"),
    ("task", "code", "recognised task or situation (codes in desc/codes)"),
)
# the recognised label's code: 0 none, then the contextual task types and the reactive
# mode's situations; a label outside them gets the next free code, announced by a
# "label_code" marker
BASE_CODES: tuple[str, ...] = ("", *TASK_TYPES, *SITUATIONS)


@dataclass(frozen=True, slots=True)
class OutletNames:
    """The two streams' names and source ids on ``machine``."""

    machine: str

    @property
    def events_source_id(self) -> str:
        return f"asa-study/{self.machine}/events"

    @property
    def state_source_id(self) -> str:
        return f"asa-study/{self.machine}/state"


def marker(
    kind: str,
    participant: str,
    trial: int | None,
    tick: int | None,
    t: float | None,
    detail: Mapping[str, Any],
) -> str:
    """One event as compact JSON: event, participant, trial (id), tick, t [s simulated],
    then the event's details."""
    body: dict[str, Any] = {"event": kind, "participant": participant, "trial": trial}
    body["tick"] = tick
    body["t"] = None if t is None else round(float(t), 6)
    body.update(detail)
    return json.dumps(body, separators=(",", ":"), default=_plain)


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def _channels(info: Any, rows: Sequence[tuple[str, str, str]]) -> None:
    channels = info.desc().append_child("channels")
    for label, unit, what in rows:
        ch = channels.append_child("channel")
        ch.append_child_value("label", label)
        ch.append_child_value("unit", unit)
        ch.append_child_value("type", what)


def _acquisition(info: Any) -> None:
    acq = info.desc().append_child("acquisition")
    acq.append_child_value("manufacturer", "asa-study")
    acq.append_child_value("version", __version__)
    acq.append_child_value("clock", "pylsl.local_clock() taken when the tick happened")


class SessionOutlets:
    """The event and state outlets of one session (created at the session's start)."""

    def __init__(self, lsl: ModuleType, names: OutletNames) -> None:
        self.lsl, self.names = lsl, names
        self.codes: dict[str, int] = {label: i for i, label in enumerate(BASE_CODES)}
        events = lsl.StreamInfo(
            EVENT_NAME, EVENT_TYPE, 1, lsl.IRREGULAR_RATE, lsl.cf_string, names.events_source_id
        )
        _channels(events, (("event", "json", "event, participant, trial, tick, t, details"),))
        _acquisition(events)
        state = lsl.StreamInfo(
            STATE_NAME,
            STATE_TYPE,
            len(STATE_CHANNELS),
            STATE_HZ,
            lsl.cf_double64,
            names.state_source_id,
        )
        _channels(state, STATE_CHANNELS)
        _acquisition(state)
        codes = state.desc().append_child("codes")
        for label, code in self.codes.items():
            c = codes.append_child("code")
            c.append_child_value("value", str(code))
            c.append_child_value("label", label)
        self.events = lsl.StreamOutlet(events)
        self.state = lsl.StreamOutlet(state)
        self._row = np.zeros(len(STATE_CHANNELS))

    def push_event(self, text: str, stamp: float) -> None:
        """One marker, stamped ``stamp`` [s, local_clock]."""
        self.events.push_sample([text], stamp)

    def code(self, label: str) -> tuple[int, bool]:
        """The code of a recognised label, and whether it is new (to announce)."""
        code = self.codes.get(label)
        if code is not None:
            return code, False
        code = self.codes[label] = len(self.codes)
        return code, True

    def push_state(self, values: np.ndarray, stamp: float) -> None:
        """One state sample (:data:`STATE_CHANNELS`), stamped ``stamp``."""
        self.state.push_sample(values, stamp)

    def close(self) -> None:
        """Take both streams off the network."""
        self.events = self.state = None  # type: ignore[assignment]
