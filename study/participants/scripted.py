"""A scripted participant: a deterministic test driver for the session engine, not a model
of people (that is :mod:`study.participants.synthetic`). It plans on the true map of the
scene so that tests and ``asa run --input scripted`` drive every phase of a protocol
headless; its behaviour (route, following, inspection, questions, getting unstuck) is in
docs/decisions.md. Every draw comes from the passed-in ``numpy.random.Generator``."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numba import njit

from sim.occupancy import OccupancyGrid, build_grid, clearance_map, inflate, shortest_path
from sim.scenario import Box, Cylinder, Scenario
from sim.types import Observation, Pose2D, wrap_angle
from study.participants.base import ParticipantBase
from study.types import ParticipantInput, ScreenState, TrialInfo
from tasks.inspection import InspectionTracker
from tasks.primary import PrimarySettings, inspection_tracker

_QUESTION = re.compile(r"^\s*(\d+)\s*([+-])\s*(\d+)\s*=\s*(\d+)")


@dataclass(frozen=True, slots=True)
class ScriptedSettings:
    """How the scripted participant drives and answers (change with ``dataclasses.replace``)."""

    speed: float = 0.45  # [m/s] cruising speed
    lookahead_m: float = 0.35  # [m] pure-pursuit look-ahead distance
    yaw_gain: float = 2.5  # [1/s] heading P gain
    stop_tolerance_m: float = 0.05  # [m] a goal pose is reached this close
    align_distance_m: float = 1.2  # [m] turn to B's heading over this last stretch
    # [m] turn to face the inspection object only this close to the orbit's entry: facing
    # it earlier, the approach's sideways drift inside the band would sweep an arc that
    # the orbit must then undo (the task counts the net arc of a visit)
    face_distance_m: float = 0.3
    clearances_m: tuple[float, ...] = (0.44, 0.38, 0.33, 0.29)  # tried in order for A*
    centre_clearance_m: float = 0.6  # [m] path points nearer obstacles are pushed away
    orbit_distance_m: float = 0.8  # [m] from the inspection object's surface
    orbit_speed: float = 0.3  # [m/s] sideways while inspecting
    arc_margin_deg: float = 30.0  # [deg] driven beyond the required arc
    answer_delay_s: float = 1.2  # [s] from a question appearing to the answer
    stuck_s: float = 1.5  # [s] pushing without moving this long counts as stuck
    backoff_s: float = 0.8  # [s] then it backs away from where it was pushing
    # stuck this often within entry_radius_m of the orbit's entry, it starts the orbit
    # from where it is (a person does not insist on an exact spot the robot will not go to)
    entry_tries: int = 2
    entry_radius_m: float = 0.5
    accuracy: float = 0.9  # probability of a right answer

    def __post_init__(self) -> None:
        for name in (
            "speed",
            "lookahead_m",
            "yaw_gain",
            "orbit_speed",
            "answer_delay_s",
            "stuck_s",
            "backoff_s",
            "entry_radius_m",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ScriptedSettings: field '{name}': must be > 0, got {value!r}")
        if isinstance(self.entry_tries, bool) or not (
            isinstance(self.entry_tries, int) and self.entry_tries >= 1
        ):
            raise ValueError(
                f"ScriptedSettings: field 'entry_tries': must be an integer >= 1, "
                f"got {self.entry_tries!r}"
            )
        if not 0.0 <= self.accuracy <= 1.0:
            raise ValueError(
                f"ScriptedSettings: field 'accuracy': must be in [0, 1], got {self.accuracy!r}"
            )


# Planned paths, shared by every scripted (and synthetic) participant of a process: a path
# depends only on the scene, its ends and the planning settings, and A* with the centring
# costs about 0.1 s, paid once per route instead of once per trial.
_PATHS: dict[tuple[Any, ...], np.ndarray] = {}
_MAX_PATHS = 256
# the orbits about the inspection object likewise (about 40 ms each: the inflated grid and
# 72 candidate arcs): the entry point (2,) [m] and the orbit, by scene, arc, ends, settings
_ORBITS: dict[tuple[Any, ...], tuple[np.ndarray, _OrbitLeg]] = {}
ORBIT_EXTRA = math.pi / 2  # [rad] an orbit goes on this far beyond its plan while watching
_ZERO = (0.0, 0.0, 0.0)  # [m/s, m/s, rad/s] no command


@njit(cache=True)
def _path_progress(
    pts: np.ndarray, progress: int, px: float, py: float, lookahead: float
) -> tuple[int, int]:
    """Where the robot at (px, py) [m] is on the path ``pts`` (k, 2) [m]: the nearest of
    the 40 points from ``progress`` on (the first on ties), and the first point from
    there on at least ``lookahead`` [m] away (-1: none). Distances are
    ``sqrt(dx * dx + dy * dy)``, what ``numpy.linalg.norm`` of the rows computes."""
    best, best_d = progress, math.inf
    for j in range(progress, min(progress + 40, pts.shape[0])):
        dx, dy = pts[j, 0] - px, pts[j, 1] - py
        d = math.sqrt(dx * dx + dy * dy)
        if j == progress or d < best_d or (math.isnan(d) and not math.isnan(best_d)):
            best, best_d = j, d
    for j in range(best, pts.shape[0]):
        dx, dy = pts[j, 0] - px, pts[j, 1] - py
        if math.sqrt(dx * dx + dy * dy) >= lookahead:
            return best, j
    return best, -1


def _clip(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


@dataclass(frozen=True, slots=True)
class _PathLeg:
    points: np.ndarray  # (k, 2) [m] map frame
    final_yaw: float | None  # [rad] heading to reach at the end (None: any)
    stop: bool  # come to rest at the end (a goal), else pass through
    face: tuple[float, float] | None = None  # turn to face this point near the end


@dataclass(frozen=True, slots=True)
class _OrbitLeg:
    centre: tuple[float, float]  # [m]
    radius: float  # [m] of the robot centre about ``centre``
    direction: int  # +1 counter-clockwise, -1 clockwise
    arc: float  # [rad] to sweep


def uniform_answer(item: Any, rng: np.random.Generator) -> Any:
    """A value drawn uniformly from what a questionnaire item allows (one draw)."""
    if item.kind == "number":
        return int(rng.integers(item.minimum, item.maximum + 1))
    return item.values[int(rng.integers(len(item.values)))]


def answer_is_correct(text: str) -> bool:
    """Whether the shown answer of a question text ``"47 + 38 = 85 ?"`` is right."""
    m = _QUESTION.match(text)
    if m is None:
        raise ValueError(f"question text: not 'a op b = c ?', got {text!r}")
    a, op, b, shown = int(m[1]), m[2], int(m[3]), int(m[4])
    return (a + b if op == "+" else a - b) == shown


class ScriptedParticipant(ParticipantBase):
    """A deterministic test driver behind the participant interface.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness (answers, questionnaires).
    settings : ScriptedSettings, optional
        Defaults to ``ScriptedSettings()``.
    """

    kind = "scripted"

    def __init__(
        self, rng: np.random.Generator, *, settings: ScriptedSettings | None = None
    ) -> None:
        self.settings = settings if settings is not None else ScriptedSettings()
        self.parameters: dict[str, Any] = {
            k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self.settings).items()
        }
        self._rng = rng
        self._grids: dict[str, OccupancyGrid] = {}
        self._maps: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._legs: list[_PathLeg | _OrbitLeg] = []
        self._leg = 0
        self._progress = 0
        self._swept = 0.0
        self._last_phi = math.nan
        self._drive = False
        self._max_speed = 1.0
        self._max_yaw_rate = 1.2
        self._question: str | None = None
        self._question_seen_t = math.nan
        self._question_right = True
        self._answered: str | None = None
        self._still_since = math.nan  # [s] when it last started pushing without moving
        self._still_at = (math.nan, math.nan, math.nan)  # pose then
        self._backoff_until = -math.inf  # [s]
        self._backoff_u = _ZERO
        self._stuck = 0  # stuck episodes on the current leg
        # the inspection as the task counts it, watched while orbiting (None: no object)
        self._watch: InspectionTracker | None = None
        self.texts_read: list[str] = []

    # ------------------------------------------------------------ non-driving

    def read(self, text: str) -> None:
        """Acknowledge a text at once (kept in ``texts_read``)."""
        self.texts_read.append(text)

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """Answer every item with a value drawn uniformly from what it allows."""
        return {item.id: uniform_answer(item, self._rng) for item in instrument.items}

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """Pick one member of each pair uniformly at random."""
        return {(a, b): (a if self._rng.random() < 0.5 else b) for a, b in pairs}

    # ------------------------------------------------------------ planning

    def _grid(self, scenario: Scenario) -> OccupancyGrid:
        key = scenario.source or scenario.name
        if key not in self._grids:
            self._grids[key] = build_grid(scenario)
        return self._grids[key]

    def _clearance(self, scenario: Scenario) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        key = "clearance:" + (scenario.source or scenario.name)
        if key not in self._maps:
            cm = clearance_map(self._grid(scenario))
            gy, gx = np.gradient(np.minimum(cm, 2.0))
            self._maps[key] = (cm, gx, gy)
        return self._maps[key]

    def _path(self, scenario: Scenario, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        key = (
            scenario.source or scenario.name,
            a.tobytes(),
            b.tobytes(),
            self.settings.clearances_m,
            self.settings.centre_clearance_m,
        )
        if key not in _PATHS:
            if len(_PATHS) >= _MAX_PATHS:
                _PATHS.pop(next(iter(_PATHS)))
            path = self._plan(scenario, a, b)
            path.setflags(write=False)
            _PATHS[key] = path
        return _PATHS[key]

    def _plan(self, scenario: Scenario, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        grid = self._grid(scenario)
        for clearance in self.settings.clearances_m:
            path = shortest_path(grid, a, b, clearance_m=clearance)
            if path is not None:
                break
        else:
            raise ValueError(f"scripted participant: no path from {a.tolist()} to {b.tolist()}")
        pts = np.vstack((a, path[1:-1], b)) if len(path) > 2 else np.vstack((a, b))
        return self._centred(scenario, pts)

    def _centred(self, scenario: Scenario, pts: np.ndarray) -> np.ndarray:
        """Push inner path points away from obstacles (A* paths hug the inflated walls),
        then smooth them; the ends stay where they are."""
        if len(pts) < 5:
            return pts
        grid = self._grid(scenario)
        cm, gx, gy = self._clearance(scenario)
        rows, cols = cm.shape
        out = pts.copy()
        inner = slice(2, len(pts) - 2)
        for _ in range(12):
            rc = grid.world_to_cell(out[inner])
            r = np.clip(rc[:, 0], 0, rows - 1)
            c = np.clip(rc[:, 1], 0, cols - 1)
            g = np.column_stack((gx[r, c], gy[r, c]))
            norm = np.linalg.norm(g, axis=1)
            move = (cm[r, c] < self.settings.centre_clearance_m) & (norm > 1e-9)
            step = np.zeros_like(g)
            step[move] = g[move] / norm[move, None] * 0.02
            out[inner] += step
        kernel = np.ones(5) / 5.0
        smooth = out.copy()
        for k in range(2):
            smooth[2:-2, k] = np.convolve(out[:, k], kernel, mode="valid")
        return smooth

    def _orbit(
        self, scenario: Scenario, grid: OccupancyGrid, arc: float, a: np.ndarray, b: np.ndarray
    ) -> tuple[np.ndarray, _OrbitLeg]:
        """:meth:`_orbit_plan`, planned once per process (the entry point read-only)."""
        key = (
            scenario.source or scenario.name,
            scenario.inspection_object,
            arc,
            a.tobytes(),
            b.tobytes(),
            self.settings.orbit_distance_m,
            self.settings.clearances_m,
        )
        if key not in _ORBITS:
            if len(_ORBITS) >= _MAX_PATHS:
                _ORBITS.pop(next(iter(_ORBITS)))
            entry, orbit = self._orbit_plan(scenario, grid, arc, a, b)
            entry = entry.copy()
            entry.setflags(write=False)
            _ORBITS[key] = (entry, orbit)
        return _ORBITS[key]

    def _orbit_plan(
        self, scenario: Scenario, grid: OccupancyGrid, arc: float, a: np.ndarray, b: np.ndarray
    ) -> tuple[np.ndarray, _OrbitLeg]:
        element = scenario.element(scenario.inspection_object)
        centre = np.asarray(element.centre, dtype=float)
        if isinstance(element, Cylinder):
            size = element.radius
        else:
            size = 0.5 * math.hypot(*element.size)
        radius = size + self.settings.orbit_distance_m
        free = inflate(grid, max(self.settings.clearances_m))
        best: tuple[float, np.ndarray, _OrbitLeg] | None = None
        steps = max(2, int(math.degrees(arc) / 5.0))
        for start_deg in range(0, 360, 10):
            theta0 = math.radians(start_deg)
            for direction in (1, -1):
                angles = theta0 + direction * np.linspace(0.0, arc, steps + 1)
                pts = centre + radius * np.column_stack((np.cos(angles), np.sin(angles)))
                if not np.all(free.is_free(pts)):
                    continue
                cost = float(np.linalg.norm(pts[0] - a) + np.linalg.norm(pts[-1] - b))
                if best is None or cost < best[0]:
                    leg = _OrbitLeg((float(centre[0]), float(centre[1])), radius, direction, arc)
                    best = (cost, pts[0], leg)
        if best is None:
            raise ValueError(
                f"scripted participant: no free arc around {scenario.inspection_object!r}"
            )
        return best[1], best[2]

    def reseed(self, rng: np.random.Generator) -> None:
        """Draw from ``rng`` from now on (a synthetic participant gives each trial its own
        stream)."""
        self._rng = rng

    def begin_trial(self, info: TrialInfo) -> None:
        """Plan the trial's route (and inspection) on the scene's occupancy grid."""
        self._legs, self._leg, self._progress, self._stuck = [], 0, 0, 0
        self._watch = None
        self._question, self._answered = None, None
        self._still_since, self._backoff_until = math.nan, -math.inf
        self._drive = info.drive
        if not info.drive:
            return
        scenario = info.scenario
        self._max_speed = scenario.robot.max_speed
        self._max_yaw_rate = scenario.robot.max_yaw_rate
        grid = self._grid(scenario)
        start = scenario.start
        here = np.array([start.x, start.y])
        goals: list[tuple[np.ndarray, float | None]] = []
        for goal in info.route:
            if goal == "dock" and scenario.dock is not None:
                b = scenario.dock.pose
                goals.append((np.array([b.x, b.y]), b.yaw))
            else:
                goals.append((np.array([start.x, start.y]), None))
        if info.inspection and scenario.inspection_object:
            primary = info.primary if info.primary is not None else PrimarySettings()
            element = scenario.element(scenario.inspection_object)
            if isinstance(element, Box | Cylinder):
                self._watch = inspection_tracker(element, primary)
            arc = math.radians(primary.min_arc_deg + self.settings.arc_margin_deg)
            entry, orbit = self._orbit(scenario, grid, arc, here, goals[0][0])
            self._legs.append(_PathLeg(self._path(scenario, here, entry), None, True, orbit.centre))
            self._legs.append(orbit)
            c = np.asarray(orbit.centre)
            end = orbit.direction * orbit.arc + math.atan2(*(entry - c)[::-1])
            here = c + orbit.radius * np.array([math.cos(end), math.sin(end)])
        for point, yaw in goals:
            self._legs.append(_PathLeg(self._path(scenario, here, point), yaw, True))
            here = point
        self._swept, self._last_phi = 0.0, math.nan

    # ------------------------------------------------------------ acting

    def intention(self) -> tuple[str, str]:
        """What it is doing now: ("route", "") while driving a path, ("inspection", object)."""
        if not self._drive or self._leg >= len(self._legs):
            return ("", "")
        leg = self._legs[self._leg]
        return ("inspection", "") if isinstance(leg, _OrbitLeg) else ("route", "")

    def _answer(self, screen: ScreenState, t: float) -> bool | None:
        text = screen.question
        if text is None:
            self._question = None
            return None
        if text != self._question:  # a new question (a blank gap separates equal ones)
            self._question, self._answered = text, None
            self._question_seen_t = t
            self._question_right = bool(self._rng.random() < self.settings.accuracy)
        if (
            self._answered == text
            or t - self._question_seen_t < self.settings.answer_delay_s - 1e-9
        ):
            return None
        self._answered = text
        right = answer_is_correct(text)
        return right if self._question_right else not right

    def act(self, obs: Observation, screen: ScreenState) -> ParticipantInput:
        """Follow the plan and answer questions."""
        answer = self._answer(screen, obs.t)
        return ParticipantInput(u=np.array(self.command(obs, screen.paused)), answer=answer)

    def command(self, obs: Observation, paused: bool) -> tuple[float, float, float]:
        """The driving part of :meth:`act`: the command (v_x, v_y, omega) [m/s, m/s,
        rad/s] of this tick (zero when not driving or ``paused``), as plain floats."""
        u = _ZERO
        if self._watch is not None:
            self._watch.update(obs.pose, obs.velocity)
        if self._drive and not paused:
            while self._leg < len(self._legs):
                leg = self._legs[self._leg]
                step = (
                    self._follow_orbit(obs.pose, leg)
                    if isinstance(leg, _OrbitLeg)
                    else self._follow_path(obs.pose, leg)
                )
                if step is not None and not self._give_up_entry(leg, obs.pose):
                    u = step
                    break
                self._leg += 1
                self._progress, self._stuck = 0, 0
                self._swept, self._last_phi = 0.0, math.nan
            u = self._unstick(obs.t, obs.pose, u)
        return u

    def _give_up_entry(self, leg: _PathLeg | _OrbitLeg, pose: Pose2D) -> bool:
        """Whether to leave ``leg``, the way to the orbit's entry (it faces the object),
        and orbit from where the robot is: after ``entry_tries`` stuck episodes within
        ``entry_radius_m`` of the entry (episodes farther away are forgotten: there it
        keeps going)."""
        if not isinstance(leg, _PathLeg) or leg.face is None:
            return False
        s = self.settings
        if math.hypot(pose.x - leg.points[-1][0], pose.y - leg.points[-1][1]) > s.entry_radius_m:
            self._stuck = 0
            return False
        return self._stuck >= s.entry_tries

    def _unstick(
        self, t: float, pose: Pose2D, u: tuple[float, float, float]
    ) -> tuple[float, float, float]:
        """Back away for ``backoff_s`` after pushing ``stuck_s`` without the robot moving
        (as a person does when the robot will not go where the stick points)."""
        s = self.settings
        if t < self._backoff_until:
            return self._backoff_u
        x0, y0, _ = self._still_at
        # the stick asks for translation: only translation counts as moving (an assistance
        # that passes the turn alone, as OA does, leaves the robot just as stuck)
        moved = math.hypot(pose.x - x0, pose.y - y0) >= 0.02
        if math.hypot(u[0], u[1]) < 0.05 or moved:
            self._still_since, self._still_at = t, (pose.x, pose.y, pose.yaw)
            return u
        if t - self._still_since >= s.stuck_s:
            norm = math.hypot(u[0], u[1])
            self._backoff_u = (-u[0] / norm * 0.5 * s.speed, -u[1] / norm * 0.5 * s.speed, 0.0)
            self._backoff_until = t + s.backoff_s
            self._stuck += 1
            self._still_since, self._still_at = t + s.backoff_s, (pose.x, pose.y, pose.yaw)
            return self._backoff_u
        return u

    def _to_robot(self, pose: Pose2D, vx: float, vy: float, w: float) -> tuple[float, float, float]:
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        return (c * vx + s * vy, -s * vx + c * vy, _clip(w, self._max_yaw_rate))

    def _follow_path(self, pose: Pose2D, leg: _PathLeg) -> tuple[float, float, float] | None:
        s = self.settings
        pts = leg.points
        px, py = float(pose.x), float(pose.y)
        ex, ey = float(pts[-1, 0]), float(pts[-1, 1])
        dx, dy = ex - px, ey - py
        to_end = math.sqrt(dx * dx + dy * dy)
        yaw_goal = leg.final_yaw
        if leg.face is not None:
            yaw_goal = math.atan2(leg.face[1] - pose.y, leg.face[0] - pose.x)
        yaw_err = 0.0 if yaw_goal is None else wrap_angle(yaw_goal - pose.yaw)
        if to_end <= s.stop_tolerance_m and abs(yaw_err) <= 0.05:
            return None
        # progress: the nearest path point from the current one on, within a window; the
        # target: the first path point from there on at least lookahead_m away (else B)
        self._progress, ahead = _path_progress(pts, self._progress, px, py, s.lookahead_m)
        if ahead >= 0:
            dx, dy = float(pts[ahead, 0]) - px, float(pts[ahead, 1]) - py
        dist = math.sqrt(dx * dx + dy * dy)
        speed = min(s.speed, 0.9 * to_end + 0.03) if leg.stop else s.speed
        vx = vy = 0.0
        if dist > 1e-9:
            limit = min(speed, dist / 0.05)
            vx, vy = dx / dist * limit, dy / dist * limit
        align = s.align_distance_m if leg.face is None else s.face_distance_m
        if yaw_goal is not None and to_end <= align:
            want = yaw_goal
        elif dist > 0.05:
            want = math.atan2(dy, dx)
        else:
            want = pose.yaw
        err = wrap_angle(want - pose.yaw)
        if abs(err) > math.radians(50):
            vx, vy = vx * 0.3, vy * 0.3  # turn mostly on the spot before driving on
        return self._to_robot(pose, vx, vy, s.yaw_gain * err)

    def _follow_orbit(self, pose: Pose2D, leg: _OrbitLeg) -> tuple[float, float, float] | None:
        s = self.settings
        cx, cy = leg.centre
        dx, dy = pose.x - cx, pose.y - cy
        dist = math.hypot(dx, dy)
        phi = math.atan2(dy, dx)
        if not math.isnan(self._last_phi):
            self._swept += leg.direction * wrap_angle(phi - self._last_phi)
        self._last_phi = phi
        # done when the watched visit's net arc counts (drift before the orbit may have
        # taken some of it back), at most a quarter turn beyond the planned arc
        watched = self._watch is not None and self._watch.done
        if watched or self._swept >= leg.arc + (0.0 if self._watch is None else ORBIT_EXTRA):
            return None
        face = math.atan2(-dy, -dx)
        # facing the centre, the robot's +y (left) is the clockwise tangent
        vy = -leg.direction * s.orbit_speed
        vx = _clip(2.0 * (dist - leg.radius), 0.1)
        w = s.yaw_gain * wrap_angle(face - pose.yaw) + leg.direction * s.orbit_speed / max(
            dist, 0.1
        )
        return (vx, vy, _clip(w, self._max_yaw_rate))
