"""Holonomic trajectory tracking: the robot's own command ``g`` that follows the local
trajectory predicted by Algorithm 3 (thesis Sec. 6.2.3, 7.6.1.2; spec section 4).

The thesis handed the predicted trajectory to the ROS navigation stack as the reference
for its local planner. Here a holonomic pure-pursuit controller takes that role:

- the predicted path is given in the current robot frame as poses ``(x, y, yaw)`` at
  ``dt``, ``2 dt``, ... (the robot is at the origin with yaw 0);
- the *look-ahead point* is the point of the path at arc length ``lookahead_m`` from the
  robot (linear interpolation between way points; the path's end if it is shorter);
- translation: towards the look-ahead point at the path's own speed there, i.e. the
  arc length to the look-ahead point over the predicted time to reach it (the speed the
  demonstrations imply, not a fixed cruise speed);
- heading: the yaw the path has at the look-ahead point, reached over the same time
  (``omega = yaw_L / t_L``), so the robot turns as the demonstrations turn there;
- the command is limited to the robot's speed and yaw-rate limits (translation scaled,
  direction kept).

Decisions where the spec is silent: the end of a predicted path is the end of the
prediction horizon (the Mahalanobis stop), not a goal, so the controller does not slow
down towards it; a path without translation (a predicted pure rotation) gives a pure
rotation; an empty path gives a zero command (the mode then keeps the user's command,
see :mod:`autonomy.contextual`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autonomy._tick_kernels import track_kernel as _track_kernel


@dataclass(frozen=True, slots=True)
class TrackingSettings:
    """Settings of :func:`track`."""

    lookahead_m: float = 0.4  # [m] arc length of the look-ahead point
    min_time_s: float = 0.05  # [s] floor of the time to the look-ahead point

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lookahead_m) and self.lookahead_m > 0):
            raise ValueError(f"tracking lookahead_m: must be > 0, got {self.lookahead_m!r}")
        if not (math.isfinite(self.min_time_s) and self.min_time_s > 0):
            raise ValueError(f"tracking min_time_s: must be > 0, got {self.min_time_s!r}")


def track(
    path: np.ndarray,
    dt: float,
    *,
    max_speed: float,
    max_yaw_rate: float,
    settings: TrackingSettings | None = None,
) -> np.ndarray:
    """Pure-pursuit command following a predicted robot-frame path.

    Parameters
    ----------
    path : numpy.ndarray
        (k, 3) predicted poses (x [m], y [m], yaw [rad]) at times dt, 2 dt, ..., k dt,
        in the current robot frame (the robot is at the origin, yaw 0).
    dt : float
        [s] time between way points.
    max_speed : float
        [m/s] translational limit.
    max_yaw_rate : float
        [rad/s] rotational limit.
    settings : TrackingSettings, optional

    Returns
    -------
    numpy.ndarray
        (3,) command (v_x [m/s], v_y [m/s], omega [rad/s]); zeros for an empty path.
    """
    settings = TrackingSettings() if settings is None else settings
    path = np.ascontiguousarray(path, dtype=float).reshape(-1, 3)
    # compiled (autonomy._tick_kernels.track_kernel), the steps as numpy computed them before
    # (tests/contextual_reference.py), operation by operation:
    # xy = (0, 0) and path[:, :2]; yaw = 0 and np.unwrap(path[:, 2]);
    # arc = 0 and np.cumsum(np.hypot(*np.diff(xy, axis=0).T)); total = arc[-1];
    # total < 1e-9 (a predicted pure rotation): omega = clip(wrap_angle(yaw[-1]) / t_end)
    # with t_end = max(k dt, min_time_s); else the look-ahead point at arc length
    # target = min(lookahead_m, total), i = searchsorted(arc, target, "right") - 1 (at most
    # k - 1), f = (target - arc[i]) / (arc[i + 1] - arc[i]) (1 for a zero span), the point
    # and yaw_l interpolated, t_l = max((i + f) dt, min_time_s); v_xy = min(target / t_l,
    # max_speed) * point / |point| (0 if |point| <= 1e-12), omega = clip(yaw_l / t_l).
    out = np.zeros(3)
    if len(path):
        _track_kernel(
            path,
            float(dt),
            float(max_speed),
            float(max_yaw_rate),
            float(settings.lookahead_m),
            float(settings.min_time_s),
            out,
        )
    return out
