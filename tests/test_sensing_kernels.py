"""The compiled laser model (sim._kernels) against the numpy code it replaced
(tests/geometry_reference.py): bit-identical ranges, noisy scans and hit points on many
seeded random scenes, fans and poses, and along a drive through a shipped scenario."""

from __future__ import annotations

import copy
import math
import sys
from pathlib import Path

import numpy as np

from sim._kernels import scan_kernel
from sim.scenario import load_scenario, parse_scenario
from sim.sensors import CrossSection, cast, cast_from, cross_section
from sim.types import Pose2D
from sim.world import World

sys.path.insert(0, str(Path(__file__).parent))
from geometry_reference import ref_cast, ref_scan  # noqa: E402


def random_section(rng: np.random.Generator) -> CrossSection:
    """Random boxes (some overlapping, some tiny) and circles in a 10 m square, cut at
    0.2 m; sometimes none of one kind."""
    boxes = [
        {
            "name": f"b{i}",
            "centre": rng.uniform(0, 10, 2).tolist(),
            "size": rng.uniform(0.01, 3.0, 2).tolist(),
            "yaw_deg": float(rng.uniform(-180, 180)),
        }
        for i in range(int(rng.integers(0, 12)))
    ]
    cylinders = [
        {"name": f"c{i}", "centre": rng.uniform(0, 10, 2).tolist(), "radius": rng.uniform(0.01, 1)}
        for i in range(int(rng.integers(0, 5)))
    ]
    if not (boxes or cylinders):  # an empty plane
        no_edges, no_circles = np.empty((0, 2)), np.empty((0, 2))
        return CrossSection(0.2, no_edges, no_edges, no_edges, no_circles, np.empty(0))
    scenario = parse_scenario(
        {
            "name": "random",
            "bounds": [[-20.0, -20.0], [30.0, 30.0]],
            "start": {"x": -10.0, "y": -10.0},
            "boxes": boxes,
            "cylinders": cylinders,
        },
        "random",
    )
    return cross_section(scenario, 0.2)


def random_fans(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float, int, float]:
    """Origins (m, 2), first angles (m,), step, n and max_range of random fans: from a
    few beams to full circles (whose last beam meets the first), any first angle."""
    m = int(rng.integers(1, 4))
    origins = rng.uniform(-1, 11, (m, 2))
    firsts = rng.uniform(-10, 10, m)
    n = int(rng.integers(1, 800))
    full = rng.random() < 0.3
    step = 2 * math.pi / max(n - 1, 1) if full else float(rng.uniform(1e-3, 2 * math.pi / n))
    max_range = float(rng.choice([0.5, 3.0, 30.0]))
    return origins, firsts, step, n, max_range


def test_cast_is_the_numpy_cast(rng: np.random.Generator) -> None:
    for _ in range(300):
        section = random_section(rng)
        origins, firsts, step, n, max_range = random_fans(rng)
        got = cast(section, origins, firsts, step, n, max_range)
        want = ref_cast(section, origins, firsts, step, n, max_range)
        assert np.array_equal(got, want)


def test_cast_from_a_pose_is_cast_from_the_map_frame_origins(rng: np.random.Generator) -> None:
    for _ in range(100):
        section = random_section(rng)
        positions, firsts, step, n, max_range = random_fans(rng)
        positions = positions / 20.0  # mounts near the robot's centre
        pose = Pose2D(*rng.uniform(0, 10, 2), float(rng.uniform(-4, 4)))
        got = cast_from(section, pose, positions, firsts, step, n, max_range)
        want = ref_cast(
            section, pose.to_map_frame(positions), pose.yaw + firsts, step, n, max_range
        )
        assert np.array_equal(got, want)


def test_scan_and_points_are_the_numpy_ones(rng: np.random.Generator) -> None:
    scenario = load_scenario("cluttered_room")
    with World(scenario, seed=int(rng.integers(1 << 31)), components=()) as world:
        rays = world._rays
        for tick in range(200):
            world.apply(np.array([0.6, 0.3 * math.sin(tick / 9), 0.9 * math.cos(tick / 13)]))
            world.step()
            pose = world.true_pose()
            before = copy.deepcopy(world._rng)  # the same draws as sense() makes
            obs = world.sense()
            z = before.standard_normal(8 + rays.start[-1])[8:]
            true = np.empty(rays.start[-1])
            for fan in world._fans:
                ranges = ref_cast(
                    fan.section,
                    pose.to_map_frame(fan.positions),
                    pose.yaw + fan.firsts,
                    fan.step,
                    fan.n,
                    fan.max_range,
                )
                for i, r in zip(fan.members, ranges, strict=True):
                    true[rays.start[i] : rays.start[i + 1]] = r
            want_ranges, want_points = ref_scan(true, z, rays)
            assert np.array_equal(np.concatenate([s.ranges for s in obs.scans]), want_ranges)
            assert np.array_equal(obs.points, want_points)
            assert world._rng.bit_generator.state == before.bit_generator.state


def test_scan_of_random_ranges_with_misses_and_clipping(rng: np.random.Generator) -> None:
    scenario = load_scenario("cluttered_room")
    with World(scenario, seed=0, components=()) as world:
        rays = world._rays
        n = rays.start[-1]
        for _ in range(200):
            true = np.where(rng.random(n) < 0.3, rays.max_range, rng.uniform(0, 12, n))
            z = rng.standard_normal(n) * rng.choice([1.0, 50.0])  # large: clipped at both ends
            got = scan_kernel(
                true, z, rays.sigma, rays.min_range, rays.max_range, rays.cos, rays.sin,
                rays.x0, rays.y0,
            )  # fmt: skip
            want = ref_scan(true, z, rays)
            assert np.array_equal(got[0], want[0])
            assert np.array_equal(got[1], want[1])
