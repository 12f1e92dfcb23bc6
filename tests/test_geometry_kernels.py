"""The compiled footprint geometry (autonomy._geometry_kernels, tasks._geometry_kernels)
against the numpy code it replaced (tests/geometry_reference.py): bit-identical arc
poses, float32 clearances, safe commands, DWA results and the trial's clearance figures,
on many seeded random inputs and on laser points seen along a drive through a shipped
scenario."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from autonomy.dwa import DWASettings, dwa
from autonomy.safety import arc_poses, footprint_clearance, safe_command
from autonomy.types import RobotModel
from sim.scenario import load_scenario
from sim.testing import cluttered_segments, synthetic_observation
from sim.world import World
from tasks.clearance import lrf_range
from tasks.geometry import footprint_clearance as task_footprint_clearance

sys.path.insert(0, str(Path(__file__).parent))
from geometry_reference import (  # noqa: E402
    ref_arc_poses,
    ref_dwa,
    ref_footprint_clearance,
    ref_lrf_range,
    ref_safe_command,
    ref_task_footprint_clearance,
)

RECTANGLE = RobotModel.rectangle(0.6, 0.5)
# one-sided lines (no parallel pairs): the footprint's NaN half widths
HEXAGON = RobotModel(
    np.array([[0.35, 0.0], [0.2, 0.25], [-0.2, 0.25], [-0.35, 0.0], [-0.2, -0.25], [0.2, -0.25]])
)
TRAPEZOID = RobotModel(np.array([[-0.3, -0.25], [0.3, -0.15], [0.3, 0.15], [-0.3, 0.25]]))
ROBOTS = (RECTANGLE, HEXAGON, TRAPEZOID)


def random_twists(rng: np.random.Generator, n: int) -> np.ndarray:
    """Twists (n, 3) with some zero, tiny and large yaw rates and some zero speeds."""
    v = rng.uniform(-1.2, 1.2, (n, 3))
    v[rng.random(n) < 0.2, 2] = 0.0
    v[rng.random(n) < 0.1, 2] *= 1e-12
    v[rng.random(n) < 0.1, :2] = 0.0
    return v


def room_points(rng: np.random.Generator, robot: RobotModel) -> np.ndarray:
    """Laser points (m, 2) [m] of a random cluttered room around a robot at the origin."""
    segments = cluttered_segments(
        rng, robot, n_boxes=int(rng.integers(2, 14)), room=(4.0, 3.5), min_clearance=0.0
    )
    return synthetic_observation(segments, rng=rng).points


def drive_points(rng: np.random.Generator, ticks: int) -> list[np.ndarray]:
    """The laser points of each tick of a drive through the shipped cluttered room."""
    out = []
    with World(load_scenario("cluttered_room"), seed=int(rng.integers(1 << 31))) as world:
        for tick in range(ticks):
            world.apply(np.array([0.7, 0.3 * math.sin(tick / 7), 1.0 * math.cos(tick / 11)]))
            world.step()
            out.append(world.sense().points)
    return out


def test_arc_poses_are_the_numpy_ones(rng: np.random.Generator) -> None:
    for _ in range(200):
        v = random_twists(rng, int(rng.integers(1, 30)))
        t = np.concatenate(([0.0], rng.uniform(0, 3, int(rng.integers(0, 20)))))
        assert np.array_equal(arc_poses(v, t), ref_arc_poses(v, t))
    assert np.array_equal(arc_poses(v[0], t), ref_arc_poses(v[0], t))  # one twist, (3,)


@pytest.mark.parametrize("robot", ROBOTS, ids=("rectangle", "hexagon", "trapezoid"))
def test_footprint_clearance_is_the_numpy_float32_one(rng, robot) -> None:
    for _ in range(200):
        n_poses = int(rng.integers(1, 60))
        poses = np.column_stack((rng.uniform(-2, 2, (n_poses, 2)), rng.uniform(-7, 7, n_poses)))
        points = rng.uniform(-3, 3, (int(rng.integers(0, 300)), 2))
        got = footprint_clearance(poses, points, robot)
        assert np.array_equal(got, ref_footprint_clearance(poses, points, robot))
    points[0] = np.nan  # NaN propagates as numpy's maximum and min do
    got = footprint_clearance(poses, points, robot)
    assert np.array_equal(got, ref_footprint_clearance(poses, points, robot), equal_nan=True)


@pytest.mark.parametrize("robot", ROBOTS, ids=("rectangle", "hexagon", "trapezoid"))
def test_safe_command_is_the_numpy_one(rng, robot) -> None:
    for _ in range(150):
        points = room_points(rng, robot)
        kwargs = {"horizon_s": float(rng.choice([0.5, 1.0, 2.0]))}
        if rng.random() < 0.3:
            kwargs |= {"step_m": 0.05, "tolerance_m": 0.03, "max_steps": 7}
        for v in random_twists(rng, 4):
            got_v, got_s = safe_command(v, points, robot, **kwargs)
            want_v, want_s = ref_safe_command(v, points, robot, **kwargs)
            assert np.array_equal(got_v, want_v) and got_s == want_s


def test_safe_command_with_non_finite_commands_is_the_numpy_one(rng) -> None:
    points = room_points(rng, RECTANGLE)
    for v in ([np.nan, 0.0, 0.0], [0.0, 0.0, np.nan], [np.inf, 0.0, 0.0], [0.0, 0.0, -np.inf]):
        with np.errstate(invalid="ignore"):  # inf * 0 in both
            try:
                want = ref_safe_command(np.array(v), points, RECTANGLE)
            except (ValueError, OverflowError) as error:
                with pytest.raises(type(error)):
                    safe_command(np.array(v), points, RECTANGLE)
                continue
            got = safe_command(np.array(v), points, RECTANGLE)
        assert np.array_equal(got[0], want[0], equal_nan=True)
        assert got[1] == want[1] or (math.isnan(got[1]) and math.isnan(want[1]))


def same_dwa(got, want) -> bool:
    fields = ("v", "path", "horizon_s", "clearance", "n_checked", "n_samples")
    return all(np.array_equal(getattr(got, f), getattr(want, f)) for f in fields)


@pytest.mark.parametrize("robot", ROBOTS, ids=("rectangle", "hexagon", "trapezoid"))
def test_dwa_is_the_numpy_one(rng, robot) -> None:
    for _ in range(60):
        points = room_points(rng, robot)
        settings = DWASettings(clearance_by_progress=bool(rng.random() < 0.7))
        for u, velocity in zip(random_twists(rng, 3), random_twists(rng, 3), strict=True):
            got = dwa(u, points, velocity, robot, settings=settings)
            assert same_dwa(got, ref_dwa(u, points, velocity, robot, settings=settings))
    # nothing admissible (the robot inside a ring of points), and no points at all
    ring = 0.2 * np.column_stack((np.cos(np.arange(60)), np.sin(np.arange(60))))
    for points in (ring, np.empty((0, 2))):
        got = dwa(u, points, velocity, robot)
        assert same_dwa(got, ref_dwa(u, points, velocity, robot))


def test_safety_and_dwa_on_a_drive_are_the_numpy_ones(rng: np.random.Generator) -> None:
    robot = RobotModel.from_spec(load_scenario("cluttered_room").robot)
    for points in drive_points(rng, 60):
        v, u = random_twists(rng, 2)
        assert np.array_equal(
            safe_command(v, points, robot)[0], ref_safe_command(v, points, robot)[0]
        )
        assert same_dwa(dwa(u, points, v, robot), ref_dwa(u, points, v, robot))
        assert task_footprint_clearance(points, robot.footprint) == (
            ref_task_footprint_clearance(points, robot.footprint)
        )
        assert lrf_range(points) == ref_lrf_range(points)


def test_trial_clearance_figures_are_the_numpy_ones(rng: np.random.Generator) -> None:
    footprints = [RECTANGLE.footprint, RECTANGLE.footprint[::-1], HEXAGON.footprint]
    footprints.append(np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.0], [0.0, 0.4]]))  # degenerate
    for _ in range(300):
        points = rng.uniform(-2, 2, (int(rng.integers(0, 400)), 2))
        for footprint in footprints:
            got = task_footprint_clearance(points, footprint)
            assert got == ref_task_footprint_clearance(points, footprint)
        assert lrf_range(points) == ref_lrf_range(points)
    points[0, 1] = np.inf
    for footprint in footprints:
        with pytest.raises(ValueError, match="finite"):
            task_footprint_clearance(points, footprint)
