"""The session process's end of the pipe to the server (docs/decisions.md, "Participants in
a browser"): one reader thread drains the pipe as messages come, so the server never waits
for a busy session, and keeps what the participant object asks for: whether a page is
connected, the newest input with the presses since it was last read, the page's JSON
messages, and the round trip of every state tick the page has drawn.

Gamepad indices: the page reports the standard mapping; the protocol's ``[input]`` numbers
axes and buttons as SDL/XInput do on Linux, so both are translated here
(:data:`STD_AXES`, :data:`STD_BUTTONS`) and the stick is computed by
:mod:`study.ui.sticks`, as on the pygame screen. Clock: ``time.monotonic`` of this
machine, the same in the server's process (Linux ``CLOCK_MONOTONIC``).
"""

from __future__ import annotations

import threading
import time
from collections import Counter, deque
from typing import Any

import numpy as np

from study.ui.sticks import GamepadMapping, axes_stick, nav_of_stick, total_stick
from study.web.messages import InputMessage

STD_AXES = {0: 0, 1: 1, 2: 3, 3: 4}  # standard axis -> SDL/XInput axis (right stick 3, 4)
# standard button -> SDL/XInput button: A B X Y LB RB, Back 8 -> 6, Start 9 -> 7, the
# stick presses 10, 11 -> 9, 10
STD_BUTTONS = {0: 0, 1: 1, 2: 2, 3: 3, 4: 4, 5: 5, 8: 6, 9: 7, 10: 9, 11: 10}
STD_DPAD = {12: "up", 13: "down", 14: "left", 15: "right"}
KEY_PRESSES = {  # held key -> the action its press causes
    "yes": "yes",
    "no": "no",
    "pause": "pause",
    "arrow_up": "up",
    "arrow_down": "down",
    "arrow_left": "left",
    "arrow_right": "right",
    "enter": "confirm",
}
_ZERO3 = np.zeros(3)
SENT_KEPT = 400  # state ticks whose send time is kept (20 s at 20 Hz)


class Link:
    """The pipe to the server, read by a thread of its own.

    Parameters
    ----------
    conn : multiprocessing.connection.Connection
        This process's end of the pipe.
    mapping : GamepadMapping
        The protocol's gamepad mapping.
    hello : str
        A JSON message for every page that connects (the protocol's keys).
    """

    def __init__(self, conn: Any, mapping: GamepadMapping, *, hello: str = "") -> None:
        self.conn = conn
        self.mapping = mapping
        self.hello = hello  # sent to every page that connects (its keys)
        self._lock = threading.Lock()
        self._send_lock = threading.Lock()
        self.connected = False
        self.changed = threading.Event()  # set by every message (waiters wake up)
        self.opened = 0  # pages connected so far (a new one: resend the screen)
        self.gone_since: float | None = time.monotonic()  # [s] monotonic, None: connected
        self.heard = 0.0  # [s] monotonic, the last message from the page
        self.input: InputMessage | None = None
        self.actions: list[str] = []  # presses not yet taken
        self.messages: deque[dict[str, Any]] = deque(maxlen=256)  # the page's JSON
        self.drops: Counter[str] = Counter()  # messages the server dropped, by reason
        self.stopped = ""  # why the server asked the session to stop ("" while it runs)
        self._sent: dict[int, float] = {}  # state tick -> when it was handed over
        self._rtt: dict[int, float] = {}  # state tick -> round trip [ms]
        self._nav: dict[str, bool] = {}
        self._thread = threading.Thread(target=self._read, name="asa-web-link", daemon=True)
        self._thread.start()

    # -------------------------------------------------------------- sending

    def send(self, payload: bytes | str, *, latest: str = "") -> None:
        """To the page (``latest``: a key under which only the newest waits, e.g. a
        camera)."""
        with self._send_lock:
            try:
                self.conn.send(("ws", payload, latest))
            except (OSError, EOFError):
                pass

    def send_state(self, tick: int, payload: bytes) -> None:
        """A ``STATE`` message of ``tick``; its hand-over time is kept for the round trip."""
        now = time.monotonic()
        with self._lock:
            self._sent[tick] = now
            if len(self._sent) > SENT_KEPT:
                for old in sorted(self._sent)[: len(self._sent) - SENT_KEPT]:
                    del self._sent[old]
        self.send(payload)

    def status(self, values: dict[str, Any]) -> None:
        """The session's state for the experimenter's view."""
        with self._send_lock:
            try:
                self.conn.send(("status", values))
            except (OSError, EOFError):
                pass

    # -------------------------------------------------------------- reading

    def _read(self) -> None:
        while True:
            try:
                msg = self.conn.recv()
            except (EOFError, OSError):
                with self._lock:
                    self.stopped = self.stopped or "the server went away"
                    self.connected = False
                self.changed.set()
                return
            self._handle(msg)
            if msg[0] == "open" and self.hello:
                self.send(self.hello)
            self.changed.set()

    def _handle(self, msg: tuple) -> None:
        kind = msg[0]
        with self._lock:
            if kind == "open":
                self.connected, self.gone_since = True, None
                self.opened += 1
                self.heard = time.monotonic()
                self.input = None
            elif kind == "gone":
                self.connected = False
                self.gone_since = time.monotonic()
            elif kind == "in":
                self.heard = msg[1]
                self._message(msg[1], msg[2])
            elif kind == "drops":
                self.drops.update(msg[1])
            elif kind == "stop":
                self.stopped = str(msg[1])

    def _message(self, when: float, body: Any) -> None:
        """One checked message from the page (under the lock)."""
        if isinstance(body, InputMessage):
            sent = self._sent.get(body.last_tick)
            if sent is not None and body.last_tick not in self._rtt:
                self._rtt[body.last_tick] = (when - sent) * 1e3
                if len(self._rtt) > SENT_KEPT:
                    for old in sorted(self._rtt)[: len(self._rtt) - SENT_KEPT]:
                        del self._rtt[old]
            self.actions.extend(self._presses(self.input, body))
            self.input = body
        else:
            self.messages.append({**body, "at": when})

    def _presses(self, before: InputMessage | None, now: InputMessage) -> list[str]:
        """The actions pressed since ``before``: buttons, the D-pad, keys, the stick."""
        old_buttons = before.buttons if before is not None else 0
        old_keys = before.held() if before is not None else set()
        out: list[str] = []
        pressed = now.buttons & ~old_buttons
        for b in range(16):
            if not pressed >> b & 1:
                continue
            if b in STD_DPAD:
                out.append(STD_DPAD[b])
            xinput = STD_BUTTONS.get(b)
            out.extend(name for name, index in self.mapping.buttons.items() if index == xinput)
        out.extend(KEY_PRESSES[k] for k in sorted(now.held() - old_keys) if k in KEY_PRESSES)
        for name, on in nav_of_stick(self._pad(now)).items():
            if on and not self._nav.get(name):
                out.append(name)
            self._nav[name] = on
        return out

    def _pad(self, msg: InputMessage) -> np.ndarray:
        if not msg.gamepad:
            return _ZERO3
        return axes_stick({STD_AXES[i]: a for i, a in enumerate(msg.axes)}, self.mapping)

    # -------------------------------------------------------------- the participant's view

    def take(self) -> tuple[list[str], list[dict[str, Any]]]:
        """The presses and JSON messages since the last call."""
        with self._lock:
            actions, self.actions = self.actions, []
            messages = list(self.messages)
            self.messages.clear()
        return actions, messages

    def clear(self) -> None:
        """Forget presses and messages (a new page: presses before it do not count)."""
        self.take()

    def stick(self) -> np.ndarray:
        """The page's stick and driving keys as one deflection (3,) in [-1, 1]."""
        with self._lock:
            msg = self.input
        if msg is None:
            return np.zeros(3)
        return total_stick([self._pad(msg)], msg.held())

    def held_nav(self) -> set[str]:
        """The form directions held: arrows, the D-pad, the left stick."""
        with self._lock:
            msg = self.input
        if msg is None:
            return set()
        held = {KEY_PRESSES[k] for k in msg.held() if k.startswith("arrow_")}
        held |= {d for b, d in STD_DPAD.items() if msg.buttons >> b & 1}
        held |= {d for d, on in nav_of_stick(self._pad(msg)).items() if on}
        return held

    def new_trial(self) -> None:
        """State ticks count from 1 again: forget the last trial's."""
        with self._lock:
            self._sent.clear()
            self._rtt.clear()

    def timing(self, tick: int) -> tuple[int | None, float | None]:
        """The newest input's age at state tick ``tick`` and the round trip [ms] of the
        state it answered; (None, None) before the page has answered a state of this
        trial."""
        with self._lock:
            msg = self.input
            if msg is None or msg.last_tick not in self._sent:
                return None, None
            return tick - msg.last_tick, self._rtt.get(msg.last_tick)

    def silent_for(self) -> float:
        """[s] since the page was last heard (inf while no page is connected)."""
        with self._lock:
            if not self.connected:
                return float("inf")
            return time.monotonic() - self.heard

    def gone_for(self) -> float:
        """[s] since the page went away (0 while one is connected)."""
        with self._lock:
            since = self.gone_since
        return 0.0 if since is None else time.monotonic() - since
