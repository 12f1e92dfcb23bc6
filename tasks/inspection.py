"""The inspection criterion of the primary task: a visit's net arc about the object.

One :class:`InspectionTracker` per trial watches the robot near the inspection object
(a box or a cylinder of the scenario): the primary task counts the inspection with it,
and the scripted participant watches the same criterion while it orbits (a person sees
when they have gone far enough round the object).
"""

from __future__ import annotations

import math

import numpy as np

from sim.scenario import Box, Cylinder
from sim.types import Pose2D, wrap_angle
from tasks.geometry import polygon_distances


class InspectionTracker:
    """Visits and arcs about one object.

    A tick qualifies when the surface distance from the robot centre is within ``band``,
    the object's centre lies within ``facing_tolerance_deg`` of the heading and the robot
    moves sideways (``|v_y| >= min_sideways_speed`` and ``|v_y| > |v_x|``). A visit is a
    maximal run of ticks within the band; the signed angle swept about the object's centre
    is summed over qualifying ticks, and the inspection is done when a visit's absolute
    net arc reaches ``min_arc_deg``.

    Parameters
    ----------
    obj : the object to inspect.
    band : (near, far) [m] surface distances of the robot centre that count.
    facing_tolerance_deg, min_sideways_speed [m/s], min_arc_deg : the criterion.
    """

    def __init__(
        self,
        obj: Box | Cylinder,
        *,
        band: tuple[float, float],
        facing_tolerance_deg: float,
        min_sideways_speed: float,
        min_arc_deg: float,
    ) -> None:
        self.obj = obj
        self.band = band
        self._facing = math.radians(facing_tolerance_deg)
        self._sideways = min_sideways_speed
        self._needed = math.radians(min_arc_deg) - 1e-12
        self._in_visit = False
        self._visit_started = False  # "started" reported for this visit
        self.visit_arc = 0.0  # [rad] signed net arc of the current visit
        self.best_arc = 0.0  # [rad] largest absolute net arc of any visit
        self.done = False
        self._last_phi = math.nan  # [rad] polar angle about the object at the last tick

    def surface_distance(self, x: float, y: float) -> float:
        """[m] from the point (x, y) to the object's surface (0 inside)."""
        obj = self.obj
        if isinstance(obj, Cylinder):
            return max(0.0, math.hypot(obj.centre[0] - x, obj.centre[1] - y) - obj.radius)
        return float(polygon_distances(np.array([[x, y]]), obj.corners())[0])

    def update(self, pose: Pose2D, v: np.ndarray) -> str | None:
        """One tick at ``pose`` with robot-frame velocity ``v`` (3,) [m/s, m/s, rad/s]:
        ``"started"`` when a visit first qualifies, ``"done"`` when the inspection
        completes, None otherwise (and always None once done)."""
        if self.done:
            return None
        cx, cy = self.obj.centre
        dx, dy = cx - pose.x, cy - pose.y
        near, far = self.band
        phi = math.atan2(-dy, -dx)  # polar angle of the robot about the object's centre
        if not near <= self.surface_distance(pose.x, pose.y) <= far:
            self._in_visit = False
            self._last_phi = phi
            return None
        if not self._in_visit:  # a new visit starts from zero
            self._in_visit, self._visit_started, self.visit_arc = True, False, 0.0
            self._last_phi = phi
        facing = abs(wrap_angle(math.atan2(dy, dx) - pose.yaw)) <= self._facing
        sideways = abs(v[1]) >= self._sideways and abs(v[1]) > abs(v[0])
        event = None
        if facing and sideways:
            if not self._visit_started:
                self._visit_started, event = True, "started"
            self.visit_arc += wrap_angle(phi - self._last_phi)
            self.best_arc = max(self.best_arc, abs(self.visit_arc))
            if abs(self.visit_arc) >= self._needed:
                self.done, event = True, "done"
        self._last_phi = phi
        return event
