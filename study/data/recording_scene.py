"""The static scene of a trial recording and the names and colours every recording uses:
entity paths (:data:`ENTITY`), thesis colours (:data:`COLOURS`), and :func:`log_static`
(the map, obstacles, semantic components, question region, footprint, and the styles of
the per-tick entities). The per-tick data: :mod:`study.data.recording`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr

from sim.occupancy import OccupancyGrid
from sim.scenario import Box, Scenario
from sim.types import COMPONENT_KINDS, SemanticComponent


@dataclass(frozen=True, slots=True)
class _Entities:
    """Every entity path of a trial recording, in one place."""

    world: str = "world"
    map: str = "world/map"  # occupancy image, static
    obstacles: str = "world/obstacles"  # outlines of walls, boxes, cylinders, tables, static
    components: str = "world/components"  # + /<kind>: semantic components, static
    question_region: str = "world/question_region"  # static polygon
    robot: str = "world/robot"  # pose transform (true pose), per tick
    footprint: str = "world/robot/footprint"  # static, robot frame
    laser: str = "world/robot/laser"  # hits, robot frame, laser_hz
    u: str = "world/robot/u"  # joystick command arrow, robot frame
    v: str = "world/robot/v"  # command sent to the robot, robot frame
    predicted_path: str = "world/predicted_path"  # map frame
    target: str = "world/target"  # recognised component, on change
    camera: str = "camera/image"  # front camera, JPEG, when given
    tail_camera: str = "camera/tail"  # tail camera (layout "laser"), JPEG, when given
    beta: str = "plots/beta"
    scores: str = "plots/scores"  # + /<candidate or situation>
    questions: str = "secondary/questions"  # TextLog
    events: str = "events"  # TextLog: collisions, dock, inspection, ...

    def component(self, kind: str) -> str:
        return f"{self.components}/{rr.escape_entity_path_part(kind)}"

    def score(self, key: str) -> str:
        return f"{self.scores}/{rr.escape_entity_path_part(key)}"


ENTITY = _Entities()

# Thesis colours (Fig. 7.26, 7.29, 7.49), as study.jobs.scene_plot.COLOURS; repeated here so
# recording does not import matplotlib.
COLOURS: dict[str, tuple[int, int, int]] = {
    "doorway": (214, 39, 40),
    "gap": (255, 127, 14),
    "dock": (44, 160, 44),
    "object": (31, 79, 214),
    "wall": (138, 43, 226),
    "obstacle": (64, 64, 64),
    "region": (59, 125, 216),
    "robot": (20, 20, 20),
    "laser": (230, 20, 20),
    "u": (120, 120, 120),
    "v": (0, 150, 60),
    "path": (0, 170, 200),
    "target": (230, 0, 126),
}


def _closed(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    return np.vstack((p, p[:1])) if len(p) else p


def _circle(centre: Sequence[float], radius: float, n: int = 24) -> np.ndarray:
    a = np.linspace(0.0, 2 * math.pi, n + 1)
    return np.column_stack((centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)))


def component_points(c: SemanticComponent) -> np.ndarray:
    """Map-frame points that show a component (k, 2) [m]."""
    parts = [np.asarray(c.centre, dtype=float).reshape(1, 2)]
    if len(c.points):
        parts = [np.asarray(c.points, dtype=float).reshape(-1, 2)]
    elif len(c.ends):
        parts.append(np.asarray(c.ends, dtype=float).reshape(-1, 2))
    return np.vstack(parts)


def log_static(
    rec: rr.RecordingStream,
    scenario: Scenario,
    components: Sequence[SemanticComponent],
    grid: OccupancyGrid,
) -> None:
    """Log the static scene of a trial: the y-up view, map, obstacles, components, question
    region, footprint and the styles of the per-tick entities."""
    rec.log(ENTITY.world, rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
    _log_map(rec, grid)
    _log_obstacles(rec, scenario)
    for kind in COMPONENT_KINDS:
        of_kind = [c for c in components if c.kind == kind]
        if of_kind:
            _log_components(rec, kind, of_kind)
    if len(scenario.question_region):
        rec.log(
            ENTITY.question_region,
            rr.LineStrips2D(
                [_closed(scenario.question_region)],
                labels=["question region"],
                colors=COLOURS["region"],
            ),
            static=True,
        )
    # styles of the per-tick entities, static so the columns carry only the data
    for entity, style in (
        (ENTITY.u, rr.Arrows2D.from_fields(colors=COLOURS["u"], radii=0.02)),
        (ENTITY.v, rr.Arrows2D.from_fields(colors=COLOURS["v"], radii=0.025)),
        (ENTITY.laser, rr.Points2D.from_fields(colors=COLOURS["laser"], radii=0.02)),
        (ENTITY.predicted_path, rr.LineStrips2D.from_fields(colors=COLOURS["path"])),
        (ENTITY.target, rr.Points2D.from_fields(colors=COLOURS["target"], radii=0.08)),
    ):
        rec.log(entity, style, static=True)
    rec.log(
        ENTITY.footprint,
        rr.LineStrips2D([_closed(scenario.robot.footprint())], colors=COLOURS["robot"]),
        static=True,
    )


def _log_map(rec: rr.RecordingStream, grid: OccupancyGrid) -> None:
    # occupancy image: pixel (u, v) -> map (x0 + u res, y_max - v res); row 0 = top
    image = np.where(grid.occupied, 60, 235).astype(np.uint8)[::-1]
    x0, _, _, y_max = grid.extent()
    rec.log(
        ENTITY.map,
        rr.Transform3D(
            translation=[x0, y_max, 0.0], scale=[grid.resolution, -grid.resolution, 1.0]
        ),
        rr.Image(image, color_model="L", draw_order=-10.0),
        static=True,
    )


def _log_obstacles(rec: rr.RecordingStream, scenario: Scenario) -> None:
    strips, names = [], []
    for box in scenario.walls + scenario.boxes:
        strips.append(_closed(box.corners()))
        names.append(box.name)
    for cyl in scenario.cylinders:
        strips.append(_circle(cyl.centre, cyl.radius))
        names.append(cyl.name)
    for table in scenario.tables:
        top = Box(table.name, "obstacle", table.centre, table.size, table.yaw, 0, table.colour)
        strips.append(_closed(top.corners()))
        names.append(table.name)
        for leg in table.leg_boxes():
            strips.append(_closed(leg.corners()))
            names.append(leg.name)
    if strips:
        rec.log(
            ENTITY.obstacles,
            rr.LineStrips2D(strips, labels=names, colors=COLOURS["obstacle"], show_labels=False),
            static=True,
        )


def _log_components(rec: rr.RecordingStream, kind: str, of_kind: list[SemanticComponent]) -> None:
    pts = [component_points(c) for c in of_kind]
    labels = [c.id for c, p in zip(of_kind, pts, strict=True) for _ in range(len(p))]
    archetypes: list[Any] = [
        rr.Points2D(
            np.vstack(pts),
            labels=labels,
            colors=COLOURS[kind],
            radii=0.04,
            show_labels=False,
        )
    ]
    passages = [c for c in of_kind if len(c.ends) == 2]
    if passages:
        archetypes.append(
            rr.LineStrips2D(
                [np.asarray(c.ends, dtype=float) for c in passages],
                labels=[c.id for c in passages],
                colors=COLOURS[kind],
                radii=0.03,
            )
        )
    rec.log(ENTITY.component(kind), *archetypes, static=True)


__all__ = ["COLOURS", "ENTITY", "component_points", "log_static"]
