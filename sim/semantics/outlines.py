"""Obstacle outlines of a scene and the exact 2D geometry between them.

Walls, boxes and table legs are convex polygons (``Box.corners()``), cylinders
circles; the passage search (:mod:`sim.semantics.passages`) and the surface points
(:mod:`sim.semantics.derive`) work on these.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.scenario import Box, Scenario

_TIE_M = 1e-7  # closest-point candidates within this of the minimum are ties [m]
_EPS_M = 1e-6  # an obstacle is shrunk by this before a crossing test (grazing is free) [m]


@dataclass(frozen=True, slots=True)
class _Shape:
    """One obstacle outline: a convex polygon (counter-clockwise) or a circle."""

    name: str
    is_wall: bool
    part_of: str  # the obstacle it is one part of (a table's leg, a group's box), "" if none
    polygon: np.ndarray | None  # (4, 2) [m] or None for a circle
    centre: np.ndarray  # (2,) [m]
    radius: float  # [m] circle radius, or the polygon's circumradius


def _box_shape(box: Box, part_of: str = "") -> _Shape:
    corners = box.corners()
    centre = np.asarray(box.centre, dtype=float)
    radius = float(np.max(np.linalg.norm(corners - centre, axis=1)))
    return _Shape(box.name, box.kind == "wall", part_of, corners, centre, radius)


def _shapes(scenario: Scenario) -> list[_Shape]:
    shapes = [
        _box_shape(b, f"group {b.group}" if b.group else "")
        for b in (*scenario.walls, *scenario.boxes)
    ]
    shapes += [_box_shape(leg, f"table {t.name}") for t in scenario.tables for leg in t.leg_boxes()]
    shapes += [
        _Shape(c.name, False, "", None, np.asarray(c.centre, dtype=float), c.radius)
        for c in scenario.cylinders
    ]
    return shapes


def _closest_on_edges(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Closest point on each edge of ``polygon`` (e, 2) to each point (k, 2) -> (k, e, 2)."""
    start = polygon
    edge = np.roll(polygon, -1, axis=0) - polygon
    rel = points[:, None, :] - start[None, :, :]
    t = np.clip(np.einsum("kei,ei->ke", rel, edge) / np.einsum("ei,ei->e", edge, edge), 0, 1)
    return start[None, :, :] + t[..., None] * edge[None, :, :]


def _inside_polygon(point: np.ndarray, polygon: np.ndarray) -> bool:
    edge = np.roll(polygon, -1, axis=0) - polygon
    rel = point - polygon
    return bool(np.all(edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0] >= 0))


def _polygons_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test for two convex polygons (touching counts as overlap)."""
    for poly in (a, b):
        edge = np.roll(poly, -1, axis=0) - poly
        for axis in np.column_stack((-edge[:, 1], edge[:, 0])):
            pa, pb = a @ axis, b @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def _closest_points(a: _Shape, b: _Shape) -> tuple[float, np.ndarray, np.ndarray] | None:
    """Clear distance [m] and the closest points on ``a`` and ``b`` (2,), (2,) [m].

    ``None`` when the outlines touch or overlap. Where the closest points form a
    stretch (parallel faces), the midpoint of the stretch is returned.
    """
    if a.polygon is None and b.polygon is None:
        between = b.centre - a.centre
        gap = float(np.hypot(*between)) - a.radius - b.radius
        if gap <= 0:
            return None
        unit = between / np.hypot(*between)
        return gap, a.centre + a.radius * unit, b.centre - b.radius * unit
    if a.polygon is None or b.polygon is None:
        poly, circle = (a, b) if b.polygon is None else (b, a)
        if _inside_polygon(circle.centre, poly.polygon):
            return None
        cands = _closest_on_edges(circle.centre[None, :], poly.polygon)[0]
        dist = np.linalg.norm(cands - circle.centre, axis=1)
        p = cands[int(np.argmin(dist))]
        gap = float(dist.min()) - circle.radius
        if gap <= 0:
            return None
        q = circle.centre + circle.radius * (p - circle.centre) / dist.min()
        return (gap, p, q) if poly is a else (gap, q, p)
    if _polygons_overlap(a.polygon, b.polygon):
        return None
    # Between non-intersecting convex polygons the distance is attained at a vertex of one
    # of them; every (vertex, closest point on the other's edge) pair is a candidate.
    on_b = _closest_on_edges(a.polygon, b.polygon).reshape(-1, 2)
    on_a = _closest_on_edges(b.polygon, a.polygon).reshape(-1, 2)
    p_all = np.vstack((np.repeat(a.polygon, len(b.polygon), axis=0), on_a))
    q_all = np.vstack((on_b, np.repeat(b.polygon, len(a.polygon), axis=0)))
    dist = np.linalg.norm(q_all - p_all, axis=1)
    best = int(np.argmin(dist))
    gap = float(dist[best])
    if gap <= 0:
        return None  # touching (as the circle's case): no direction across
    offset = q_all[best] - p_all[best]  # unique for convex sets
    across = np.array([-offset[1], offset[0]]) / gap
    along = p_all[dist <= gap + _TIE_M] @ across
    p = p_all[best] + across * ((along.min() + along.max()) / 2 - p_all[best] @ across)
    return gap, p, p + offset


def _segment_hits(shape: _Shape, p: np.ndarray, q: np.ndarray, margin: float) -> bool:
    """Whether segment p-q meets ``shape`` grown by ``margin`` [m] (negative: shrunk, so
    that grazing does not count)."""
    if shape.polygon is None:
        d = q - p
        t = np.clip((shape.centre - p) @ d / (d @ d), 0.0, 1.0)
        return bool(np.hypot(*(p + t * d - shape.centre)) < shape.radius + margin)
    poly = shape.polygon
    edge = np.roll(poly, -1, axis=0) - poly
    inward = np.column_stack((-edge[:, 1], edge[:, 0])) / np.linalg.norm(edge, axis=1)[:, None]
    t_lo, t_hi = 0.0, 1.0  # Liang-Barsky clip against each half-plane
    for n, v in zip(inward, poly, strict=True):
        a0 = float(n @ (p - v)) + margin
        b0 = float(n @ (q - p))
        if abs(b0) < 1e-15:
            if a0 < 0:
                return False
            continue
        t0 = -a0 / b0
        if b0 > 0:
            t_lo = max(t_lo, t0)
        else:
            t_hi = min(t_hi, t0)
        if t_lo > t_hi:
            return False
    return True


def _any_hit(
    shapes: Sequence[_Shape], p: np.ndarray, q: np.ndarray, *, margin: float = -_EPS_M
) -> bool:
    mid, half = (p + q) / 2, float(np.hypot(*(q - p))) / 2
    return any(
        float(np.hypot(*(s.centre - mid))) <= s.radius + half + margin
        and _segment_hits(s, p, q, margin)
        for s in shapes
    )


def _clearance(point: np.ndarray, shapes: Sequence[_Shape]) -> float:
    """Distance [m] from ``point`` (2,) to the nearest outline of ``shapes`` (0 inside)."""
    best = np.inf
    for shape in shapes:
        gap = float(np.hypot(*(point - shape.centre)))
        if gap - shape.radius >= best:
            continue
        if shape.polygon is None:
            best = min(best, max(gap - shape.radius, 0.0))
        elif _inside_polygon(point, shape.polygon):
            return 0.0
        else:
            near = _closest_on_edges(point[None], shape.polygon)[0]
            best = min(best, float(np.min(np.hypot(*(near - point).T))))
    return best
