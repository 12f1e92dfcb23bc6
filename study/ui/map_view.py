"""The map panel of the driving screen (thesis Fig. 7.47: the complete 2D map of the scene
given to every participant): the occupancy map pre-rendered once per scenario, the question
region in pale yellow, the robot at its estimated pose with a heading arrow, the laser hits,
the stick's command, the trial's goals with their tolerance and, when the protocol says so
(``[ui] show_object``), the object to inspect in its scene colour. Conventions in
docs/decisions.md (study/ui).
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from sim.scene import Box, Cylinder
from sim.types import Pose2D
from study.ui.describe import Goal, map_cells

FREE = (250, 250, 250)
OCCUPIED = (70, 70, 70)
REGION = (255, 244, 190)
ROBOT = (40, 90, 200)
HEADING = (255, 255, 255)
LASER = (170, 40, 210)  # the purple dots (study.engine.texts.LASER_COLOUR_NAME)
ARROW = (20, 170, 60)
GOAL = (0, 140, 150)
MARK_TEXT = (0, 0, 0)


class MapView:
    """The scene's map in a rectangle of the window."""

    def __init__(self, rect: pygame.Rect, *, show_object: bool = False) -> None:
        self.rect = rect
        self.show_object = show_object
        self.image: pygame.Surface | None = None
        self.pos = (0, 0)
        self._key = ""
        self._to_px = (0.0, 0.0, 1.0)  # x0_px, y0_px, px per m
        self._object: Box | Cylinder | None = None
        self.goals: tuple[Goal, ...] = ()
        self._labels: dict[str, pygame.Surface] = {}

    def _label(self, font: pygame.font.Font, text: str) -> pygame.Surface:
        image = self._labels.get(text)
        if image is None:
            image = self._labels[text] = font.render(text, True, MARK_TEXT)
        return image

    # -------------------------------------------------------------- set up

    def set_scene(self, scenario: Scenario, grid: OccupancyGrid) -> None:
        """Pre-render the map of ``scenario`` (once per scenario)."""
        key = scenario.source or scenario.name
        if key == self._key:
            return
        classes = map_cells(scenario, grid)
        rows, cols = classes.shape
        rgb = np.array([FREE, REGION, OCCUPIED], dtype=np.uint8)[classes]
        image = np.ascontiguousarray(rgb[::-1].swapaxes(0, 1))  # (cols, rows): x first, y down
        surf = pygame.surfarray.make_surface(image)
        scale = min(self.rect.width / cols, self.rect.height / rows)
        size = (max(1, int(cols * scale)), max(1, int(rows * scale)))
        self.image = pygame.transform.smoothscale(surf, size)
        left = self.rect.left + (self.rect.width - size[0]) // 2
        top = self.rect.top + (self.rect.height - size[1]) // 2
        px_per_m = scale / grid.resolution
        x0, y0 = grid.origin
        # x_px = left + (x - x0) * k ; y_px = top + size_h - (y - y0) * k
        self._to_px = (left - x0 * px_per_m, top + size[1] + y0 * px_per_m, px_per_m)
        self.pos = (left, top)
        self._object = None
        if scenario.inspection_object:
            element = scenario.element(scenario.inspection_object)
            if isinstance(element, Box | Cylinder):
                self._object = element
        self._key = key

    def set_goals(self, goals: tuple[Goal, ...]) -> None:
        """The goals of the trial's route (:func:`study.ui.describe.goals`)."""
        self.goals = goals

    def to_px(self, xy: np.ndarray) -> np.ndarray:
        """Map-frame points (k, 2) [m] -> window pixels (k, 2)."""
        ox, oy, k = self._to_px
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.column_stack((ox + xy[:, 0] * k, oy - xy[:, 1] * k))

    @property
    def px_per_m(self) -> float:
        return self._to_px[2]

    # -------------------------------------------------------------- drawing

    def draw(
        self,
        surface: pygame.Surface,
        font: pygame.font.Font,
        *,
        scenario_marks: tuple[tuple[str, float, float], ...],
        points: np.ndarray,
        pose: Pose2D | None,
        footprint: np.ndarray,
        stick: np.ndarray,
    ) -> list[str]:
        """One frame of the map; returns the labels drawn."""
        if self.image is None:
            return []
        surface.blit(self.image, self.pos)
        if self.show_object and self._object is not None:
            self._draw_object(surface)
        labels = self._draw_goals(surface, font)
        drawn = {g.label for g in self.goals}
        for label, x, y in scenario_marks:
            if label not in drawn:
                px = self.to_px(np.array([x, y]))[0]  # the label just above its point
                image = self._label(font, label)
                surface.blit(image, image.get_rect(midbottom=(int(px[0]), int(px[1]) - 8)))
                labels.append(label)
        clip = surface.get_clip()
        surface.set_clip(self.rect)  # hits beyond the map stay in its rectangle
        if len(points):
            for px, py in self.to_px(points).astype(int):
                pygame.draw.circle(surface, LASER, (px, py), 2)
        if pose is not None:
            self._draw_robot(surface, pose, footprint, stick)
        surface.set_clip(clip)
        return labels

    def _draw_object(self, surface: pygame.Surface) -> None:
        obj = self._object
        colour = tuple(int(255 * c) for c in obj.colour)
        if isinstance(obj, Cylinder):
            c = self.to_px(np.array(obj.centre))[0]
            r = max(4, int(obj.radius * self.px_per_m))
            pygame.draw.circle(surface, colour, (int(c[0]), int(c[1])), r)
            pygame.draw.circle(surface, MARK_TEXT, (int(c[0]), int(c[1])), r, 1)
            return
        hx, hy = obj.size[0] / 2, obj.size[1] / 2
        corners = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        rot = np.array([[math.cos(obj.yaw), -math.sin(obj.yaw)],
                        [math.sin(obj.yaw), math.cos(obj.yaw)]])  # fmt: skip
        px = self.to_px(corners @ rot.T + np.asarray(obj.centre))
        pygame.draw.polygon(surface, colour, [tuple(p) for p in px])
        pygame.draw.polygon(surface, MARK_TEXT, [tuple(p) for p in px], 1)

    def _draw_goals(self, surface: pygame.Surface, font: pygame.font.Font) -> list[str]:
        labels = []
        k = self.px_per_m
        for g in self.goals:
            c = self.to_px(np.array([g.x, g.y]))[0]
            centre = (int(c[0]), int(c[1]))
            r = max(5, int(g.tolerance_m * k))
            pygame.draw.circle(surface, GOAL, centre, r, 2)
            if g.yaw is not None:
                reach = r + max(8, int(0.35 * k))
                lo, hi = g.yaw - g.tolerance_rad, g.yaw + g.tolerance_rad
                wedge = [centre] + [
                    (c[0] + reach * math.cos(a), c[1] - reach * math.sin(a))
                    for a in np.linspace(lo, hi, 9)
                ]
                pygame.draw.polygon(surface, GOAL, wedge, 1)
                tip = (c[0] + reach * math.cos(g.yaw), c[1] - reach * math.sin(g.yaw))
                pygame.draw.line(surface, GOAL, centre, tip, 2)
            image = self._label(font, g.label)
            surface.blit(image, image.get_rect(midbottom=(centre[0], centre[1] - r - 1)))
            labels.append(g.label)
        return labels

    def _draw_robot(
        self, surface: pygame.Surface, pose: Pose2D, footprint: np.ndarray, stick: np.ndarray
    ) -> None:
        corners = self.to_px(pose.to_map_frame(footprint))
        pygame.draw.polygon(surface, ROBOT, [tuple(c) for c in corners])
        # the heading: a white arrow filling the footprint's front, outlined
        front, back = footprint[:, 0].max(), footprint[:, 0].min()
        half = footprint[:, 1].max()
        arrow = np.array([[front, 0.0], [back * 0.4, half * 0.75], [back * 0.1, 0.0],
                          [back * 0.4, -half * 0.75]])  # fmt: skip
        px = [tuple(p) for p in self.to_px(pose.to_map_frame(arrow))]
        pygame.draw.polygon(surface, HEADING, px)
        pygame.draw.polygon(surface, MARK_TEXT, px, 1)
        if np.hypot(stick[0], stick[1]) > 0.02 or abs(stick[2]) > 0.02:
            self._draw_stick(surface, pose, stick)

    def _draw_stick(self, surface: pygame.Surface, pose: Pose2D, stick: np.ndarray) -> None:
        length = 0.9  # [m] on the map at full deflection
        tip_r = np.array([[0.0, 0.0], [stick[0] * length, stick[1] * length]])
        a, b = self.to_px(pose.to_map_frame(tip_r))
        pygame.draw.line(surface, ARROW, tuple(a), tuple(b), 4)
        d = b - a
        n = float(np.hypot(*d))
        if n > 3:
            d /= n
            left = b - 10 * d + 6 * np.array([-d[1], d[0]])
            right = b - 10 * d - 6 * np.array([-d[1], d[0]])
            pygame.draw.polygon(surface, ARROW, [tuple(b), tuple(left), tuple(right)])
        if abs(stick[2]) > 0.02:
            r = 18
            start = math.pi / 2 - 0.2
            span = stick[2] * math.pi * 0.8
            rect = pygame.Rect(0, 0, 2 * r, 2 * r)
            rect.center = (int(a[0]), int(a[1]))
            lo, hi = (start, start + span) if span > 0 else (start + span, start)
            pygame.draw.arc(surface, ARROW, rect, lo, hi, 3)
