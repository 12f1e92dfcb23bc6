"""The safety layer and the footprint-versus-laser-points geometry it shares with the DWA
(spec section 4; thesis 7.6.1.2 and footnote 31).

Every command sent to the robot is checked for collision along its direction "with the
dynamic window concept" -- the footprint forward-simulated against the current laser
points -- and scaled down until it is collision-free; the thesis adds it to the
contextual mode for ticks where the recognition confidence is low. The geometry
(:func:`arc_poses`, :func:`footprint_clearance`, :func:`interval_clearance`,
:func:`translation_distance`) is also used by :mod:`autonomy.dwa` and
:mod:`autonomy.reactive_bn`; with it the collision tests are exact in continuous time,
not only at the sampled poses. Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

import math

import numpy as np

from autonomy._geometry_kernels import arc_poses_kernel, clearance_kernel, safe_arc_check
from autonomy.types import RobotModel

# Working precision of the many (pose, point) evaluations (autonomy._geometry_kernels
# computes in it): its rounding (~1e-6 m at room scale) is far below any margin used here.
_WORK_DTYPE = np.float32


def arc_poses(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Poses reached from the origin under constant robot-frame twists.

    Parameters
    ----------
    v : (s, 3) or (3,) twists (v_x [m/s], v_y [m/s], omega [rad/s]).
    t : (k,) times [s].

    Returns
    -------
    (s, k, 3) poses (x [m], y [m], yaw [rad]) in the frame of the start pose.
    """
    v = np.ascontiguousarray(np.atleast_2d(v), dtype=float)
    return arc_poses_kernel(v, np.ascontiguousarray(t, dtype=float).reshape(-1))


def footprint_clearance(poses: np.ndarray, points: np.ndarray, robot: RobotModel) -> np.ndarray:
    """Half-plane clearance of the footprint at each pose to the nearest point.

    Parameters
    ----------
    poses : (p, 3) poses (x [m], y [m], yaw [rad]) in the points' frame.
    points : (m, 2) [m] laser points.
    robot : gives the footprint's edge normals and offsets.

    Returns
    -------
    (p,) [m] ``min_points max_edges (n_e . q - c_e)``: negative inside the footprint,
    ``> c`` iff no point lies in the footprint inflated by ``c``; ``inf`` without points.
    """
    poses = np.ascontiguousarray(poses, dtype=float).reshape(-1, 3)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(points) == 0:
        return np.full(len(poses), np.inf)
    px, py = _work_points(points)
    return clearance_kernel(poses, px, py, robot.line_normals, robot.line_mid, robot.line_half)


def _work_points(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points' coordinates (m, 2) [m] as two contiguous (m,) arrays in working precision."""
    return points[:, 0].astype(_WORK_DTYPE), points[:, 1].astype(_WORK_DTYPE)


def sweep_rate(v: np.ndarray, radius: float, dt: float) -> np.ndarray:
    """Upper bound on how fast the clearance can change under constant twists [m/s].

    A laser point within ``radius`` [m] of the robot's origin moves in the robot
    frame at most at ``|v_xy| + |omega| r``; allowing for ``r`` to grow over one
    check interval ``dt`` [s] (Gronwall) gives ``(|v_xy| + |omega| radius) e^{|omega| dt}``.

    Parameters
    ----------
    v : (s, 3) or (3,) twists.
    radius : [m] radius of the region where clearance is decided (``inflated_radius``).
    dt : [s] time between checked poses.

    Returns
    -------
    (s,) [m/s] or a scalar array for one twist.
    """
    v = np.asarray(v, dtype=float)
    w = np.abs(v[..., 2])
    return (np.hypot(v[..., 0], v[..., 1]) + w * radius) * np.exp(w * dt)


def interval_clearance(h0: float, h: np.ndarray, rate: np.ndarray, dt: float) -> np.ndarray:
    """Guaranteed clearance on each interval between checked poses.

    Parameters
    ----------
    h0 : [m] clearance at the start pose (time 0).
    h : (s, k) [m] clearances at times dt, 2 dt, ..., k dt.
    rate : (s,) [m/s] bound from :func:`sweep_rate`.
    dt : [s] interval.

    Returns
    -------
    (s, k) [m] lower bound of the clearance on ``[(j-1) dt, j dt]`` for j = 1..k,
    ``(h_{j-1} + h_j - rate dt) / 2`` (the two cones from the interval's ends meet there).
    """
    h = np.asarray(h, dtype=float)
    prev = np.concatenate((np.full((h.shape[0], 1), h0), h[:, :-1]), axis=1)
    return 0.5 * (prev + h - np.asarray(rate, dtype=float)[:, None] * dt)


_RADII: dict = {}  # (robot, margin) -> inflated radius [m]; robots hash by identity


def inflated_radius(robot: RobotModel, margin: float) -> float:
    """``robot.inflated_radius(margin)`` [m], remembered: the DWA and the safety layer ask
    for the same few margins every tick."""
    key = (robot, margin)
    radius = _RADII.get(key)
    if radius is None:
        if len(_RADII) >= 64:
            _RADII.clear()
        radius = _RADII[key] = robot.inflated_radius(margin)
    return radius


def required_clearance(c0: float, robot: RobotModel, tolerance_m: float) -> float:
    """Clearance [m] a motion must keep: the protective margin, or, inside the
    protective field already, the current clearance ``c0`` less ``tolerance_m``."""
    return min(robot.protective_margin, c0 - tolerance_m)


def translation_distance(
    points: np.ndarray, direction: np.ndarray, robot: RobotModel
) -> np.ndarray:
    """How far the footprint can translate along ``direction`` before touching each point.

    Parameters
    ----------
    points : (m, 2) [m] robot-frame points.
    direction : (2,) translation direction (any length > 0).
    robot : gives the footprint.

    Returns
    -------
    (m,) [m] translation distance to contact (0 for points inside the footprint,
    ``inf`` for points the translated footprint never reaches).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    u = np.asarray(direction, dtype=float)[:2]
    u = u / np.linalg.norm(u)
    # point p touches the footprint moved by lam*u iff p - lam*u is inside:
    # n_e . p - lam n_e . u <= c_e for every edge (Cyrus-Beck clipping of that ray)
    num = points @ robot.edge_normals.T - robot.edge_offsets  # (m, e)
    den = robot.edge_normals @ u  # (e,)
    lam_in = np.zeros(len(points))  # entering edges: the ray enters after max(num / den)
    lam_out = np.full(len(points), np.inf)  # leaving edges: it leaves at min(num / den)
    ok = np.ones(len(points), dtype=bool)  # parallel edges: the ray must start inside
    with np.errstate(over="ignore"):
        for e, d in enumerate(den.tolist()):
            if d > 1e-12:
                np.maximum(lam_in, num[:, e] / d, out=lam_in)
            elif d < -1e-12:
                np.minimum(lam_out, num[:, e] / d, out=lam_out)
            else:
                ok &= num[:, e] <= 0.0
    return np.where(ok & (lam_in <= lam_out), lam_in, np.inf)


def safe_command(
    v: np.ndarray,
    points: np.ndarray,
    robot: RobotModel,
    *,
    horizon_s: float = 1.0,
    step_m: float = 0.02,
    tolerance_m: float = 0.01,
    max_steps: int = 200,
) -> tuple[np.ndarray, float]:
    """Scale a command down until the footprint stays clear of the laser points.

    Parameters
    ----------
    v : (3,) command (v_x [m/s], v_y [m/s], omega [rad/s]), robot frame.
    points : (m, 2) [m] current laser points in the robot frame.
    robot : footprint, protective margin, acceleration limits, control tick.
    horizon_s : [s] how long the scaled command, held constant, must stay clear;
        extended to ``dt + |v| / (2 max_accel)`` when braking needs longer.
    step_m : [m] largest motion of any footprint point between checked poses
        (finer is tighter near obstacles and slower).
    tolerance_m : [m] allowed loss of clearance when already inside the protective field.
    max_steps : cap on the number of checked poses.

    Returns
    -------
    v_safe : (3,) ``scale * v``.
    scale : in [0, 1]; 1 when ``v`` is safe as it is.
    """
    v = np.ascontiguousarray(v, dtype=float).reshape(3)
    if horizon_s <= 0 or step_m <= 0:
        raise ValueError(
            f"safe_command: horizon_s and step_m must be positive, got {horizon_s}, {step_m}"
        )
    vx, vy, w = v.tolist()  # Python floats: the same arithmetic, less overhead
    speed = math.hypot(vx, vy)
    yaw_rate = abs(w)
    if speed == 0.0 and yaw_rate == 0.0:
        return v.copy(), 1.0
    brake = max(speed / (2 * robot.max_accel), yaw_rate / (2 * robot.max_yaw_accel))
    tau_max = max(horizon_s, robot.dt + brake)  # checked time of the unscaled command
    radius = inflated_radius(robot, robot.protective_margin)

    points = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    reach = speed * tau_max + radius + step_m  # points beyond it cannot be reached
    rate0 = speed + yaw_rate * radius
    x_steps = tau_max * rate0 / step_m  # poses n_steps = min(max_steps, max(2, ceil(.)))
    # the arc's poses every dtau, exact in between (interval_clearance), checked against
    # the points within reach up to the first interval below the required clearance
    bad, dtau = safe_arc_check(
        v, points, reach, x_steps, tau_max, float(max_steps), radius,
        robot.protective_margin, tolerance_m,
        robot.line_normals, robot.line_mid, robot.line_half,
    )  # fmt: skip
    if bad == -3:
        math.ceil(x_steps)  # raises, as for a non-finite number of steps
    if bad < 0:
        return v.copy(), 1.0
    tau_safe = bad * dtau  # the arc is clear on [0, tau_safe]
    # largest s with s * T(s) <= tau_safe, T(s) = max(horizon, dt + s * brake)
    s = tau_safe / horizon_s
    if robot.dt + s * brake > horizon_s:
        s = (-robot.dt + math.sqrt(robot.dt**2 + 4 * brake * tau_safe)) / (2 * brake)
    s = min(max(s, 0.0), 1.0)
    return v * s, s
