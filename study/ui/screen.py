"""The participant's window: the driving screen and the text pages (issue 5, "The screen";
thesis Sec. 7.6.1 and Fig. 7.47: the camera image on the left, the map with the robot and
its laser scan on the right, the secondary task's question below, the gamepad in hand).

Layout (fractions of the window, which comes from the protocol's ``[ui] window``):

- top, 9 %: the status line, the phase's instruction and under it the practice feedback,
  the trial's elapsed time on the right; never the name of the active mode;
- middle: the camera image on the left half, the occupancy map of the whole scene on the
  right half (``show_map = false``: the camera alone, centred), each scaled to fit with its
  aspect ratio kept;
- ``layout = "laser"`` (thesis Sec. 7.5, Fig. 7.42) instead: the robot-centred laser scan
  with the robot model and the stick arrow on the left (:mod:`study.ui.laser_view`), the
  front camera top right and the tail camera (the back view) bottom right; no map;
- bottom, 22 %: the secondary-task window, the question with its shown answer and the
  Yes / No buttons named after the gamepad buttons and keys, and for one second after an
  answer the confirmation "Answer recorded: Yes" (never whether it was right).

The map and laser drawing conventions are in docs/decisions.md (study/ui); every
string drawn goes through :meth:`Screen.text`, which remembers it in ``texts_seen`` so a
test can check that the mode's name is never on screen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pygame

from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from sim.types import Pose2D
from study.types import ScreenState
from study.ui.laser_view import draw_laser_view

BACKGROUND = (32, 34, 40)
PANEL = (48, 52, 60)
TEXT = (235, 235, 235)
DIM = (150, 150, 150)
FREE = (250, 250, 250)
OCCUPIED = (70, 70, 70)
REGION = (255, 244, 190)
ROBOT = (40, 90, 200)
LASER = (230, 20, 20)  # the red dots
ARROW = (20, 170, 60)
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
    """

    def __init__(
        self,
        size: tuple[int, int],
        *,
        fullscreen: bool = False,
        show_map: bool = True,
        layout: str = "map",
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
        self._layout()
        self._map: pygame.Surface | None = None
        self._map_key = ""
        self._map_to_px: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 0.0)
        self._marks: list[tuple[str, float, float]] = []

    def _layout(self) -> None:
        w, h = self.width, self.height
        top, bottom = int(h * 0.09), int(h * 0.22)
        middle = pygame.Rect(0, top, w, h - top - bottom)
        self.status_rect = pygame.Rect(0, 0, w, top)
        self.question_rect = pygame.Rect(0, h - bottom, w, bottom)
        self.laser_rect = self.tail_rect = pygame.Rect(0, 0, 0, 0)
        if self.layout == "laser":
            split, half = int(w * 0.55), middle.height // 2
            self.laser_rect = pygame.Rect(0, middle.top, split, middle.height).inflate(-12, -12)
            self.camera_rect = pygame.Rect(split, middle.top, w - split, half).inflate(-12, -12)
            self.tail_rect = pygame.Rect(
                split, middle.top + half, w - split, middle.height - half
            ).inflate(-12, -12)
            self.map_rect = pygame.Rect(0, 0, 0, 0)
        elif self.show_map:
            self.camera_rect = pygame.Rect(0, middle.top, w // 2, middle.height).inflate(-12, -12)
            self.map_rect = pygame.Rect(w // 2, middle.top, w - w // 2, middle.height).inflate(
                -12, -12
            )
        else:
            self.camera_rect = middle.inflate(-12, -12)
            self.map_rect = pygame.Rect(0, 0, 0, 0)

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

    def flip(self) -> None:
        """Show the frame."""
        import time

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

    # -------------------------------------------------------------- the map

    def set_scene(self, scenario: Scenario, grid: OccupancyGrid) -> None:
        """Pre-render the map of ``scenario`` (once per scenario)."""
        key = scenario.source or scenario.name
        if key == self._map_key or not self.show_map:
            return
        occ = np.asarray(grid.occupied)
        rgb = np.empty((*occ.shape, 3), dtype=np.uint8)
        rgb[:] = FREE
        rows, cols = occ.shape
        if len(scenario.question_region):
            centres = grid.cell_to_world(
                np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), -1).reshape(
                    -1, 2
                )
            )
            inside = _in_polygon(centres, np.asarray(scenario.question_region)).reshape(rows, cols)
            rgb[inside] = REGION
        rgb[occ] = OCCUPIED
        image = np.ascontiguousarray(rgb[::-1].swapaxes(0, 1))  # (cols, rows): x first, y down
        surf = pygame.surfarray.make_surface(image)
        scale = min(self.map_rect.width / cols, self.map_rect.height / rows)
        size = (max(1, int(cols * scale)), max(1, int(rows * scale)))
        self._map = pygame.transform.smoothscale(surf, size)
        left = self.map_rect.left + (self.map_rect.width - size[0]) // 2
        top = self.map_rect.top + (self.map_rect.height - size[1]) // 2
        px_per_m = scale / grid.resolution
        x0, y0 = grid.origin
        # x_px = left + (x - x0) * k ; y_px = top + size_h - (y - y0) * k
        self._map_to_px = (left - x0 * px_per_m, top + size[1] + y0 * px_per_m, px_per_m, 0.0)
        self._map_pos = (left, top)
        self._marks = [("A", scenario.start.x, scenario.start.y)]
        if scenario.dock is not None:
            self._marks.append(("B", scenario.dock.pose.x, scenario.dock.pose.y))
        self._map_key = key

    def to_px(self, xy: np.ndarray) -> np.ndarray:
        """Map-frame points (k, 2) [m] -> window pixels (k, 2)."""
        ox, oy, k, _ = self._map_to_px
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.column_stack((ox + xy[:, 0] * k, oy - xy[:, 1] * k))

    # -------------------------------------------------------------- frames

    def draw_trial(self, view: TrialView, *, footprint: np.ndarray) -> None:
        """One frame of the driving screen (``footprint`` (4, 2) [m] robot frame)."""
        s = self.surface
        s.fill(BACKGROUND)
        st = view.screen
        # status line
        pygame.draw.rect(s, PANEL, self.status_rect)
        pad = self.status_rect.height // 8
        self.text(st.instruction, (12, pad), font="small")
        if st.feedback:
            self.text(
                st.feedback,
                (12, pad + self.fonts["small"].get_linesize()),
                font="small",
                colour=HIGHLIGHT,
            )
        minutes, seconds = divmod(int(st.t), 60)
        self.text(
            f"{minutes}:{seconds:02d}",
            (self.width - 12, pad),
            font="small",
            anchor="topright",
            colour=DIM,
        )
        self._camera_panel("front", view.camera, self.camera_rect)
        if self.layout == "laser":
            self._camera_panel("tail", view.tail_camera, self.tail_rect)
            draw_laser_view(
                s, self.laser_rect, points=view.scan, footprint=footprint, stick=view.stick
            )
        # map
        if self.show_map and self._map is not None:
            s.blit(self._map, self._map_pos)
            for label, x, y in self._marks:
                px = self.to_px(np.array([x, y]))[0]
                self.text(
                    label, (int(px[0]), int(px[1])), font="small", colour=(0, 0, 0), anchor="center"
                )
            if len(view.points):
                for px, py in self.to_px(view.points).astype(int):
                    pygame.draw.circle(s, LASER, (px, py), 2)
            if view.pose is not None:
                self._robot(view.pose, footprint, view.stick)
        # secondary task
        self._question(view)
        if view.overlay:
            box = pygame.Rect(0, 0, int(self.width * 0.7), int(self.height * 0.3))
            box.center = (self.width // 2, self.height // 2)
            pygame.draw.rect(s, PANEL, box, border_radius=12)
            pygame.draw.rect(s, HIGHLIGHT, box, width=3, border_radius=12)
            self.paragraph(view.overlay, box.inflate(-40, -40), font="large")
        self.flip()

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

    def _robot(self, pose: Pose2D, footprint: np.ndarray, stick: np.ndarray) -> None:
        s = self.surface
        corners = self.to_px(pose.to_map_frame(footprint))
        pygame.draw.polygon(s, ROBOT, [tuple(c) for c in corners])
        nose = self.to_px(pose.to_map_frame(np.array([[0.0, 0.0], [footprint[:, 0].max(), 0.0]])))
        pygame.draw.line(s, (255, 255, 255), tuple(nose[0]), tuple(nose[1]), 3)
        if np.hypot(stick[0], stick[1]) > 0.02 or abs(stick[2]) > 0.02:
            length = 0.9  # [m] on the map at full deflection
            tip_r = np.array([[0.0, 0.0], [stick[0] * length, stick[1] * length]])
            a, b = self.to_px(pose.to_map_frame(tip_r))
            pygame.draw.line(s, ARROW, tuple(a), tuple(b), 4)
            d = b - a
            n = float(np.hypot(*d))
            if n > 3:
                d /= n
                left = b - 10 * d + 6 * np.array([-d[1], d[0]])
                right = b - 10 * d - 6 * np.array([-d[1], d[0]])
                pygame.draw.polygon(s, ARROW, [tuple(b), tuple(left), tuple(right)])
            if abs(stick[2]) > 0.02:
                r = 18
                start = math.pi / 2 - 0.2
                span = stick[2] * math.pi * 0.8
                rect = pygame.Rect(0, 0, 2 * r, 2 * r)
                rect.center = (int(a[0]), int(a[1]))
                lo, hi = (start, start + span) if span > 0 else (start + span, start)
                pygame.draw.arc(s, ARROW, rect, lo, hi, 3)

    def _question(self, view: TrialView) -> None:
        s, r = self.surface, self.question_rect
        pygame.draw.rect(s, PANEL, r)
        question = view.screen.question
        cy = r.top + r.height // 3
        if question:
            self.text(question, (r.centerx, cy), font="large", anchor="center")
        else:
            self.text("Questions appear here.", (r.centerx, cy), anchor="center", colour=DIM)
        bw, bh = int(self.width * 0.2), int(r.height * 0.32)
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

    def draw_page(self, title: str, body: str, prompt: str) -> None:
        """A text screen (briefing, instructions, feedback, break, debrief)."""
        s = self.surface
        s.fill(BACKGROUND)
        margin = int(self.width * 0.1)
        y = int(self.height * 0.1)
        if title:
            self.text(title, (margin, y), font="large")
            y += self.fonts["large"].get_linesize() * 2
        self.paragraph(body, pygame.Rect(margin, y, self.width - 2 * margin, self.height))
        self.text(
            prompt, (self.width // 2, int(self.height * 0.9)), anchor="center", colour=HIGHLIGHT
        )
        self.flip()

    def close(self) -> None:
        pygame.display.quit()


def _in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule: which of ``points`` (k, 2) lie inside ``polygon`` (m, 2)."""
    x, y = points[:, 0], points[:, 1]
    inside = np.zeros(len(points), dtype=bool)
    px, py = polygon[:, 0], polygon[:, 1]
    j = len(polygon) - 1
    for i in range(len(polygon)):
        crosses = (py[i] > y) != (py[j] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xs = (px[j] - px[i]) * (y - py[i]) / (py[j] - py[i]) + px[i]
        inside ^= crosses & (x < xs)
        j = i
    return inside
