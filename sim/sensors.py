"""The robot's 2D laser scanners as an exact ray caster over the scene's cross-section
(thesis Sec. 7.6.1.1; spec section 7).

Every element of a scenario is a vertical extrusion standing on the floor (walls,
boxes, table legs, cylinders) or a slab at a fixed height (a table top):
:func:`scene_solids` lists them as :class:`Solid` boxes and cylinders, the one
description of the scene's shape that the physics (``sim.world``) builds its bodies
from too. What a horizontal laser at height ``h`` can hit is a 2D cross-section
(:func:`cross_section`): convex outlines whose edges have outward normals, and
circles; :func:`cast` computes the range of every beam of one or more scanners in one
vectorised pass. pybullet's ``rayTestBatch`` stays a selectable backend
(``WorldSettings.laser_backend``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.scenario import Box, Scenario
from sim.types import Pose2D

_TWO_PI = 2.0 * math.pi


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


def _beam_pairs(
    lo: np.ndarray, span: np.ndarray, step: float, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Expand angular intervals into (interval index, beam index) pairs.

    ``lo`` (m,) in [0, 2 pi) and ``span`` (m,) in [0, pi] are angles relative to
    beam 0; beam k points at ``k * step``. An interval that runs past 2 pi also
    covers the beams in [0, lo + span - 2 pi].
    """
    wraps = np.flatnonzero(lo + span >= _TWO_PI)
    if len(wraps):  # the wrapped part as an interval of its own
        lo = np.concatenate((lo, np.zeros(len(wraps))))
        span = np.concatenate((span, span[wraps] + lo[wraps] - _TWO_PI))
        owner_of = np.concatenate((np.arange(len(span) - len(wraps)), wraps))
    else:
        owner_of = None
    first = np.ceil(lo / step).astype(np.int64)
    last = np.minimum(np.floor((lo + span) / step).astype(np.int64), n - 1)
    count = np.maximum(last - first + 1, 0)
    interval = np.repeat(np.arange(len(lo)), count)
    beam = np.arange(len(interval)) - np.repeat(np.cumsum(count) - count - first, count)
    return (interval if owner_of is None else owner_of[interval]), beam


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
    origins = np.asarray(origins, dtype=float).reshape(-1, 2)
    first = np.asarray(first_angles, dtype=float).reshape(-1)
    ranges = np.full(len(origins) * n, max_range)
    beam_angles = (first[:, None] + step * np.arange(n)).ravel()
    cos_b, sin_b = np.cos(beam_angles), np.sin(beam_angles)

    # (sensor, edge) pairs with the edge facing the sensor (closed convex outlines: the
    # back faces are hidden behind the front ones), (sensor, circle) pairs with the
    # circle not containing the sensor nor out of its range.
    rel_a = section.edge_a - origins[:, None, :]  # (m, s, 2)
    offset = np.einsum("sj,msj->ms", section.normals, rel_a)  # n . (a - o)
    le, se = np.nonzero(offset < 0.0)
    rel_a, offset = rel_a[le, se], offset[le, se]
    normals = section.normals[se]
    rel_c = section.centres - origins[:, None, :]  # (m, c, 2)
    dist = np.hypot(rel_c[..., 0], rel_c[..., 1])
    lc, sc = np.nonzero((dist > section.radii) & (dist - section.radii < max_range))
    rel_c, dist, radii = rel_c[lc, sc], dist[lc, sc], section.radii[sc]
    k = len(le)

    # Angular intervals relative to beam 0: edges from end to end, circles centre +- half.
    ends = np.concatenate((rel_a, section.edge_b[se] - origins[le], rel_c))
    ang = np.arctan2(ends[:, 1], ends[:, 0]) - np.concatenate((first[le], first[le], first[lc]))
    sweep = np.mod(ang[k : 2 * k] - ang[:k] + math.pi, _TWO_PI) - math.pi  # in (-pi, pi)
    half = np.arcsin(radii / dist)
    lo = np.mod(
        np.concatenate((np.where(sweep < 0.0, ang[k : 2 * k], ang[:k]), ang[2 * k :] - half)),
        _TWO_PI,
    )
    owner, beam = _beam_pairs(lo, np.concatenate((np.abs(sweep), 2.0 * half)), step, n)
    if len(owner) == 0:
        return ranges.reshape(-1, n)
    beam += np.concatenate((le, lc))[owner] * n  # index into the flat (m * n) fans
    on_edge = owner < k

    e, be = owner[on_edge], beam[on_edge]
    # Ray o + t d meets the edge's line n . (p - a) = 0 at t = n . (a - o) / n . d;
    # n . (a - o) < 0 for a facing edge, and n . d < 0 for a beam that hits its face.
    den = normals[e, 0] * cos_b[be] + normals[e, 1] * sin_b[be]
    t_edge = np.divide(offset[e], den, out=np.full(len(e), np.inf), where=den < 0.0)

    c, bc = owner[~on_edge] - k, beam[~on_edge]
    along = rel_c[c, 0] * cos_b[bc] + rel_c[c, 1] * sin_b[bc]
    perp_sq = dist[c] ** 2 - along**2
    t_circle = along - np.sqrt(np.maximum(radii[c] ** 2 - perp_sq, 0.0))

    np.minimum.at(ranges, np.concatenate((be, bc)), np.concatenate((t_edge, t_circle)))
    return ranges.reshape(-1, n)
