"""The robot's laser beams: directions, per-beam constants, and fans cast together."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.scenario import LaserSpec, Scenario
from sim.sensors import CrossSection, cross_section


@dataclass(frozen=True, slots=True)
class Beams:
    """One laser's beam directions, precomputed once."""

    angles: np.ndarray  # (n,) [rad] beam directions in the robot frame, read-only
    origin: np.ndarray  # (2,) [m] mount position in the robot frame, read-only
    step: float  # [rad] between beams


@dataclass(frozen=True, slots=True)
class Fans:
    """Lasers with the same height, beam layout and range: cast in one pass."""

    members: tuple[int, ...]  # indices into robot.lasers
    positions: np.ndarray  # (m, 2) [m] mounts in the robot frame
    firsts: np.ndarray  # (m,) [rad] robot-frame direction of each one's beam 0
    step: float  # [rad] between beams
    n: int  # beams per laser
    height: float  # [m] above the floor
    max_range: float  # [m]
    section: CrossSection  # the scene at this height


@dataclass(frozen=True, slots=True)
class Rays:
    """Every beam of every laser, concatenated in laser order: per-beam constants."""

    start: tuple[int, ...]  # where each laser's beams begin; last entry = number of beams
    x0: np.ndarray  # (n,) [m] mount x in the robot frame
    y0: np.ndarray  # (n,) [m] mount y in the robot frame
    cos: np.ndarray  # (n,) cos of the beam direction in the robot frame
    sin: np.ndarray  # (n,) sin of the beam direction in the robot frame
    sigma: np.ndarray  # (n,) [m] range noise
    min_range: np.ndarray  # (n,) [m]
    max_range: np.ndarray  # (n,) [m]


def laser_rays(lasers: tuple[LaserSpec, ...], beams: tuple[Beams, ...]) -> Rays:
    """Every beam of every laser in laser order, with its per-beam constants."""
    counts = [len(b.angles) for b in beams]

    def per_beam(values: list[float]) -> np.ndarray:
        return np.repeat(np.array(values, dtype=float), counts)

    return Rays(
        start=tuple(np.concatenate(([0], np.cumsum(counts))).tolist()),
        x0=per_beam([spec.position[0] for spec in lasers]),
        y0=per_beam([spec.position[1] for spec in lasers]),
        cos=np.cos(np.concatenate([b.angles for b in beams])),
        sin=np.sin(np.concatenate([b.angles for b in beams])),
        sigma=per_beam([spec.sigma for spec in lasers]),
        min_range=per_beam([spec.min_range for spec in lasers]),
        max_range=per_beam([spec.max_range for spec in lasers]),
    )


def laser_beams(spec: LaserSpec) -> Beams:
    """Beams evenly spread over the field of view, centred on the mount's heading."""
    n = spec.n_beams
    step = spec.fov / (n - 1) if n > 1 else spec.resolution
    angles = spec.yaw + (step * np.arange(n) - spec.fov / 2 if n > 1 else np.zeros(1))
    origin = np.array(spec.position, dtype=float)
    angles.flags.writeable = origin.flags.writeable = False
    return Beams(angles, origin, step)


def laser_fans(scenario: Scenario, beams: tuple[Beams, ...]) -> tuple[Fans, ...]:
    """The robot's lasers grouped into fans cast in one pass (same height, beam layout
    and range), each with the scene's cross-section at its height."""
    lasers = scenario.robot.lasers
    groups: dict[tuple, list[int]] = {}
    for i, (spec, one) in enumerate(zip(lasers, beams, strict=True)):
        key = (spec.height, one.step, len(one.angles), spec.max_range)
        groups.setdefault(key, []).append(i)
    sections: dict[float, CrossSection] = {}
    fans = []
    for (height, step, n, max_range), members in groups.items():
        if height not in sections:
            sections[height] = cross_section(scenario, height)
        fans.append(
            Fans(
                members=tuple(members),
                positions=np.array([lasers[i].position for i in members], dtype=float),
                firsts=np.array([beams[i].angles[0] for i in members], dtype=float),
                step=step,
                n=n,
                height=height,
                max_range=max_range,
                section=sections[height],
            )
        )
    return tuple(fans)
