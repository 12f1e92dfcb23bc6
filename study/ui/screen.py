"""The participant's window: the driving screen and the text pages (issue 5, "The screen";
thesis Sec. 7.6.1 and Fig. 7.47: the camera image on the left, the map with the robot and
its laser scan on the right, the secondary task's question below, the gamepad in hand).

Layout (fractions of the window, which comes from the protocol's ``[ui] window``):

- top, 9 %: the status line: the trial's title ("Trial 1 of 3", "Practice 1 of 3, attempt
  1 of 2") with a one-line reminder of the task, under it any feedback, the trial's elapsed
  time on the right; never the name of the active mode;
- middle: the camera image on the left half, the occupancy map of the whole scene on the
  right half (:mod:`study.ui.map_view`; ``show_map = false``: the camera alone, centred),
  each scaled to fit with its aspect ratio kept;
- ``layout = "laser"`` (thesis Sec. 7.5, Fig. 7.42) instead: the robot-centred laser scan
  with the robot model and the stick arrow on the left (:mod:`study.ui.laser_view`), the
  front camera top right and the tail camera (the back view) bottom right; no map;
- then, only in a trial that asks questions, 18 %: the secondary-task window, the question
  with its shown answer and the Yes / No buttons named after the protocol's gamepad
  buttons and keys, and for one second after an answer the confirmation "Answer recorded:
  Yes" (never whether it was right);
- bottom: the key legend, gamepad and keyboard (:mod:`study.ui.legend`), on every screen.

The map and laser drawing conventions are in docs/decisions.md (study/ui); every string
drawn goes through :meth:`Screen.text` (or the legend), which remembers it in
``texts_seen`` so a test can check that the mode's name is never on screen.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pygame

from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from sim.types import Pose2D
from study.types import ScreenState
from study.ui.describe import DriveScreen, PageScreen
from study.ui.laser_view import draw_laser_view
from study.ui.legend import Legend, draw_legend, legend_height
from study.ui.map_view import ARROW, LASER, REGION, ROBOT, MapView

__all__ = [
    "ARROW",
    "BACKGROUND",
    "CONFIRM_S",
    "DIM",
    "HIGHLIGHT",
    "LASER",
    "NO_COLOUR",
    "PANEL",
    "REGION",
    "ROBOT",
    "TEXT",
    "YES_COLOUR",
    "Screen",
    "TrialView",
]

BACKGROUND = (32, 34, 40)
PANEL = (48, 52, 60)
TEXT = (235, 235, 235)
DIM = (150, 150, 150)
YES_COLOUR = (40, 140, 70)
NO_COLOUR = (170, 50, 50)
HIGHLIGHT = (240, 190, 40)
CONFIRM_S = 1.0  # [s] how long the answer confirmation stays


@dataclass(frozen=True, slots=True)
class TrialView:
    """Everything one frame of the driving screen shows."""

    screen: ScreenState
    pose: Pose2D | None = None  # estimated pose, map frame
    points: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))  # (k, 2) [m] map
    stick: np.ndarray = field(default_factory=lambda: np.zeros(3))  # (3,) deflection [-1, 1]
    camera: np.ndarray | None = None  # (h, w, 3) uint8
    tail_camera: np.ndarray | None = None  # (h, w, 3) uint8, the back view (laser layout)
    scan: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))  # (k, 2) [m] robot
    confirmation: str = ""  # shown under the question
    overlay: str = ""  # a message over everything (device lost, paused)
    title: str = ""  # "Trial 1 of 3"
    reminder: str = ""  # the task in one line
    legend: Legend = ()
    yes_label: str = "Yes  (A / Y)"
    no_label: str = "No  (B / N)"


class Screen:
    """The pygame window.

    Parameters
    ----------
    size : (int, int)
        [px] window width and height.
    fullscreen : bool
        Open fullscreen (the size is then the display's).
    show_map : bool
        Draw the map panel.
    layout : str
        "map" (camera and map) or "laser" (laser scan, front and tail cameras; no map).
    show_object : bool
        Mark the inspection object on the map in its colour.
    """

    def __init__(
        self,
        size: tuple[int, int],
        *,
        fullscreen: bool = False,
        show_map: bool = True,
        layout: str = "map",
        show_object: bool = False,
    ) -> None:
        if layout not in ("map", "laser"):
            raise ValueError(f"Screen: layout must be one of map, laser, got {layout!r}")
        pygame.display.init()
        pygame.font.init()
        flags = pygame.FULLSCREEN if fullscreen else 0
        self.surface = pygame.display.set_mode((0, 0) if fullscreen else size, flags)
        pygame.display.set_caption("Robot study")
        self.width, self.height = self.surface.get_size()
        self.layout = layout
        self.show_map = show_map and layout == "map"
        h = self.height
        self.fonts = {
            "legend": pygame.font.Font(None, max(18, h // 34)),
            "small": pygame.font.Font(None, max(18, h // 30)),
            "body": pygame.font.Font(None, max(22, h // 24)),
            "large": pygame.font.Font(None, max(28, h // 16)),
        }
        self.texts_seen: set[str] = set()
        self._text_cache: dict[tuple[str, str, tuple[int, int, int]], pygame.Surface] = {}
        # id of the image and its scaled surface, per panel
        self._scaled: dict[str, tuple[int, pygame.Surface | None]] = {}
        self.frames = 0
        self.frame_times: list[float] = []  # perf_counter of every flip
        self.questions = True
        self._legends: dict[Legend, pygame.Surface] = {}
        self._fitted: dict[tuple[str, int, str], str] = {}
        self.map = MapView(pygame.Rect(0, 0, 0, 0), show_object=show_object)
        self._marks: tuple[tuple[str, float, float], ...] = ()
        self._grid: tuple[Scenario, OccupancyGrid] | None = None
        self._layout()

    def _layout(self) -> None:
        w, h = self.width, self.height
        top = int(h * 0.09)
        self.legend_rect = pygame.Rect(0, 0, w, legend_height(self.fonts["legend"]))
        self.legend_rect.bottom = h
        bottom = int(h * 0.18) if self.questions else 0
        middle = pygame.Rect(0, top, w, self.legend_rect.top - bottom - top)
        self.status_rect = pygame.Rect(0, 0, w, top)
        self.question_rect = pygame.Rect(0, middle.bottom, w, bottom)
        self.laser_rect = self.tail_rect = pygame.Rect(0, 0, 0, 0)
        self.map_rect = pygame.Rect(0, 0, 0, 0)
        if self.layout == "laser":
            split, half = int(w * 0.55), middle.height // 2
            self.laser_rect = pygame.Rect(0, middle.top, split, middle.height).inflate(-12, -12)
            self.camera_rect = pygame.Rect(split, middle.top, w - split, half).inflate(-12, -12)
            self.tail_rect = pygame.Rect(
                split, middle.top + half, w - split, middle.height - half
            ).inflate(-12, -12)
        elif self.show_map:
            self.camera_rect = pygame.Rect(0, middle.top, w // 2, middle.height).inflate(-12, -12)
            self.map_rect = pygame.Rect(w // 2, middle.top, w - w // 2, middle.height).inflate(
                -12, -12
            )
        else:
            self.camera_rect = middle.inflate(-12, -12)
        if self.map_rect != self.map.rect:
            self.map = MapView(self.map_rect, show_object=self.map.show_object)
            if self._grid is not None:
                self.map.set_scene(*self._grid)
        self._scaled.clear()

    # -------------------------------------------------------------- primitives

    def text(
        self,
        value: str,
        pos: tuple[int, int],
        *,
        font: str = "body",
        colour: tuple[int, int, int] = TEXT,
        anchor: str = "topleft",
    ) -> pygame.Rect:
        """Draw one line of text; returns its rectangle."""
        self.texts_seen.add(value)
        key = (value, font, colour)
        image = self._text_cache.get(key)
        if image is None:
            if len(self._text_cache) > 500:
                self._text_cache.clear()
            image = self._text_cache[key] = self.fonts[font].render(value, True, colour)
        rect = image.get_rect(**{anchor: pos})
        self.surface.blit(image, rect)
        return rect

    def wrap(self, value: str, width: int, *, font: str = "body") -> list[str]:
        """``value`` broken into lines no wider than ``width`` px (paragraphs kept)."""
        f = self.fonts[font]
        lines: list[str] = []
        for paragraph in value.split("\n"):
            line = ""
            for word in paragraph.split():
                trial = f"{line} {word}".strip()
                if f.size(trial)[0] <= width or not line:
                    line = trial
                else:
                    lines.append(line)
                    line = word
            lines.append(line)
        return lines

    def fit(self, value: str, width: int, *, font: str = "body") -> str:
        """``value`` cut at a word to fit ``width`` px, with an ellipsis if cut."""
        key = (value, width, font)
        if key in self._fitted:
            return self._fitted[key]
        f = self.fonts[font]
        fitted = value
        if f.size(value)[0] > width:
            words = value.split()
            while words and f.size(" ".join(words) + " ...")[0] > width:
                words.pop()
            fitted = " ".join(words) + " ..."
        if len(self._fitted) > 100:
            self._fitted.clear()
        self._fitted[key] = fitted
        return fitted

    def paragraph(self, value: str, rect: pygame.Rect, *, font: str = "body", colour=TEXT) -> int:
        """Wrapped text from the top of ``rect``; returns the y below the last line."""
        y = rect.top
        step = self.fonts[font].get_linesize()
        for line in self.wrap(value, rect.width, font=font):
            if line:
                self.text(line, (rect.left, y), font=font, colour=colour)
            y += step
        return y

    def button(
        self, label: str, rect: pygame.Rect, colour: tuple[int, int, int], *, active: bool = True
    ) -> None:
        pygame.draw.rect(self.surface, colour if active else PANEL, rect, border_radius=8)
        pygame.draw.rect(self.surface, TEXT if active else DIM, rect, width=2, border_radius=8)
        self.text(label, rect.center, anchor="center", colour=TEXT if active else DIM)

    def legend(self, legend: Legend) -> None:
        """The key legend in its strip at the bottom of the window (drawn once per legend)."""
        if not legend:
            return
        strip = self._legends.get(legend)
        if strip is None:
            strip = pygame.Surface(self.legend_rect.size)
            strip.fill(BACKGROUND)
            pygame.draw.line(strip, PANEL, (0, 0), (strip.get_width(), 0), 2)
            area = strip.get_rect()
            draw_legend(strip, area, legend, self.fonts["legend"], self.texts_seen)
            self._legends[legend] = strip
        self.surface.blit(strip, self.legend_rect)

    def flip(self) -> None:
        """Show the frame."""
        pygame.display.flip()
        self.frames += 1
        self.frame_times.append(time.perf_counter())
        if len(self.frame_times) > 10000:
            del self.frame_times[:5000]

    def save(self, path: str | Path) -> Path:
        """The current frame as a PNG."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        pygame.image.save(self.surface, str(path))
        return path

    # -------------------------------------------------------------- the trial's scene

    def set_scene(self, scenario: Scenario, grid: OccupancyGrid) -> None:
        """Pre-render the map of ``scenario`` (once per scenario)."""
        if not self.show_map:
            return
        self._grid = (scenario, grid)
        self.map.set_scene(scenario, grid)

    def set_trial(self, drive: DriveScreen) -> None:
        """The trial's driving screen: the question window only if it asks questions, the
        goals and the marks A and B on the map."""
        if drive.questions != self.questions:
            self.questions = drive.questions
            self._layout()
        if self.show_map:
            self.map.set_goals(drive.goals)
            self._marks = drive.marks

    # -------------------------------------------------------------- frames

    def draw_trial(self, view: TrialView, *, footprint: np.ndarray) -> None:
        """One frame of the driving screen (``footprint`` (4, 2) [m] robot frame)."""
        s = self.surface
        s.fill(BACKGROUND)
        self._status(view)
        self._camera_panel("front", view.camera, self.camera_rect)
        if self.layout == "laser":
            self._camera_panel("tail", view.tail_camera, self.tail_rect)
            draw_laser_view(
                s, self.laser_rect, points=view.scan, footprint=footprint, stick=view.stick
            )
        if self.show_map:
            labels = self.map.draw(
                s, self.fonts["small"], scenario_marks=self._marks, points=view.points,
                pose=view.pose, footprint=footprint, stick=view.stick,
            )  # fmt: skip
            self.texts_seen.update(labels)
        if self.questions:
            self._question(view)
        self.legend(view.legend)
        if view.overlay:
            self._overlay(view.overlay)
        self.flip()

    def _status(self, view: TrialView) -> None:
        st = view.screen
        pygame.draw.rect(self.surface, PANEL, self.status_rect)
        pad = self.status_rect.height // 8
        minutes, seconds = divmod(int(st.t), 60)
        clock = self.text(
            f"{minutes}:{seconds:02d}", (self.width - 12, pad), font="small",
            anchor="topright", colour=DIM,
        )  # fmt: skip
        x = 12
        if view.title:
            x = self.text(view.title, (x, pad), font="small", colour=HIGHLIGHT).right + 16
        if view.reminder:
            room = clock.left - 16 - x
            self.text(self.fit(view.reminder, room, font="small"), (x, pad), font="small")
        if st.feedback:
            y = pad + self.fonts["small"].get_linesize() + 4
            self.text(st.feedback, (12, y), font="small", colour=HIGHLIGHT)

    def _overlay(self, message: str) -> None:
        box = pygame.Rect(0, 0, int(self.width * 0.7), int(self.height * 0.3))
        box.center = (self.width // 2, self.height // 2)
        pygame.draw.rect(self.surface, PANEL, box, border_radius=12)
        pygame.draw.rect(self.surface, HIGHLIGHT, box, width=3, border_radius=12)
        self.paragraph(message, box.inflate(-40, -40), font="large")

    def _camera_panel(self, name: str, image: np.ndarray | None, rect: pygame.Rect) -> None:
        """A camera image centred in ``rect``, or a placeholder before the first image."""
        if image is None:
            pygame.draw.rect(self.surface, PANEL, rect)
            self.text("Camera starting ...", rect.center, anchor="center", colour=DIM)
            return
        cam = self._camera_surface(name, image, rect)
        self.surface.blit(cam, cam.get_rect(center=rect.center))

    def _camera_surface(self, name: str, image: np.ndarray, rect: pygame.Rect) -> pygame.Surface:
        """``image`` (h, w, 3) scaled to ``rect``, converted once per new image."""
        key, surf = self._scaled.get(name, (0, None))
        if key != id(image) or surf is None:
            cam = pygame.surfarray.make_surface(np.ascontiguousarray(image.swapaxes(0, 1)))
            h, w = image.shape[:2]
            scale = min(rect.width / w, rect.height / h)
            surf = pygame.transform.scale(cam, (int(w * scale), int(h * scale)))
            self._scaled[name] = (id(image), surf)
        return surf

    def _question(self, view: TrialView) -> None:
        s, r = self.surface, self.question_rect
        pygame.draw.rect(s, PANEL, r)
        question = view.screen.question
        cy = r.top + r.height // 3
        if question:
            self.text(question, (r.centerx, cy), font="large", anchor="center")
        else:
            self.text("Questions appear here.", (r.centerx, cy), anchor="center", colour=DIM)
        bw, bh = int(self.width * 0.2), int(r.height * 0.34)
        yes = pygame.Rect(0, 0, bw, bh)
        no = pygame.Rect(0, 0, bw, bh)
        yes.center = (r.centerx - bw * 3 // 4, r.top + r.height * 3 // 4)
        no.center = (r.centerx + bw * 3 // 4, r.top + r.height * 3 // 4)
        self.button(view.yes_label, yes, YES_COLOUR, active=bool(question))
        self.button(view.no_label, no, NO_COLOUR, active=bool(question))
        if view.confirmation:
            self.text(
                view.confirmation, (r.right - 20, yes.centery), anchor="midright", colour=HIGHLIGHT
            )

    def draw_page(self, page: PageScreen) -> None:
        """A text screen (briefing, instructions, feedback, time's up, debrief): the prompt
        (how to go on) just above the legend."""
        title, body, legend, prompt = page.title, page.body, page.legend, page.prompt
        s = self.surface
        s.fill(BACKGROUND)
        margin = int(self.width * 0.1)
        y = int(self.height * 0.1)
        if title:
            self.text(title, (margin, y), font="large")
            y += self.fonts["large"].get_linesize() * 2
        room = pygame.Rect(margin, y, self.width - 2 * margin, self.legend_rect.top - y)
        self.paragraph(body, room)
        if prompt:
            at = (self.width // 2, self.legend_rect.top - self.fonts["body"].get_linesize())
            self.text(prompt, at, anchor="midbottom", colour=HIGHLIGHT)
        self.legend(legend)
        self.flip()

    def close(self) -> None:
        pygame.display.quit()
