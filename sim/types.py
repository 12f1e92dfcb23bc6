"""Plain value types the simulation hands out: poses, scans, IMU readings, semantic
components and the observation of one control tick.

Frozen, slotted dataclasses passed by value (DESIGN.md, "One control tick").
Arrays carry their shape and unit in the field comment. Frames: the map frame
is the scenario's (x right, y up, yaw counter-clockwise from +x); the robot
frame has x forward, y to the left, origin at the robot's centre.

Commands ``u`` and ``v`` everywhere are robot-frame velocities in physical
units, ``(v_x [m/s], v_y [m/s], omega [rad/s])``, shape (3,).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

COMPONENT_KINDS = ("doorway", "gap", "dock", "object", "wall")


def wrap_angle(angle: float) -> float:
    """An angle [rad] wrapped into [-pi, pi) (the one scalar wrap of sim, tasks and study;
    ``autonomy`` keeps its own vectorised one, as it may not import sim)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True, slots=True)
class Pose2D:
    x: float  # [m]
    y: float  # [m]
    yaw: float  # [rad], counter-clockwise from the map's +x

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.y, self.yaw])

    def to_robot_frame(self, points: np.ndarray) -> np.ndarray:
        """Map-frame points (k, 2) [m] -> the frame of a robot at this pose (k, 2) [m]."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        d = np.asarray(points, dtype=float).reshape(-1, 2) - (self.x, self.y)
        return np.column_stack((c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]))

    def to_map_frame(self, points: np.ndarray) -> np.ndarray:
        """Robot-frame points (k, 2) [m] -> map frame (k, 2) [m]."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.column_stack(
            (c * p[:, 0] - s * p[:, 1] + self.x, s * p[:, 0] + c * p[:, 1] + self.y)
        )


@dataclass(frozen=True, slots=True)
class SemanticComponent:
    """A candidate target of a contextual task (spec section 3, thesis Fig. 7.49).

    For doorways and gaps ``centre`` is the passage's centre point and ``ends`` its
    two end points; for the dock ``centre`` is the docking place under the table;
    for objects and wall segments ``points`` are surface points, and the
    intentional target point is the one nearest the robot (:meth:`target_point`).
    """

    id: str
    kind: str  # one of COMPONENT_KINDS
    centre: np.ndarray  # (2,) [m]
    points: np.ndarray  # (k, 2) [m] surface points (objects, walls); the ends for passages
    ends: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))  # (2, 2) [m] or (0, 2)
    width: float = math.nan  # [m] clear width of a doorway or gap
    normal: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) passage crossing dir.
    source: tuple[str, ...] = ()  # names of the scene elements it was derived from

    def target_point(self) -> np.ndarray:
        """Intentional target point ``s`` (spec section 3), in this component's frame (2,) [m]:
        the centre of a doorway, gap or dock; the surface point nearest the origin of
        an object or wall segment (so call it on a component in the robot frame)."""
        if self.kind in ("object", "wall") and len(self.points):
            return self.points[int(np.argmin(np.einsum("ij,ij->i", self.points, self.points)))]
        return self.centre

    def transformed(self, pose: Pose2D) -> SemanticComponent:
        """This component (map frame) seen from a robot at ``pose``."""
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        rot = np.array([[c, s], [-s, c]])
        return SemanticComponent(
            id=self.id,
            kind=self.kind,
            centre=pose.to_robot_frame(self.centre)[0],
            points=pose.to_robot_frame(self.points) if len(self.points) else self.points,
            ends=pose.to_robot_frame(self.ends) if len(self.ends) else self.ends,
            width=self.width,
            normal=rot @ self.normal,
            source=self.source,
        )


@dataclass(frozen=True, slots=True)
class LaserScan:
    name: str
    angles: np.ndarray  # (n,) [rad] beam directions in the robot frame
    ranges: np.ndarray  # (n,) [m] noisy; == max_range where nothing was hit
    origin: np.ndarray  # (2,) [m] sensor position in the robot frame
    max_range: float  # [m]

    def points(self) -> np.ndarray:
        """Hit points in the robot frame (k, 2) [m], max-range readings dropped."""
        hit = self.ranges < self.max_range
        r, a = self.ranges[hit], self.angles[hit]
        return np.column_stack((self.origin[0] + r * np.cos(a), self.origin[1] + r * np.sin(a)))


@dataclass(frozen=True, slots=True)
class ImuReading:
    yaw_rate: float  # [rad/s], noisy
    accel: np.ndarray  # (2,) [m/s^2] robot-frame linear acceleration, noisy


@dataclass(frozen=True, slots=True)
class Observation:
    """What the robot knows at one control tick."""

    t: float  # [s] simulated time
    pose: Pose2D  # estimated pose in the map frame (small noise)
    velocity: np.ndarray  # (3,) robot-frame (v_x [m/s], v_y [m/s], omega [rad/s]), estimated
    scans: tuple[LaserScan, ...]
    points: np.ndarray  # (m, 2) [m] laser hits of all scanners in the robot frame
    imu: ImuReading
    # semantic components in the robot frame: a tuple, or from World.sense a read-only
    # sequence computed when first read (sim.semantics.RobotFrameComponents)
    components: Sequence[SemanticComponent]


@dataclass(frozen=True, slots=True)
class Contact:
    """One collision episode: reported once when it starts, closed when it ends."""

    index: int  # 0, 1, ... in order of start within one world
    t_start: float  # [s]
    position: np.ndarray  # (2,) [m] map-frame contact point at the start
    obstacle: str  # name of the scene element touched
    t_end: float = math.nan  # [s], nan while the contact lasts
