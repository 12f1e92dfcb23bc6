"""Compiled loops of the laser model: the exact 2D ray cast (:func:`sim.sensors.cast`)
and the noisy scan with its hit points (:meth:`sim.world.World.sense`).

Each kernel repeats the floating-point operations of the vectorised numpy code it
replaced, in the same order (no fastmath, no fused multiply-add), so its results are
bit-identical to it; ``tests/test_sensing_kernels.py`` checks that against the numpy
code kept in ``tests/geometry_reference.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_TWO_PI = 2.0 * math.pi


@njit(cache=True)
def _wrap(x: float) -> float:
    """``np.mod(x, 2 pi)``: Python's (and numpy's) floored modulo, in [0, 2 pi]."""
    return x % _TWO_PI


@njit(cache=True)
def _beam_range(lo: float, span: float, step: float, n: int) -> tuple[int, int]:
    """First and last beam (inclusive; last < first when none) whose direction ``k step``
    lies in ``[lo, lo + span]``; ``lo`` (in [0, 2 pi]) and ``span`` relative to beam 0."""
    first = int(math.ceil(lo / step))
    last = min(int(math.floor((lo + span) / step)), n - 1)
    return first, last


@njit(cache=True)
def _intervals(lo: float, span: float, step: float, n: int) -> tuple[int, int, int, int]:
    """The beams of an angular interval as two inclusive ranges: its own, and, for an
    interval running past 2 pi, the wrapped part ``[0, lo + span - 2 pi]`` (else empty)."""
    a0, a1 = _beam_range(lo, span, step, n)
    if lo + span >= _TWO_PI:
        b0, b1 = _beam_range(0.0, span + lo - _TWO_PI, step, n)
    else:
        b0, b1 = 0, -1
    return a0, a1, b0, b1


@njit(cache=True)
def _edge_hits(out, k0, k1, nx, ny, offset, cos_b, sin_b) -> None:
    """Lower ``out[k0..k1]`` to where those beams meet the facing edge's line
    ``n . (p - a) = 0``: ``t = n . (a - o) / n . d`` for beams with ``n . d < 0``."""
    for k in range(k0, k1 + 1):
        den = nx * cos_b[k] + ny * sin_b[k]
        if den < 0.0:
            out[k] = min(out[k], offset / den)


@njit(cache=True)
def _circle_hits(out, k0, k1, rx, ry, dist, r, cos_b, sin_b) -> None:
    """Lower ``out[k0..k1]`` to where those beams enter the circle of radius ``r`` whose
    centre lies at ``(rx, ry)``, ``dist`` away from the sensor."""
    for k in range(k0, k1 + 1):
        along = rx * cos_b[k] + ry * sin_b[k]
        perp_sq = dist * dist - along * along
        out[k] = min(out[k], along - np.sqrt(max(r * r - perp_sq, 0.0)))


@njit(cache=True)
def cast_kernel(
    edge_a: np.ndarray,
    edge_b: np.ndarray,
    normals: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    origins: np.ndarray,
    first: np.ndarray,
    step: float,
    n: int,
    max_range: float,
) -> np.ndarray:
    """Ranges (m, n) [m] of :func:`sim.sensors.cast`: edges (s, 2) ``edge_a``, ``edge_b``
    with outward ``normals`` (s, 2), circles ``centres`` (c, 2), ``radii`` (c,), sensors
    at ``origins`` (m, 2) with beam 0 at ``first`` (m,) [rad].

    Per sensor, the edges facing it (of closed convex outlines: the back faces are hidden
    behind the front ones) and the circles that neither contain it nor lie out of range
    are intersected exactly with the beams inside their angular interval relative to
    beam 0 (an edge's from end to end, a circle's centre +- asin(r / d)); each beam
    keeps its nearest hit."""
    m = origins.shape[0]
    ranges = np.full((m, n), max_range)
    cos_b = np.empty(n)
    sin_b = np.empty(n)
    for i in range(m):
        ox, oy, f = origins[i, 0], origins[i, 1], first[i]
        for k in range(n):
            angle = f + step * float(k)
            cos_b[k] = np.cos(angle)
            sin_b[k] = np.sin(angle)
        out = ranges[i]
        for e in range(edge_a.shape[0]):
            nx, ny = normals[e, 0], normals[e, 1]
            rx, ry = edge_a[e, 0] - ox, edge_a[e, 1] - oy
            offset = nx * rx + ny * ry  # n . (a - o) < 0: the edge faces the sensor
            if not offset < 0.0:
                continue
            ang_a = np.arctan2(ry, rx) - f
            ang_b = np.arctan2(edge_b[e, 1] - oy, edge_b[e, 0] - ox) - f
            sweep = _wrap(ang_b - ang_a + math.pi) - math.pi
            lo = _wrap(ang_b if sweep < 0.0 else ang_a)
            a0, a1, b0, b1 = _intervals(lo, abs(sweep), step, n)
            _edge_hits(out, a0, a1, nx, ny, offset, cos_b, sin_b)
            _edge_hits(out, b0, b1, nx, ny, offset, cos_b, sin_b)
        for c in range(centres.shape[0]):
            rx, ry = centres[c, 0] - ox, centres[c, 1] - oy
            dist = np.hypot(rx, ry)
            r = radii[c]
            if not (dist > r and dist - r < max_range):
                continue
            half = np.arcsin(r / dist)
            lo = _wrap(np.arctan2(ry, rx) - f - half)
            a0, a1, b0, b1 = _intervals(lo, 2.0 * half, step, n)
            _circle_hits(out, a0, a1, rx, ry, dist, r, cos_b, sin_b)
            _circle_hits(out, b0, b1, rx, ry, dist, r, cos_b, sin_b)
    return ranges


@njit(cache=True)
def scan_kernel(
    true: np.ndarray,
    z: np.ndarray,
    sigma: np.ndarray,
    min_range: np.ndarray,
    max_range: np.ndarray,
    cos: np.ndarray,
    sin: np.ndarray,
    x0: np.ndarray,
    y0: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy ranges and hit points of all beams (:meth:`sim.world.World.sense`).

    Parameters
    ----------
    true : (n,) [m] noise-free ranges, ``max_range`` where nothing is hit.
    z : (n,) standard normal draws, one per beam.
    sigma, min_range, max_range : (n,) [m] per-beam noise and range limits.
    cos, sin, x0, y0 : (n,) robot-frame beam directions and mount positions [m].

    Returns
    -------
    ranges : (n,) [m] ``clip(true + sigma z, min_range, max_range)`` where something is
        hit, else ``max_range``.
    points : (k, 2) [m] robot-frame end points of the beams with ``ranges < max_range``,
        in beam order.
    """
    n = true.shape[0]
    ranges = np.empty(n)
    ends = np.empty((n, 2))
    k = 0
    for i in range(n):
        top = max_range[i]
        r = top
        if true[i] < top:
            r = min(max(true[i] + sigma[i] * z[i], min_range[i]), top)
        ranges[i] = r
        if r < top:
            ends[k, 0] = r * cos[i] + x0[i]
            ends[k, 1] = r * sin[i] + y0[i]
            k += 1
    return ranges, ends[:k].copy()


@njit(cache=True)
def cast_from_pose_kernel(
    edge_a: np.ndarray,
    edge_b: np.ndarray,
    normals: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    x: float,
    y: float,
    yaw: float,
    positions: np.ndarray,
    firsts: np.ndarray,
    step: float,
    n: int,
    max_range: float,
) -> np.ndarray:
    """:func:`cast_kernel` for sensors mounted at robot-frame ``positions`` (m, 2) [m]
    with beam 0 at robot-frame ``firsts`` (m,) [rad], on a robot at map pose
    ``(x, y, yaw)``: the origins as ``sim.types.Pose2D.to_map_frame`` computes them."""
    c, s = math.cos(yaw), math.sin(yaw)
    m = positions.shape[0]
    origins = np.empty((m, 2))
    first = np.empty(m)
    for i in range(m):
        px, py = positions[i, 0], positions[i, 1]
        origins[i, 0] = c * px - s * py + x
        origins[i, 1] = s * px + c * py + y
        first[i] = yaw + firsts[i]
    return cast_kernel(edge_a, edge_b, normals, centres, radii, origins, first, step, n, max_range)
