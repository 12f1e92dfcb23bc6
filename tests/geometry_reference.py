"""The numpy code that the compiled kernels of issue 25 replaced, kept verbatim (renamed
``ref_*``) as the oracle of tests/test_sensing_kernels.py and
tests/test_geometry_kernels.py: sim.sensors.cast and World.sense's scan, the safety
layer's geometry and safe_command, the DWA's scores and check, and the trial's clearance
figures (tasks.geometry, tasks.clearance). The kernels must give bit-identical results."""

from __future__ import annotations

import math

import numpy as np

from autonomy.dwa import DWAResult, DWASettings, _progress, thin_points, window_samples
from autonomy.safety import (
    inflated_radius,
    interval_clearance,
    required_clearance,
    sweep_rate,
)
from autonomy.types import RobotModel
from sim.sensors import CrossSection
from tasks.geometry import polygon_distances

_TWO_PI = 2.0 * math.pi
_WORK_DTYPE = np.float32
_CHUNK_ELEMENTS = 1 << 15


def _beam_pairs(
    lo: np.ndarray, span: np.ndarray, step: float, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Expand angular intervals into (interval index, beam index) pairs.

    ``lo`` (m,) in [0, 2 pi) and ``span`` (m,) in [0, pi] are angles relative to
    beam 0; beam k points at ``k * step``. An interval that runs past 2 pi also
    covers the beams in [0, lo + span - 2 pi].
    """
    wraps = np.flatnonzero(lo + span >= _TWO_PI)
    if len(wraps):  # the wrapped part as an interval of its own
        lo = np.concatenate((lo, np.zeros(len(wraps))))
        span = np.concatenate((span, span[wraps] + lo[wraps] - _TWO_PI))
        owner_of = np.concatenate((np.arange(len(span) - len(wraps)), wraps))
    else:
        owner_of = None
    first = np.ceil(lo / step).astype(np.int64)
    last = np.minimum(np.floor((lo + span) / step).astype(np.int64), n - 1)
    count = np.maximum(last - first + 1, 0)
    interval = np.repeat(np.arange(len(lo)), count)
    beam = np.arange(len(interval)) - np.repeat(np.cumsum(count) - count - first, count)
    return (interval if owner_of is None else owner_of[interval]), beam


def ref_cast(
    section: CrossSection,
    origins: np.ndarray,
    first_angles: np.ndarray,
    step: float,
    n: int,
    max_range: float,
) -> np.ndarray:
    """Exact ranges of fans of ``n`` horizontal beams, one fan per sensor, in one pass.

    Parameters
    ----------
    section : the scene cut at the sensors' height.
    origins : (m, 2) [m] sensor positions in the map frame.
    first_angles : (m,) [rad] map-frame direction of each sensor's beam 0; beam k
        points at ``first_angles + k * step``.
    step : [rad] angle between beams, > 0.
    n : beams per sensor; ``(n - 1) * step`` must not exceed 2 pi.
    max_range : [m] longest range reported.

    Returns
    -------
    ranges : (m, n) [m] distance from each origin to the first surface hit, exactly
        ``max_range`` where nothing lies within ``max_range``.
    """
    origins = np.asarray(origins, dtype=float).reshape(-1, 2)
    first = np.asarray(first_angles, dtype=float).reshape(-1)
    ranges = np.full(len(origins) * n, max_range)
    beam_angles = (first[:, None] + step * np.arange(n)).ravel()
    cos_b, sin_b = np.cos(beam_angles), np.sin(beam_angles)

    # (sensor, edge) pairs with the edge facing the sensor (closed convex outlines: the
    # back faces are hidden behind the front ones), (sensor, circle) pairs with the
    # circle not containing the sensor nor out of its range.
    rel_a = section.edge_a - origins[:, None, :]  # (m, s, 2)
    offset = np.einsum("sj,msj->ms", section.normals, rel_a)  # n . (a - o)
    le, se = np.nonzero(offset < 0.0)
    rel_a, offset = rel_a[le, se], offset[le, se]
    normals = section.normals[se]
    rel_c = section.centres - origins[:, None, :]  # (m, c, 2)
    dist = np.hypot(rel_c[..., 0], rel_c[..., 1])
    lc, sc = np.nonzero((dist > section.radii) & (dist - section.radii < max_range))
    rel_c, dist, radii = rel_c[lc, sc], dist[lc, sc], section.radii[sc]
    k = len(le)

    # Angular intervals relative to beam 0: edges from end to end, circles centre +- half.
    ends = np.concatenate((rel_a, section.edge_b[se] - origins[le], rel_c))
    ang = np.arctan2(ends[:, 1], ends[:, 0]) - np.concatenate((first[le], first[le], first[lc]))
    sweep = np.mod(ang[k : 2 * k] - ang[:k] + math.pi, _TWO_PI) - math.pi  # in (-pi, pi)
    half = np.arcsin(radii / dist)
    lo = np.mod(
        np.concatenate((np.where(sweep < 0.0, ang[k : 2 * k], ang[:k]), ang[2 * k :] - half)),
        _TWO_PI,
    )
    owner, beam = _beam_pairs(lo, np.concatenate((np.abs(sweep), 2.0 * half)), step, n)
    if len(owner) == 0:
        return ranges.reshape(-1, n)
    beam += np.concatenate((le, lc))[owner] * n  # index into the flat (m * n) fans
    on_edge = owner < k

    e, be = owner[on_edge], beam[on_edge]
    # Ray o + t d meets the edge's line n . (p - a) = 0 at t = n . (a - o) / n . d;
    # n . (a - o) < 0 for a facing edge, and n . d < 0 for a beam that hits its face.
    den = normals[e, 0] * cos_b[be] + normals[e, 1] * sin_b[be]
    t_edge = np.divide(offset[e], den, out=np.full(len(e), np.inf), where=den < 0.0)

    c, bc = owner[~on_edge] - k, beam[~on_edge]
    along = rel_c[c, 0] * cos_b[bc] + rel_c[c, 1] * sin_b[bc]
    perp_sq = dist[c] ** 2 - along**2
    t_circle = along - np.sqrt(np.maximum(radii[c] ** 2 - perp_sq, 0.0))

    np.minimum.at(ranges, np.concatenate((be, bc)), np.concatenate((t_edge, t_circle)))
    return ranges.reshape(-1, n)


def ref_scan(true, z, rays):
    """World.sense's noisy ranges and hit points from the noise-free ranges ``true`` and
    the beams' draws ``z`` (``rays``: sim.lasers.Rays)."""
    ranges = np.where(
        true < rays.max_range,
        np.clip(true + rays.sigma * z, rays.min_range, rays.max_range),
        rays.max_range,
    )
    seen = ranges < rays.max_range
    # every beam's end point, then the hits: the same numbers as indexing first, in
    # fewer numpy calls
    ends = np.empty((len(ranges), 2))
    np.multiply(ranges, rays.cos, out=ends[:, 0])
    ends[:, 0] += rays.x0
    np.multiply(ranges, rays.sin, out=ends[:, 1])
    ends[:, 1] += rays.y0
    points = ends[seen]
    return ranges, points


def ref_arc_poses(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Poses reached from the origin under constant robot-frame twists.

    Parameters
    ----------
    v : (s, 3) or (3,) twists (v_x [m/s], v_y [m/s], omega [rad/s]).
    t : (k,) times [s].

    Returns
    -------
    (s, k, 3) poses (x [m], y [m], yaw [rad]) in the frame of the start pose.
    """
    v = np.atleast_2d(np.asarray(v, dtype=float))
    t = np.asarray(t, dtype=float)
    vx, vy, w = v[:, 0, None], v[:, 1, None], v[:, 2, None]
    a = w * t  # heading change
    # sin(a)/w and (1 - cos a)/w written with sinc so that w -> 0 is exact
    s1 = t * _sinc(a / np.pi)
    s2 = t * np.sin(a / 2) * _sinc(a / (2 * np.pi))
    out = np.empty((*a.shape, 3))
    np.subtract(vx * s1, vy * s2, out=out[..., 0])
    np.add(vx * s2, vy * s1, out=out[..., 1])
    out[..., 2] = a
    return out


_EPS = float(np.finfo(float).eps)


def _sinc(x: np.ndarray) -> np.ndarray:
    """``numpy.sinc`` of a float array, the same operations without its per-call overhead."""
    x = np.pi * x
    y = np.where(x, x, _EPS)
    return np.sin(y) / y


def ref_footprint_clearance(poses: np.ndarray, points: np.ndarray, robot: RobotModel) -> np.ndarray:
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
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    n_poses, n_points = len(poses), len(points)
    if n_points == 0:
        return np.full(n_poses, np.inf)
    normals, mid, half = robot.line_normals, robot.line_mid, robot.line_half
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    nx, ny = normals[:, 0], normals[:, 1]
    # line normals rotated into the points' frame, and the lines' offsets there
    ax64, ay64 = c * nx - s * ny, s * nx + c * ny  # (p, l)
    b = mid + ax64 * poses[:, 0, None] + ay64 * poses[:, 1, None]
    ax, ay, b = (a.astype(_WORK_DTYPE) for a in (ax64, ay64, b))
    px = points[:, 0].astype(_WORK_DTYPE)
    py = points[:, 1].astype(_WORK_DTYPE)
    out = np.empty(n_poses)
    rows = max(1, _CHUNK_ELEMENTS // n_points)
    for start in range(0, n_poses, rows):
        sl = slice(start, start + rows)
        h = val = tmp = None
        for e in range(len(normals)):
            val = np.multiply(ax[sl, e, None], px, out=val)
            tmp = np.multiply(ay[sl, e, None], py, out=tmp)
            val += tmp
            val -= b[sl, e, None]
            if not np.isnan(half[e]):  # a pair of parallel edges: |n . q - mid| - half
                np.abs(val, out=val)
                val -= _WORK_DTYPE(half[e])
            if h is None:
                h, val = val, None
            else:
                np.maximum(h, val, out=h)
        out[sl] = h.min(axis=1)
    return out


def ref_safe_command(
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
    v = np.asarray(v, dtype=float).reshape(3)
    if horizon_s <= 0 or step_m <= 0:
        raise ValueError(
            f"safe_command: horizon_s and step_m must be positive, got {horizon_s}, {step_m}"
        )
    speed = math.hypot(v[0], v[1])
    yaw_rate = abs(v[2])
    if speed == 0.0 and yaw_rate == 0.0:
        return v.copy(), 1.0
    brake = max(speed / (2 * robot.max_accel), yaw_rate / (2 * robot.max_yaw_accel))
    tau_max = max(horizon_s, robot.dt + brake)  # checked time of the unscaled command
    radius = inflated_radius(robot, robot.protective_margin)

    points = np.asarray(points, dtype=float).reshape(-1, 2)
    reach = speed * tau_max + radius + step_m
    points = points[np.einsum("ij,ij->i", points, points) <= reach * reach]
    if len(points) == 0:
        return v.copy(), 1.0

    c0 = float(ref_footprint_clearance(np.zeros((1, 3)), points, robot)[0])
    required = required_clearance(c0, robot, tolerance_m)
    rate0 = speed + yaw_rate * radius
    n_steps = int(min(max_steps, max(2, math.ceil(tau_max * rate0 / step_m))))
    dtau = tau_max / n_steps
    rate = sweep_rate(v, radius, dtau)
    poses = ref_arc_poses(v, dtau * np.arange(1, n_steps + 1))[0]
    h = ref_footprint_clearance(poses, points, robot)
    bound = interval_clearance(c0, h[None, :], np.atleast_1d(rate), dtau)[0]
    bad = np.flatnonzero(bound < required)
    if len(bad) == 0:
        return v.copy(), 1.0
    tau_safe = bad[0] * dtau  # the arc is clear on [0, tau_safe]
    # largest s with s * T(s) <= tau_safe, T(s) = max(horizon, dt + s * brake)
    s = tau_safe / horizon_s
    if robot.dt + s * brake > horizon_s:
        s = (-robot.dt + math.sqrt(robot.dt**2 + 4 * brake * tau_safe)) / (2 * brake)
    s = min(max(s, 0.0), 1.0)
    return v * s, s


def ref_scores(
    samples: np.ndarray,
    speed: np.ndarray,
    u: np.ndarray,
    points: np.ndarray,
    sq: np.ndarray,
    robot: RobotModel,
    st: DWASettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Scores of the twists ``samples`` (n, 3) and their poses (n, n_look, 3) every
    ``score_step_s`` along the horizon::

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
    n = len(samples)
    n_look = max(1, math.ceil(st.horizon_s / st.score_step_s - 1e-9))
    look = ref_arc_poses(samples, st.score_step_s * np.arange(1, n_look + 1))
    cap = st.clearance_cap_m
    reach = speed.max() * st.score_step_s * n_look + inflated_radius(
        robot, max(robot.protective_margin, cap)
    )
    coarse = thin_points(points[sq <= reach * reach], st.score_cell_m)
    h_look = ref_footprint_clearance(look.reshape(-1, 3), coarse, robot).reshape(n, n_look)
    scale = np.array([2 * robot.max_speed, 2 * robot.max_speed, 2 * robot.max_yaw_rate])
    agreement = 1 - np.linalg.norm((samples - u) / scale, axis=1) / math.sqrt(3)
    clearance = np.clip(h_look.min(axis=1), 0.0, cap) / cap
    return st.weight_agreement * agreement + st.weight_clearance * clearance * _progress(
        samples, u, st.clearance_by_progress
    ), look


def ref_dwa(
    u: np.ndarray,
    points: np.ndarray,
    velocity: np.ndarray,
    robot: RobotModel,
    *,
    settings: DWASettings | None = None,
) -> DWAResult:
    """Best admissible twist near the user's command ``u`` (eq. 3.8, ``g = DWA(u, z)``).

    The twists are scored (:func:`_scores`), then checked for collision in score order,
    in batches of doubling size, with every laser point and poses every ``step_s``,
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
    c0 = float(ref_footprint_clearance(np.zeros((1, 3)), check, robot)[0])
    required = required_clearance(c0, robot, st.tolerance_m)

    score, look = ref_scores(samples, speed, u, points, sq, robot, st)

    # exact admissibility, best-scored twists first, a batch at a time
    rate = sweep_rate(samples, radius, st.step_s)
    steps = np.arange(1, n_check.max() + 1)
    order = np.argsort(-score, kind="stable")
    start, size = 0, st.batch
    while start < n:
        batch = order[start : start + size]
        poses = ref_arc_poses(samples[batch], st.step_s * steps)
        h = ref_footprint_clearance(poses.reshape(-1, 3), check, robot).reshape(len(batch), -1)
        bound = interval_clearance(c0, h, rate[batch], st.step_s)
        bound = np.where(steps <= n_check[batch, None], bound, np.inf).min(axis=1)
        ok = np.flatnonzero(bound >= required)
        if len(ok):
            best = batch[ok[0]]
            path = np.vstack((np.zeros((1, 3)), look[best]))
            return DWAResult(
                v=samples[best].copy(),
                path=path,
                horizon_s=float(n_check[best] * st.step_s),
                clearance=float(bound[ok[0]]),
                n_checked=start + int(ok[0]) + 1,
                n_samples=n,
            )
        start, size = start + size, 2 * size  # doubling: few passes when many fail
    return DWAResult(np.zeros(3), np.zeros((1, 3)), 0.0, -math.inf, n, n)


def ref_task_footprint_clearance(points: np.ndarray, footprint: np.ndarray) -> float:
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
    closed-form path; it equals the general result of :func:`polygon_distances` to
    rounding (~1e-16 m).
    """
    box = _axis_aligned_box(footprint)
    if box is None:
        d = polygon_distances(points, footprint)
        return float(d.min()) if len(d) else math.inf
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(p)):
        raise ValueError("points: must be finite")
    if len(p) == 0:
        return math.inf
    # the robot's rectangle, axis-aligned in its own frame: per point, the distance to
    # the rectangle is the norm of how far it lies outside each slab (0 inside)
    x0, x1, y0, y1 = box
    x, y = p[:, 0], p[:, 1]
    dx = np.maximum(np.maximum(x0 - x, x - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - y, y - y1), 0.0)
    return math.sqrt(float((dx * dx + dy * dy).min()))


def _axis_aligned_box(polygon: np.ndarray) -> tuple[float, float, float, float] | None:
    """``(x_min, x_max, y_min, y_max)`` [m] if ``polygon`` (4, 2) is an axis-aligned
    rectangle of positive area (edges alternately along x and y), else None."""
    a = np.asarray(polygon, dtype=float)
    if a.shape != (4, 2) or not np.all(np.isfinite(a)):
        return None
    (ax, ay), (bx, by), (cx, cy), (dx, dy) = a.tolist()
    x_first = ay == by and bx == cx and cy == dy and dx == ax  # edges x, y, x, y
    y_first = ax == bx and by == cy and cx == dx and dy == ay  # edges y, x, y, x
    if not (x_first or y_first):
        return None
    x0, x1, y0, y1 = min(ax, cx), max(ax, cx), min(ay, cy), max(ay, cy)
    return (x0, x1, y0, y1) if x0 < x1 and y0 < y1 else None


def ref_lrf_range(points: np.ndarray) -> float:
    """Minimum distance [m] from the robot's centre to the laser hits.

    Parameters
    ----------
    points : ndarray, shape (m, 2)
        Laser hits of every scanner [m] in the robot frame (``Observation.points``).

    Returns
    -------
    float
        ``min_i |p_i|``; ``inf`` without hits (nothing within range).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(p) == 0:
        return math.inf
    return float(np.sqrt(np.einsum("ij,ij->i", p, p).min()))
