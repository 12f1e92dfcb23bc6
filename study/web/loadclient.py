"""Protocol clients: participants' pages without a browser, for measuring the study server
alone (``asa bench --only web``; issue 37). Each client opens its invite's link as the
page does (``static/app.js``) and speaks the wire protocol of :mod:`study.web.messages`:
the browser check and the pings of the latency gate answered, ``STATE`` messages decoded,
``CAMERA`` frames counted (not decoded), and an ``INPUT`` for every state received (as a
page sends one on the animation frame that drew it; 20 Hz without states) carrying the
last tick received (the page's "drawn") and a rising sequence number.

The scripted person behind it presses the standard gamepad's A on a page, right then A on
every row of a form and on a pair, answers every question yes, and on a driving screen
holds the left stick towards the trial's last goal (as :class:`study.web.testing.Person`
pushes its stick forwards). All clients share one asyncio event loop and one aiohttp
session; :func:`run_clients` is the entry.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import aiohttp
import numpy as np

from study.engine.protocol import DEFAULT_AXES, DEFAULT_BUTTONS
from study.ui.sticks import GamepadMapping
from study.web import messages as wire
from study.web.link import STD_AXES, STD_BUTTONS

INPUT_HZ = 20.0  # [Hz] input messages a client sends while no state comes
HOLD = 3  # inputs a scripted press is held for, then released for (about 150 ms each)
STICK = 0.7  # the stick's deflection towards the goal
RIGHT = 15  # the standard mapping's D-pad right
WINDOW = (1280, 800)  # [px] the window the client reports to the browser check
ENDINGS = ("end", "aborted", "refused", "taken_over")  # messages after which a page stops


@dataclass
class ClientRecord:
    """What one client saw and sent."""

    link: str
    screens: list[str] = field(default_factory=list)  # kinds of the screens, in order
    states: int = 0  # STATE messages decoded
    camera_frames: int = 0  # CAMERA messages received
    drive_camera_frames: int = 0  # ... of them while driving
    drive_s: float = 0.0  # [s] monotonic, from a trial's first state to its last
    maps: int = 0  # MAP messages received
    inputs: int = 0  # INPUT messages sent
    pongs: int = 0  # pings answered
    end: dict[str, Any] | None = None  # the end page's message (completed or excluded)
    stopped: str = ""  # why it stopped otherwise ("aborted", "timeout", an error)

    @property
    def camera_fps(self) -> float:
        """[1/s] camera frames received while driving."""
        return self.drive_camera_frames / self.drive_s if self.drive_s > 0 else 0.0


def _std_index(table: dict[int, int]) -> dict[int, int]:
    """SDL/XInput index -> standard-mapping index (inverse of :mod:`study.web.link`'s)."""
    return {sdl: std for std, sdl in table.items()}


def _screen_key(screen: dict[str, Any]) -> tuple:
    """What makes a screen another one (a form's updates do not): as the scripted person's
    :meth:`study.web.testing.Person.key`."""
    return tuple(screen.get(k) for k in ("kind", "title", "body", "progress", "tag"))


class ProtocolClient:
    """One participant's page over the wire protocol, with a scripted person behind it.

    Parameters
    ----------
    link : str
        The invite's link (``http://host:port/s/<token>``).
    mapping : GamepadMapping, optional
        The protocol's gamepad mapping (default: the default ``[input]``'s); the client
        sends the standard-mapping axes and buttons that give its stick and its "yes".
    """

    def __init__(self, link: str, *, mapping: GamepadMapping | None = None) -> None:
        self.link = link
        self.mapping = mapping or GamepadMapping(DEFAULT_AXES, DEFAULT_BUTTONS)
        self.record = ClientRecord(link)
        self.screen: dict[str, Any] | None = None
        self._key: tuple | None = None
        self._yes = _std_index(STD_BUTTONS)[int(self.mapping.buttons["yes"])]
        self._axes = _std_index(STD_AXES)
        self._buttons: deque[int] = deque()  # the buttons held in the next input periods
        self._seq = 0
        self._tick = 0  # the last state tick received: the page's "drawn"
        self._pose: tuple[float, float, float] | None = None
        self._since: float | None = None  # [s] monotonic, this trial's first state
        self._last_state = 0.0  # [s] monotonic
        self._question = ""
        self._drawn = asyncio.Event()  # set by a state not yet answered

    @property
    def ws_url(self) -> str:
        return (
            self.link.replace("http://", "ws://", 1)
            .replace("https://", "wss://", 1)
            .replace("/s/", "/ws/", 1)
        )

    @property
    def driving(self) -> bool:
        """On a driving screen whose states have begun."""
        return self._since is not None

    @property
    def done(self) -> bool:
        return self.record.end is not None or bool(self.record.stopped)

    async def run(self, http: aiohttp.ClientSession) -> ClientRecord:
        """Join, follow the session to its end page (or until it is stopped)."""
        async with http.ws_connect(self.ws_url, max_msg_size=0) as ws:
            await ws.send_str(json.dumps({"type": "hello"}))
            sender = asyncio.create_task(self._send_inputs(ws))
            try:
                async for msg in ws:
                    if msg.type == aiohttp.WSMsgType.BINARY:
                        self._binary(msg.data)
                    elif msg.type == aiohttp.WSMsgType.TEXT:
                        for reply in self._text(json.loads(msg.data)):
                            await ws.send_str(json.dumps(reply))
                    if self.done:
                        break
            finally:
                sender.cancel()
                self._leave_drive()
        if not self.done:
            self.record.stopped = "the server closed the connection"
        return self.record

    # -------------------------------------------------------------- the server's messages

    def _text(self, m: dict[str, Any]) -> list[dict[str, Any]]:
        """One JSON message from the server; the replies."""
        kind = m.get("type")
        if kind == "check":
            w, h = WINDOW
            return [{"type": "check", "width": w, "height": h, "mobile": False,
                     "gamepad": True, "agent": "asa protocol client"}]  # fmt: skip
        if kind == "ping":
            self.record.pongs += 1
            return [{"type": "pong", "id": m["id"]}]
        if kind == "screen":
            self._screen(m["screen"])
        elif kind == "strip" and m.get("question") and m["question"] != self._question:
            self._question = m["question"]
            self._press(self._yes)
        elif kind == "end":
            self.record.end = m
        elif kind in ENDINGS:
            self.record.stopped = str(kind)
        return []

    def _screen(self, screen: dict[str, Any]) -> None:
        """A screen: the presses it needs, once per screen (a re-sent one needs none)."""
        key = _screen_key(screen)
        if key == self._key:
            return
        self._leave_drive()
        self._key, self.screen = key, screen
        self.record.screens.append(screen["kind"])
        if screen["kind"] == "page":
            self._press(self._yes)
        elif screen["kind"] == "form":
            for _ in screen["rows"]:
                self._press(RIGHT)
                self._press(self._yes)
            self._press(self._yes)
        elif screen["kind"] == "pair":
            self._press(RIGHT)
            self._press(self._yes)
        elif screen["kind"] == "drive":
            self._tick, self._pose, self._question = 0, None, ""

    def _leave_drive(self) -> None:
        if self._since is not None:
            self.record.drive_s += self._last_state - self._since
        self._since = None

    def _binary(self, data: bytes) -> None:
        kind = data[0]
        if kind == wire.STATE:
            state = wire.unpack_state(data)
            self._tick, self._pose = state["tick"], state["pose"]
            self.record.states += 1
            self._drawn.set()
            self._last_state = time.monotonic()
            if self.screen is not None and self.screen["kind"] == "drive" and self._since is None:
                self._since = self._last_state
        elif kind == wire.CAMERA:
            wire.CAMERA_HEAD.unpack_from(data)  # its head read, the JPEG not decoded
            self.record.camera_frames += 1
            self.record.drive_camera_frames += int(self.driving)
        elif kind == wire.MAP:
            self.record.maps += 1

    # -------------------------------------------------------------- the person's input

    def _press(self, button: int) -> None:
        """Press ``button`` for :data:`HOLD` input periods, then release it as long."""
        self._buttons.extend([1 << button] * HOLD + [0] * HOLD)

    def _stick(self) -> tuple[float, float, float, float]:
        """The standard axes: the left stick towards the trial's last goal."""
        screen, pose = self.screen, self._pose
        if screen is None or screen["kind"] != "drive" or not screen["drive"] or pose is None:
            return (0.0, 0.0, 0.0, 0.0)
        if not screen["goals"]:
            return (0.0, 0.0, 0.0, 0.0)
        goal = screen["goals"][-1]
        dx, dy = goal["x"] - pose[0], goal["y"] - pose[1]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        forwards, left = c * dx + s * dy, -s * dx + c * dy  # the goal in the robot's frame
        d = math.hypot(forwards, left)
        if d < 0.5 * goal["tolerance_m"]:
            return (0.0, 0.0, 0.0, 0.0)
        raw = self.mapping.stick_to_raw(np.array([forwards / d, left / d, 0.0]) * STICK)
        axes = [0.0, 0.0, 0.0, 0.0]
        for sdl, value in raw.items():
            if sdl in self._axes:
                axes[self._axes[sdl]] = value
        return (axes[0], axes[1], axes[2], axes[3])

    async def _send_inputs(self, ws: aiohttp.ClientWebSocketResponse) -> None:
        """An ``INPUT`` as soon as a state arrived (a page answers on its next animation
        frame), and 1/20 s after the last one when none did (pages, a late state)."""
        while not ws.closed:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._drawn.wait(), 1.0 / INPUT_HZ)
            self._drawn.clear()
            buttons = self._buttons.popleft() if self._buttons else 0
            self._seq += 1
            payload = wire.pack_input(self._seq, self._tick, self._stick(), buttons=buttons,
                                      gamepad=True)  # fmt: skip
            try:
                await ws.send_bytes(payload)
            except (ConnectionError, RuntimeError):
                return
            self.record.inputs += 1


async def _every(
    clients: Sequence[ProtocolClient], every_s: float, call: Callable[[list], None]
) -> None:
    while True:
        await asyncio.sleep(every_s)
        call(list(clients))


async def _run_all(
    links: Sequence[str], mapping: GamepadMapping | None, timeout_s: float, every_s: float,
    on_every: Callable[[list], None] | None,
) -> list[ClientRecord]:  # fmt: skip
    clients = [ProtocolClient(link, mapping=mapping) for link in links]
    async with aiohttp.ClientSession() as http:
        watch = asyncio.create_task(_every(clients, every_s, on_every)) if on_every else None
        runs = asyncio.gather(*(c.run(http) for c in clients), return_exceptions=True)
        try:
            results = await asyncio.wait_for(runs, timeout_s)
        except TimeoutError:
            results = [None] * len(clients)
        finally:
            if watch is not None:
                watch.cancel()
    for client, result in zip(clients, results, strict=True):
        if isinstance(result, BaseException):
            client.record.stopped = f"{type(result).__name__}: {result}"
        elif result is None and not client.done:
            client.record.stopped = "timeout"
    return [c.record for c in clients]


def run_clients(
    links: Sequence[str], *, mapping: GamepadMapping | None = None, timeout_s: float = 600.0,
    every_s: float = 1.0, on_every: Callable[[list[ProtocolClient]], None] | None = None,
) -> list[ClientRecord]:  # fmt: skip
    """A :class:`ProtocolClient` per link, all at once in one event loop, each to its
    session's end (at most ``timeout_s``); their records in the links' order.
    ``on_every(clients)`` is called every ``every_s`` seconds while they run (in the
    loop: it must be quick)."""
    return asyncio.run(_run_all(links, mapping, timeout_s, every_s, on_every))
