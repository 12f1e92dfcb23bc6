"""Scripted skills that perform the contextual tasks the way a person with a gamepad
would (thesis Sec. 7.2.3, 7.4.1-7.4.2; spec section 3).

A skill is reset with a :class:`~tasks.contextual.ContextualTask` and a
``numpy.random.Generator`` (which draws its random parameters) and is then asked every
control tick for a command: ``act(obs) -> SkillStep(u, done, phase)``, ``u`` a
robot-frame joystick command ``(v_x [m/s], v_y [m/s], omega [rad/s])``. Skills work in
the map frame of the estimated pose ``obs.pose`` (the participant sees the robot on the
map); each command passes the obstacle guard (:mod:`tasks.guard`); every skill stops
after ``max_ticks`` calls with ``done`` and phase ``"timeout"``. The human hand on the
stick is :mod:`tasks.stick`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.types import Observation, Pose2D, SemanticComponent, wrap_angle
from tasks.contextual import TARGET_KIND, ContextualTask
from tasks.guard import _guard, _unit, free_ahead

_ZERO = np.zeros(3)
_ZERO.flags.writeable = False


# --------------------------------------------------------------------------- values


@dataclass(frozen=True, slots=True)
class SkillSettings:
    """How the scripted skills drive (speeds, gains, the tasks' random ranges)."""

    speed: float = 0.4  # [m/s] cruise speed
    slow_speed: float = 0.25  # [m/s] through passages and under the table
    side_speed: float = 0.3  # [m/s] sideways during an inspection
    max_omega: float = 0.8  # [rad/s] a person turns gently
    k_pos: float = 1.2  # [1/s] position gain
    k_yaw: float = 1.8  # [1/s] heading gain
    lookahead: float = 0.7  # [m] carrot distance along a line being followed
    k_lateral: float = 1.5  # [1/s] lateral gain on a passage's centre line (narrow: precise)
    face_travel_m: float = 1.0  # [m] farther than this from a way point: face the travel
    pass_distance: float = 0.8  # [m] pre- and post-point of a crossing from the centre
    inspection_distance: tuple[float, float] = (0.8, 1.0)  # [m] nearest surface to centre
    inspection_arc_deg: tuple[float, float] = (120.0, 200.0)  # [deg] arc to sweep
    wall_distance: tuple[float, float] = (0.5, 0.7)  # [m] wall face to robot centre
    wall_length: tuple[float, float] = (2.0, 4.0)  # [m] length to follow
    wall_end_margin: float = 0.6  # [m] stop this far before the face ends
    bypass_clearance: tuple[float, float] = (0.3, 0.5)  # [m] robot side to circumcircle
    dock_pre_distance: float = 1.2  # [m] pre-point before the dock centre
    dock_tolerance: float = 0.08  # [m] done when the centre is this close to the dock's
    align_tolerance: tuple[float, float] = (0.15, 0.2)  # [m], [rad] to start a crossing
    half_length: float = 0.3  # [m] footprint half extent along x
    half_width: float = 0.25  # [m] footprint half extent along y
    guard_margin: float = 0.03  # [m] widening of the swept corridor
    guard_stop: float = 0.06  # [m] free distance at which the guard stops the robot
    guard_gain: float = 1.5  # [1/s] speed <= gain * (free - stop)
    blocked_distance: float = 0.25  # [m] a crossing ends early when the way on is this tight
    max_ticks: int = 2400  # calls before "timeout" (120 s at 20 Hz)

    def __post_init__(self) -> None:
        for name in ("speed", "slow_speed", "side_speed", "max_omega", "k_pos", "k_yaw"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SkillSettings: field '{name}': must be positive")
        if self.max_ticks < 1:
            raise ValueError("SkillSettings: field 'max_ticks': must be at least 1")


@dataclass(frozen=True, slots=True)
class SkillStep:
    """A skill's answer for one tick."""

    u: np.ndarray  # (3,) robot-frame command (v_x [m/s], v_y [m/s], omega [rad/s])
    done: bool  # the task is finished (completed, or "timeout")
    phase: str  # what the skill is doing: "approach", "cross", ..., "done", "timeout"


@dataclass(frozen=True, slots=True)
class WallFace:
    """The face of a wall segment on one side, in the map frame."""

    point: np.ndarray  # (2,) [m] a point on the face line (the points' mean, moved onto it)
    tangent: np.ndarray  # (2,) unit direction along the wall
    normal: np.ndarray  # (2,) unit normal pointing away from the wall, to the chosen side
    lo: float  # [m] extent of the face along ``tangent`` from ``point``
    hi: float  # [m]


# --------------------------------------------------------------------------- geometry


def _yaw(v: np.ndarray) -> float:
    return math.atan2(float(v[1]), float(v[0]))


def _to_robot(pose: Pose2D, vec: np.ndarray) -> np.ndarray:
    """A map-frame vector (2,) in the robot frame (rotation only)."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return np.array([c * vec[0] + s * vec[1], -s * vec[0] + c * vec[1]])


def _position(pose: Pose2D) -> np.ndarray:
    return np.array([pose.x, pose.y])


def wall_face(points: np.ndarray, position: np.ndarray) -> WallFace:
    """The face of a wall segment that looks towards ``position``.

    Parameters
    ----------
    points : numpy.ndarray
        (k, 2) [m] the wall component's surface points (both faces or one), map frame.
    position : numpy.ndarray
        (2,) [m] where the robot is, map frame.

    Returns
    -------
    WallFace
        The principal axis of the points is the tangent; the face on the robot's side
        of the axis is the one kept (a wall seen from one side has points on that side).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    mean = pts.mean(axis=0)
    centred = pts - mean
    _, vecs = np.linalg.eigh(centred.T @ centred)
    tangent = vecs[:, -1]
    axis = np.array([-tangent[1], tangent[0]])
    across = centred @ axis
    side = 1.0 if float((np.asarray(position) - mean) @ axis) >= 0 else -1.0
    face = side * across > 1e-6
    if not np.any(face):  # a one-sided wall seen from behind its points: use them all
        face = np.ones(len(pts), dtype=bool)
    offset = float(np.median(across[face]))
    along = centred[face] @ tangent
    return WallFace(
        point=mean + offset * axis,
        tangent=tangent,
        normal=side * axis,
        lo=float(along.min()),
        hi=float(along.max()),
    )


# --------------------------------------------------------------------------- skills


class Skill:
    """Base of the scripted skills: task bookkeeping, the step cap, the guard.

    Subclasses implement ``_setup(obs, comp)`` (first tick: map-frame geometry) and
    ``_control(obs, comp) -> (u, phase, done)``.
    """

    task_types: tuple[str, ...] = ()

    def __init__(self, settings: SkillSettings | None = None) -> None:
        self.settings = SkillSettings() if settings is None else settings
        self.task: ContextualTask | None = None

    def reset(self, task: ContextualTask, rng: np.random.Generator) -> None:
        """Start ``task``; ``rng`` draws this performance's random parameters."""
        if task.type not in self.task_types:
            raise ValueError(
                f"{type(self).__name__}: task type {task.type!r} not handled; "
                f"allowed: {', '.join(self.task_types)}"
            )
        self.task = task
        self._rng = rng
        self._ticks = 0
        self._finished: str | None = None
        self._ready = False
        self._draw(rng)

    def _draw(self, rng: np.random.Generator) -> None:
        """Draw the random parameters of one performance."""

    def act(self, obs: Observation) -> SkillStep:
        """The ideal command for this tick.

        Parameters
        ----------
        obs : Observation
            This tick's observation; ``obs.components`` must contain the target.

        Returns
        -------
        SkillStep
            ``u`` (3,) robot frame [m/s, m/s, rad/s]; once ``done``, ``u`` is zero.
        """
        if self.task is None:
            raise RuntimeError(f"{type(self).__name__}.act called before reset()")
        if self._finished is not None:
            return SkillStep(_ZERO, True, self._finished)
        self._ticks += 1
        if self._ticks > self.settings.max_ticks:
            self._finished = "timeout"
            return SkillStep(_ZERO, True, "timeout")
        comp = _find(obs, self.task)
        if not self._ready:
            self._setup(obs, comp)
            self._ready = True
        u, phase, done = self._control(obs, comp)
        if done:
            self._finished = phase
            return SkillStep(_ZERO, True, phase)
        u = _guard(np.asarray(u, dtype=float), obs.points, self.settings)
        return SkillStep(u, False, phase)

    # helpers for subclasses ------------------------------------------------

    def _setup(self, obs: Observation, comp: SemanticComponent) -> None:
        raise NotImplementedError

    def _control(self, obs: Observation, comp: SemanticComponent) -> tuple[np.ndarray, str, bool]:
        raise NotImplementedError

    def _track(self, pose: Pose2D, goal: np.ndarray, yaw_goal: float, speed: float) -> np.ndarray:
        """Command towards map point ``goal`` at most ``speed`` while turning to ``yaw_goal``."""
        s = self.settings
        e = goal - _position(pose)
        dist = float(np.hypot(e[0], e[1]))
        v_map = e / dist * min(speed, s.k_pos * dist) if dist > 1e-9 else np.zeros(2)
        omega = float(np.clip(s.k_yaw * wrap_angle(yaw_goal - pose.yaw), -s.max_omega, s.max_omega))
        v = _to_robot(pose, v_map)
        return np.array([v[0], v[1], omega])

    def _travel_yaw(self, pose: Pose2D, goal: np.ndarray, final_yaw: float) -> float:
        """Face the direction of travel while far from ``goal``, else ``final_yaw``."""
        e = goal - _position(pose)
        return _yaw(e) if float(np.hypot(*e)) > self.settings.face_travel_m else final_yaw


def _find(obs: Observation, task: ContextualTask) -> SemanticComponent:
    for comp in obs.components:
        if comp.id == task.target_id:
            if comp.kind != TARGET_KIND[task.type]:
                raise ValueError(
                    f"task target {task.target_id!r}: is a {comp.kind}, "
                    f"{task.type} needs a {TARGET_KIND[task.type]}"
                )
            return comp
    raise ValueError(f"task target {task.target_id!r}: no such component in the observation")


def _map_centre(obs: Observation, comp: SemanticComponent) -> np.ndarray:
    return obs.pose.to_map_frame(comp.centre)[0]


def _map_vector(obs: Observation, vec: np.ndarray) -> np.ndarray:
    c, s = math.cos(obs.pose.yaw), math.sin(obs.pose.yaw)
    return np.array([c * vec[0] - s * vec[1], s * vec[0] + c * vec[1]])


class CrossingSkill(Skill):
    """Doorway or gap crossing: line up on the normal, drive through."""

    task_types = ("doorway_crossing", "gap_crossing")

    def _setup(self, obs: Observation, comp: SemanticComponent) -> None:
        self.centre_ = _map_centre(obs, comp)
        normal = _unit(_map_vector(obs, comp.normal))
        side = 1.0 if float((_position(obs.pose) - self.centre_) @ normal) >= 0 else -1.0
        self.direction_ = -side * normal  # travel away from the side the robot is on
        self.pre_ = self.centre_ - self.settings.pass_distance * self.direction_
        self.phase_ = "approach"

    def _control(self, obs: Observation, comp: SemanticComponent) -> tuple[np.ndarray, str, bool]:
        s, pose = self.settings, obs.pose
        d, yaw_d = self.direction_, _yaw(self.direction_)
        rel = _position(pose) - self.centre_
        along = float(rel @ d)
        if along >= s.pass_distance:
            return _ZERO, "done", True
        if along >= s.half_length + 0.2 and (
            free_ahead(obs.points, _to_robot(pose, d), s) < s.blocked_distance
        ):  # through, and something is in the way beyond: a person stops here
            return _ZERO, "done", True
        if self.phase_ == "approach":
            err = float(np.hypot(*(self.pre_ - _position(pose))))
            if (
                err < s.align_tolerance[0]
                and abs(wrap_angle(yaw_d - pose.yaw)) < s.align_tolerance[1]
            ):
                self.phase_ = "cross"
            else:
                yaw = self._travel_yaw(pose, self.pre_, yaw_d)
                return self._track(pose, self.pre_, yaw, s.speed), "approach", False
        # along the centre line at slow speed, correcting the offset firmly (people line
        # up carefully for a narrow passage)
        across = np.array([-d[1], d[0]])
        lateral = float(rel @ across)
        v_map = d * s.slow_speed - across * float(np.clip(s.k_lateral * lateral, -0.2, 0.2))
        omega = float(np.clip(s.k_yaw * wrap_angle(yaw_d - pose.yaw), -s.max_omega, s.max_omega))
        v = _to_robot(pose, v_map)
        return np.array([v[0], v[1], omega]), "cross", False


class InspectionSkill(Skill):
    """Object inspection: approach, face the object, move sideways around it."""

    task_types = ("object_inspection",)

    def _draw(self, rng: np.random.Generator) -> None:
        s = self.settings
        self.distance_ = float(rng.uniform(*s.inspection_distance))
        self.arc_ = math.radians(float(rng.uniform(*s.inspection_arc_deg)))
        self.sign_ = 1.0 if self.task.direction == "ccw" else -1.0

    def _setup(self, obs: Observation, comp: SemanticComponent) -> None:
        self.centre_ = _map_centre(obs, comp)
        self.phase_ = "approach"
        self.swept_ = 0.0
        self.angle_ = 0.0

    def _position_angle(self, pose: Pose2D) -> float:
        rel = _position(pose) - self.centre_
        return math.atan2(rel[1], rel[0])

    def _control(self, obs: Observation, comp: SemanticComponent) -> tuple[np.ndarray, str, bool]:
        s = self.settings
        target = comp.target_point()  # robot frame
        dist = float(np.hypot(*target))
        radial = target / max(dist, 1e-9)
        bearing = math.atan2(target[1], target[0])
        err = dist - self.distance_
        if self.phase_ == "approach":
            if abs(err) < 0.15 and abs(bearing) < 0.2:
                self.phase_ = "inspect"
                self.angle_ = self._position_angle(obs.pose)
            else:
                v = radial * float(np.clip(s.k_pos * err, -s.speed, s.speed))
                omega = float(np.clip(s.k_yaw * bearing, -s.max_omega, s.max_omega))
                return np.array([v[0], v[1], omega]), "approach", False
        angle = self._position_angle(obs.pose)
        self.swept_ += wrap_angle(angle - self.angle_)
        self.angle_ = angle
        if self.sign_ * self.swept_ >= self.arc_:
            return _ZERO, "done", True
        # moving to the robot's right while facing the object sweeps counter-clockwise
        tangent = -self.sign_ * np.array([-radial[1], radial[0]])
        v = s.side_speed * tangent + radial * float(np.clip(s.k_pos * err, -s.speed, s.speed))
        centre_dist = max(float(np.hypot(*obs.pose.to_robot_frame(self.centre_)[0])), 0.3)
        omega_ff = self.sign_ * s.side_speed / centre_dist  # the circling rate
        omega = float(np.clip(omega_ff + s.k_yaw * bearing, -s.max_omega, s.max_omega))
        return np.array([v[0], v[1], omega]), "inspect", False


class WallFollowingSkill(Skill):
    """Wall following: approach the wall, turn parallel, drive along it."""

    task_types = ("wall_following",)

    def _draw(self, rng: np.random.Generator) -> None:
        s = self.settings
        self.distance_ = float(rng.uniform(*s.wall_distance))
        self.length_ = float(rng.uniform(*s.wall_length))

    def _setup(self, obs: Observation, comp: SemanticComponent) -> None:
        pts = obs.pose.to_map_frame(comp.points)
        self.face_ = face = wall_face(pts, _position(obs.pose))
        n = face.normal
        # wall on the robot's left: the robot's left is -n, so its heading is -n turned right
        if self.task.direction == "left":
            heading = np.array([-n[1], n[0]])
        else:
            heading = np.array([n[1], -n[0]])
        self.heading_ = heading
        self.sense_ = 1.0 if float(heading @ face.tangent) >= 0 else -1.0
        self.end_ = (face.hi if self.sense_ > 0 else -face.lo) - self.settings.wall_end_margin
        self.phase_ = "approach"
        self.start_along_ = 0.0

    def _control(self, obs: Observation, comp: SemanticComponent) -> tuple[np.ndarray, str, bool]:
        s, pose, face = self.settings, obs.pose, self.face_
        rel = _position(pose) - face.point
        along = self.sense_ * float(rel @ face.tangent)  # along the heading
        lateral = float(rel @ face.normal)
        yaw_h = _yaw(self.heading_)
        if along >= self.end_:
            return _ZERO, ("done" if self.phase_ == "follow" else "wall_end"), True
        if self.phase_ == "approach":
            aligned = abs(wrap_angle(yaw_h - pose.yaw)) < s.align_tolerance[1]
            if abs(lateral - self.distance_) < 0.1 and aligned:
                self.phase_ = "follow"
                self.start_along_ = along
        elif along - self.start_along_ >= self.length_:
            return _ZERO, "done", True
        elif free_ahead(obs.points, _to_robot(pose, self.heading_), s) < s.blocked_distance:
            return _ZERO, "done", True  # something stands against the wall: it "ends" here
        carrot = (
            face.point
            + face.normal * self.distance_
            + face.tangent * self.sense_ * (along + s.lookahead)
        )
        if self.phase_ == "approach" and abs(lateral - self.distance_) > 0.4:
            yaw = _yaw(carrot - _position(pose))
        else:
            yaw = yaw_h
        return self._track(pose, carrot, yaw, s.speed), self.phase_, False


class BypassSkill(Skill):
    """Object bypass: swerve past the object on the chosen side."""

    task_types = ("object_bypass",)

    def _draw(self, rng: np.random.Generator) -> None:
        self.clearance_ = float(rng.uniform(*self.settings.bypass_clearance))

    def _setup(self, obs: Observation, comp: SemanticComponent) -> None:
        s = self.settings
        self.centre_ = _map_centre(obs, comp)
        pts = obs.pose.to_map_frame(comp.points) if len(comp.points) else self.centre_[None]
        self.radius_ = float(np.max(np.hypot(*(pts - self.centre_).T)))
        self.direction_ = d = _unit(self.centre_ - _position(obs.pose))
        right = np.array([d[1], -d[0]])
        # object on the robot's left: the robot passes on the object's right
        side = right if self.task.direction == "left" else -right
        self.offset_ = side * (self.radius_ + s.half_width + self.clearance_)

    def _control(self, obs: Observation, comp: SemanticComponent) -> tuple[np.ndarray, str, bool]:
        s, pose = self.settings, obs.pose
        d = self.direction_
        along = float((_position(pose) - self.centre_) @ d)
        if along >= self.radius_ + s.half_length + 0.2:
            return _ZERO, "done", True
        ahead = along + s.lookahead
        # swerve over about a metre, starting 1.6 m before the circumcircle
        ramp = float(np.clip((ahead + self.radius_ + 1.6) / 1.0, 0.0, 1.0))
        carrot = self.centre_ + d * ahead + ramp * self.offset_
        yaw = _yaw(carrot - _position(pose))
        phase = "approach" if along < -self.radius_ - s.half_length else "pass"
        return self._track(pose, carrot, yaw, s.speed), phase, False


class DockingSkill(Skill):
    """Robot docking: line up on the dock's approach normal, drive in under the table."""

    task_types = ("robot_docking",)

    def _setup(self, obs: Observation, comp: SemanticComponent) -> None:
        self.centre_ = _map_centre(obs, comp)
        self.normal_ = _unit(_map_vector(obs, comp.normal))
        self.pre_ = self.centre_ - self.settings.dock_pre_distance * self.normal_
        self.phase_ = "approach"

    def _control(self, obs: Observation, comp: SemanticComponent) -> tuple[np.ndarray, str, bool]:
        s, pose = self.settings, obs.pose
        n, yaw_n = self.normal_, _yaw(self.normal_)
        pos = _position(pose)
        if float(np.hypot(*(self.centre_ - pos))) < s.dock_tolerance:
            return _ZERO, "done", True
        err = float(np.hypot(*(self.pre_ - pos)))
        yaw_err = abs(wrap_angle(yaw_n - pose.yaw))
        if self.phase_ == "approach" and err < 0.25:
            self.phase_ = "align"
        if self.phase_ == "align" and err < 0.08 and yaw_err < 0.08:
            self.phase_ = "enter"
        if self.phase_ == "approach":
            yaw = self._travel_yaw(pose, self.pre_, yaw_n)
            return self._track(pose, self.pre_, yaw, s.speed), "approach", False
        if self.phase_ == "align":
            return self._track(pose, self.pre_, yaw_n, s.slow_speed), "align", False
        along = float((pos - self.centre_) @ n)
        carrot = self.centre_ + n * min(along + s.lookahead, 0.0)
        return self._track(pose, carrot, yaw_n, s.slow_speed), "enter", False


SKILLS: dict[str, type[Skill]] = {
    "doorway_crossing": CrossingSkill,
    "gap_crossing": CrossingSkill,
    "object_inspection": InspectionSkill,
    "object_bypass": BypassSkill,
    "wall_following": WallFollowingSkill,
    "robot_docking": DockingSkill,
}


def make_skill(task_type: str, *, settings: SkillSettings | None = None) -> Skill:
    """A new skill for ``task_type`` (one of ``tasks.contextual.TASK_TYPES``)."""
    if task_type not in SKILLS:
        raise ValueError(f"task: unknown task type {task_type!r}; allowed: {', '.join(SKILLS)}")
    return SKILLS[task_type](settings)
