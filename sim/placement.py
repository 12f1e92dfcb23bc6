"""Impossible placements in a scene: a pose inside an obstacle, a question region that
encloses nothing or leaves the map (issue 20).

Exact, cheap geometry on the scene's elements, no grid: the loader
(:func:`sim.scenario.parse_scenario`) refuses such a file, and the scene checker
(:func:`sim.check.check_scene`) reports the same problems first for scenes built in code.
Whether the robot's whole footprint fits, and whether it can drive anywhere, is the
checker's question.
"""

from __future__ import annotations

import math

import numpy as np

from sim.scene import Scenario

MIN_REGION_AREA_M2 = 0.01  # [m^2] a question region smaller than 10 cm x 10 cm is a mistake


def obstacle_at(scenario: Scenario, x: float, y: float) -> str | None:
    """The name of the obstacle (wall, box, table leg, cylinder) whose inside holds map
    point (x, y) [m], or ``None``; a point on an edge is not inside."""
    for box in scenario.obstacle_boxes():
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        dx, dy = x - box.centre[0], y - box.centre[1]
        u, v = c * dx + s * dy, -s * dx + c * dy
        if abs(u) < box.size[0] / 2 and abs(v) < box.size[1] / 2:
            return box.name
    for cyl in scenario.cylinders:
        if math.hypot(x - cyl.centre[0], y - cyl.centre[1]) < cyl.radius:
            return cyl.name
    return None


def polygon_area(polygon: np.ndarray) -> float:
    """Area [m^2] of a simple polygon (n, 2) [m] by the shoelace formula."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def placement_problems(scenario: Scenario) -> list[tuple[str, str]]:
    """Every impossible placement as ``(field, message)``: start or dock pose inside an
    obstacle, a question region of (nearly) zero area or with a corner outside the bounds."""
    out: list[tuple[str, str]] = []
    poses = [("start", scenario.start)]
    if scenario.dock is not None:
        poses.append(("dock", scenario.dock.pose))
    for field, pose in poses:
        hit = obstacle_at(scenario, pose.x, pose.y)
        if hit is not None:
            out.append((field, f"pose ({pose.x:g}, {pose.y:g}) lies inside {hit!r}"))
    region = np.asarray(scenario.question_region, dtype=float).reshape(-1, 2)
    if len(region) >= 3:
        area = polygon_area(region)
        if area < MIN_REGION_AREA_M2:
            out.append(
                (
                    "question_region.polygon",
                    f"encloses {area:.3g} m^2 (a line or a point); it needs at least "
                    f"{MIN_REGION_AREA_M2:g} m^2",
                )
            )
        (x0, y0), (x1, y1) = scenario.bounds
        inside_x = (region[:, 0] >= x0) & (region[:, 0] <= x1)
        outside = ~(inside_x & (region[:, 1] >= y0) & (region[:, 1] <= y1))
        if outside.any():
            px, py = region[int(np.argmax(outside))]
            out.append(
                (
                    "question_region.polygon",
                    f"point ({px:g}, {py:g}) lies outside the bounds "
                    f"[[{x0:g}, {y0:g}], [{x1:g}, {y1:g}]]",
                )
            )
    return out
