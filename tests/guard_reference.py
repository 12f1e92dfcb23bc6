"""The obstacle guard as it was before issue 25's kernels (tasks/guard.py at 5b8a1d4):
the readable reference the tests compare :func:`tasks.guard.guard_command` with, bit for
bit. The same numpy operations in the same order (the corridor's ``along`` is numpy's
matrix product, as in the kernelled guard)."""

from __future__ import annotations

import math

import numpy as np

from tasks.skills import SkillSettings


def _free_all(points: np.ndarray, dirs: np.ndarray, s: SkillSettings) -> np.ndarray:
    """:func:`free_ahead` for many unit directions (k, 2) at once -> (k,) [m]."""
    along = dirs @ points.T  # (k, m)
    across = dirs[:, :1] * points[:, 1] - dirs[:, 1:] * points[:, 0]
    ax, ay = np.abs(dirs[:, :1]), np.abs(dirs[:, 1:])
    front = s.half_length * ax + s.half_width * ay
    half = s.half_length * ay + s.half_width * ax
    inside = (np.abs(across) < half + s.guard_margin) & (along > front - 0.02)
    return np.where(inside, along - front, np.inf).min(axis=1)


def _turn_guard(omega: float, points: np.ndarray, s: SkillSettings) -> float:
    """``omega`` [rad/s], or 0 when turning 0.15 rad that way would sweep the footprint
    (grown by ``guard_margin``) over a laser point (a box's corners swing out)."""
    if abs(omega) < 1e-9:
        return omega
    reach = math.hypot(s.half_length, s.half_width) + s.guard_margin
    near = points[np.einsum("ij,ij->i", points, points) < reach * reach]
    if not len(near):
        return omega
    for a in (0.05, 0.1, 0.15):  # seen from the turned robot, points turn the other way
        c, si = math.cos(a), math.sin(-a if omega > 0 else a)
        x = c * near[:, 0] - si * near[:, 1]
        y = si * near[:, 0] + c * near[:, 1]
        hit = (np.abs(x) < s.half_length + s.guard_margin) & (
            np.abs(y) < s.half_width + s.guard_margin
        )
        if np.any(hit):
            return 0.0
    return omega


_GUARD_OFFSETS = np.linspace(-1.2, 1.2, 17)  # [rad] directions the guard may take instead
_GUARD_COS = np.cos(_GUARD_OFFSETS)
_GUARD_PENALTY = 0.02 * np.abs(_GUARD_OFFSETS)


def _guard_reach(speed: float, s: SkillSettings) -> float:
    """Distance [m] from the robot's centre beyond which no laser point can cap a motion at
    ``speed`` [m/s] in any direction (see :func:`_guard`); ``inf`` for a gain <= 0."""
    if not s.guard_gain > 0:
        return math.inf
    # a point in the corridor of unit d has |across| < half + margin and is free by
    # along - front with along = sqrt(|p|^2 - across^2); front, half <= the circumradius
    radius = math.hypot(s.half_length, s.half_width)
    ahead = s.guard_stop + speed / s.guard_gain + radius + 0.01  # 0.01 m: rounding slack
    side = radius + max(s.guard_margin, 0.0)
    return math.sqrt(ahead * ahead + side * side)


def guard_reference(u: np.ndarray, points: np.ndarray, s: SkillSettings) -> np.ndarray:
    """Keep the footprint off the laser points (robot frame): of the wanted direction
    and directions up to 1.2 rad either side, take the one with the most progress in
    the wanted direction once each is capped to ``guard_gain * (free - guard_stop)``
    (people steer around what they would hit and slow down near it); rotation is kept.

    Speed: only the points within :func:`_guard_reach` of the centre enter the corridor
    test. A point farther away is free by at least ``guard_stop + speed / guard_gain``
    (plus a slack) along every direction whose corridor it lies in, so it cannot cap the
    speed: the capped speeds, hence the result, are exactly those over all points. The
    turn guard's points (within the footprint's circumradius plus the margin) are a
    subset of those, in the same order.
    """
    if len(points) == 0:
        return u
    speed = float(np.hypot(u[0], u[1]))
    reach = _guard_reach(speed, s)
    if math.isfinite(reach):
        points = points[np.einsum("ij,ij->i", points, points) < reach * reach]
    u = np.array([u[0], u[1], _turn_guard(float(u[2]), points, s)])
    if speed < 1e-9:
        return u
    base = math.atan2(u[1], u[0])
    angles = base + _GUARD_OFFSETS
    dirs = np.column_stack((np.cos(angles), np.sin(angles)))
    if len(points):
        free = _free_all(points, dirs, s)
        allowed = np.minimum(speed, np.maximum(0.0, s.guard_gain * (free - s.guard_stop)))
    else:  # nothing within reach: every direction at full speed (as with free = inf)
        allowed = np.full(len(dirs), speed)
    progress = allowed * _GUARD_COS - _GUARD_PENALTY
    best = int(np.argmax(progress))
    if progress[best] <= 0.0:
        return np.array([0.0, 0.0, u[2]])
    v = dirs[best] * allowed[best]
    return np.array([v[0], v[1], u[2]])
