"""A person at the pygame screen (issue 5): :class:`HumanParticipant` implements the
participant interface (:mod:`study.participants.base`) with the window of :mod:`study.ui`.

- ``read(text)``: a text page (briefing, practice feedback, debrief), continue with A,
  Enter, Space or Y.
- ``fill(instrument)``: the questionnaire page of :mod:`study.ui.forms`; ``choose(pairs)``:
  the NASA-TLX pairwise comparisons, one page per pair.
- ``attach(world, event)`` (the trial loop's hook) and ``begin_trial(info)``: the map of the
  trial's scenario, the camera feed on its world, then a "get ready" page that says what the
  trial asks (route, inspection, questions, time limit; never the mode) and serves as the
  break between trials; the trial starts when the participant presses A / Enter.
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

from questionnaires import nasa_tlx
from sim.occupancy import OccupancyGrid, build_grid
from sim.types import Observation
from study.engine.protocol import InputSettings, UiSettings
from study.participants.base import ParticipantBase
from study.types import ParticipantInput, ScreenState, TrialInfo
from study.ui.camera import CameraFeed
from study.ui.clock import UiClock
from study.ui.forms import FormState, FormView, PairView
from study.ui.input import GamepadMapping, InputState
from study.ui.screen import CONFIRM_S, Screen, TrialView

CONTINUE = "Press A on the gamepad (or Enter) to continue."
LOST = (
    "The gamepad was disconnected. The trial is paused. Please plug it in again: the trial "
    "continues as soon as it is back."
)
PAUSED = "Paused. Please wait for the experimenter."
_PHASE_TITLES = {
    "training": "Training",
    "practice": "Practice",
    "baseline": "Questions only",
    "main": "Trial",
}
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


def _route_text(info: TrialInfo) -> str:
    dock = info.scenario.dock
    under = dock is not None and bool(dock.table)
    names = {"dock": "B (under the table)" if under else "B", "start": "A"}
    stops = [names.get(r, r) for r in info.route]
    if not info.drive:
        return (
            "The robot stands still. Questions appear at the bottom of the screen: is the "
            "shown result correct? Answer Yes or No as quickly and accurately as you can."
        )
    text = "Drive the robot from A to " + " and then to ".join(stops) + "." if stops else ""
    if info.phase == "training":
        text = "Drive freely and get used to the robot."
    if info.inspection:
        text += " On the way, inspect the red object: drive around it so you can see it."
    if info.secondary:
        text += " Questions appear at the bottom of the screen: answer them with Yes or No."
    if info.time_limit_s < 1e6:
        text += f" You have {info.time_limit_s:.0f} s."
    return text.strip()


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
        self.input = InputState(self.mapping)
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
            ui.window, fullscreen=ui.fullscreen, show_map=ui.show_map, layout=ui.layout
        )
        pygame.joystick.init()
        # the tail camera is rendered only for the screen that shows it (Sec. 7.5)
        self.camera = camera if camera is not None else CameraFeed()
        self.camera.tail = ui.layout == "laser"
        self.world: Any = None
        self._event: Callable[..., None] | None = None
        self._grids: dict[str, OccupancyGrid] = {}
        self._footprint = np.zeros((4, 2))
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
        handle: Callable[[pygame.event.Event, list[str]], bool],
        inject: Callable[[], Any] | None = None,
    ) -> Any:
        """Run one page until ``handle`` says it is done; returns what ``inject`` returned."""
        self._pump(keep=False)  # presses from before the page do not count
        self._pending.clear()
        injected = inject() if inject is not None else None
        draw()
        self.snapshot(tag)
        while True:
            for event in pygame.event.get():
                actions = self.input.handle(event)
                if "quit" in actions:
                    raise KeyboardInterrupt("the participant's window was closed")
                if handle(event, actions):
                    return injected
            draw()
            self._page_clock.tick(self.fps)

    # -------------------------------------------------------------- pages

    def read(self, text: str) -> None:
        """A text page; returns when the participant continues."""

        def handle(event: pygame.event.Event, actions: list[str]) -> bool:
            return "confirm" in actions or "yes" in actions or event.type == pygame.MOUSEBUTTONDOWN

        self._page(
            "text",
            lambda: self.screen.draw_page("", text, CONTINUE),
            handle,
            (lambda: self.driver.on_text(text)) if self.driver is not None else None,
        )

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """A questionnaire page; returns item id -> answer once every required item is set."""
        state = FormState(instrument)
        view = FormView(self.screen, state)

        def handle(event: pygame.event.Event, actions: list[str]) -> bool:
            if event.type == pygame.MOUSEBUTTONDOWN and event.button == 1:
                view.click(event.pos)
            for a in actions:
                state.action(a)
            return state.done

        inject = None
        if self.driver is not None:
            driver = self.driver

            def inject() -> Any:
                return driver.on_form(instrument, context, FormState(instrument))

        self._page(f"form_{instrument.id}", view.draw, handle, inject)
        view.draw()
        self.snapshot(f"form_{instrument.id}_done")
        return state.answers()

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """The pairwise comparisons, one page each; pair -> chosen subscale id."""
        titles = {s.id: s.title for s in nasa_tlx.SUBSCALES}
        texts = {s.id: s.description for s in nasa_tlx.SUBSCALES}
        if self.driver is not None:
            self.driver.on_choose(pairs)
        out: dict[tuple[str, str], str] = {}
        for k, pair in enumerate(pairs):
            view = PairView(self.screen, pair, titles, texts)
            progress = f"Pair {k + 1} of {len(pairs)}"

            def handle(
                event: pygame.event.Event, actions: list[str], view: PairView = view
            ) -> bool:
                if event.type == pygame.MOUSEBUTTONDOWN and event.button == 1:
                    view.click(event.pos)
                for a in actions:
                    view.action(a)
                return view.chosen is not None

            inject = None
            if self.driver is not None:

                def inject(pair: tuple[str, str] = pair, driver: Any = self.driver) -> None:
                    driver.on_pair(pair)

            self._page(
                "pair",
                lambda view=view, progress=progress: view.draw(nasa_tlx.PAIR_QUESTION, progress),
                handle,
                inject,
            )
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
        """A "get ready" page saying what the trial asks; the trial starts on A / Enter."""
        self._info = info
        robot = info.scenario.robot
        self._footprint = robot.footprint()
        self._limits = (float(robot.max_speed), float(robot.max_yaw_rate))
        self._lost_pause = False
        self._overlay = ""
        self._confirm = ("", 0.0)
        self._view = None
        self._next_shot = 0.0
        title = _PHASE_TITLES.get(info.phase, info.phase.title())
        body = _route_text(info)
        if info.phase == "main":
            body += "\n\nTake a short break if you like."
        if self.driver is not None:
            self.driver.begin_trial(info)

        def handle(event: pygame.event.Event, actions: list[str]) -> bool:
            return "confirm" in actions or "yes" in actions

        self._page(
            f"{info.phase}_ready",
            lambda: self.screen.draw_page(title, body, "Press A (or Enter) to start."),
            handle,
            (lambda: self.driver.on_ready(info)) if self.driver is not None else None,
        )
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
        now = time.perf_counter()
        if self.status is not None and now >= self._next_status:
            self._next_status = now + self.status_every_s
            self.status(self.status_line(screen))
        return ParticipantInput(u=u, answer=answer, pause=pause)

    def _frame(self, pump: bool = True) -> None:
        """One frame of the driving screen from the last tick's view (also between ticks)."""
        if pump:
            self._pump()
        view = self._view
        if view is None:
            return
        self.camera.update()
        overlay = self._overlay
        if not overlay and view.screen.paused:
            overlay = PAUSED
        text, since = self._confirm
        confirmation = text if text and time.perf_counter() - since < CONFIRM_S else ""
        drive = self._info is None or self._info.drive
        self.screen.draw_trial(
            TrialView(
                screen=view.screen,
                pose=view.pose,
                points=view.points,
                stick=self.input.stick() if drive else _ZERO3,
                camera=self.camera.image,
                tail_camera=self.camera.tail_image,
                scan=view.scan,
                confirmation=confirmation,
                overlay=overlay,
            ),
            footprint=self._footprint,
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
        if self._view is not None:
            self.snapshot(f"{self._view.screen.phase}_end")
        self.world = None
        self._event = None
        if self.driver is not None:
            self.driver.end_trial(outcome)

    def camera_image(self, which: str = "front") -> np.ndarray | None:
        """The front (or tail) camera image on the screen now (the trial loop logs it in
        the recording instead of rendering its own), None before the first frame."""
        return self.camera.tail_image if which == "tail" else self.camera.image

    def close(self) -> None:
        """Stop the camera worker and close the window."""
        self.camera.close()
        self.screen.close()
