"""The scene description: frozen dataclasses of a validated scenario (thesis Sec.
7.6.1.1), loaded by :mod:`sim.scenario`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.types import Pose2D


@dataclass(frozen=True, slots=True)
class Box:
    """An oriented box standing on the floor. Walls are boxes of kind ``wall``."""

    name: str
    kind: str  # "wall" or "obstacle"
    centre: tuple[float, float]  # [m]
    size: tuple[float, float]  # (along its own x, along its own y) [m]
    yaw: float  # [rad]
    height: float  # [m]
    colour: tuple[float, float, float]  # RGB in [0, 1]
    group: str = ""  # boxes of one group are parts of one obstacle (a map blob); "" alone

    def corners(self) -> np.ndarray:
        """Footprint corners in the map frame, counter-clockwise (4, 2) [m]."""
        hx, hy = self.size[0] / 2, self.size[1] / 2
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        return Pose2D(self.centre[0], self.centre[1], self.yaw).to_map_frame(local)


@dataclass(frozen=True, slots=True)
class Cylinder:
    name: str
    centre: tuple[float, float]  # [m]
    radius: float  # [m]
    height: float  # [m]
    colour: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Table:
    """A table: four square legs at the corners and a top at ``height``."""

    name: str
    centre: tuple[float, float]  # [m]
    size: tuple[float, float]  # top size [m]
    yaw: float  # [rad]
    height: float  # [m] underside of the top
    leg: float  # [m] side of a square leg
    top_thickness: float  # [m]
    colour: tuple[float, float, float]

    def leg_boxes(self) -> tuple[Box, ...]:
        """The four legs as obstacle boxes (what a laser at robot height sees)."""
        hx, hy = self.size[0] / 2 - self.leg / 2, self.size[1] / 2 - self.leg / 2
        pose = Pose2D(self.centre[0], self.centre[1], self.yaw)
        centres = pose.to_map_frame(np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]))
        return tuple(
            Box(
                name=f"{self.name}.leg{i}",
                kind="obstacle",
                centre=(float(c[0]), float(c[1])),
                size=(self.leg, self.leg),
                yaw=self.yaw,
                height=self.height,
                colour=self.colour,
            )
            for i, c in enumerate(centres)
        )


@dataclass(frozen=True, slots=True)
class Dock:
    pose: Pose2D  # pose B
    table: str  # name of the table it is under ("" if none)
    tolerance_m: float  # position tolerance for "docked" [m]
    tolerance_rad: float  # heading tolerance [rad]


@dataclass(frozen=True, slots=True)
class LaserSpec:
    name: str
    position: tuple[float, float]  # [m] in the robot frame
    yaw: float  # [rad] in the robot frame
    fov: float  # [rad] total field of view
    resolution: float  # [rad] between beams
    max_range: float  # [m]
    min_range: float  # [m]
    height: float  # [m] above the floor
    sigma: float  # [m] Gaussian range noise

    @property
    def n_beams(self) -> int:
        return int(round(self.fov / self.resolution)) + 1


@dataclass(frozen=True, slots=True)
class CameraSpec:
    position: tuple[float, float]  # [m] in the robot frame
    height: float  # [m] above the floor
    pitch: float  # [rad], negative looks down
    fov: float  # [rad] vertical field of view
    width: int  # [px]
    height_px: int  # [px]
    far: float  # [m]
    yaw: float = 0.0  # [rad] in the robot frame; pi looks backwards (the tail camera)


@dataclass(frozen=True, slots=True)
class RobotSpec:
    """A holonomic base with a rectangular footprint (spec section 1 and 7)."""

    length: float  # [m] along the robot's x
    width: float  # [m] along the robot's y
    height: float  # [m]
    mass: float  # [kg]
    max_speed: float  # [m/s] translational limit (thesis 7.6.1.1: 1.0)
    max_yaw_rate: float  # [rad/s] (thesis: 1.2)
    max_accel: float  # [m/s^2]
    max_yaw_accel: float  # [rad/s^2]
    protective_margin: float  # [m] laser protective field beyond the footprint
    pose_sigma: tuple[float, float]  # pose-estimate noise ([m], [rad])
    imu_sigma: tuple[float, float]  # IMU noise (yaw rate [rad/s], acceleration [m/s^2])
    lasers: tuple[LaserSpec, ...]
    camera: CameraSpec  # the front camera
    tail_camera: CameraSpec  # rear-facing, at the back (thesis Sec. 7.5, Fig. 7.42)

    def footprint(self) -> np.ndarray:
        """Footprint corners in the robot frame, counter-clockwise (4, 2) [m]."""
        hx, hy = self.length / 2, self.width / 2
        return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])


@dataclass(frozen=True, slots=True)
class ComponentOverride:
    """A component added by hand, or replacing a derived one with the same id."""

    id: str
    kind: str
    centre: tuple[float, float]
    ends: tuple[tuple[float, float], ...]  # () or two points
    points: tuple[tuple[float, float], ...]  # surface points, () for passages and dock


@dataclass(frozen=True, slots=True)
class SemanticSettings:
    passage_width: tuple[float, float]  # [m] clear widths counted as doorway or gap
    surface_spacing: float  # [m] between sampled surface points of objects and walls
    components: tuple[ComponentOverride, ...]
    remove: tuple[str, ...]  # ids of derived components to drop
    # where doorways, gaps, objects and walls come from: "geometry" (the exact shapes) or
    # "map" (an occupancy image, thesis appendix Alg. 4-5); docks come from the tables
    source: str = "geometry"
    map_file: str = ""  # the map's YAML as the scenario names it ("" : the scene rendered)
    map_grid: Any = None  # sim.occupancy.OccupancyGrid read from map_file, else None


@dataclass(frozen=True, slots=True)
class Scenario:
    name: str
    description: str
    source: str  # the file it was loaded from ("" if built in code)
    bounds: tuple[tuple[float, float], tuple[float, float]]  # ((x_min, y_min), (x_max, y_max))
    start: Pose2D  # pose A
    dock: Dock | None  # pose B
    walls: tuple[Box, ...]
    boxes: tuple[Box, ...]
    cylinders: tuple[Cylinder, ...]
    tables: tuple[Table, ...]
    inspection_object: str  # name of a box or cylinder, "" if none
    question_region: np.ndarray  # (k, 2) [m] polygon, (0, 2) if none
    robot: RobotSpec
    semantics: SemanticSettings

    def obstacle_boxes(self) -> tuple[Box, ...]:
        """Everything box-shaped a laser at robot height sees: walls, boxes, table legs."""
        legs = tuple(b for t in self.tables for b in t.leg_boxes())
        return self.walls + self.boxes + legs

    def element(self, name: str) -> Box | Cylinder | Table:
        """The scene element called ``name``; ``KeyError`` if there is none."""
        for e in (*self.walls, *self.boxes, *self.cylinders, *self.tables):
            if e.name == name:
                return e
        raise KeyError(name)
