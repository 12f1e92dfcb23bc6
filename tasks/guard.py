"""The scripted skills' obstacle guard: people do not drive into walls on purpose
(thesis Sec. 7.4.1-7.4.2).

For the wanted direction and 16 others up to 1.2 rad either side, the laser points in
the corridor the footprint sweeps cap the speed at ``guard_gain * (free -
guard_stop)``; the direction with the most progress along the wanted one wins, so the
robot slows down near obstacles and slides past an edge instead of stalling on it. A
turn that would swing the footprint's corners over a point is held.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

if TYPE_CHECKING:
    from tasks.skills import SkillSettings


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.hypot(v[0], v[1]))
    return v / n if n > 1e-12 else np.array([1.0, 0.0])


def _corridor(points: np.ndarray, d: np.ndarray, s: SkillSettings) -> tuple[np.ndarray, np.ndarray]:
    """Free distances [m] ahead of the footprint and signed lateral offsets [m] (+ left)
    of the laser points (robot frame) in the corridor it sweeps along unit ``d``."""
    along = points @ d
    across = points[:, 1] * d[0] - points[:, 0] * d[1]  # cross(d, p): + left of d
    front = s.half_length * abs(d[0]) + s.half_width * abs(d[1])  # the box's support along d
    half = s.half_length * abs(d[1]) + s.half_width * abs(d[0])
    # points beside the body (behind its front face) are not in the way of this motion
    inside = (np.abs(across) < half + s.guard_margin) & (along > front - 0.02)
    return along[inside] - front, across[inside]


def free_ahead(points: np.ndarray, direction: np.ndarray, s: SkillSettings) -> float:
    """Free distance [m] the footprint can travel along robot-frame ``direction`` (2,)
    before it meets a laser point (``inf`` when the corridor is empty)."""
    gaps, _ = _corridor(np.asarray(points).reshape(-1, 2), _unit(np.asarray(direction)), s)
    return float(gaps.min()) if len(gaps) else math.inf


@njit(cache=True)
def _near_points(
    points: np.ndarray,
    u0: float,
    u1: float,
    turning: bool,
    settings: tuple[float, float, float, float, float, float],
    turn_cos: np.ndarray,
    turn_sin: np.ndarray,
) -> tuple[np.ndarray, bool, float]:
    """The laser points (m, 2) [m] that can cap the speed of the command (u0, u1) [m/s]
    (within :func:`_guard_reach`, all of them for a gain <= 0), in order; whether one of
    them within the footprint's circumradius plus the margin hits the grown footprint
    once rotated by one of the angles given by ``turn_cos``, ``turn_sin`` (the turn guard,
    when ``turning``); and the speed ``hypot(u0, u1)`` [m/s]. ``settings`` is
    (half_length, half_width, guard_margin, guard_gain, guard_stop, circumradius)."""
    hl, hw, margin, gain, stop, radius = settings
    speed = np.hypot(u0, u1)
    filtered = gain > 0
    reach2 = 0.0
    if filtered:  # _guard_reach's arithmetic
        ahead = stop + speed / gain + radius + 0.01
        side = radius + (0.0 if 0.0 > margin else margin)  # Python's max(margin, 0.0)
        reach = math.sqrt(ahead * ahead + side * side)
        reach2 = reach * reach
        filtered = math.isfinite(reach)
    turn = radius + margin
    turn2 = turn * turn
    box_x, box_y = hl + margin, hw + margin
    near = np.empty((points.shape[0], 2))
    k = 0
    hit = False
    for j in range(points.shape[0]):
        px, py = points[j, 0], points[j, 1]
        sq = px * px + py * py
        if filtered and not sq < reach2:
            continue
        near[k, 0], near[k, 1] = px, py
        k += 1
        if turning and not hit and sq < turn2:
            for a in range(turn_cos.shape[0]):
                c, si = turn_cos[a], turn_sin[a]
                x = c * px - si * py
                y = si * px + c * py
                if abs(x) < box_x and abs(y) < box_y:
                    hit = True
                    break
    return near[:k], hit, speed


@njit(cache=True)
def _best_direction(
    along: np.ndarray,
    dirs: np.ndarray,
    near: np.ndarray,
    settings: tuple[float, float, float, float, float],
    speed: float,
    cosines: np.ndarray,
    penalty: np.ndarray,
) -> tuple[int, float, float]:
    """Of the unit directions ``dirs`` (k, 2), the one with the most progress once capped
    by the points ``near`` (m, 2) in its corridor; ``along`` (k, m) is ``dirs @ near.T``;
    ``settings`` is (half_length, half_width, guard_margin, guard_gain, guard_stop).
    Returns (index, its allowed speed [m/s], its progress), with numpy's ``minimum``,
    ``maximum`` and ``argmax`` semantics (NaN propagates, the first maximum wins)."""
    hl, hw, margin, gain, stop = settings
    best, best_p, best_allowed = -1, 0.0, 0.0
    for i in range(dirs.shape[0]):
        d0, d1 = dirs[i, 0], dirs[i, 1]
        ax, ay = abs(d0), abs(d1)
        front = hl * ax + hw * ay
        half = hl * ay + hw * ax
        free = np.inf
        for j in range(near.shape[0]):
            if not along[i, j] > front - 0.02:
                continue
            across = d0 * near[j, 1] - d1 * near[j, 0]
            gap = along[i, j] - front
            if abs(across) < half + margin and gap < free:
                free = gap
        capped = gain * (free - stop)
        capped = 0.0 if 0.0 >= capped else capped
        allowed = speed if (speed <= capped or math.isnan(speed)) else capped
        p = allowed * cosines[i] - penalty[i]
        if best < 0 or p > best_p or (math.isnan(p) and not math.isnan(best_p)):
            best, best_p, best_allowed = i, p, allowed
    return best, best_allowed, best_p


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


_TURN_ANGLES = (0.05, 0.1, 0.15)  # [rad] the turn guard's look ahead, in this order
# seen from the turned robot, points turn the other way: rotations by -a (omega > 0), +a
_TURN_COS = np.array([math.cos(a) for a in _TURN_ANGLES])
_TURN_SIN = {
    True: np.array([math.sin(-a) for a in _TURN_ANGLES]),
    False: np.array([math.sin(a) for a in _TURN_ANGLES]),
}


def guard_uvw(
    u0: float, u1: float, u2: float, points: np.ndarray, s: SkillSettings
) -> tuple[float, float, float]:
    """Keep the footprint off the laser points ``points`` (m, 2) [m] (robot frame; none:
    ``u`` unchanged): of the wanted direction and directions up to 1.2 rad either
    side, take the one with the most progress in the wanted direction once each is capped
    to ``guard_gain * (free - guard_stop)`` (people steer around what they would hit and
    slow down near it); rotation is kept unless the turn guard holds it.

    ``u0, u1, u2`` is the wanted command [m/s, m/s, rad/s]; returns the guarded one.

    Speed: only the points within :func:`_guard_reach` of the centre enter the corridor
    test. A point farther away is free by at least ``guard_stop + speed / guard_gain``
    (plus a slack) along every direction whose corridor it lies in, so it cannot cap the
    speed: the capped speeds, hence the result, are exactly those over all points. The
    turn guard's points (within the footprint's circumradius plus the margin) are a
    subset of those, in the same order. The corridors' ``along`` distances are numpy's
    matrix product ``dirs @ near.T`` (the BLAS's rounding), the rest is compiled scalar
    arithmetic in numpy's order of operations.
    """
    points = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    if len(points) == 0:
        return u0, u1, u2
    near, hit, speed = _near_points(
        points,
        u0,
        u1,
        not abs(u2) < 1e-9,
        (
            s.half_length,
            s.half_width,
            s.guard_margin,
            s.guard_gain,
            s.guard_stop,
            math.hypot(s.half_length, s.half_width),
        ),
        _TURN_COS,
        _TURN_SIN[u2 > 0],
    )
    w = 0.0 if hit else u2
    if speed < 1e-9:
        return u0, u1, w
    angles = math.atan2(u1, u0) + _GUARD_OFFSETS
    dirs = np.empty((len(angles), 2))
    dirs[:, 0] = np.cos(angles)
    dirs[:, 1] = np.sin(angles)
    along = dirs @ near.T if len(near) else np.empty((len(angles), 0))
    best, allowed, progress = _best_direction(
        along,
        dirs,
        near,
        (s.half_length, s.half_width, s.guard_margin, s.guard_gain, s.guard_stop),
        speed,
        _GUARD_COS,
        _GUARD_PENALTY,
    )
    if progress <= 0.0:
        return 0.0, 0.0, w
    return float(dirs[best, 0] * allowed), float(dirs[best, 1] * allowed), w


def guard_command(u: np.ndarray, points: np.ndarray, settings: SkillSettings) -> np.ndarray:
    """The skills' obstacle guard (:func:`guard_uvw`) for any ideal command: ``u``
    (3,) robot frame [m/s, m/s, rad/s], ``points`` (k, 2) laser points in the robot frame
    [m]; returns the guarded command (3,) (``u`` itself when there are no points). Used
    by synthetic participants."""
    return _guard(np.asarray(u, dtype=float), points, settings)


def _guard(u: np.ndarray, points: np.ndarray, s: SkillSettings) -> np.ndarray:
    """:func:`guard_command` of a float command ``u`` (3,)."""
    points = np.asarray(points).reshape(-1, 2)
    if len(points) == 0:
        return u
    return np.array(guard_uvw(float(u[0]), float(u[1]), float(u[2]), points, s))
