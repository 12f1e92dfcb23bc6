"""A person at a browser page (issue 37): :class:`WebParticipant` implements the participant
interface (:mod:`study.participants.base`) over a :class:`study.web.link.Link`, with the
same screens as the pygame one (:mod:`study.ui.describe`) and the same session flow:

- ``read``, ``fill``, ``choose``: send the screen's description, apply the page's presses
  (held directions repeat as on the pygame screen), send it again when it changed, and
  return when it is done; the form's logic is :class:`study.ui.forms.FormState`.
- ``attach`` and ``begin_trial``: the scene's map once, the "get ready" page, the driving
  screen; ``end_trial``: "time's up" or "crashed" as on the pygame screen.
- ``act``: the tick's state to the page (20 Hz, binary), the camera at ``[web] camera_hz``
  latest-wins, and the newest input back without waiting, with its age and round trip.

A page that goes away (or falls silent while driving) pauses the trial through the
participant's pause, with ``connection_lost`` / ``connection_back`` events; one away
longer than ``[web] grace_s`` ends the session (:class:`ConnectionGone`), resumable. The
experimenter's abort arrives as a stop: during a trial through the trial's abort, on a
page as :class:`SessionStopped`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from sim.occupancy import OccupancyGrid, build_grid
from sim.types import Observation
from study.engine.clocks import ExperimenterControl
from study.engine.protocol import InputSettings, UiSettings
from study.participants.base import ParticipantBase
from study.types import ParticipantInput, ScreenState, TrialInfo
from study.ui import describe
from study.ui.controls import Controls
from study.ui.forms import FormState
from study.ui.sticks import NavRepeat
from study.web import messages as wire
from study.web.link import Link
from study.web.scene import map_message, scene_message
from study.web.settings import WebSettings

CONNECTION_LOST = "The connection was lost. The trial is paused until you are back."
POLL_S = 0.02  # [s] pages poll the link at 50 Hz
STATUS_EVERY_S = 1.0  # [s] between two status lines for the experimenter's view
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


class SessionStopped(Exception):
    """The session cannot go on: the experimenter aborted it or the server stopped."""


class ConnectionGone(SessionStopped):
    """The page stayed away longer than the protocol's grace period."""


class WebParticipant(ParticipantBase):
    """A participant at a browser page, through the study server.

    Parameters
    ----------
    ui, inputs, web : UiSettings, InputSettings, WebSettings
        The protocol's ``[ui]``, ``[input]`` and ``[web]``.
    link : Link
        The pipe to the server.
    parameters : mapping
        Stored with the participant row (the interface, Prolific's ids, the check).
    camera : CameraFeed, optional
        Renders the camera off the control path; None: no camera on the page.
    control : ExperimenterControl, optional
        The session's; the experimenter's abort during a trial goes through it.
    """

    kind = "human"
    shows_camera = True

    def __init__(
        self,
        ui: UiSettings,
        inputs: InputSettings,
        web: WebSettings,
        link: Link,
        *,
        parameters: Mapping[str, Any] | None = None,
        camera: Any | None = None,
        control: ExperimenterControl | None = None,
    ) -> None:
        self.ui, self.web, self.link = ui, web, link
        self.controls = Controls.from_settings(inputs)
        self.parameters = {"interface": "browser", **(parameters or {})}
        self.camera = camera
        self._jpeg: Any = None  # cv2.imencode, imported here, not in a tick
        if camera is not None:
            camera.tail = ui.layout == "laser"
            import cv2  # an ordinary dependency (opencv-python-headless)

            self._jpeg = cv2
        self.control = control
        self.world: Any = None
        self._event: Callable[..., None] | None = None
        self._grids: dict[str, OccupancyGrid] = {}
        self._map: tuple[bytes, str] | None = None  # the scene's MAP and JSON messages
        self._map_id = 0
        self._info: TrialInfo | None = None
        self._drive: describe.DriveScreen | None = None
        self._screen: str = ""  # the JSON of the screen shown (resent to a new page)
        self._opened = 0  # link.opened when the screen was last sent
        self._ended = ""
        self._title = ""
        self._limits = (1.0, 1.0)
        self._tick = 0  # the trial's act calls: the state messages' tick
        self._lost = False  # the trial is paused because the page is away
        self._strip = describe.DriveStrip()
        self._confirm = ("", 0.0)
        self._camera_due = 0.0
        self._camera_frames = 0
        self._status_due = 0.0
        self._drops: dict[str, int] = {}  # the link's drop counts when last stored
        self.rtts: list[float] = []  # [ms] the round trips of this trial's ticks
        self.ages: list[int] = []  # the input ages of this trial's ticks

    # -------------------------------------------------------------- screens

    def _show(self, screen: describe.Screen) -> None:
        """Send ``screen`` and remember it for a page that connects later."""
        self._screen = wire.server_json("screen", screen=describe.to_json(screen))
        self._opened = self.link.opened
        self.link.send(self._screen)

    def _resend(self) -> None:
        """A new page connected: the map and the screen again."""
        self._opened = self.link.opened
        if self._map is not None and self._drive is not None:
            self.link.send(self._map[1])
            self.link.send(self._map[0])
        if self._screen:
            self.link.send(self._screen)

    def _wait(self) -> None:
        """Wait for the page (at most :data:`POLL_S`); raise when the session must stop."""
        link = self.link
        link.changed.wait(POLL_S)
        link.changed.clear()
        if link.stopped:
            raise SessionStopped(link.stopped)
        gone = link.gone_for()
        if gone > self.web.grace_s:
            raise ConnectionGone(f"the page was away for more than {self.web.grace_s:g} s")
        if link.connected and link.opened != self._opened:
            self._resend()

    def _page(
        self,
        show: Callable[[], describe.Screen],
        handle: Callable[[list[str], list[dict[str, Any]]], bool],
        *,
        repeat: bool = False,
    ) -> None:
        """Show a page until ``handle(presses, messages)`` says it is done; send it again
        whenever it changed. ``repeat``: held directions repeat (forms)."""
        self.link.clear()
        self._show(show())
        repeats = NavRepeat()
        while True:
            self._wait()
            actions, msgs = self.link.take()
            if repeat:
                actions += repeats.step(time.perf_counter(), self.link.held_nav())
            if not actions and not msgs:
                continue
            if handle(actions, msgs):
                return
            self._show(show())

    def _text(self, page: describe.PageScreen) -> None:
        def handle(actions: list[str], msgs: list[dict[str, Any]]) -> bool:
            click = any(m["type"] == "click" and m["target"] == "page" for m in msgs)
            return click or "confirm" in actions or "yes" in actions

        self._page(lambda: page, handle)

    def read(self, text: str) -> None:
        """A text page; returns when the participant continues."""
        tag, title = (f"{self._ended}_result", self._title) if self._ended else ("page", "")
        self._ended = ""
        self._text(describe.text_page(text, self.controls, title=title, tag=tag))

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """A questionnaire page; item id -> answer once every required item is set."""
        self._ended = ""
        state = FormState(instrument)

        def handle(actions: list[str], msgs: list[dict[str, Any]]) -> bool:
            for m in msgs:
                _form_message(state, m)
            for a in actions:
                state.action(a)
            return state.done

        self._page(lambda: describe.form_screen(state, self.controls), handle, repeat=True)
        return state.answers()

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """The pairwise comparisons, one page each; pair -> chosen subscale id."""
        self._ended = ""
        out: dict[tuple[str, str], str] = {}
        for k, pair in enumerate(pairs):
            pick: list[int | None] = [None, None]  # highlighted, chosen

            def handle(actions: list[str], msgs: list[dict[str, Any]], pick=pick) -> bool:
                for m in msgs:
                    if m["type"] == "click" and m["target"] == "pair" and m["index"] < 2:
                        pick[0] = pick[1] = m["index"]
                for a in actions:
                    if a in ("left", "right"):
                        pick[0] = 0 if a == "left" else 1
                    elif a in ("confirm", "yes") and pick[0] is not None:
                        pick[1] = pick[0]
                return pick[1] is not None

            def show(pair=pair, k=k, pick=pick) -> describe.Screen:
                return describe.pair_screen(pair, k, len(pairs), pick[0], self.controls)

            self._page(show, handle)
            out[(pair[0], pair[1])] = pair[int(pick[1])]  # type: ignore[arg-type]
        return out

    # -------------------------------------------------------------- trials

    def attach(self, world: Any, event: Callable[..., None]) -> None:
        """The trial's world (read only) and its event writer; the scene's map."""
        self.world, self._event = world, event
        scenario = world.scenario
        key = scenario.source or scenario.name
        if key not in self._grids:
            self._grids[key] = build_grid(scenario)
            self._map_id += 1
            grid = self._grids[key]
            self._map = (map_message(self._map_id, scenario, grid), scene_message(
                self._map_id, scenario, show_object=self.ui.show_object))  # fmt: skip
        if self.camera is not None:
            self.camera.set_world(world)

    def begin_trial(self, info: TrialInfo) -> None:
        """The "get ready" page; then the driving screen with the scene's map."""
        self._info = info
        robot = info.scenario.robot
        self._limits = (float(robot.max_speed), float(robot.max_yaw_rate))
        self._ended = ""
        page, reminder = describe.ready_page(info, self.ui, self.controls)
        self._title = page.title
        self._text(page)
        self._drive = describe.drive_screen(
            info, self.ui, self.controls, title=page.title, reminder=reminder
        )
        self._tick, self._lost, self._confirm = 0, False, ("", 0.0)
        self._strip = describe.DriveStrip()
        self.rtts, self.ages = [], []
        self.link.clear()
        self.link.new_trial()
        self._resend_drive()

    def _resend_drive(self) -> None:
        assert self._map is not None and self._drive is not None  # attach came first
        self.link.send(self._map[1])
        self.link.send(self._map[0])
        self._show(self._drive)
        self.link.send(wire.server_json("strip", **_strip_json(self._strip)))

    def act(self, obs: Observation, screen: ScreenState) -> ParticipantInput:
        """One control tick: the state to the page, the newest input back."""
        link = self.link
        self._tick += 1
        toggles = self._connection(screen)
        actions, msgs = link.take()
        self._page_events(screen.t, msgs)
        answer: bool | None = None
        for a in actions:
            if a == "pause" and not self._lost:
                toggles += 1
            elif a in ("yes", "no") and answer is None and not screen.paused:
                answer = a == "yes"
        if answer is not None and screen.question:
            self._confirm = (f"Answer recorded: {'Yes' if answer else 'No'}", time.perf_counter())
        drive = self._info is None or self._info.drive
        stick = link.stick() if drive else _ZERO3
        paused = screen.paused or self._lost
        speed, yaw_rate = self._limits
        u = _ZERO3 if paused or not drive else stick * np.array([speed, speed, yaw_rate])
        self._send_tick(obs, screen, stick)
        age, rtt = link.timing(self._tick)
        if age is not None:
            self.ages.append(age)
        if rtt is not None:
            self.rtts.append(rtt)
        self._status(screen, age)
        return ParticipantInput(
            u=u, answer=answer, pause=toggles % 2 == 1, age_ticks=age, rtt_ms=rtt
        )

    def _connection(self, screen: ScreenState) -> int:
        """Pause the trial when the page went away or fell silent, resume when it is back;
        returns the pause toggles this causes (0 or 1)."""
        link = self.link
        if link.stopped and self.control is not None:
            self.control.abort(f"stopped: {link.stopped}")
        gone = link.silent_for() > self.web.silent_s
        if gone and link.gone_for() > self.web.grace_s:
            raise ConnectionGone(f"the page was away for more than {self.web.grace_s:g} s")
        if gone and not self._lost:
            self._lost = True
            if self._event is not None:
                self._event(screen.t, "connection_lost", silent_s=round(link.silent_for(), 3))
            return 0 if screen.paused else 1
        if not gone and self._lost:
            self._lost = False
            if self._event is not None:
                self._event(screen.t, "connection_back")
            if link.opened != self._opened:
                self._resend_drive()
            return 1 if screen.paused else 0
        return 0

    def _page_events(self, t: float, msgs: list[dict[str, Any]]) -> None:
        """The page hidden or shown, focus lost or back, messages the server dropped since
        the last such event (by reason): events of the trial."""
        if self._event is None:
            return
        drops = dict(self.link.drops)
        if drops != self._drops:
            new = {k: v - self._drops.get(k, 0) for k, v in drops.items()}
            self._event(t, "messages_dropped", **{k: v for k, v in new.items() if v})
            self._drops = drops
        for m in msgs:
            if m["type"] == "visibility":
                self._event(t, "page_hidden" if m["hidden"] else "page_visible")
            elif m["type"] == "focus":
                self._event(t, "focus_back" if m["focused"] else "focus_lost")

    def _send_tick(self, obs: Observation, screen: ScreenState, stick: np.ndarray) -> None:
        """The tick's state, the strip when it changed, a camera frame when one is due."""
        pose = obs.pose
        points = pose.to_map_frame(obs.points) if len(obs.points) else np.empty((0, 2))
        payload = wire.pack_state(
            self._tick, screen.t, (pose.x, pose.y, pose.yaw), stick, points, paused=screen.paused
        )
        self.link.send_state(self._tick, payload)
        text, since = self._confirm
        overlay = CONNECTION_LOST if self._lost else ""
        if not overlay and screen.paused:
            overlay = describe.paused_text(self.ui, self.controls)
        strip = describe.DriveStrip(
            question=screen.question,
            confirmation=text if text and time.perf_counter() - since < 1.0 else "",
            overlay=overlay,
            feedback=screen.feedback,
        )
        if strip != self._strip:
            self._strip = strip
            self.link.send(wire.server_json("strip", **_strip_json(strip)))
        self._send_camera()

    def _send_camera(self) -> None:
        camera = self.camera
        if camera is None or self.web.camera_hz <= 0:
            return
        camera.update()
        now = time.monotonic()
        if camera.frames == self._camera_frames or now < self._camera_due:
            return
        self._camera_frames = camera.frames
        period = 1.0 / self.web.camera_hz  # on a schedule: a late frame does not shift it
        self._camera_due = max(self._camera_due + period, now - period)
        cv2 = self._jpeg
        for which, image in (("front", camera.image), ("tail", camera.tail_image)):
            if image is None:
                continue
            ok, jpeg = cv2.imencode(".jpg", image[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 70])
            if ok:
                self.link.send(wire.pack_camera(self._tick, which, jpeg.tobytes()), latest=which)

    def _status(self, screen: ScreenState, age: int | None) -> None:
        now = time.monotonic()
        if now < self._status_due or self.world is None:
            return
        self._status_due = now + STATUS_EVERY_S
        pose = self.world.true_pose()
        recent = self.rtts[-40:]
        self.link.status({
            "phase": screen.phase, "title": self._title, "t": round(screen.t, 1),
            "paused": screen.paused, "lost": self._lost, "age": age,
            "rtt_ms": round(float(np.median(recent)), 1) if recent else None,
            "pose": [round(pose.x, 2), round(pose.y, 2), round(pose.yaw, 2)],
            "collisions": len(self.world.contacts()),
        })  # fmt: skip

    def end_trial(self, outcome: dict[str, Any]) -> None:
        """ "Time's up" or "crashed" as on the pygame screen."""
        info = self._info
        self.world, self._event = None, None
        if info is None:
            return
        self._ended = info.phase if info.phase == "practice" else ""
        page = describe.ended_page(info, outcome, self.ui, self.controls)
        if page is not None:
            self._text(page)

    def camera_image(self, which: str = "front") -> np.ndarray | None:
        """The camera image the page was sent last (the recording logs it)."""
        if self.camera is None:
            return None
        return self.camera.tail_image if which == "tail" else self.camera.image

    def close(self) -> None:
        """Stop the camera's worker."""
        if self.camera is not None:
            self.camera.close()


def _strip_json(strip: describe.DriveStrip) -> dict[str, Any]:
    return {
        "question": strip.question,
        "confirmation": strip.confirmation,
        "overlay": strip.overlay,
        "feedback": strip.feedback,
    }


def _form_message(state: FormState, m: dict[str, Any]) -> None:
    """A typed key or a click on a form page, checked against the form's rows."""
    rows = len(state.items)
    if m["type"] == "key":
        if m["key"] == "Backspace":
            state.backspace()
        else:
            state.type_digit(m["key"])
        return
    if m["type"] != "click":
        return
    target = m["target"]
    if target == "done":
        state.select(state.done_row)
        state.finish()
    elif target == "row" and m["row"] <= rows:
        state.select(m["row"])
    elif target == "option" and m["row"] < rows and m["index"] < len(state.options[m["row"]]):
        state.choose(m["row"], m["index"])
    elif target == "fraction" and m["row"] < rows and state.items[m["row"]].kind == "slider":
        state.set_fraction(m["row"], m["fraction"])
