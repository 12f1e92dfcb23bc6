"""A person at the pygame screen (issue 5): :class:`HumanParticipant` implements the
participant interface (:mod:`study.participants.base`) with the window of :mod:`study.ui`.

- ``read(text)``: a text page (briefing, practice feedback, debrief), continue with the
  gamepad's Yes button, Enter, Space or the Yes key.
- ``fill(instrument)``: the questionnaire page of :mod:`study.ui.forms`; ``choose(pairs)``:
  the NASA-TLX pairwise comparisons, one page per pair.
- ``attach(world, event)`` (the trial loop's hook) and ``begin_trial(info)``: the map of the
  trial's scenario, the camera feed on its world, then a "get ready" page, its title the
  trial's place ("Training 2 of 3", "Practice 1 of 3, attempt 1 of 2") and its body the
  protocol's instruction for the phase (never the mode), which serves as the break between
  trials; the trial starts when the participant presses the Yes button or Enter.
- ``end_trial(outcome)``: after a trial that its time limit ended (training, main) a
  "time's up" page, after one a collision ended (``end_on_collision``) a page saying so.
- Every screen carries the key legend of :mod:`study.ui.legend`; every text shown is the
  protocol's (``[ui.instructions]``, ``[ui.texts]``).
- ``act(obs, screen)``: pump the input events, draw the driving screen, return the stick's
  command, a Yes/No press and the pause button. :meth:`HumanParticipant.clock` gives the
  :class:`study.ui.clock.UiClock` that draws more frames between ticks.

Its choices where the spec is silent are in docs/decisions.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pygame

from sim.occupancy import OccupancyGrid, build_grid
from sim.types import Observation
from study.engine.protocol import InputSettings, UiSettings
from study.participants.base import ParticipantBase
from study.types import ParticipantInput, ScreenState, TrialInfo
from study.ui import describe
from study.ui import legend as legends
from study.ui.camera import CameraFeed
from study.ui.clock import UiClock
from study.ui.form_view import FormView, PairView
from study.ui.forms import FormState
from study.ui.input import DIGIT_KEYS, GamepadMapping, InputState, NavRepeat
from study.ui.screen import CONFIRM_S, Screen, TrialView

LOST = describe.DEVICE_LOST
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


class HumanParticipant(ParticipantBase):
    """A participant at the pygame screen.

    Parameters
    ----------
    ui : UiSettings
        The protocol's ``[ui]`` (window size, fullscreen, map).
    inputs : InputSettings
        The protocol's ``[input]`` (gamepad mapping, deadzone).
    driver : EventDriver, optional
        Injects another participant's decisions as events (headless runs,
        :mod:`study.ui.inject`); ``kind`` and ``parameters`` are then the driver's.
    snapshots : Path, optional
        Folder for PNG snapshots.
    snapshot_every_s : float
        [s] of trial time between snapshots.
    camera : CameraFeed, optional
        Default: a worker process (:class:`study.ui.camera.CameraFeed`).
    status : callable, optional
        Receives the experimenter's status lines.
    status_every_s : float
        [s] of wall time between status lines.
    fps : float
        [1/s] frame rate of the pages and of the frames between control ticks.
    """

    kind = "human"
    shows_camera = True  # the recording logs the image on the screen (camera_image)

    def __init__(
        self,
        ui: UiSettings,
        inputs: InputSettings,
        *,
        driver: Any | None = None,
        snapshots: Path | None = None,
        snapshot_every_s: float = 5.0,
        camera: CameraFeed | None = None,
        status: Callable[[str], None] | None = None,
        status_every_s: float = 5.0,
        fps: float = 40.0,
    ) -> None:
        self.ui = ui
        self.mapping = GamepadMapping.from_settings(inputs)
        self.input = InputState(self.mapping, inputs.keys)
        self.controls = legends.Controls.from_settings(inputs)
        self.driver = driver
        self.parameters: dict[str, Any] = {"interface": "pygame"}
        if driver is not None:
            self.kind = driver.kind
            self.parameters = {**driver.parameters, "interface": "pygame", "input": "injected"}
        self.snapshots = Path(snapshots) if snapshots is not None else None
        self.snapshot_every_s = snapshot_every_s
        self.status = status
        self.status_every_s = status_every_s
        self.fps = fps
        self.screen = Screen(
            ui.window, fullscreen=ui.fullscreen, show_map=ui.show_map, layout=ui.layout,
            show_object=ui.show_object,
        )  # fmt: skip
        pygame.joystick.init()
        # the tail camera is rendered only for the screen that shows it (Sec. 7.5)
        self.camera = camera if camera is not None else CameraFeed()
        self.camera.tail = ui.layout == "laser"
        self.world: Any = None
        self._event: Callable[..., None] | None = None
        self._grids: dict[str, OccupancyGrid] = {}
        self._limits = (1.0, 1.0)
        self._info: TrialInfo | None = None
        self._pending: list[str] = []
        self._lost_pause = False
        self._overlay = ""
        self._confirm = ("", 0.0)
        self._view: TrialView | None = None
        self._shots = 0
        self._next_shot = 0.0
        self._next_status = 0.0
        self._trial_frames = (0, 0.0, 0)  # screen frames, wall time, camera frames at start
        self._page_clock = pygame.time.Clock()
        self._title = ""  # the running trial's title
        self._drive: describe.DriveScreen | None = None  # the running trial's screen
        self._ended = ""  # phase of the trial that just ended (names the next page)
        self._asked = False  # the running trial has shown a question

    # -------------------------------------------------------------- plumbing

    def clock(self) -> UiClock:
        """The wall clock for :func:`study.engine.session.run_session` that draws between ticks."""
        return UiClock(self._frame, fps=self.fps)

    def snapshot(self, tag: str) -> Path | None:
        """Save the current frame to the snapshot folder (if any)."""
        if self.snapshots is None:
            return None
        self._shots += 1
        return self.screen.save(self.snapshots / f"{self._shots:04d}_{tag}.png")

    def _pump(self, *, keep: bool = True) -> None:
        """Feed every queued event to the input state; keep the actions for ``act``."""
        for event in pygame.event.get():
            actions = self.input.handle(event)
            if "quit" in actions:
                raise KeyboardInterrupt("the participant's window was closed")
            if keep:
                self._pending.extend(actions)
            elif "device_lost" in actions or "device_back" in actions:
                self._pending.extend(a for a in actions if a.startswith("device_"))

    def _page(
        self,
        tag: str,
        draw: Callable[[], None],
        handle: Callable[[pygame.event.Event | None, list[str]], bool],
        inject: Callable[[], Any] | None = None,
        *,
        repeat: bool = False,
    ) -> Any:
        """Run one page until ``handle`` says it is done; returns what ``inject`` returned.
        ``repeat``: held directions repeat (forms), passed to ``handle`` with no event."""
        self._pump(keep=False)  # presses from before the page do not count
        self._pending.clear()
        injected = inject() if inject is not None else None
        draw()
        self.snapshot(tag)
        repeats = NavRepeat()
        while True:
            for event in pygame.event.get():
                actions = self.input.handle(event)
                if "quit" in actions:
                    raise KeyboardInterrupt("the participant's window was closed")
                if handle(event, actions):
                    return injected
            if repeat:
                steps = repeats.step(time.perf_counter(), self.input.held_nav())
                if steps and handle(None, steps):
                    return injected
            draw()
            self._page_clock.tick(self.fps)

    # -------------------------------------------------------------- pages

    def read(self, text: str) -> None:
        """A text page; returns when the participant continues."""
        # right after a trial (practice): its result, under the trial's title
        tag, title = (f"{self._ended}_result", self._title) if self._ended else ("page", "")
        self._ended = ""
        inject = (lambda: self.driver.on_text(text)) if self.driver else None
        self._text_page(tag, title, text, inject)

    def _text_page(
        self, tag: str, title: str, body: str, inject: Callable[[], Any] | None, verb: str = ""
    ) -> None:
        """A page of text that the Yes button, Enter (or a click) ends."""
        self._show_page(describe.text_page(body, self.controls, title=title, tag=tag, verb=verb),
                        inject)  # fmt: skip

    def _show_page(self, page: describe.PageScreen, inject: Callable[[], Any] | None) -> None:
        """Show ``page`` until the Yes button, Enter (or a click) ends it."""

        def handle(event: pygame.event.Event | None, actions: list[str]) -> bool:
            click = event is not None and event.type == pygame.MOUSEBUTTONDOWN
            return "confirm" in actions or "yes" in actions or click

        self._page(page.tag, lambda: self.screen.draw_page(page), handle, inject)

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """A questionnaire page; returns item id -> answer once every required item is set."""
        self._ended = ""
        state = FormState(instrument)
        view = FormView(self.screen, state, self.controls)

        def handle(event: pygame.event.Event | None, actions: list[str]) -> bool:
            if event is not None and event.type == pygame.MOUSEBUTTONDOWN and event.button == 1:
                view.click(event.pos)
            if event is not None and event.type == pygame.KEYDOWN:
                if event.key in DIGIT_KEYS:
                    state.type_digit(DIGIT_KEYS[event.key])
                elif event.key in (pygame.K_BACKSPACE, pygame.K_DELETE):
                    state.backspace()
            for a in actions:
                state.action(a)
            return state.done

        inject = None
        if self.driver is not None:
            driver = self.driver

            def inject() -> Any:
                return driver.on_form(instrument, context, FormState(instrument))

        self._page(f"form_{instrument.id}", view.draw, handle, inject, repeat=True)
        view.draw()
        self.snapshot(f"form_{instrument.id}_done")
        return state.answers()

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """The pairwise comparisons, one page each; pair -> chosen subscale id."""
        self._ended = ""
        if self.driver is not None:
            self.driver.on_choose(pairs)
        out: dict[tuple[str, str], str] = {}
        for k, pair in enumerate(pairs):
            view = PairView(self.screen, (pair[0], pair[1]), k, len(pairs), self.controls)

            def handle(
                event: pygame.event.Event | None, actions: list[str], view: PairView = view
            ) -> bool:
                if event is not None and event.type == pygame.MOUSEBUTTONDOWN and event.button == 1:
                    view.click(event.pos)
                for a in actions:
                    view.action(a)
                return view.chosen is not None

            inject = None
            if self.driver is not None:

                def inject(pair: tuple[str, str] = pair, driver: Any = self.driver) -> None:
                    driver.on_pair(pair)

            self._page("pair", view.draw, handle, inject)
            assert view.chosen is not None  # the page returns only once chosen
            out[(pair[0], pair[1])] = view.chosen
        return out

    # -------------------------------------------------------------- trials

    def attach(self, world: Any, event: Callable[..., None]) -> None:
        """The trial loop's hook: the trial's world (read only) and its event writer."""
        self.world = world
        self._event = event
        scenario = world.scenario
        key = scenario.source or scenario.name
        if key not in self._grids:
            self._grids[key] = build_grid(scenario)
        self.screen.set_scene(scenario, self._grids[key])
        self.camera.set_world(world)

    def begin_trial(self, info: TrialInfo) -> None:
        """A "get ready" page saying what the trial asks; the trial starts on the Yes button
        or Enter."""
        self._info = info
        robot = info.scenario.robot
        self._limits = (float(robot.max_speed), float(robot.max_yaw_rate))
        self._lost_pause = False
        self._overlay = ""
        self._confirm = ("", 0.0)
        self._view = None
        self._next_shot = 0.0
        self._asked = False
        self._ended = ""
        page, reminder = describe.ready_page(info, self.ui, self.controls)
        self._title = page.title
        self._drive = describe.drive_screen(
            info, self.ui, self.controls, title=page.title, reminder=reminder
        )
        self.screen.set_trial(self._drive)
        if self.driver is not None:
            self.driver.begin_trial(info)
        inject = (lambda: self.driver.on_ready(info)) if self.driver is not None else None
        self._show_page(page, inject)
        self._pending.clear()
        self._trial_frames = (self.screen.frames, time.perf_counter(), self.camera.frames)
        self._next_status = time.perf_counter() + self.status_every_s

    def act(self, obs: Observation, screen: ScreenState) -> ParticipantInput:
        """One control tick: input events in, the driving screen drawn, the command out."""
        if self.driver is not None:
            self.driver.on_act(obs, screen)
        self._pump()
        actions, self._pending = self._pending, []
        toggles = 0  # presses of the trial's pause toggle this tick
        answer: bool | None = None
        t = screen.t
        for a in actions:
            if a == "device_lost":
                name = self.input.lost[-1] if self.input.lost else "gamepad"
                if self._event is not None:
                    self._event(t, "input_lost", device=name)
                self._overlay = LOST
                if not screen.paused and not self._lost_pause:
                    toggles += 1
                    self._lost_pause = True
            elif a == "device_back":
                if self._event is not None:
                    self._event(t, "input_back", device=self.input.last_device or "gamepad")
                self._overlay = ""
                if self._lost_pause:
                    toggles += 1 if screen.paused else -1  # -1: lost within this same tick
                    self._lost_pause = False
            elif a == "pause":
                toggles += 1
            elif a in ("yes", "no") and answer is None and not screen.paused:
                answer = a == "yes"
        pause = toggles % 2 == 1
        if answer is not None and screen.question:
            self._confirm = (f"Answer recorded: {'Yes' if answer else 'No'}", time.perf_counter())
        drive = self._info is None or self._info.drive
        u = self.input.command(*self._limits) if drive and not screen.paused else _ZERO3
        self._view = TrialView(
            screen=screen,
            pose=obs.pose,
            points=obs.pose.to_map_frame(obs.points) if len(obs.points) else np.empty((0, 2)),
            stick=self.input.stick() if drive else _ZERO3,
            scan=obs.points,
        )
        self._frame(pump=False)
        if t >= self._next_shot:
            self.snapshot(f"{screen.phase}_t{int(t):03d}")
            self._next_shot = t + self.snapshot_every_s
        if screen.question and not self._asked:  # the trial's first question
            self._asked = True
            self.snapshot(f"{screen.phase}_question")
        now = time.perf_counter()
        if self.status is not None and now >= self._next_status:
            self._next_status = now + self.status_every_s
            self.status(self.status_line(screen))
        return ParticipantInput(u=u, answer=answer, pause=pause)

    def _frame(self, pump: bool = True) -> None:
        """One frame of the driving screen from the last tick's view (also between ticks)."""
        if pump:
            self._pump()
        view, drive = self._view, self._drive
        if view is None or drive is None:
            return
        self.camera.update()
        overlay = self._overlay
        if not overlay and view.screen.paused:
            overlay = describe.paused_text(self.ui, self.controls)
        text, since = self._confirm
        confirmation = text if text and time.perf_counter() - since < CONFIRM_S else ""
        self.screen.draw_trial(
            TrialView(
                screen=view.screen,
                pose=view.pose,
                points=view.points,
                stick=self.input.stick() if drive.drive else _ZERO3,
                camera=self.camera.image,
                tail_camera=self.camera.tail_image,
                scan=view.scan,
                confirmation=confirmation,
                overlay=overlay,
                title=drive.title,
                reminder=drive.reminder,
                legend=drive.legend,
                yes_label=drive.yes_label,
                no_label=drive.no_label,
            ),
            footprint=np.asarray(drive.footprint),
        )

    def status_line(self, screen: ScreenState) -> str:
        """The experimenter's status line for the running trial."""
        frames0, wall0, cam0 = self._trial_frames
        wall = max(1e-9, time.perf_counter() - wall0)
        collisions = len(self.world.contacts()) if self.world is not None else 0
        return (
            f"{screen.phase}: t {screen.t:5.1f} s, {collisions} collisions, screen "
            f"{(self.screen.frames - frames0) / wall:.0f} fps, camera "
            f"{(self.camera.frames - cam0) / wall:.0f} fps" + (", paused" if screen.paused else "")
        )

    def trial_rates(self) -> tuple[float, float]:
        """Screen and camera frames per second of wall time since the trial started."""
        frames0, wall0, cam0 = self._trial_frames
        wall = max(1e-9, time.perf_counter() - wall0)
        return (self.screen.frames - frames0) / wall, (self.camera.frames - cam0) / wall

    def intention(self) -> tuple[str, str]:
        """Ground truth only when a driver decides (a person's intention is unknown)."""
        return self.driver.intention() if self.driver is not None else ("", "")

    def end_trial(self, outcome: dict[str, Any]) -> None:
        """The trial's last frame; a "time's up" page when its time limit ended a training or
        main trial, a page saying so when a collision ended it (``end_on_collision``)."""
        info = self._info
        if self._view is not None:
            self.snapshot(f"{self._view.screen.phase}_end")
        self.world = None
        self._event = None
        if self.driver is not None:
            self.driver.end_trial(outcome)
        if info is None:
            return
        # the runner follows a practice attempt with its result page (read)
        self._ended = info.phase if info.phase == "practice" else ""
        page = describe.ended_page(info, outcome, self.ui, self.controls)
        if page is None:
            return
        inject = self.driver.on_page if self.driver is not None else None
        self._show_page(page, inject)

    def camera_image(self, which: str = "front") -> np.ndarray | None:
        """The front (or tail) camera image on the screen now (the trial loop logs it in
        the recording instead of rendering its own), None before the first frame."""
        return self.camera.tail_image if which == "tail" else self.camera.image

    def close(self) -> None:
        """Stop the camera worker and close the window."""
        self.camera.close()
        self.screen.close()
