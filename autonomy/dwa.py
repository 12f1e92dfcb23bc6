"""Vectorised holonomic Dynamic Window Approach, the action of General Obstacle
Avoidance (thesis Ch. 3.2.1.1, eq. 3.8; Fox, Burgard and Thrun 1997, adapted to a
holonomic base).

Every tick the dynamic window is the box of twists ``(v_x, v_y, omega)`` reachable from
the current velocity estimate within one control tick under the acceleration limits,
intersected with the velocity limits. A grid of twists in the window, plus its points
nearest the user's command ``u`` and nearest standstill, each held constant (closed-form
arcs), are scored (see :func:`dwa`) and then checked for collision in score order; the
first admissible one is the answer. In free space that is the window's point nearest
``u``, i.e. ``u`` itself whenever it is reachable (spec section 2). Choices where the
thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from autonomy._geometry_kernels import first_admissible, horizon_clearances
from autonomy.safety import (
    _work_points,
    arc_poses,
    footprint_clearance,
    inflated_radius,
    required_clearance,
    sweep_rate,
)
from autonomy.types import RobotModel


@dataclass(frozen=True, slots=True)
class DWASettings:
    """Settings of :func:`dwa`; change with ``dataclasses.replace``."""

    horizon_s: float = 1.5  # [s] a twist must stay clear this long (longer if braking needs it)
    step_s: float = 0.1  # [s] between poses of the collision check (exact in between)
    score_step_s: float = 0.25  # [s] between poses the clearance score looks at
    n_vx: int = 5  # grid points of the window per channel
    n_vy: int = 5
    n_omega: int = 3
    weight_agreement: float = 1.0  # w_a: closeness to the user's command
    weight_clearance: float = 0.2  # w_c: smallest clearance within the horizon
    clearance_cap_m: float = 0.3  # [m] clearance beyond this scores no better
    # the clearance term counts in proportion to the twist's progress along u (so slowing
    # down or stopping never outscores following the user); False: it counts in full
    clearance_by_progress: bool = True
    tolerance_m: float = 0.01  # [m] clearance loss allowed inside the protective field
    score_cell_m: float = 0.05  # [m] the scores see one laser point per grid square this size
    # unused since the collision check runs compiled, one twist at a time and stopping at
    # the first admissible one (issue 25); kept so that settings naming it stay valid
    batch: int = 8

    def __post_init__(self) -> None:
        positive = ("horizon_s", "step_s", "score_step_s", "clearance_cap_m", "score_cell_m")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"DWA setting {name}: must be positive, got {getattr(self, name)}")
        for name in ("n_vx", "n_vy", "n_omega", "batch"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"DWA setting {name}: must be an integer >= 1, got {value!r}")
        for name in ("weight_agreement", "weight_clearance", "tolerance_m"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"DWA setting {name}: must be >= 0, got {getattr(self, name)}")


@dataclass(frozen=True, slots=True, eq=False)
class DWAResult:
    v: np.ndarray  # (3,) chosen twist (v_x [m/s], v_y [m/s], omega [rad/s])
    path: np.ndarray  # (k, 3) its poses (x [m], y [m], yaw [rad]) over the horizon
    horizon_s: float  # [s] the chosen twist, held, stays clear at least this long
    clearance: float  # [m] guaranteed footprint clearance over that horizon
    n_checked: int  # twists checked for collision until one was admissible
    n_samples: int  # twists scored


def dynamic_window(velocity: np.ndarray, robot: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """Box of twists reachable within one tick, inside the velocity limits.

    Parameters
    ----------
    velocity : (3,) current robot-frame velocity estimate.
    robot : limits and control tick.

    Returns
    -------
    lo, hi : (3,) corners of the window (v_x [m/s], v_y [m/s], omega [rad/s]).
    """
    limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
    step = robot.dt * np.array([robot.max_accel, robot.max_accel, robot.max_yaw_accel])
    v0 = np.asarray(velocity, dtype=float).reshape(3)
    return np.clip(v0 - step, -limit, limit), np.clip(v0 + step, -limit, limit)


def _limit_speed(v: np.ndarray, max_speed: float) -> np.ndarray:
    speed = np.hypot(v[:, 0], v[:, 1])
    factor = np.minimum(1.0, max_speed / np.maximum(speed, 1e-12))
    return np.column_stack((v[:, 0] * factor, v[:, 1] * factor, v[:, 2]))


def window_samples(
    u: np.ndarray, velocity: np.ndarray, robot: RobotModel, settings: DWASettings
) -> np.ndarray:
    """The twists the DWA evaluates: a grid over the window, the window's point
    nearest ``u`` (first row) and its point nearest standstill (second row).

    Returns
    -------
    (s, 3) twists within the velocity limits.
    """
    lo, hi = dynamic_window(velocity, robot)
    axes = [
        np.linspace(lo[i], hi[i], n)
        for i, n in enumerate((settings.n_vx, settings.n_vy, settings.n_omega))
    ]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    special = np.clip(np.vstack((np.asarray(u, dtype=float).reshape(3), np.zeros(3))), lo, hi)
    return _limit_speed(np.vstack((special, grid)), robot.max_speed)


def thin_points(points: np.ndarray, cell: float) -> np.ndarray:
    """One point per ``cell`` x ``cell`` [m] grid square (the first in scan order):
    (m, 2) -> (m', 2), m' <= m. Every dropped point lies within ``cell * sqrt(2)`` of a
    kept one. Compiled (:func:`_first_in_cell`); the numpy below for coordinates whose
    cell index an int64 does not hold."""
    if len(points) == 0:
        return points
    if points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 2:
        keep = _first_in_cell(np.ascontiguousarray(points), float(cell))
        if keep is not None:
            return points[keep]
    keys = np.floor(points / cell).astype(np.int64)
    _, first = np.unique(keys[:, 0] * 1_000_003 + keys[:, 1], return_index=True)
    return points[np.sort(first)]


@njit(cache=True)
def _first_in_cell(points: np.ndarray, cell: float) -> np.ndarray | None:
    """The mask (m,) of :func:`thin_points`' kept points: per cell key
    ``floor(x / cell) * 1_000_003 + floor(y / cell)`` (int64, wrapping as numpy's), its
    first point; None when a cell index is not finite or beyond 2**62."""
    m = points.shape[0]
    keys = np.empty(m, dtype=np.int64)
    for i in range(m):
        fx, fy = math.floor(points[i, 0] / cell), math.floor(points[i, 1] / cell)
        if not (abs(fx) < 2.0**62 and abs(fy) < 2.0**62):
            return None
        keys[i] = np.int64(fx) * np.int64(1_000_003) + np.int64(fy)
    size = 16
    while size < 2 * m:
        size *= 2
    table = np.empty(size, dtype=np.int64)  # open addressing: the keys seen so far
    used = np.zeros(size, dtype=np.bool_)
    keep = np.zeros(m, dtype=np.bool_)
    for i in range(m):
        h = np.uint64(keys[i]) * np.uint64(0x9E3779B97F4A7C15)
        slot = np.int64(h >> np.uint64(40)) & (size - 1)
        while used[slot] and table[slot] != keys[i]:
            slot = (slot + 1) & (size - 1)
        if not used[slot]:  # the key's first point
            used[slot], table[slot], keep[i] = True, keys[i], True
    return keep


def _scores(
    samples: np.ndarray,
    speed: np.ndarray,
    u: np.ndarray,
    points: np.ndarray,
    sq: np.ndarray,
    robot: RobotModel,
    st: DWASettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Scores of the twists ``samples`` (n, 3), and the times (n_look,) [s] of the poses
    every ``score_step_s`` along the horizon that they look at::

        J = w_a (1 - ||v - u||_n) + w_c p min(clearance, c_cap) / c_cap

    ``||v - u||_n`` in [0, 1] is the distance to the user's command with each channel
    normalised by twice its limit: smallest for the twist with the user's heading, speed
    and turn rate, so it carries the heading and velocity terms of Fox's objective; the
    clearance term (the footprint's smallest clearance along the horizon, capped) pushes
    away from obstacles. ``p`` in [0, 1] is the twist's progress along the user's
    translation relative to the window's point nearest ``u``, ``v*`` (first row of
    ``samples``): ``clip(v_xy . u_xy / v*_xy . u_xy, 0, 1)`` (1 for every twist when
    ``v*`` makes no progress, or with ``clearance_by_progress`` off). So the clearance a
    standstill keeps cannot outscore an admissible twist that follows the user -- from
    rest in front of a narrow doorway it otherwise does, for good, since the window is
    centred on the velocity -- and in free space ``v*`` still scores best.
    The scores see one laser point per ``score_cell_m`` square (``points`` (m, 2) [m],
    ``sq`` their squared norms): they only rank the twists."""
    n_look = max(1, math.ceil(st.horizon_s / st.score_step_s - 1e-9))
    times = st.score_step_s * np.arange(1, n_look + 1)
    cap = st.clearance_cap_m
    reach = speed.max() * st.score_step_s * n_look + inflated_radius(
        robot, max(robot.protective_margin, cap)
    )
    coarse = thin_points(points[sq <= reach * reach], st.score_cell_m)
    if len(coarse):
        px, py = _work_points(coarse)
        lines = (robot.line_normals, robot.line_mid, robot.line_half)
        # the smallest clearance along each arc (a negative one where it goes below 0)
        low = horizon_clearances(samples, times, px, py, *lines)
    else:
        low = np.full(len(samples), np.inf)
    scale = np.array([2 * robot.max_speed, 2 * robot.max_speed, 2 * robot.max_yaw_rate])
    agreement = 1 - np.linalg.norm((samples - u) / scale, axis=1) / math.sqrt(3)
    clearance = np.clip(low, 0.0, cap) / cap
    return st.weight_agreement * agreement + st.weight_clearance * clearance * _progress(
        samples, u, st.clearance_by_progress
    ), times


def _progress(samples: np.ndarray, u: np.ndarray, enabled: bool) -> np.ndarray | float:
    """Progress (n,) in [0, 1] of the twists ``samples`` (n, 3) along the translation of
    ``u`` (3,), relative to the first row ``v*``: ``clip(v_xy . u_xy / v*_xy . u_xy, 0,
    1)``; 1 when not ``enabled`` or when ``v*`` makes no progress along ``u``."""
    along = samples[:, 0] * u[0] + samples[:, 1] * u[1]
    best = float(along[0])
    if not enabled or best < 1e-12:
        return 1.0
    return np.clip(along / best, 0.0, 1.0)


def dwa(
    u: np.ndarray,
    points: np.ndarray,
    velocity: np.ndarray,
    robot: RobotModel,
    *,
    settings: DWASettings | None = None,
) -> DWAResult:
    """Best admissible twist near the user's command ``u`` (eq. 3.8, ``g = DWA(u, z)``).

    The twists are scored (:func:`_scores`), then checked for collision in score order
    (``autonomy._geometry_kernels.first_admissible``), with every laser point and poses
    every ``step_s``,
    exactly in continuous time (:func:`autonomy.safety.interval_clearance`); the first
    twist whose footprint stays out of its protective field for ``horizon_s`` -- and for
    as long as braking from it to a stop takes, Fox's admissibility -- is the answer.

    Parameters
    ----------
    u : (3,) user command (v_x [m/s], v_y [m/s], omega [rad/s]), robot frame.
    points : (m, 2) [m] laser points in the robot frame.
    velocity : (3,) current robot-frame velocity estimate (centre of the window).
    robot : footprint, protective margin, limits, control tick.
    settings : :class:`DWASettings`; defaults when None.

    Returns
    -------
    :class:`DWAResult`; ``v`` is zero when no sampled twist is admissible.
    """
    st = settings if settings is not None else DWASettings()
    u = np.asarray(u, dtype=float).reshape(3)
    samples = window_samples(u, velocity, robot, st)
    n = len(samples)
    speed = np.hypot(samples[:, 0], samples[:, 1])
    margin = robot.protective_margin
    radius = inflated_radius(robot, margin)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    sq = np.einsum("ij,ij->i", points, points)

    # admissible: clear while held for horizon_s, and while braking to a stop (Fox et al.)
    brake = np.maximum(
        speed / (2 * robot.max_accel), np.abs(samples[:, 2]) / (2 * robot.max_yaw_accel)
    )
    n_check = np.ceil(np.maximum(st.horizon_s, robot.dt + brake) / st.step_s - 1e-9).astype(int)
    check = points[sq <= (speed.max() * st.step_s * n_check.max() + radius) ** 2]
    c0 = float(footprint_clearance(np.zeros((1, 3)), check, robot)[0])
    required = required_clearance(c0, robot, st.tolerance_m)

    score, times = _scores(samples, speed, u, points, sq, robot, st)

    # exact admissibility, best-scored twists first
    rate = sweep_rate(samples, radius, st.step_s)
    order = np.argsort(-score, kind="stable")
    px, py = _work_points(check)
    lines = (robot.line_normals, robot.line_mid, robot.line_half)
    pos, low = first_admissible(
        samples, order, n_check, rate, st.step_s, c0, required, px, py, *lines
    )
    if pos >= 0:
        best = order[pos]
        path = np.vstack((np.zeros((1, 3)), arc_poses(samples[best], times)[0]))
        return DWAResult(
            v=samples[best].copy(),
            path=path,
            horizon_s=float(n_check[best] * st.step_s),
            clearance=low,
            n_checked=pos + 1,
            n_samples=n,
        )
    return DWAResult(np.zeros(3), np.zeros((1, 3)), 0.0, -math.inf, n, n)
