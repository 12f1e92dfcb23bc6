"""The robot-centred laser-scan pane of the ``layout = "laser"`` screen (thesis Sec. 7.5,
Fig. 7.42 left: "the laser scan reflections from the LRF with the robot model ... the arrow
starting from the robot represents the user input via joystick").

The robot stays in the centre of the pane with its heading pointing up (robot x up, robot y
to the left), as rviz shows a scan in the robot's own frame; the hits of both lasers are
purple dots, faint rings every metre give the scale, the footprint is drawn as the robot model with
a white line to its front, and the current stick input is a green arrow from the robot's
centre (a short arc at the centre for rotation). Nothing of the scene beyond the laser hits
is drawn: the participant has no global view.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

VIEW_RADIUS_M = 4.0  # [m] from the robot's centre to the pane's nearer edge
RING_STEP_M = 1.0  # [m] between scale rings
ARROW_LENGTH_M = 1.2  # [m] of the arrow at full deflection
BACKGROUND = (18, 20, 24)
RING = (60, 64, 72)
LASER = (190, 70, 235)  # purple: the object to inspect is the red thing
ROBOT = (40, 90, 200)
ARROW = (20, 190, 70)


def robot_to_px(points: np.ndarray, rect: pygame.Rect, px_per_m: float) -> np.ndarray:
    """Robot-frame points (k, 2) [m] -> pane pixels (k, 2), robot x pointing up."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    cx, cy = rect.center
    return np.column_stack((cx - p[:, 1] * px_per_m, cy - p[:, 0] * px_per_m))


def draw_laser_view(
    surface: pygame.Surface,
    rect: pygame.Rect,
    *,
    points: np.ndarray,
    footprint: np.ndarray,
    stick: np.ndarray,
) -> None:
    """Draw the pane.

    Parameters
    ----------
    points : (k, 2) [m] laser hits of every scanner in the robot frame.
    footprint : (n, 2) [m] the robot's outline in its frame.
    stick : (3,) stick deflection in [-1, 1] (forward, left, counter-clockwise).
    """
    pygame.draw.rect(surface, BACKGROUND, rect)
    px_per_m = min(rect.width, rect.height) / 2.0 / VIEW_RADIUS_M
    clip = surface.get_clip()
    surface.set_clip(rect)
    reach = math.hypot(rect.width, rect.height) / 2.0 / px_per_m
    for k in range(1, int(reach / RING_STEP_M) + 1):
        pygame.draw.circle(surface, RING, rect.center, int(k * RING_STEP_M * px_per_m), 1)
    if len(points):
        for x, y in robot_to_px(points, rect, px_per_m).astype(int):
            pygame.draw.circle(surface, LASER, (int(x), int(y)), 2)
    corners = robot_to_px(footprint, rect, px_per_m)
    pygame.draw.polygon(surface, ROBOT, [tuple(c) for c in corners])
    nose = robot_to_px(np.array([[0.0, 0.0], [footprint[:, 0].max(), 0.0]]), rect, px_per_m)
    pygame.draw.line(surface, (255, 255, 255), tuple(nose[0]), tuple(nose[1]), 3)
    _stick_arrow(surface, rect, px_per_m, stick)
    surface.set_clip(clip)


def _stick_arrow(
    surface: pygame.Surface, rect: pygame.Rect, px_per_m: float, stick: np.ndarray
) -> None:
    """The joystick input u as an arrow from the robot's centre (Fig. 7.42)."""
    if math.hypot(stick[0], stick[1]) > 0.02:
        tip = np.array([[0.0, 0.0], [stick[0] * ARROW_LENGTH_M, stick[1] * ARROW_LENGTH_M]])
        a, b = robot_to_px(tip, rect, px_per_m)
        pygame.draw.line(surface, ARROW, tuple(a), tuple(b), 5)
        d = b - a
        n = float(np.hypot(*d))
        if n > 3:
            d /= n
            side = np.array([-d[1], d[0]])
            head = [tuple(b + 6 * d), tuple(b - 12 * d + 8 * side), tuple(b - 12 * d - 8 * side)]
            pygame.draw.polygon(surface, ARROW, head)
    if abs(stick[2]) > 0.02:
        r = int(0.45 * px_per_m)
        box = pygame.Rect(0, 0, 2 * r, 2 * r)
        box.center = rect.center
        start = math.pi / 2 - 0.2  # pygame's angles: counter-clockwise from the right
        span = stick[2] * math.pi * 0.8
        lo, hi = (start, start + span) if span > 0 else (start + span, start)
        pygame.draw.arc(surface, ARROW, box, lo, hi, 4)
