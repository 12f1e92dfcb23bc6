"""The simulated world: a pybullet scene built from a scenario, a holonomic robot in it,
its sensors and its collisions (thesis Sec. 7.6.1.1; spec section 7).

The map frame is the scenario's (x right, y up, yaw counter-clockwise from +x, z up
from the floor); the robot frame has x forward, y left, origin at the centre of the
footprint. Commands and velocities are robot-frame ``(v_x [m/s], v_y [m/s], omega
[rad/s])``. One control tick is ``dt`` (20 Hz); the physics runs
``round(dt * physics_hz)`` substeps of equal length per tick. Sensor noise comes from
the world's own generator, seeded by ``seed``: the same seed, commands and calls give
an identical run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import TracebackType
from typing import Any

import numpy as np

from sim._kernels import scan_kernel
from sim._pybullet import pybullet as p
from sim.bodies import JOINTS, SCENE_GROUP, build_robot, build_scene
from sim.lasers import Fans, laser_beams, laser_fans, laser_rays
from sim.scenario import Scenario
from sim.scene import RobotSpec
from sim.semantics import RobotFrameComponents, derive_components, in_robot_frame
from sim.sensors import cast_from
from sim.types import (
    Contact,
    ImuReading,
    LaserScan,
    Observation,
    Pose2D,
    SemanticComponent,
    wrap_angle,
)

LASER_BACKENDS = ("analytic", "pybullet")

_CAMERA_NEAR_M = 0.05


@dataclass(frozen=True, slots=True)
class WorldSettings:
    """How the world is simulated (not what it contains: that is the scenario)."""

    dt: float = 0.05  # [s] control tick (20 Hz)
    physics_hz: int = 240  # physics substeps per second (rounded to whole substeps per tick)
    contact_debounce_s: float = 0.3  # [s] no contact this long ends a collision episode
    contact_tolerance_m: float = 0.001  # [m] contact points closer than this count as touch
    motor_force_factor: float = 3.0  # x, y motor force / (mass * max_accel); > 1 to track the ramp
    velocity_sigma: float = 0.01  # [m/s] noise of the odometry's (v_x, v_y)
    laser_backend: str = "analytic"  # "analytic" (exact 2D caster) or "pybullet" (rayTestBatch)
    gui: bool = False  # pybullet's own window (one per process); DIRECT otherwise

    def __post_init__(self) -> None:
        for name in ("dt", "physics_hz", "contact_tolerance_m", "motor_force_factor"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise ValueError(f"WorldSettings: field '{name}': must be positive, got {value!r}")
        if not (self.contact_debounce_s >= 0 and self.velocity_sigma >= 0):
            raise ValueError(
                "WorldSettings: fields 'contact_debounce_s' and 'velocity_sigma': "
                "must be zero or positive"
            )
        if self.laser_backend not in LASER_BACKENDS:
            raise ValueError(
                f"WorldSettings: field 'laser_backend': must be one of "
                f"{', '.join(LASER_BACKENDS)}, got {self.laser_backend!r}"
            )


def clip_command(v: np.ndarray, max_speed: float, max_yaw_rate: float) -> np.ndarray:
    """Clip a robot-frame command (3,) to the speed limits.

    The translational part is scaled down along its own direction so that its norm
    is at most ``max_speed`` [m/s]; omega is clipped to ``max_yaw_rate`` [rad/s].
    """
    out = np.array(v, dtype=float).reshape(3)
    speed = math.hypot(out[0], out[1])
    if speed > max_speed:
        out[:2] *= max_speed / speed
    out[2] = min(max(out[2], -max_yaw_rate), max_yaw_rate)
    return out


def motor_limits(robot: RobotSpec, motor_force_factor: float, h: float) -> list[float]:
    """Largest force [N] of the x and y joint motors and torque [N m] of the yaw motor.

    The x and y motors get ``motor_force_factor`` times what ``max_accel`` needs, so an
    obstacle pushes back. The yaw motor must not give way to a contact, as a holonomic
    base's wheels hold its heading: in one physics substep ``h`` [s] it can absorb the
    largest angular impulse a contact can deliver, the robot's momentum at top speed
    stopped at the footprint's farthest point from its centre,
    ``mass * max_speed * half_diagonal / h`` (or what ``max_yaw_accel`` needs, if more).
    """
    force = motor_force_factor * robot.mass * robot.max_accel
    yaw_inertia = robot.mass * (robot.length**2 + robot.width**2) / 12.0  # box about z
    ramp = motor_force_factor * yaw_inertia * robot.max_yaw_accel
    impact = robot.mass * robot.max_speed * math.hypot(robot.length, robot.width) / 2 / h
    return [force, force, max(ramp, impact)]


class World:
    """A pybullet scene of ``scenario`` with the holonomic robot at pose A.

    Parameters
    ----------
    scenario : the room.
    seed : seeds the world's noise generator.
    settings : simulation settings.
    components : the scene's semantic components in the map frame; ``None`` derives
        them with ``sim.semantics.derive_components`` when first needed.

    One control tick is ``world.apply(v); contacts = world.step(); obs = world.sense()``.
    Use as a context manager, or call :meth:`close`, to free the pybullet client.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        seed: int,
        settings: WorldSettings = WorldSettings(),  # noqa: B008 (frozen, so safe to share)
        components: tuple[SemanticComponent, ...] | None = None,
    ) -> None:
        self.scenario = scenario
        self.settings = settings
        self.seed = seed
        self._map_components = components
        self._components_packed = False
        self._rng = np.random.default_rng(seed)
        self._substeps = max(1, round(settings.dt * settings.physics_hz))
        self._h = settings.dt / self._substeps
        self._client = p.connect(p.GUI if settings.gui else p.DIRECT)
        if self._client < 0:
            raise RuntimeError("pybullet: could not connect (a GUI is already open?)")
        self._pb = {"physicsClientId": self._client}
        p.setGravity(0.0, 0.0, 0.0, **self._pb)
        p.setPhysicsEngineParameter(
            fixedTimeStep=self._h, numSubSteps=0, deterministicOverlappingPairs=1, **self._pb
        )
        self._groups = build_scene(scenario, self._pb)  # static body -> its solids
        self._robot = build_robot(scenario, self._pb)
        robot = scenario.robot
        self._forces = motor_limits(robot, settings.motor_force_factor, self._h)
        self._beams = tuple(laser_beams(spec) for spec in robot.lasers)
        self._fans = laser_fans(scenario, self._beams)
        self._rays = laser_rays(robot.lasers, self._beams)
        self._ranges_key: tuple[float, float, float] | None = None  # pose of self._ranges
        self._ranges = np.empty(0)
        self._reset_state(scenario.start)

    # ------------------------------------------------------------------ state

    def _reset_state(self, pose: Pose2D) -> None:
        for j, q in zip(JOINTS, (pose.x, pose.y, pose.yaw), strict=True):
            p.resetJointState(self._robot, j, q, 0.0, **self._pb)
        self._command = (0.0, 0.0, 0.0)  # robot frame, clipped
        self._setpoint = (0.0, 0.0, 0.0)  # motor targets: map-frame (v_x, v_y, omega)
        self._ticks = 0
        self._contacts: list[Contact] = []
        self._open: int | None = None  # index of the episode still open
        self._last_touch = -math.inf
        self._touching = False
        self._accel_map = np.zeros(2)
        self._read_state()

    def _read_state(self, states: Any | None = None) -> None:
        """Pose and velocity from pybullet's joint ``states`` of the robot (read if None)."""
        if states is None:
            states = p.getJointStates(self._robot, JOINTS, **self._pb)
        self._q = (states[0][0], states[1][0], states[2][0])
        self._qd = (states[0][1], states[1][1], states[2][1])

    def reset(self, pose: Pose2D | None = None, *, seed: int | None = None) -> Observation:
        """Put the robot at ``pose`` (default: the scenario's start A) at rest, time 0.

        Contacts are forgotten; ``seed`` (if given) reseeds the noise generator.
        Returns the first observation.
        """
        if seed is not None:
            self.seed = seed
            self._rng = np.random.default_rng(seed)
        self._reset_state(self.scenario.start if pose is None else pose)
        return self.sense()

    @property
    def client(self) -> int:
        """The pybullet physics client id of this world."""
        return self._client

    @property
    def t(self) -> float:
        """Simulated time since the last reset [s]."""
        return self._ticks * self.settings.dt

    def true_pose(self) -> Pose2D:
        """The robot's exact pose in the map frame."""
        return Pose2D(self._q[0], self._q[1], wrap_angle(self._q[2]))

    def true_velocity(self) -> np.ndarray:
        """The robot's exact velocity (3,): robot-frame (v_x [m/s], v_y [m/s], omega [rad/s])."""
        c, s = math.cos(self._q[2]), math.sin(self._q[2])
        vx, vy, w = self._qd
        return np.array([c * vx + s * vy, -s * vx + c * vy, w])

    @property
    def touching(self) -> bool:
        """Whether the robot touched a scene element at the last physics substep."""
        return self._touching

    def contacts(self) -> list[Contact]:
        """All collision episodes since the last reset, in order (ended ones have t_end)."""
        return list(self._contacts)

    # ------------------------------------------------------------------ acting

    def apply(self, v: np.ndarray) -> None:
        """Command robot-frame velocity ``v`` (3,) (v_x [m/s], v_y [m/s], omega [rad/s]).

        Held until the next call; clipped to the robot's speed limits here and rate
        limited to its acceleration limits while stepping.
        """
        v = np.asarray(v, dtype=float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"World.apply: v must be 3 finite numbers, got {v!r}")
        r = self.scenario.robot
        self._command = tuple(clip_command(v, r.max_speed, r.max_yaw_rate).tolist())

    def step(self) -> list[Contact]:
        """Advance one control tick ``dt``; return the collision episodes that started in it.

        The joint positions are the true pose. The command, clipped to ``max_speed`` and
        ``max_yaw_rate`` (thesis 7.6.1.1: 1.0 m/s, 1.2 rad/s), is followed by a velocity
        set-point rate limited by ``max_accel`` (translational vector) and
        ``max_yaw_accel``; each substep turns it into map-frame joint velocities with the
        heading halfway through the substep, so a constant command drives a circular
        arc. VELOCITY_CONTROL motors drive the joints (:func:`motor_limits`): the x and y
        motors with a finite force, so an obstacle pushes back, the yaw motor with
        enough torque that no contact turns the robot; contacts are frictionless, so the
        robot slides along what it touches.
        The pybullet calls are bound once per tick and a substep without any contact
        point skips the contact bookkeeping.
        """
        r = self.scenario.robot
        h = self._h
        dv_max, dw_max = r.max_accel * h, r.max_yaw_accel * h
        cx, cy, cw = self._command
        spx, spy, spw = self._setpoint
        v_before = np.array(self._qd[:2])
        started: list[Contact] = []
        first_substep = self._ticks * self._substeps
        robot, joints, forces, cid = self._robot, JOINTS, self._forces, self._client
        control, step_simulation = p.setJointMotorControlArray, p.stepSimulation
        joint_states, contact_points = p.getJointStates, p.getContactPoints
        velocity_control = p.VELOCITY_CONTROL
        cos, sin, hypot = math.cos, math.sin, math.hypot
        for i in range(self._substeps):
            spw += min(max(cw - spw, -dw_max), dw_max)
            # the robot-frame command in the map frame at the heading halfway through
            # the substep, so that a turning robot follows its arc to second order
            yaw = self._q[2] + 0.5 * h * spw
            c, s = cos(yaw), sin(yaw)
            dx, dy = c * cx - s * cy - spx, s * cx + c * cy - spy
            norm = hypot(dx, dy)
            if norm > dv_max:
                dx, dy = dx * dv_max / norm, dy * dv_max / norm
            spx += dx
            spy += dy
            control(
                robot,
                joints,
                velocity_control,
                targetVelocities=[spx, spy, spw],
                forces=forces,
                physicsClientId=cid,
            )
            step_simulation(physicsClientId=cid)
            self._read_state(joint_states(robot, joints, physicsClientId=cid))
            points = contact_points(bodyA=robot, physicsClientId=cid)
            if points or self._open is not None:
                self._track_contacts((first_substep + i + 1) * h, started, points)
            else:  # nothing touches and no episode is open: nothing to record
                self._touching = False
        self._setpoint = (spx, spy, spw)
        self._ticks += 1
        self._accel_map = (np.array(self._qd[:2]) - v_before) / self.settings.dt
        return started

    def _track_contacts(self, t: float, started: list[Contact], points: Any | None = None) -> None:
        """Open or close the collision episode after the physics substep ending at ``t``
        (``points``: pybullet's contact points of the robot then, read here if None).

        An episode starts at the first substep at which the robot's box touches any scene
        element (a contact point closer than ``contact_tolerance_m``) and ends once it
        has touched nothing for ``contact_debounce_s``. It keeps the time, the map-frame
        point on the obstacle and the element touched first (table parts are
        ``table.leg0``..``table.leg3`` and ``table.top``); ``t_end`` is the last touch.
        """
        tol = self.settings.contact_tolerance_m
        if points is None:
            points = p.getContactPoints(bodyA=self._robot, **self._pb)
        touch = [c for c in points if c[8] <= tol]
        self._touching = bool(touch)
        if touch:
            self._last_touch = t
            if self._open is None:
                deepest = min(touch, key=lambda c: c[8])
                robot_is_a = deepest[1] == self._robot
                other = deepest[2] if robot_is_a else deepest[1]
                point = deepest[6] if robot_is_a else deepest[5]
                contact = Contact(
                    index=len(self._contacts),
                    t_start=t,
                    position=np.array(point[:2]),
                    obstacle=self._element_at(other, point),
                )
                self._open = contact.index
                self._contacts.append(contact)
                started.append(contact)
        elif (
            self._open is not None
            and t - self._last_touch >= self.settings.contact_debounce_s - 1e-9
        ):
            self._contacts[self._open] = replace(self._contacts[self._open], t_end=self._last_touch)
            self._open = None

    def _element_at(self, body: int, point: tuple[float, float, float]) -> str:
        """Name of the scene element of static ``body`` nearest to map ``point``."""
        group = self._groups[body]
        distances = [e.distance(np.asarray(point)) for e in group]
        return group[int(np.argmin(distances))].name

    # ------------------------------------------------------------------ sensing

    def _components_seen_from(self, pose: Pose2D) -> RobotFrameComponents:
        """The semantic components in the frame of a robot at ``pose`` (computed when
        first read)."""
        if self._map_components is None:
            self._map_components = derive_components(self.scenario)
        elif not self._components_packed:
            # seen from the map's origin: the same components, packed once for speed
            self._map_components = in_robot_frame(self._map_components, Pose2D(0.0, 0.0, 0.0))
        self._components_packed = True
        return RobotFrameComponents(self._map_components, pose)

    def _true_ranges(self, pose: Pose2D) -> np.ndarray:
        """Noise-free ranges [m] of all beams from ``pose`` (in :class:`sim.lasers.Rays` order),
        max_range where nothing is hit; read-only.

        The scene is static, so the last result is reused while the pose is exactly the
        same (a robot at rest, e.g. the whole baseline block).
        """
        key = (pose.x, pose.y, pose.yaw)
        if self._ranges_key == key:
            return self._ranges
        out = np.empty(self._rays.start[-1])
        analytic = self.settings.laser_backend == "analytic"
        for fan in self._fans:
            if analytic:
                ranges = cast_from(
                    fan.section, pose, fan.positions, fan.firsts, fan.step, fan.n, fan.max_range
                )
            else:
                origins = pose.to_map_frame(fan.positions)
                ranges = self._ray_test(fan, origins, pose.yaw + fan.firsts)
            for i, r in zip(fan.members, ranges, strict=True):
                out[self._rays.start[i] : self._rays.start[i + 1]] = r
        out.flags.writeable = False
        self._ranges_key, self._ranges = key, out
        return out

    def _ray_test(self, fan: Fans, origins: np.ndarray, firsts: np.ndarray) -> np.ndarray:
        """pybullet's rayTestBatch for the fans of ``fan`` (m, n) [m]."""
        angles = (firsts[:, None] + fan.step * np.arange(fan.n)).ravel()
        start = np.column_stack(
            (np.repeat(origins, fan.n, axis=0), np.full(len(angles), fan.height))
        )
        direction = np.column_stack((np.cos(angles), np.sin(angles), np.zeros(len(angles))))
        hits = p.rayTestBatch(
            start.tolist(),
            (start + fan.max_range * direction).tolist(),
            numThreads=1,
            collisionFilterMask=SCENE_GROUP,  # the scene, not the robot
            **self._pb,
        )
        fraction = np.array([hit[2] if hit[0] >= 0 else 1.0 for hit in hits])
        return (fraction * fan.max_range).reshape(-1, fan.n)

    def sense(self) -> Observation:
        """What the robot knows now (draws this tick's noise).

        Lasers: beams cast horizontally at the laser's height from the true pose (the
        robot never seen), range + N(0, sigma^2) clipped to [min_range, max_range],
        exactly ``max_range`` where nothing is hit. Pose estimate: true pose +
        N(0, diag(s_xy^2, s_xy^2, s_yaw^2)), ``robot.pose_sigma``. IMU: yaw rate +
        N(0, s_g^2) and the robot-frame finite-difference acceleration of the last tick +
        N(0, s_a^2) per axis, ``robot.imu_sigma``. Velocity: true (v_x, v_y) +
        N(0, ``velocity_sigma``^2), omega the IMU's noisy yaw rate. Semantic components:
        in the robot frame of the estimated pose, computed when first read. The camera
        is rendered only by :meth:`camera_image`.

        Returns
        -------
        Observation with the noisy pose and velocity estimates, one LaserScan per
        ``robot.lasers`` entry (ranges (n,) [m]), all laser hits (m, 2) [m] in the
        robot frame, the IMU reading and the semantic components in the robot frame
        of the estimated pose.
        """
        r = self.scenario.robot
        pose = self.true_pose()
        vel = self.true_velocity()
        rays = self._rays
        z = self._rng.standard_normal(8 + rays.start[-1])
        (s_xy, s_yaw), (s_gyro, s_acc) = r.pose_sigma, r.imu_sigma
        estimate = Pose2D(
            pose.x + s_xy * z[0], pose.y + s_xy * z[1], wrap_angle(pose.yaw + s_yaw * z[2])
        )
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        ax, ay = self._accel_map
        yaw_rate = float(vel[2] + s_gyro * z[3])
        imu = ImuReading(
            yaw_rate=yaw_rate,
            accel=np.array([c * ax + s * ay + s_acc * z[4], -s * ax + c * ay + s_acc * z[5]]),
        )
        sv = self.settings.velocity_sigma
        velocity = np.array([vel[0] + sv * z[6], vel[1] + sv * z[7], yaw_rate])

        ranges, points = scan_kernel(
            self._true_ranges(pose),
            z[8:],
            rays.sigma,
            rays.min_range,
            rays.max_range,
            rays.cos,
            rays.sin,
            rays.x0,
            rays.y0,
        )
        scans = tuple(
            LaserScan(
                name=spec.name,
                angles=beams.angles,
                ranges=ranges[a:b],
                origin=beams.origin,
                max_range=spec.max_range,
            )
            for spec, beams, a, b in zip(
                r.lasers, self._beams, rays.start[:-1], rays.start[1:], strict=True
            )
        )
        return Observation(
            t=self.t,
            pose=estimate,
            velocity=velocity,
            scans=scans,
            points=points,
            imu=imu,
            components=self._components_seen_from(estimate),
        )

    def camera_image(self, which: str = "front", *, width_px: int | None = None) -> np.ndarray:
        """Render one of the robot's cameras from the true pose.

        Parameters
        ----------
        which : "front" (``robot.camera``) or "tail" (``robot.tail_camera``, looking back;
            thesis Sec. 7.5, Fig. 7.42).
        width_px : int, optional
            Render this many pixels wide instead (the height keeps the camera's aspect):
            a smaller image costs less to render.

        Returns
        -------
        (height_px, width, 3) uint8 RGB image, pybullet's ER_TINY_RENDERER, no shadows.
        """
        robot = self.scenario.robot
        cams = {"front": robot.camera, "tail": robot.tail_camera}
        if which not in cams:
            raise ValueError(f"camera_image: which must be one of front, tail, got {which!r}")
        cam = cams[which]
        pose = self.true_pose()
        eye_xy = pose.to_map_frame(np.array(cam.position))[0]
        yaw = pose.yaw + cam.yaw
        cy, sy = math.cos(yaw), math.sin(yaw)
        cp, sp = math.cos(cam.pitch), math.sin(cam.pitch)
        eye = [float(eye_xy[0]), float(eye_xy[1]), cam.height]
        forward = [cy * cp, sy * cp, sp]
        up = [-cy * sp, -sy * sp, cp]
        view = p.computeViewMatrix(
            eye, [eye[0] + forward[0], eye[1] + forward[1], eye[2] + forward[2]], up, **self._pb
        )
        projection = p.computeProjectionMatrixFOV(
            math.degrees(cam.fov), cam.width / cam.height_px, _CAMERA_NEAR_M, cam.far, **self._pb
        )
        width, height = cam.width, cam.height_px
        if width_px is not None:
            width, height = int(width_px), max(1, round(cam.height_px * width_px / cam.width))
        _, _, rgba, _, _ = p.getCameraImage(
            width,
            height,
            view,
            projection,
            shadow=0,
            renderer=p.ER_TINY_RENDERER,
            flags=p.ER_NO_SEGMENTATION_MASK,
            **self._pb,
        )
        image = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)
        return image[:, :, :3].copy()

    # ------------------------------------------------------------------ lifetime

    def close(self) -> None:
        """Disconnect the pybullet client (idempotent)."""
        if self._client >= 0:
            p.disconnect(**self._pb)
            self._client = -1

    def __enter__(self) -> World:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
