"""Distances from the robot's footprint or position to polygons (thesis Sec. 7.5,
Fig. 7.44b and Table 7.10: the robot's clearance to obstacles)."""

from __future__ import annotations

import math

import numpy as np

from tasks._geometry_kernels import box_clearance_sq, box_of


def polygon_distances(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Euclidean distance from each point to a filled polygon, 0 inside.

    Parameters
    ----------
    points : ndarray, shape (m, 2)
        Points [m].
    polygon : ndarray, shape (k, 2)
        Vertices [m] of a simple polygon in order (either orientation), k >= 3.

    Returns
    -------
    ndarray, shape (m,)
        Distances [m]; 0 for points inside or on the boundary (even-odd rule).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    a = np.asarray(polygon, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2 or len(a) < 3 or not np.all(np.isfinite(a)):
        raise ValueError(f"polygon: must be (k, 2) finite vertices with k >= 3, got {a.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points: must be finite")
    if len(p) == 0:
        return np.empty(0)
    b = np.roll(a, -1, axis=0)
    ex, ey = (b - a).T  # (k,) edge vectors
    ax, ay, by = a[:, 0], a[:, 1], b[:, 1]
    length2 = ex * ex + ey * ey
    px, py = p[:, 0:1], p[:, 1:2]  # (m, 1)
    rx, ry = px - ax, py - ay  # (m, k) from each edge's start
    with np.errstate(invalid="ignore", divide="ignore"):
        # Nearest point of each edge: the projection clipped to the segment.
        s = np.clip(np.where(length2 > 0, (rx * ex + ry * ey) / length2, 0.0), 0.0, 1.0)
        dx, dy = rx - s * ex, ry - s * ey
        dist = np.sqrt((dx * dx + dy * dy).min(axis=1))
        # Even-odd rule: count edges crossing the horizontal ray to the point's right.
        straddles = (ay > py) != (by > py)
        x_cross = ax + ry * ex / (by - ay)
    inside = (np.count_nonzero(straddles & (px < x_cross), axis=1) % 2) == 1
    return np.where(inside, 0.0, dist)


def footprint_clearance(points: np.ndarray, footprint: np.ndarray) -> float:
    """Minimum distance [m] from the robot's footprint to the laser points.

    Parameters
    ----------
    points : ndarray, shape (m, 2)
        Laser hits [m] in the robot frame (``Observation.points``).
    footprint : ndarray, shape (k, 2)
        Footprint polygon [m] in the robot frame (``RobotSpec.footprint()``).

    Returns
    -------
    float
        The smallest point-to-polygon distance [m]; 0 if a point lies inside
        the footprint; ``inf`` without points.

    Notes
    -----
    An axis-aligned rectangle (any robot's ``RobotSpec.footprint()``) takes a
    closed-form path (compiled, ``tasks._geometry_kernels``); it equals the general
    result of :func:`polygon_distances` to rounding (~1e-16 m).
    """
    a = np.ascontiguousarray(footprint, dtype=float)
    is_box, x0, x1, y0, y1 = box_of(a) if a.ndim == 2 else (False, 0.0, 0.0, 0.0, 0.0)
    if not is_box:
        d = polygon_distances(points, footprint)
        return float(d.min()) if len(d) else math.inf
    p = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    if len(p) == 0:
        return math.inf
    # the robot's rectangle, axis-aligned in its own frame: per point, the distance to
    # the rectangle is the norm of how far it lies outside each slab (0 inside)
    d2 = box_clearance_sq(p, x0, x1, y0, y1)
    if math.isnan(d2):
        raise ValueError("points: must be finite")
    return math.sqrt(d2)
