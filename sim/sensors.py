"""The robot's 2D laser scanners as an exact ray caster over the scene's cross-section
(thesis Sec. 7.6.1.1; spec section 7).

Every element of a scenario is a vertical extrusion standing on the floor (walls,
boxes, table legs, cylinders) or a slab at a fixed height (a table top):
:func:`scene_solids` lists them as :class:`Solid` boxes and cylinders, the one
description of the scene's shape that the physics (``sim.world``) builds its bodies
from too. What a horizontal laser at height ``h`` can hit is a 2D cross-section
(:func:`cross_section`): convex outlines whose edges have outward normals, and
circles; :func:`cast` computes the range of every beam of one or more scanners in one
compiled pass (``sim._kernels``). pybullet's ``rayTestBatch`` stays a selectable backend
(``WorldSettings.laser_backend``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim._kernels import cast_from_pose_kernel, cast_kernel
from sim.scenario import Box, Scenario
from sim.types import Pose2D


@dataclass(frozen=True, slots=True)
class CrossSection:
    """The scene cut by a horizontal plane: convex outlines and circles, map frame.

    Edges belong to counter-clockwise outlines, so the outward normal of edge a -> b
    is the direction of (b - a) turned clockwise by 90 degrees.
    """

    height: float  # [m] of the cutting plane above the floor
    edge_a: np.ndarray  # (s, 2) [m] edge start points
    edge_b: np.ndarray  # (s, 2) [m] edge end points
    normals: np.ndarray  # (s, 2) outward unit normals
    centres: np.ndarray  # (c, 2) [m] circle centres
    radii: np.ndarray  # (c,) [m] circle radii


@dataclass(frozen=True, slots=True)
class Solid:
    """A static scene element as a solid: an oriented box or an upright cylinder.

    The one description of the scene's shape that both the physics (``sim.world``)
    and the lasers use, so what the robot bumps into is what its lasers see.
    """

    name: str  # the scenario's; table parts "<table>.leg0".."<table>.leg3", "<table>.top"
    centre: tuple[float, float]  # [m] map frame
    size: tuple[float, float]  # [m] a box's extent along its own x and y; (0, 0) for cylinders
    yaw: float  # [rad]
    radius: float  # [m] a cylinder's; 0 for boxes
    z: tuple[float, float]  # [m] bottom and top above the floor
    colour: tuple[float, float, float]  # RGB in [0, 1]

    def corners(self) -> np.ndarray:
        """A box's outline in the map frame, counter-clockwise (4, 2) [m]."""
        hx, hy = self.size[0] / 2, self.size[1] / 2
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        return Pose2D(self.centre[0], self.centre[1], self.yaw).to_map_frame(local)

    def distance(self, point: np.ndarray) -> float:
        """Distance [m] from map point (3,) to this solid, 0 inside."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = point[0] - self.centre[0], point[1] - self.centre[1]
        dz = max(self.z[0] - point[2], point[2] - self.z[1], 0.0)
        if self.radius:
            return math.hypot(max(math.hypot(dx, dy) - self.radius, 0.0), dz)
        out_x = max(abs(c * dx + s * dy) - self.size[0] / 2, 0.0)
        out_y = max(abs(-s * dx + c * dy) - self.size[1] / 2, 0.0)
        return math.hypot(out_x, out_y, dz)


def _box_solid(box: Box, z0: float, z1: float) -> Solid:
    return Solid(box.name, box.centre, box.size, box.yaw, 0.0, (z0, z1), box.colour)


def scene_solids(scenario: Scenario) -> tuple[Solid, ...]:
    """Walls, boxes, cylinders, then each table's legs and top, as solids."""
    out = [_box_solid(b, 0.0, b.height) for b in (*scenario.walls, *scenario.boxes)]
    out += [
        Solid(c.name, c.centre, (0.0, 0.0), 0.0, c.radius, (0.0, c.height), c.colour)
        for c in scenario.cylinders
    ]
    for t in scenario.tables:
        out += [_box_solid(leg, 0.0, t.height) for leg in t.leg_boxes()]
        top = Box(f"{t.name}.top", "obstacle", t.centre, t.size, t.yaw, t.height, t.colour)
        out.append(_box_solid(top, t.height, t.height + t.top_thickness))
    return tuple(out)


def cross_section(scenario: Scenario, height: float) -> CrossSection:
    """Cut ``scenario`` at ``height`` [m] above the floor (done once per laser height)."""
    cut = [s for s in scene_solids(scenario) if s.z[0] <= height < s.z[1]]
    boxes = [s for s in cut if not s.radius]
    if boxes:
        corners = np.stack([b.corners() for b in boxes])  # (k, 4, 2), counter-clockwise
        a = corners.reshape(-1, 2)
        b = np.roll(corners, -1, axis=1).reshape(-1, 2)
    else:
        a = b = np.empty((0, 2))
    d = b - a
    normals = np.column_stack((d[:, 1], -d[:, 0])) / np.hypot(d[:, 0], d[:, 1])[:, None]
    cylinders = [s for s in cut if s.radius]
    centres = np.array([c.centre for c in cylinders], dtype=float).reshape(-1, 2)
    radii = np.array([c.radius for c in cylinders], dtype=float)
    return CrossSection(height, a, b, normals, centres, radii)


def cast(
    section: CrossSection,
    origins: np.ndarray,
    first_angles: np.ndarray,
    step: float,
    n: int,
    max_range: float,
) -> np.ndarray:
    """Exact ranges of fans of ``n`` horizontal beams, one fan per sensor, in one pass.

    Parameters
    ----------
    section : the scene cut at the sensors' height.
    origins : (m, 2) [m] sensor positions in the map frame.
    first_angles : (m,) [rad] map-frame direction of each sensor's beam 0; beam k
        points at ``first_angles + k * step``.
    step : [rad] angle between beams, > 0.
    n : beams per sensor; ``(n - 1) * step`` must not exceed 2 pi.
    max_range : [m] longest range reported.

    Returns
    -------
    ranges : (m, n) [m] distance from each origin to the first surface hit, exactly
        ``max_range`` where nothing lies within ``max_range``.
    """
    origins = np.ascontiguousarray(origins, dtype=float).reshape(-1, 2)
    first = np.ascontiguousarray(first_angles, dtype=float).reshape(-1)
    s = section
    return cast_kernel(
        s.edge_a,
        s.edge_b,
        s.normals,
        s.centres,
        s.radii,
        origins,
        first,
        float(step),
        int(n),
        float(max_range),
    )


def cast_from(
    section: CrossSection,
    pose: Pose2D,
    positions: np.ndarray,
    firsts: np.ndarray,
    step: float,
    n: int,
    max_range: float,
) -> np.ndarray:
    """:func:`cast` for sensors on a robot at map ``pose``: mounted at robot-frame
    ``positions`` (m, 2) [m] with beam 0 at robot-frame ``firsts`` (m,) [rad]; the same
    numbers as ``cast(section, pose.to_map_frame(positions), pose.yaw + firsts, ...)``.
    Both arrays must be contiguous float64 (``sim.lasers.Fans`` holds them so).

    Returns
    -------
    ranges : (m, n) [m].
    """
    s = section
    return cast_from_pose_kernel(
        s.edge_a,
        s.edge_b,
        s.normals,
        s.centres,
        s.radii,
        pose.x,
        pose.y,
        pose.yaw,
        positions,
        firsts,
        float(step),
        int(n),
        float(max_range),
    )
