"""The primary navigation task: progress along the route, the inspection, scoring
(thesis Sec. 7.6.1.2, 7.6.2 and Fig. 7.50c; Sec. 7.5, Fig. 7.44b and Table 7.10;
spec section 7).

Drive from A, dock under the table at B, drive back to A; on the way inspect the red
cylinder "by moving the robot sideways while facing the object"; as fast and as
safely as possible. The score is the completion time plus 60 s per collision; the
outcome also carries the robot's clearance to obstacles. Pure: the control loop calls
:meth:`PrimaryTask.update` once per tick and records the :class:`PrimaryEvent` values
it returns; :meth:`PrimaryTask.outcome` gives the trial's result.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sim.scenario import Box, Cylinder, Scenario
from sim.types import Contact, Pose2D, wrap_angle
from tasks.inspection import InspectionTracker

GOALS: tuple[str, ...] = ("dock", "start")
ROUTE_POINT_GOALS: dict[str, str] = {"A": "start", "B": "dock"}  # a protocol's route points
EVENT_KINDS: tuple[str, ...] = (
    "leg_reached",
    "dock_reached",
    "inspection_started",
    "inspection_done",
    "inspection_missing",
    "timeout",
    "task_completed",
)
EventKind = Literal[
    "leg_reached",
    "dock_reached",
    "inspection_started",
    "inspection_done",
    "inspection_missing",
    "timeout",
    "task_completed",
]
CLEARANCE_BIN_WIDTH_M = 0.1
CLEARANCE_BIN_EDGES_M: np.ndarray = np.round(np.arange(21) * CLEARANCE_BIN_WIDTH_M, 10)
"""(21,) [m] edges of the 20 clearance bins; a 21st bin counts values >= 2 m."""
_EPS_S = 1e-9  # tolerance on time comparisons, against sums of float tick periods


@dataclass(frozen=True, slots=True)
class PrimarySettings:
    """Settings of the primary task; change with ``dataclasses.replace``.

    Attributes
    ----------
    route : tuple of str
        Goals in order, each ``"dock"`` (pose B) or ``"start"`` (A). Thesis:
        ``("dock", "start")``; a practice course may use ``("dock",)``.
    inspection_required : bool
        Whether the last goal only completes the task after the inspection.
    goal_tolerance_m : float
        Distance [m] of the robot centre from A that counts as back at A.
    inspection_distance_m : tuple of float
        ``(near, far)`` [m], the band of distances from the object's surface to
        the robot centre in which inspection motion counts.
    facing_tolerance_deg : float
        Largest angle [deg] between the heading and the bearing of the object's
        centre that counts as facing it.
    min_sideways_speed : float
        Smallest ``|v_y|`` [m/s] that counts as moving sideways.
    min_arc_deg : float
        Arc [deg] about the object's centre one visit must sweep.
    timeout_s : float
        Time [s] after which an unfinished trial ends.
    collision_penalty_s : float
        Time [s] added to the score per collision (thesis: 60).
    """

    route: tuple[str, ...] = ("dock", "start")
    inspection_required: bool = True
    goal_tolerance_m: float = 0.3
    inspection_distance_m: tuple[float, float] = (0.4, 1.6)
    facing_tolerance_deg: float = 25.0
    min_sideways_speed: float = 0.05
    min_arc_deg: float = 90.0
    timeout_s: float = 600.0
    collision_penalty_s: float = 60.0

    def __post_init__(self) -> None:
        route = self.route
        if (
            not isinstance(route, tuple)
            or not route
            or any(not isinstance(g, str) or g not in GOALS for g in route)
        ):
            raise _bad("route", f"must be a non-empty tuple of goals from {GOALS}", route)
        if route[0] == "start":
            raise _bad("route", "cannot begin with 'start' (the robot starts at A)", route)
        if any(a == b for a, b in zip(route, route[1:], strict=False)):
            raise _bad("route", "cannot name the same goal twice in a row", route)
        if not isinstance(self.inspection_required, bool):
            raise _bad("inspection_required", "must be true or false", self.inspection_required)
        band = self.inspection_distance_m
        if (
            not isinstance(band, tuple)
            or len(band) != 2
            or not all(_is_finite(b) for b in band)
            or not 0.0 <= band[0] < band[1]
        ):
            raise _bad("inspection_distance_m", "must be (near, far) with 0 <= near < far", band)
        if not _is_finite(self.facing_tolerance_deg) or not 0 < self.facing_tolerance_deg <= 180:
            raise _bad(
                "facing_tolerance_deg", "must be an angle in (0, 180]", self.facing_tolerance_deg
            )
        for name in ("goal_tolerance_m", "min_arc_deg", "timeout_s"):
            value = getattr(self, name)
            if not _is_finite(value) or value <= 0.0:
                raise _bad(name, "must be a positive number", value)
        for name in ("min_sideways_speed", "collision_penalty_s"):
            value = getattr(self, name)
            if not _is_finite(value) or value < 0.0:
                raise _bad(name, "must be zero or a positive number", value)


@dataclass(frozen=True, slots=True)
class PrimaryEvent:
    """Something that happened in the primary task, for recording and display.

    Attributes
    ----------
    kind : str
        One of :data:`EVENT_KINDS`.
    t : float
        Simulated time [s] of the tick.
    leg_index : int or None
        0-based leg of the route concerned (``leg_reached``, ``dock_reached``,
        ``inspection_missing``); None otherwise.
    goal : str or None
        That leg's goal, ``"dock"`` or ``"start"``.
    arc_deg : float or None
        ``inspection_done``: absolute net arc [deg] of the visit.
    """

    kind: EventKind
    t: float
    leg_index: int | None = None
    goal: str | None = None
    arc_deg: float | None = None


@dataclass(frozen=True, slots=True)
class PrimaryOutcome:
    """The result of one trial (or of the trial so far).

    Attributes
    ----------
    completed : bool
        Whether every goal was reached (and the inspection done, if required).
    timed_out : bool
        Whether the trial ended by timeout.
    completion_time_s : float
        [s] from ``t_start`` to completion; ``timeout_s`` after a timeout; the
        elapsed time while the task runs.
    collisions : int
        Collision episodes during the task.
    score : float
        ``completion_time_s + collision_penalty_s * collisions`` [s]; lower is better.
    path_length_m : float
        Length [m] of the true path.
    clearance_mean_m, clearance_std_m, clearance_min_m : float
        Mean, standard deviation (ddof=0) and minimum [m] of the finite per-tick
        clearances; NaN without any.
    clearance_histogram : tuple of int
        (21,) tick counts per bin of :data:`CLEARANCE_BIN_EDGES_M`, the last for >= 2 m.
    clearance_samples : int
        Ticks whose clearance was counted in the histogram.
    inspection_required, inspection_done : bool
    inspection_arc_deg : float
        Largest absolute net arc [deg] of any visit.
    inspection_time_s : float
        [s] from ``t_start`` to the inspection; NaN if not done.
    route : tuple of str
    legs_reached : int
    leg_times_s : tuple of float
        Duration [s] of each reached leg, in route order.
    """

    completed: bool
    timed_out: bool
    completion_time_s: float
    collisions: int
    score: float
    path_length_m: float
    clearance_mean_m: float
    clearance_std_m: float
    clearance_min_m: float
    clearance_histogram: tuple[int, ...]
    clearance_samples: int
    inspection_required: bool
    inspection_done: bool
    inspection_arc_deg: float
    inspection_time_s: float
    route: tuple[str, ...]
    legs_reached: int
    leg_times_s: tuple[float, ...]


def route_from_points(points: Sequence[str]) -> tuple[str, ...]:
    """A protocol's route points (``["A", "B", "A"]``, starting at A) as goals.

    Parameters
    ----------
    points : sequence of str
        Route points, ``"A"`` (start pose) or ``"B"`` (dock pose), the first ``"A"``.

    Returns
    -------
    tuple of str
        The goals after the start, for :attr:`PrimarySettings.route`:
        ``("dock", "start")`` for ``["A", "B", "A"]``.
    """
    points = list(points)
    if not points or points[0] != "A" or any(p not in ROUTE_POINT_GOALS for p in points):
        raise ValueError(f"route: must start at 'A' and name only 'A' and 'B', got {points}")
    return tuple(ROUTE_POINT_GOALS[p] for p in points[1:])


# ---------------------------------------------------------------------------- task


def inspection_tracker(obj: Box | Cylinder, settings: PrimarySettings) -> InspectionTracker:
    """A tracker of the inspection of ``obj`` with the criterion of ``settings``."""
    return InspectionTracker(
        obj,
        band=settings.inspection_distance_m,
        facing_tolerance_deg=settings.facing_tolerance_deg,
        min_sideways_speed=settings.min_sideways_speed,
        min_arc_deg=settings.min_arc_deg,
    )


class PrimaryTask:
    """The primary-task state machine of one trial.

    Parameters
    ----------
    scenario : Scenario
        The scene: start A, the dock B and the inspection object.
    settings : PrimarySettings, optional
        Defaults to ``PrimarySettings()``.
    t_start : float
        Simulated time [s] at which the trial starts (the World's reset time).

    Raises
    ------
    ValueError
        If the route needs a dock the scenario lacks, or the inspection is
        required and the scenario names no inspection object.

    Notes
    -----
    Call :meth:`update` once per control tick with non-decreasing ``t``; once
    :attr:`done`, further updates return no events and change nothing.
    """

    def __init__(
        self, scenario: Scenario, *, settings: PrimarySettings | None = None, t_start: float = 0.0
    ) -> None:
        self.settings = s = settings if settings is not None else PrimarySettings()
        self.scenario = scenario
        where = scenario.source or scenario.name
        if "dock" in s.route and scenario.dock is None:
            raise ValueError(
                f"{where}: field 'dock': the route {list(s.route)} needs a [dock] pose "
                "and this scenario has none"
            )
        self._object: Box | Cylinder | None = None
        if scenario.inspection_object:
            element = scenario.element(scenario.inspection_object)
            if isinstance(element, Box | Cylinder):
                self._object = element
        if s.inspection_required and self._object is None:
            raise ValueError(
                f"{where}: field 'inspection_object': the inspection is required "
                "but this scenario names no box or cylinder to inspect"
            )
        if not _is_finite(t_start):
            raise ValueError(f"PrimaryTask.t_start: must be a finite time, got {t_start!r}")
        self.t_start = float(t_start)
        self._t_last = -math.inf
        self._leg = 0
        self._leg_times: list[float] = []  # elapsed [s] at which each leg was reached
        self._at_final = False  # inside the last goal's tolerance while inspection pending
        self._done = False
        self._timed_out = False
        self._completion_s = math.nan
        self._contacts: set[int] = set()
        self._last_xy: tuple[float, float] | None = None
        self._path_m = 0.0
        self._clearances: list[float] = []  # [m] finite per-tick clearances
        self._hist = np.zeros(len(CLEARANCE_BIN_EDGES_M), dtype=np.int64)
        self._hist_n = 0
        self._tracker = None if self._object is None else inspection_tracker(self._object, s)
        self._inspection_s = math.nan

    # -- state ------------------------------------------------------------------------

    @property
    def leg_index(self) -> int:
        """0-based index of the leg being driven; ``len(route)`` once all are reached."""
        return self._leg

    @property
    def next_goal(self) -> str | None:
        """The goal of the current leg, or None once all are reached."""
        route = self.settings.route
        return route[self._leg] if self._leg < len(route) else None

    @property
    def done(self) -> bool:
        """Whether the task has ended (completed or timed out)."""
        return self._done

    @property
    def completed(self) -> bool:
        return self._done and not self._timed_out

    @property
    def timed_out(self) -> bool:
        return self._timed_out

    @property
    def inspection_done(self) -> bool:
        return self._tracker is not None and self._tracker.done

    @property
    def inspection_arc_deg(self) -> float:
        """Largest absolute net arc [deg] of any visit so far."""
        return 0.0 if self._tracker is None else math.degrees(self._tracker.best_arc)

    @property
    def collisions(self) -> int:
        return len(self._contacts)

    @property
    def elapsed_s(self) -> float:
        """[s] from ``t_start`` to the last update (0 before the first)."""
        return max(0.0, self._t_last - self.t_start) if math.isfinite(self._t_last) else 0.0

    # -- driving ----------------------------------------------------------------------

    def update(
        self,
        t: float,
        pose: Pose2D,
        velocity: np.ndarray,
        clearance_m: float,
        contacts_started: Sequence[Contact] = (),
    ) -> list[PrimaryEvent]:
        """Advance to the tick at time ``t`` [s].

        Parameters
        ----------
        t : float
            Simulated time [s], not less than that of any earlier call.
        pose : Pose2D
            The robot's true pose in the map frame.
        velocity : ndarray, shape (3,)
            Robot-frame ``(v_x [m/s], v_y [m/s], omega [rad/s])``.
        clearance_m : float
            The tick's minimum clearance [m] (:func:`tasks.geometry.footprint_clearance`); NaN
            if there was no measurement.
        contacts_started : sequence of Contact
            Collision episodes that started during the tick (``World.step()``).

        Returns
        -------
        list of PrimaryEvent
            In the order they happened (possibly empty).
        """
        if not _is_finite(t) or t < self._t_last:
            raise ValueError(
                f"PrimaryTask.update: t must be finite and non-decreasing, got {t!r} "
                f"after {self._t_last!r}"
            )
        if self._done:
            return []
        v = np.asarray(velocity, dtype=float)
        if v.shape != (3,):
            raise ValueError(f"PrimaryTask.update: velocity must have shape (3,), got {v.shape}")
        clearance = float(clearance_m)
        if clearance < 0.0:
            raise ValueError(f"PrimaryTask.update: clearance_m must be >= 0, got {clearance!r}")
        self._t_last = float(t)
        elapsed = self._t_last - self.t_start
        events: list[PrimaryEvent] = []

        for contact in contacts_started:
            self._contacts.add(int(contact.index))
        xy = (float(pose.x), float(pose.y))
        if self._last_xy is not None:
            self._path_m += math.hypot(xy[0] - self._last_xy[0], xy[1] - self._last_xy[1])
        self._last_xy = xy
        self._add_clearance(clearance)
        self._inspect(t, pose, v, events)

        self._advance(t, elapsed, pose, events)
        return events

    def _advance(self, t: float, elapsed: float, pose: Pose2D, events: list[PrimaryEvent]) -> None:
        """Reach the current leg's goal, or end the task by timeout.

        Goals are taken strictly in order, at most one per tick. With
        ``inspection_required`` the last goal without the inspection reports
        ``inspection_missing`` once per arrival and does not complete the task. The first
        tick with elapsed time ``>= timeout_s`` that has not completed the task ends it
        with ``completion_time_s = timeout_s`` (reaching the last goal on that very tick
        counts as completion).
        """
        s = self.settings
        goal = s.route[self._leg]
        if self._goal_reached(goal, pose):
            final = self._leg == len(s.route) - 1
            if final and s.inspection_required and not self.inspection_done:
                if not self._at_final:
                    events.append(PrimaryEvent("inspection_missing", t, self._leg, goal))
                self._at_final = True
            else:
                events.append(PrimaryEvent("leg_reached", t, self._leg, goal))
                if goal == "dock":
                    events.append(PrimaryEvent("dock_reached", t, self._leg, goal))
                self._leg_times.append(elapsed)
                self._leg += 1
                if final:
                    self._done = True
                    self._completion_s = elapsed
                    events.append(PrimaryEvent("task_completed", t))
        else:
            self._at_final = False
        if not self._done and elapsed >= s.timeout_s - _EPS_S:
            self._done = True
            self._timed_out = True
            self._completion_s = s.timeout_s
            events.append(PrimaryEvent("timeout", t))

    def _goal_reached(self, goal: str, pose: Pose2D) -> bool:
        if goal == "start":
            a = self.scenario.start
            return math.hypot(pose.x - a.x, pose.y - a.y) <= self.settings.goal_tolerance_m
        dock = self.scenario.dock
        assert dock is not None  # checked in __init__
        b = dock.pose
        return (
            math.hypot(pose.x - b.x, pose.y - b.y) <= dock.tolerance_m
            and abs(wrap_angle(pose.yaw - b.yaw)) <= dock.tolerance_rad
        )

    def _add_clearance(self, clearance: float) -> None:
        if math.isnan(clearance):
            return
        self._hist_n += 1
        k = int(np.searchsorted(CLEARANCE_BIN_EDGES_M, clearance, side="right")) - 1
        self._hist[min(k, len(self._hist) - 1)] += 1  # the last bin: 2 m and more, inf
        if math.isfinite(clearance):
            self._clearances.append(clearance)

    def _inspect(self, t: float, pose: Pose2D, v: np.ndarray, events: list[PrimaryEvent]) -> None:
        """Track the inspection (:class:`tasks.inspection.InspectionTracker`, the criterion
        of ``settings``); report ``inspection_started`` and ``inspection_done``."""
        if self._tracker is None:
            return
        event = self._tracker.update(pose, v)
        if event == "started":
            events.append(PrimaryEvent("inspection_started", t))
        elif event == "done":
            self._inspection_s = t - self.t_start
            arc = math.degrees(abs(self._tracker.visit_arc))
            events.append(PrimaryEvent("inspection_done", t, arc_deg=arc))

    # -- result -----------------------------------------------------------------------

    def outcome(self) -> PrimaryOutcome:
        """The trial's result, or the trial so far while it runs.

        Before the task ends: ``completed`` and ``timed_out`` False, the elapsed time as
        completion time (what an aborted trial stores). Clearance statistics skip NaN
        (no measurement); ``inf`` counts in the histogram's overflow bin only.
        """
        s = self.settings
        time_s = self._completion_s if self._done else self.elapsed_s
        if self._clearances:
            c = np.asarray(self._clearances)
            mean, std, cmin = float(c.mean()), float(c.std()), float(c.min())  # Table 7.10
        else:
            mean = std = cmin = math.nan
        legs = np.diff(np.concatenate(([0.0], self._leg_times)))
        return PrimaryOutcome(
            completed=self.completed,
            timed_out=self._timed_out,
            completion_time_s=float(time_s),
            collisions=self.collisions,
            score=float(time_s + s.collision_penalty_s * self.collisions),  # spec section 7
            path_length_m=self._path_m,
            clearance_mean_m=mean,
            clearance_std_m=std,
            clearance_min_m=cmin,
            clearance_histogram=tuple(int(c) for c in self._hist),
            clearance_samples=self._hist_n,
            inspection_required=s.inspection_required,
            inspection_done=self.inspection_done,
            inspection_arc_deg=self.inspection_arc_deg,
            inspection_time_s=self._inspection_s,
            route=s.route,
            legs_reached=self._leg,
            leg_times_s=tuple(float(x) for x in legs),
        )


def _is_real(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _is_finite(value: object) -> bool:
    return _is_real(value) and math.isfinite(value)  # type: ignore[arg-type]


def _bad(field: str, message: str, value: object) -> ValueError:
    return ValueError(f"PrimarySettings.{field}: {message}, got {value!r}")
