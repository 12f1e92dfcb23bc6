"""The holonomic DWA, the safety layer and their shared footprint geometry (autonomy.dwa,
autonomy.safety): properties checked against an independent dense simulation of the
footprint (midpoint integration at 1 ms, point-in-polygon and point-to-segment
distances written here), for any seed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.dwa import DWASettings, dwa, dynamic_window, thin_points
from autonomy.safety import (
    arc_poses,
    footprint_clearance,
    safe_command,
    translation_distance,
)
from autonomy.types import RobotModel
from sim.testing import box_segments, cluttered_segments, synthetic_observation

ROBOT = RobotModel.rectangle(0.6, 0.5)


# ----------------------------------------------------------- independent reference


def dense_poses(v: np.ndarray, horizon: float, dt: float = 1e-3) -> np.ndarray:
    """Poses (n, 3) under a constant body twist, midpoint integration (not closed form)."""
    n = max(1, int(math.ceil(horizon / dt)))
    yaw_mid = v[2] * dt * (np.arange(n) + 0.5)
    step_x = dt * (np.cos(yaw_mid) * v[0] - np.sin(yaw_mid) * v[1])
    step_y = dt * (np.sin(yaw_mid) * v[0] + np.cos(yaw_mid) * v[1])
    x = np.concatenate(([0.0], np.cumsum(step_x)))
    y = np.concatenate(([0.0], np.cumsum(step_y)))
    return np.column_stack((x, y, v[2] * dt * np.arange(n + 1)))


def polygon_distance(q: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Signed Euclidean distance of points q (..., 2) to a convex CCW polygon:
    negative inside."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    e = b - a  # (k, 2)
    rel = q[..., None, :] - a  # (..., k, 2)
    t = np.clip(np.einsum("...kj,kj->...k", rel, e) / np.einsum("kj,kj->k", e, e), 0, 1)
    closest = a + t[..., None] * e
    dist = np.linalg.norm(q[..., None, :] - closest, axis=-1).min(axis=-1)
    cross = e[:, 0] * rel[..., 1] - e[:, 1] * rel[..., 0]
    inside = np.all(cross >= 0, axis=-1)
    return np.where(inside, -dist, dist)


def min_distance_along(v: np.ndarray, horizon: float, points: np.ndarray) -> float:
    """Smallest Euclidean distance [m] between the footprint and the points while the
    twist ``v`` is held for ``horizon`` seconds (negative: collision)."""
    poses = dense_poses(v, horizon)
    reach = np.hypot(v[0], v[1]) * horizon + 1.0
    pts = points[np.hypot(points[:, 0], points[:, 1]) <= reach]
    if len(pts) == 0:
        return math.inf
    best = math.inf
    for chunk in np.array_split(poses, max(1, len(poses) // 200)):
        c, s = np.cos(chunk[:, 2]), np.sin(chunk[:, 2])
        dx = pts[None, :, 0] - chunk[:, 0, None]
        dy = pts[None, :, 1] - chunk[:, 1, None]
        q = np.stack((c[:, None] * dx + s[:, None] * dy, -s[:, None] * dx + c[:, None] * dy), -1)
        best = min(best, float(polygon_distance(q, ROBOT.footprint).min()))
    return best


def random_scene(rng: np.random.Generator, min_clearance: float = 0.08) -> np.ndarray:
    segments = cluttered_segments(
        rng, ROBOT, n_boxes=int(rng.integers(4, 14)), room=(4.0, 3.5), min_clearance=min_clearance
    )
    return synthetic_observation(segments).points


def random_twist(rng: np.random.Generator) -> np.ndarray:
    speed, heading = rng.uniform(0, ROBOT.max_speed), rng.uniform(-math.pi, math.pi)
    yaw_rate = rng.uniform(-ROBOT.max_yaw_rate, ROBOT.max_yaw_rate) * rng.integers(0, 2)
    return np.array([speed * math.cos(heading), speed * math.sin(heading), yaw_rate])


# ---------------------------------------------------------------------- geometry


def test_footprint_clearance_matches_brute_force(rng):
    trapezoid = RobotModel(np.array([[-0.3, -0.25], [0.3, -0.15], [0.3, 0.15], [-0.3, 0.25]]))
    poses = rng.uniform(-1, 1, (40, 3))
    points = rng.uniform(-2, 2, (150, 2))
    for robot in (ROBOT, trapezoid):
        expected = []
        for x, y, yaw in poses:
            c, s = math.cos(yaw), math.sin(yaw)
            d = points - (x, y)
            q = np.column_stack((c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]))
            # half-plane distance from the edges' end points, not from the model's normals
            a = robot.footprint
            e = np.roll(a, -1, axis=0) - a
            n = np.column_stack((e[:, 1], -e[:, 0])) / np.linalg.norm(e, axis=1)[:, None]
            expected.append(np.einsum("mkj,kj->mk", q[:, None, :] - a, n).max(axis=1).min())
        got = footprint_clearance(poses, points, robot)
        np.testing.assert_allclose(got, expected, atol=1e-5)
        # the half-plane clearance never exceeds the Euclidean distance
        for (x, y, yaw), h in zip(poses, got, strict=True):
            c, s = math.cos(yaw), math.sin(yaw)
            d = points - (x, y)
            q = np.column_stack((c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]))
            assert h <= polygon_distance(q, robot.footprint).min() + 1e-5


@settings(max_examples=40, deadline=None)
@given(
    vx=st.floats(-1, 1), vy=st.floats(-1, 1), w=st.floats(-1.2, 1.2), horizon=st.floats(0.1, 2.0)
)
def test_arc_poses_match_integration(vx, vy, w, horizon):
    v = np.array([vx, vy, w])
    dense = dense_poses(v, horizon, dt=1e-4)
    t = 1e-4 * np.arange(len(dense))
    closed = arc_poses(v, t)[0]
    np.testing.assert_allclose(closed, dense, atol=1e-6)


def test_arc_poses_continuous_in_yaw_rate():
    t = np.linspace(0, 1.5, 16)
    straight = arc_poses(np.array([0.7, -0.2, 0.0]), t)
    almost = arc_poses(np.array([0.7, -0.2, 1e-9]), t)
    np.testing.assert_allclose(straight, almost, atol=1e-8)


def test_translation_distance_matches_stepping(rng):
    points = rng.uniform(-2.5, 2.5, (60, 2))
    points = points[polygon_distance(points, ROBOT.footprint) > 0]
    for _ in range(5):
        heading = rng.uniform(-math.pi, math.pi)
        direction = np.array([math.cos(heading), math.sin(heading)])
        got = translation_distance(points, direction, ROBOT)
        step = 1e-3
        shifts = step * np.arange(0, 5000)
        for p, d in zip(points, got, strict=True):
            inside = polygon_distance(p - shifts[:, None] * direction, ROBOT.footprint) <= 0
            expected = shifts[np.argmax(inside)] if inside.any() else math.inf
            if math.isinf(expected):
                assert math.isinf(d) or d > shifts[-1]
            else:
                assert abs(d - expected) <= 1.5 * step


def test_robot_model_validates_footprint():
    with pytest.raises(ValueError, match="counter-clockwise"):
        RobotModel(ROBOT.footprint[::-1].copy())
    with pytest.raises(ValueError, match="footprint"):
        RobotModel(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="max_speed"):
        RobotModel.rectangle(max_speed=0.0)
    assert ROBOT.inflated_radius(0.05) == pytest.approx(math.hypot(0.35, 0.30))


# ------------------------------------------------------------------------- DWA


def test_dwa_never_returns_a_colliding_twist(rng):
    moved = 0
    for _ in range(14):
        points = random_scene(rng)
        velocity = random_twist(rng)
        u = random_twist(rng)
        result = dwa(u, points, velocity, ROBOT)
        lo, hi = dynamic_window(velocity, ROBOT)
        if np.any(result.v != 0):
            moved += 1
            assert np.all(result.v >= lo - 1e-12) and np.all(result.v <= hi + 1e-12)
            assert result.horizon_s >= DWASettings().horizon_s - 1e-9
            # the protective field stays clear (up to the integration's tolerance)
            assert min_distance_along(result.v, result.horizon_s, points) >= (
                ROBOT.protective_margin - 2e-3
            )
    assert moved >= 7  # the check is not passed by standing still


@settings(max_examples=30, deadline=None)
@given(
    u=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1.2, 1.2)),
    v0=st.tuples(st.floats(-0.7, 0.7), st.floats(-0.7, 0.7), st.floats(-1.2, 1.2)),
)
def test_dwa_in_free_space_returns_u_limited_by_the_window(u, v0):
    u, v0 = np.array(u), np.array(v0)
    result = dwa(u, np.empty((0, 2)), v0, ROBOT)
    lo, hi = dynamic_window(v0, ROBOT)
    expected = np.clip(u, lo, hi)
    speed = math.hypot(expected[0], expected[1])
    if speed > ROBOT.max_speed:
        expected[:2] *= ROBOT.max_speed / speed
    np.testing.assert_allclose(result.v, expected, atol=1e-12)


def test_dwa_keeps_the_heading_in_a_corridor():
    # walls 0.15 m beside the robot; the user drives along the corridor
    walls = np.concatenate([box_segments((0, 0.45), (8, 0.1)), box_segments((0, -0.45), (8, 0.1))])
    points = synthetic_observation(walls).points
    u = np.array([0.6, 0.0, 0.0])
    result = dwa(u, points, np.array([0.5, 0.0, 0.0]), ROBOT)
    assert result.v[0] == pytest.approx(0.6)
    assert abs(result.v[1]) < 1e-9 and abs(result.v[2]) < 1e-9
    # drifting into a wall is refused; the command keeps the forward speed
    result = dwa(np.array([0.6, 0.3, 0.0]), points, np.array([0.5, 0.1, 0.0]), ROBOT)
    assert result.v[0] > 0.3
    assert min_distance_along(result.v, result.horizon_s, points) >= ROBOT.protective_margin - 2e-3


def test_dwa_stops_when_nothing_is_admissible():
    # a wall 2 cm in front of the robot moving towards it at full speed
    wall = box_segments((0.3 + 0.02 + 0.05, 0.0), (0.1, 4.0))
    points = synthetic_observation(wall).points
    result = dwa(np.array([1.0, 0, 0]), points, np.array([1.0, 0, 0]), ROBOT)
    assert np.all(result.v == 0) and result.n_checked == result.n_samples


def test_collision_checks_hold_between_checked_poses():
    # a thin pole 0.2 m ahead; with 1 s between checks the poses before and after
    # straddle it, so only the bound between poses can see it
    pole = np.array([[0.5, 0.0]])
    coarse = DWASettings(horizon_s=1.0, step_s=1.0)
    result = dwa(np.array([1.0, 0, 0]), pole, np.array([0.95, 0, 0]), ROBOT, settings=coarse)
    assert min_distance_along(result.v, result.horizon_s, pole) >= ROBOT.protective_margin - 2e-3
    v_safe, scale = safe_command(np.array([1.0, 0, 0]), pole, ROBOT, step_m=0.8)
    assert scale < 1
    assert min_distance_along(v_safe, 1.0, pole) >= ROBOT.protective_margin - 2e-3


def test_thin_points_keeps_one_point_per_cell(rng):
    points = rng.uniform(-1, 1, (500, 2))
    thin = thin_points(points, 0.1)
    keys = np.floor(thin / 0.1)
    assert len(np.unique(keys, axis=0)) == len(thin)
    assert len(np.unique(np.floor(points / 0.1), axis=0)) == len(thin)
    d = np.linalg.norm(points[:, None] - thin[None], axis=2).min(axis=1)
    assert d.max() <= 0.1 * math.sqrt(2)


# ---------------------------------------------------------------------- safety


def test_safety_output_never_collides_within_its_horizon(rng):
    scaled = 0
    for _ in range(25):
        points = random_scene(rng, min_clearance=0.07)
        v = random_twist(rng)
        v_safe, scale = safe_command(v, points, ROBOT, horizon_s=1.0)
        assert 0.0 <= scale <= 1.0
        np.testing.assert_allclose(v_safe, scale * v)
        brake = max(
            math.hypot(v_safe[0], v_safe[1]) / (2 * ROBOT.max_accel),
            abs(v_safe[2]) / (2 * ROBOT.max_yaw_accel),
        )
        horizon = max(1.0, ROBOT.dt + brake)
        assert min_distance_along(v_safe, horizon, points) >= ROBOT.protective_margin - 2e-3
        scaled += scale < 1
    assert scaled >= 3  # the scenes do make the layer act


def test_safety_scales_a_straight_approach_to_the_free_distance():
    # wall face 0.30 m ahead of the footprint; 0.25 m may be driven within the horizon
    wall = box_segments((0.3 + 0.30 + 0.05, 0.0), (0.1, 4.0))
    points = synthetic_observation(wall).points
    v_safe, scale = safe_command(np.array([0.5, 0.0, 0.0]), points, ROBOT, horizon_s=1.0)
    # s * 0.5 m/s * 1 s = 0.25 m, less at most one check step of 0.02 m
    assert 0.46 <= scale <= 0.5 + 1e-9
    assert v_safe[0] == pytest.approx(0.5 * scale)


def test_safety_checks_rotation_in_place():
    # a wall 3 cm beside the robot's left side: turning swings a corner into it
    wall = box_segments((0.0, 0.25 + 0.03 + 0.05), (4.0, 0.1))
    points = synthetic_observation(wall).points
    v = np.array([0.0, 0.0, 1.0])
    v_safe, scale = safe_command(v, points, ROBOT, horizon_s=1.0)
    assert scale < 0.2
    assert min_distance_along(v_safe, 1.0, points) >= 0.0
    far = box_segments((0.0, 0.25 + 0.5 + 0.05), (4.0, 0.1))
    _, scale_far = safe_command(v, synthetic_observation(far).points, ROBOT, horizon_s=1.0)
    assert scale_far == 1.0


def test_safety_leaves_a_command_away_from_obstacles_unchanged(rng):
    wall = box_segments((0.3 + 0.1 + 0.05, 0.0), (0.1, 4.0))  # close ahead, nothing behind
    points = synthetic_observation(wall).points
    for _ in range(10):
        heading = rng.uniform(0.6 * math.pi, 1.4 * math.pi)
        v = rng.uniform(0.1, 1.0) * np.array([math.cos(heading), math.sin(heading), 0.0])
        v_safe, scale = safe_command(v, points, ROBOT)
        assert scale == 1.0 and np.array_equal(v_safe, v)
    assert safe_command(np.zeros(3), points, ROBOT)[1] == 1.0


def test_safety_lets_a_robot_inside_its_protective_field_back_away():
    wall = box_segments((0.3 + 0.03 + 0.05, 0.0), (0.1, 4.0))  # 3 cm: inside the 5 cm field
    points = synthetic_observation(wall).points
    assert footprint_clearance(np.zeros((1, 3)), points, ROBOT)[0] < ROBOT.protective_margin
    assert safe_command(np.array([-0.4, 0.0, 0.0]), points, ROBOT)[1] == 1.0
    assert safe_command(np.array([0.4, 0.0, 0.0]), points, ROBOT)[1] == 0.0
