"""Scene and observation generators that tests and benchmarks share.

Exact 2D ray casting in numpy against line segments: a synthetic room seen by the
scenario's default two 270-degree scanners, without pybullet.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from sim.types import ImuReading, LaserScan, Observation, Pose2D

# scenario defaults (sim.scenario.DEFAULT_LASERS, LASER_DEFAULTS): name, mount, yaw
LASER_MOUNTS = (("front", (0.3, 0.0), 0.0), ("rear", (-0.3, 0.0), math.pi))

# The working precision of autonomy.safety.footprint_clearance, whose arithmetic
# _clearance_at_origin repeats so that the generated rooms stay the same draws.
_WORK_DTYPE = np.float32


class Footprint(Protocol):
    """The footprint's lines as ``autonomy.types.RobotModel`` derives them."""

    line_normals: np.ndarray  # (l, 2) unit normals
    line_mid: np.ndarray  # (l,) [m]
    line_half: np.ndarray  # (l,) [m], nan for a one-sided line


def box_segments(centre: tuple[float, float], size: tuple[float, float], yaw: float = 0.0):
    """The four sides of a box as segments (4, 2, 2) [m]."""
    hx, hy = size[0] / 2, size[1] / 2
    c, s = math.cos(yaw), math.sin(yaw)
    corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ np.array([[c, s], [-s, c]])
    corners += centre
    return np.stack((corners, np.roll(corners, -1, axis=0)), axis=1)


def cast_segments(
    segments: np.ndarray, origin: np.ndarray, angles: np.ndarray, max_range: float
) -> np.ndarray:
    """Exact ranges [m] of beams from ``origin`` at ``angles`` (n,) against segments
    (k, 2, 2); ``max_range`` where nothing is hit."""
    d = np.column_stack((np.cos(angles), np.sin(angles)))  # (n, 2)
    a = segments[:, 0]  # (k, 2)
    e = segments[:, 1] - a
    w = a - origin
    denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (n, k)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[None, :, 0] * e[None, :, 1] - w[None, :, 1] * e[None, :, 0]) / denom
        s = (w[None, :, 0] * d[:, None, 1] - w[None, :, 1] * d[:, None, 0]) / denom
    valid = (np.abs(denom) > 1e-12) & (t > 0) & (s >= 0) & (s <= 1)
    return np.minimum(np.min(np.where(valid, t, np.inf), axis=1, initial=np.inf), max_range)


def synthetic_observation(
    segments: np.ndarray,
    *,
    velocity: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    sigma: float = 0.01,
    max_range: float = 8.0,
    fov_deg: float = 270.0,
    resolution_deg: float = 1.0,
    components: tuple = (),
) -> Observation:
    """What a robot at the origin (robot frame = map frame) with the default two
    scanners sees of ``segments`` (k, 2, 2) [m]; Gaussian range noise ``sigma`` [m]
    when ``rng`` is given."""
    n = int(round(fov_deg / resolution_deg)) + 1
    scans, points = [], []
    for name, mount, yaw in LASER_MOUNTS:
        angles = yaw + np.radians(np.linspace(-fov_deg / 2, fov_deg / 2, n))
        origin = np.array(mount)
        ranges = cast_segments(segments, origin, angles, max_range)
        hit = ranges < max_range
        if rng is not None:
            ranges = np.where(
                hit, np.clip(ranges + sigma * rng.standard_normal(n), 0.05, max_range), ranges
            )
        scan = LaserScan(name, angles, ranges, origin, max_range)
        scans.append(scan)
        points.append(scan.points())
    return Observation(
        t=0.0,
        pose=Pose2D(0.0, 0.0, 0.0),
        velocity=np.zeros(3) if velocity is None else np.asarray(velocity, dtype=float),
        scans=tuple(scans),
        points=np.vstack(points),
        imu=ImuReading(0.0, np.zeros(2)),
        components=components,
    )


def _clearance_at_origin(outline: np.ndarray, robot: Footprint) -> float:
    """Half-plane clearance [m] of the footprint at the origin to the points ``outline``
    (m, 2) [m]: ``autonomy.safety.footprint_clearance`` at pose (0, 0, 0), the same
    float32 operations in the same order."""
    ax = robot.line_normals[:, 0].astype(_WORK_DTYPE)
    ay = robot.line_normals[:, 1].astype(_WORK_DTYPE)
    b = robot.line_mid.astype(_WORK_DTYPE)
    px = outline[:, 0].astype(_WORK_DTYPE)
    py = outline[:, 1].astype(_WORK_DTYPE)
    h = None
    for e in range(len(b)):
        val = ax[e] * px
        val += ay[e] * py
        val -= b[e]
        if not np.isnan(robot.line_half[e]):  # a pair of parallel edges: |n . q - mid| - half
            np.abs(val, out=val)
            val -= _WORK_DTYPE(robot.line_half[e])
        h = val if h is None else np.maximum(h, val)
    return float(h.min())


def cluttered_segments(
    rng: np.random.Generator,
    robot: Footprint,
    *,
    n_boxes: int = 10,
    room: tuple[float, float] = (7.0, 6.0),
    min_clearance: float = 0.1,
) -> np.ndarray:
    """A room of ``room`` [m] around the origin with ``n_boxes`` random boxes, none
    closer than ``min_clearance`` [m] to the robot's footprint at the origin.

    ``robot`` is an ``autonomy.types.RobotModel`` (any object with its footprint lines).

    Returns
    -------
    (k, 2, 2) [m] wall and box segments.
    """
    offset = rng.uniform(-0.25, 0.25, 2) * np.array(room) / 2
    segments = [box_segments(tuple(offset), room)]
    while len(segments) < n_boxes + 1:
        centre = rng.uniform(-0.45, 0.45, 2) * np.array(room) + offset
        size, yaw = rng.uniform(0.15, 0.9, 2), rng.uniform(0, math.pi)
        box = box_segments(tuple(centre), tuple(size), yaw)
        along = np.linspace(0, 1, 101)[None, :, None]  # <= 1 cm apart on these boxes
        outline = (box[:, 0, None] + along * (box[:, 1] - box[:, 0])[:, None]).reshape(-1, 2)
        c, s = math.cos(yaw), math.sin(yaw)
        robot_in_box = np.all(
            np.abs([c * -centre[0] + s * -centre[1], -s * -centre[0] + c * -centre[1]]) < size / 2
        )
        if not robot_in_box and _clearance_at_origin(outline, robot) > min_clearance:
            segments.append(box)
    return np.concatenate(segments)
