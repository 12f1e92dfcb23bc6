"""Compiled loops of the footprint-versus-laser-points geometry (:mod:`autonomy.safety`,
:mod:`autonomy.dwa`).

Each kernel repeats the floating-point operations of the vectorised numpy code it
replaced, in the same order and precision (the clearances in float32, as
:func:`autonomy.safety.footprint_clearance` works; no fastmath, no fused multiply-add),
so its results are bit-identical to it; ``tests/test_geometry_kernels.py`` checks that
against the numpy code kept in ``tests/geometry_reference.py``. Where a caller only needs
the first pose or twist that fails a test, the loops stop there.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_F32 = np.float32
_EPS = float(np.finfo(float).eps)
_TWO_PI = 2 * np.pi


@njit(cache=True)
def _sinc(x: float) -> float:
    """``autonomy.safety._sinc`` (numpy's sinc) of one number."""
    y = np.pi * x
    if y == 0.0:
        y = _EPS
    return np.sin(y) / y


@njit(cache=True)
def arc_pose(vx: float, vy: float, w: float, t: float, out: np.ndarray) -> None:
    """Pose (x [m], y [m], yaw [rad]) into ``out`` (3,) reached in ``t`` [s] under the
    constant twist ``(vx, vy, w)``; :func:`autonomy.safety.arc_poses` for one entry."""
    a = w * t  # heading change
    s1 = t * _sinc(a / np.pi)  # sin(a) / w
    s2 = t * np.sin(a / 2) * _sinc(a / _TWO_PI)  # (1 - cos a) / w
    out[0] = vx * s1 - vy * s2
    out[1] = vx * s2 + vy * s1
    out[2] = a


@njit(cache=True)
def arc_poses_kernel(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Poses (s, k, 3) reached from the origin under twists ``v`` (s, 3) at times ``t``
    (k,) [s]."""
    out = np.empty((v.shape[0], t.shape[0], 3))
    for i in range(v.shape[0]):
        for j in range(t.shape[0]):
            arc_pose(v[i, 0], v[i, 1], v[i, 2], t[j], out[i, j])
    return out


@njit(cache=True)
def _lines_at(x, y, yaw, normals, mid, ax, ay, b) -> None:
    """The footprint's lines at pose (x, y, yaw), in the points' frame and float32:
    normals ``(ax, ay)`` (l,) and offsets ``b`` (l,)."""
    c, s = np.cos(yaw), np.sin(yaw)
    for e in range(normals.shape[0]):
        nx, ny = normals[e, 0], normals[e, 1]
        ax64 = c * nx - s * ny
        ay64 = s * nx + c * ny
        ax[e] = _F32(ax64)
        ay[e] = _F32(ay64)
        b[e] = _F32(mid[e] + ax64 * x + ay64 * y)


@njit(cache=True)
def _clearance_f32(ax, ay, b, half, two_sided, px, py, stop_below=-np.inf) -> np.float32:
    """``min_points max_lines`` of the half-plane values in float32 (see
    :func:`clearance_kernel`); NaN propagates as with ``np.maximum`` and ``min``. Stops
    at the first point whose value is below ``stop_below`` (returning that value)."""
    best = _F32(np.inf)
    for j in range(px.shape[0]):
        h = _F32(0.0)
        for e in range(ax.shape[0]):
            val = ax[e] * px[j]
            val += ay[e] * py[j]
            val -= b[e]
            if two_sided[e]:  # a pair of parallel edges: |n . q - mid| - half
                val = abs(val) - half[e]
            if e == 0 or val > h or val != val:
                h = val
        if h < best or h != h:
            best = h
            if best < stop_below:
                break
    return best


@njit(cache=True)
def clearance_kernel(
    poses: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    normals: np.ndarray,
    mid: np.ndarray,
    half: np.ndarray,
) -> np.ndarray:
    """:func:`autonomy.safety.footprint_clearance` (p,) [m] of poses (p, 3) to the points
    ``(px, py)`` (m,) float32, the footprint's lines ``normals`` (l, 2), ``mid`` (l,),
    ``half`` (l,) [m] (NaN: a one-sided line); at least one point."""
    ax, ay, b, half32, two_sided = _line_work(normals.shape[0], half)
    out = np.empty(poses.shape[0])
    for i in range(poses.shape[0]):
        _lines_at(poses[i, 0], poses[i, 1], poses[i, 2], normals, mid, ax, ay, b)
        out[i] = _clearance_f32(ax, ay, b, half32, two_sided, px, py)
    return out


@njit(cache=True)
def _line_work(
    n_lines: int, half: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Work arrays of :func:`_lines_at` (float32 ``ax``, ``ay``, ``b``, (l,)) and the
    lines' float32 half widths and sidedness (:func:`_half_lines`)."""
    ax = np.empty(n_lines, dtype=_F32)
    ay = np.empty(n_lines, dtype=_F32)
    b = np.empty(n_lines, dtype=_F32)
    half32, two_sided = _half_lines(half)
    return ax, ay, b, half32, two_sided


@njit(cache=True)
def _half_lines(half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lines' half widths in float32 and whether each is two-sided (not NaN)."""
    half32 = np.empty(half.shape[0], dtype=_F32)
    two_sided = np.empty(half.shape[0], dtype=np.bool_)
    for e in range(half.shape[0]):
        two_sided[e] = not np.isnan(half[e])
        half32[e] = _F32(half[e]) if two_sided[e] else _F32(0.0)
    return half32, two_sided


@njit(cache=True)
def first_unsafe_step(
    v: np.ndarray,
    rate: float,
    dtau: float,
    n_steps: int,
    c0: float,
    required: float,
    px: np.ndarray,
    py: np.ndarray,
    normals: np.ndarray,
    mid: np.ndarray,
    half: np.ndarray,
) -> int:
    """Index j (0-based) of the first interval ``[j dtau, (j + 1) dtau]`` along the arc of
    the twist ``v`` (3,) whose guaranteed clearance ``(h_j + h_{j+1} - rate dtau) / 2``
    (``autonomy.safety.interval_clearance``; ``h_0 = c0``) falls below ``required`` [m];
    -1 when none of the ``n_steps`` does. The arc's poses are checked in order and the
    loop stops at the first failure (:func:`autonomy.safety.safe_command`)."""
    ax, ay, b, half32, two_sided = _line_work(normals.shape[0], half)
    pose = np.empty(3)
    prev = c0
    for j in range(n_steps):
        arc_pose(v[0], v[1], v[2], dtau * float(j + 1), pose)
        _lines_at(pose[0], pose[1], pose[2], normals, mid, ax, ay, b)
        h = float(_clearance_f32(ax, ay, b, half32, two_sided, px, py))
        if 0.5 * (prev + h - rate * dtau) < required:
            return j
        prev = h
    return -1


@njit(cache=True)
def _arc_min_clearance(
    v, times, px, py, normals, mid, half32, two_sided, ax, ay, b, pose, stop_below
) -> float:
    """Smallest clearance [m] of the footprint to the points over the poses of twist
    ``v`` (3,) at ``times`` (k,) [s]; stops at the first one below ``stop_below``
    (and returns it)."""
    low = np.inf
    for j in range(times.shape[0]):
        arc_pose(v[0], v[1], v[2], times[j], pose)
        _lines_at(pose[0], pose[1], pose[2], normals, mid, ax, ay, b)
        h = float(_clearance_f32(ax, ay, b, half32, two_sided, px, py, stop_below))
        if h < low or h != h:
            low = h
        if low < stop_below or low != low:
            break
    return low


@njit(cache=True)
def horizon_clearances(
    samples: np.ndarray,
    times: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    normals: np.ndarray,
    mid: np.ndarray,
    half: np.ndarray,
) -> np.ndarray:
    """Per twist of ``samples`` (n, 3), the smallest footprint clearance [m] over its
    poses at ``times`` (k,) [s], or a negative one of them: the row minimum of
    ``footprint_clearance(arc_poses(samples, times))`` wherever that is >= 0, and some
    value < 0 wherever it is negative (what ``clip(., 0, cap)`` needs, :mod:`autonomy.dwa`)."""
    ax, ay, b, half32, two_sided = _line_work(normals.shape[0], half)
    pose = np.empty(3)
    out = np.empty(samples.shape[0])
    for i in range(samples.shape[0]):
        out[i] = _arc_min_clearance(
            samples[i], times, px, py, normals, mid, half32, two_sided, ax, ay, b, pose, 0.0
        )
    return out


@njit(cache=True)
def first_admissible(
    samples: np.ndarray,
    order: np.ndarray,
    n_check: np.ndarray,
    rate: np.ndarray,
    step: float,
    c0: float,
    required: float,
    px: np.ndarray,
    py: np.ndarray,
    normals: np.ndarray,
    mid: np.ndarray,
    half: np.ndarray,
) -> tuple[int, float]:
    """The first twist in ``order`` whose guaranteed clearance stays >= ``required`` [m]
    on every interval up to ``n_check[i] * step`` [s] (``autonomy.safety.
    interval_clearance`` with ``rate`` (n,) [m/s], ``h_0 = c0``): its position in
    ``order`` and its smallest interval clearance [m]; ``(-1, -inf)`` when none is. Each
    twist's check stops at its first failing interval (:func:`autonomy.dwa.dwa`)."""
    ax, ay, b, half32, two_sided = _line_work(normals.shape[0], half)
    pose = np.empty(3)
    for pos in range(order.shape[0]):
        i = order[pos]
        prev, low, ok = c0, np.inf, True
        for j in range(n_check[i]):
            arc_pose(samples[i, 0], samples[i, 1], samples[i, 2], step * float(j + 1), pose)
            _lines_at(pose[0], pose[1], pose[2], normals, mid, ax, ay, b)
            h = float(_clearance_f32(ax, ay, b, half32, two_sided, px, py))
            bound = 0.5 * (prev + h - rate[i] * step)
            if not bound >= required:
                ok = False
                break
            low = min(low, bound)
            prev = h
        if ok:
            return pos, low
    return -1, -np.inf


@njit(cache=True)
def _near_points(points: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """The points (m, 2) [m] with ``|p|^2 <= reach^2``, as float32 x and y (k,)."""
    r2 = reach * reach
    px = np.empty(points.shape[0], dtype=_F32)
    py = np.empty(points.shape[0], dtype=_F32)
    k = 0
    for i in range(points.shape[0]):
        x, y = points[i, 0], points[i, 1]
        if x * x + y * y <= r2:
            px[k], py[k] = _F32(x), _F32(y)
            k += 1
    return px[:k], py[:k]


@njit(cache=True)
def safe_arc_check(
    v: np.ndarray,
    points: np.ndarray,
    reach: float,
    x_steps: float,
    tau_max: float,
    max_steps: float,
    radius: float,
    margin: float,
    tolerance_m: float,
    normals: np.ndarray,
    mid: np.ndarray,
    half: np.ndarray,
) -> tuple[int, float]:
    """The collision check of :func:`autonomy.safety.safe_command` for the twist ``v``
    (3,) against the laser points (m, 2) [m] within ``reach`` [m]: the start clearance
    ``c0``, the required clearance ``min(margin, c0 - tolerance_m)``, ``n_steps =
    min(max_steps, max(2, ceil(x_steps)))`` poses ``dtau = tau_max / n_steps`` [s] apart
    and the sweep rate bound, then :func:`first_unsafe_step`.

    Returns
    -------
    code : the first unsafe interval's index; -1 when none is, -2 when no point lies
        within ``reach``, -3 when ``x_steps`` is not finite (the caller raises).
    dtau : [s] (0 unless code >= -1).
    """
    px, py = _near_points(points, reach)
    if px.shape[0] == 0:
        return -2, 0.0
    if not np.isfinite(x_steps):
        return -3, 0.0
    ax, ay, b, half32, two_sided = _line_work(normals.shape[0], half)
    _lines_at(0.0, 0.0, 0.0, normals, mid, ax, ay, b)
    c0 = float(_clearance_f32(ax, ay, b, half32, two_sided, px, py))
    lowered = c0 - tolerance_m
    required = lowered if lowered < margin else margin  # Python's min(margin, lowered)
    steps = np.ceil(x_steps)
    steps = steps if steps > 2.0 else 2.0
    n_steps = int(steps if steps < max_steps else max_steps)
    dtau = tau_max / n_steps
    w = abs(v[2])
    rate = (np.hypot(v[0], v[1]) + w * radius) * np.exp(w * dtau)  # safety.sweep_rate
    bad = first_unsafe_step(v, rate, dtau, n_steps, c0, required, px, py, normals, mid, half)
    return bad, dtau
