"""A collision filter for asa-study, in the style of ROS 2 Nav2's AssistedTeleop behaviour
(nav2_behaviors/plugins/assisted_teleop.cpp): the operator's command, projected forward
over a short horizon in fixed steps, is scaled down by the time to the first projected
collision, and zeroed when the first step already collides. No intention inference, no
command of its own: the widely used baseline a lab compares a shared-autonomy method
against.

An example of a mode package (asa-study docs/modes.md): it registers itself in the
``asa_study.modes`` entry-point group of its pyproject.toml, so a protocol names it
``collision_filter``; it sees only plain observations (laser hits in the robot frame) and
the robot model, as the built-in modes do.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy.types import EMPTY_PATH, Assist, RobotModel


@dataclass(frozen=True, slots=True)
class CollisionFilterSettings:
    """Nav2's parameters (its defaults) and the footprint's margin.

    Attributes
    ----------
    projection_time_s : [s] horizon over which the command is projected (Nav2: 1.0).
    simulation_time_step_s : [s] step of the projection (Nav2: 0.1).
    margin_m : [m] a laser hit this close to the projected footprint counts as a collision
        (Nav2 checks the costmap's footprint cost; here the footprint is inflated).
    """

    projection_time_s: float = 1.0
    simulation_time_step_s: float = 0.1
    margin_m: float = 0.05

    def __post_init__(self) -> None:
        if not 0 < self.simulation_time_step_s <= self.projection_time_s:
            raise ValueError(
                "mode 'collision_filter': need 0 < simulation_time_step_s <= "
                f"projection_time_s, got {self.simulation_time_step_s} and "
                f"{self.projection_time_s}"
            )
        if self.margin_m < 0:
            raise ValueError(f"mode 'collision_filter': margin_m must be >= 0, got {self.margin_m}")


def project(pose: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
    """The pose (x, y, yaw) (3,) after ``dt`` [s] at the robot-frame command ``u`` (3,):
    one Euler step, as Nav2's ``projectPose`` (with the lateral term rotated correctly:
    Nav2 subtracts ``v_y cos(yaw)`` from y)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array(
        [
            pose[0] + dt * (u[0] * c - u[1] * s),
            pose[1] + dt * (u[0] * s + u[1] * c),
            pose[2] + dt * u[2],
        ]
    )


class CollisionFilter:
    """The mode: ``v = scale * u``, ``scale`` = time to the first projected collision over
    the horizon (1 when none, 0 when the first step collides); ``beta = 1 - scale``."""

    name = "collision_filter"

    def __init__(self, settings: CollisionFilterSettings) -> None:
        self.settings = settings
        self.robot: RobotModel | None = None

    def reset(self, robot: RobotModel) -> None:
        self.robot = robot

    def collides(self, pose: np.ndarray, points: np.ndarray) -> bool:
        """Whether a laser hit (robot frame, (m, 2)) lies within the footprint, inflated
        by the margin, placed at ``pose`` (robot frame)."""
        if len(points) == 0:
            return False
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d = points - pose[:2]
        local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
        inside = (local @ self.robot.edge_normals.T - self.robot.edge_offsets).max(axis=1)
        return bool(np.any(inside <= self.settings.margin_m))

    def scale(self, u: np.ndarray, points: np.ndarray) -> tuple[float, np.ndarray]:
        """(the command's scale, the projected poses (k, 3) up to the first collision)."""
        st = self.settings
        pose, path = np.zeros(3), []
        steps = int(math.floor(st.projection_time_s / st.simulation_time_step_s + 1e-9))
        for k in range(1, steps + 1):
            pose = project(pose, u, st.simulation_time_step_s)
            path.append(pose)
            if self.collides(pose, points):
                t = k * st.simulation_time_step_s
                return (0.0 if k == 1 else t / st.projection_time_s), np.array(path)
        return 1.0, np.array(path) if path else EMPTY_PATH

    def step(self, obs: Any, u: np.ndarray) -> Assist:
        start = time.perf_counter()
        u = np.asarray(u, dtype=float).reshape(3)
        points = np.asarray(obs.points, dtype=float).reshape(-1, 2)
        scale, path = self.scale(u, points) if np.any(u != 0) else (1.0, EMPTY_PATH)
        v = scale * u
        return Assist(
            v=v,
            g=np.zeros(3),
            beta=1.0 - scale,
            label="",
            target="",
            scores={"scale": scale},
            predicted_path=path,
            timings_ms={"total": (time.perf_counter() - start) * 1e3},
        )

    def settings_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self.settings)


def make_collision_filter(**settings: Any) -> CollisionFilter:
    """The entry point: keyword settings of :class:`CollisionFilterSettings`."""
    allowed = [f.name for f in dataclasses.fields(CollisionFilterSettings)]
    unknown = sorted(set(settings) - set(allowed))
    if unknown:
        raise ValueError(
            f"mode 'collision_filter': unknown setting {unknown[0]!r}; allowed: "
            f"{', '.join(allowed)}"
        )
    return CollisionFilter(CollisionFilterSettings(**settings))
