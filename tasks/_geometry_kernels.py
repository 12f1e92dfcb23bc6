"""Compiled loops of the trial's per-tick clearance figures (:mod:`tasks.geometry`,
:mod:`tasks.clearance`).

Each kernel repeats the floating-point operations of the vectorised numpy code it
replaced, in the same order, so its results are bit-identical to it;
``tests/test_geometry_kernels.py`` checks that against the numpy code kept in
``tests/geometry_reference.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def box_of(polygon: np.ndarray) -> tuple[bool, float, float, float, float]:
    """``(True, x_min, x_max, y_min, y_max)`` [m] if ``polygon`` (k, 2) is an axis-aligned
    rectangle of positive area with finite corners (four edges alternately along x and
    y), else ``(False, 0, 0, 0, 0)``; ``tasks.geometry._axis_aligned_box``."""
    if polygon.shape[0] != 4 or polygon.shape[1] != 2 or not np.all(np.isfinite(polygon)):
        return False, 0.0, 0.0, 0.0, 0.0
    ax, ay, bx, by = polygon[0, 0], polygon[0, 1], polygon[1, 0], polygon[1, 1]
    cx, cy, dx, dy = polygon[2, 0], polygon[2, 1], polygon[3, 0], polygon[3, 1]
    x_first = ay == by and bx == cx and cy == dy and dx == ax  # edges x, y, x, y
    y_first = ax == bx and by == cy and cx == dx and dy == ay  # edges y, x, y, x
    if not (x_first or y_first):
        return False, 0.0, 0.0, 0.0, 0.0
    x0, x1, y0, y1 = min(ax, cx), max(ax, cx), min(ay, cy), max(ay, cy)
    if x0 < x1 and y0 < y1:
        return True, x0, x1, y0, y1
    return False, 0.0, 0.0, 0.0, 0.0


@njit(cache=True)
def box_clearance_sq(points: np.ndarray, x0: float, x1: float, y0: float, y1: float) -> float:
    """Smallest squared distance [m^2] from the points (m, 2), m >= 1, to the rectangle
    ``[x0, x1] x [y0, y1]`` (0 inside); NaN if a coordinate is not finite."""
    best = np.inf
    for i in range(points.shape[0]):
        x, y = points[i, 0], points[i, 1]
        if not (np.isfinite(x) and np.isfinite(y)):
            return np.nan
        # how far the point lies outside each slab
        dx = max(max(x0 - x, x - x1), 0.0)
        dy = max(max(y0 - y, y - y1), 0.0)
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
    return best


@njit(cache=True)
def min_norm_sq(points: np.ndarray) -> float:
    """``min_i |p_i|^2`` [m^2] of the points (m, 2), m >= 1 (NaN propagates)."""
    best = np.inf
    for i in range(points.shape[0]):
        d2 = points[i, 0] * points[i, 0] + points[i, 1] * points[i, 1]
        if d2 < best or d2 != d2:
            best = d2
    return best
