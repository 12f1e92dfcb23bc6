"""The reactive mode's exclusive arbitration (autonomy.reactive_bn, setting
``arbitration = "exclusive"``, thesis Sec. 3.2.1.1): the MAP situation's action alone
keeps the footprint ``d_safe`` from the laser points along its direction, where the blend
of eq. (3.2) crept into walls. Closed loops here are kinematic (the command integrated
exactly over each tick, the room re-seen by sim.testing's scanners), without pybullet."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import autonomy.reactive_bn as reactive_bn
from autonomy.dwa import DWAResult, DWASettings
from autonomy.reactive_bn import ReactiveBNMode, ReactiveSettings, hold_creep
from autonomy.safety import arc_poses, footprint_clearance, translation_distance
from autonomy.types import RobotModel
from sim.testing import box_segments, cluttered_segments, synthetic_observation

ROBOT = RobotModel.rectangle(0.6, 0.5)
D_SAFE = ReactiveSettings().d_safe


def mode(arbitration: str = "exclusive") -> ReactiveBNMode:
    m = ReactiveBNMode(ReactiveSettings(arbitration=arbitration))
    m.reset(ROBOT)
    return m


def distance_along(points: np.ndarray, v: np.ndarray) -> float:
    """[m] how far the footprint translates along ``v``'s direction before touching."""
    direction = v[:2] / math.hypot(v[0], v[1])  # hypot: no underflow for tiny v
    return float(np.min(translation_distance(points, direction, ROBOT), initial=math.inf))


@settings(max_examples=60, deadline=None)
@given(
    scene=st.integers(0, 2**32 - 1),
    heading=st.floats(-math.pi, math.pi),
    speed=st.floats(0.0, 1.0),
    omega=st.floats(-1.2, 1.2),
)
def test_exclusive_command_never_brings_the_footprint_within_d_safe(scene, heading, speed, omega):
    """Any cluttered room (some with obstacles already inside d_safe), any velocity and
    input: the command, held for one tick along its own direction, leaves the footprint at
    least ``min(d_safe, d_0)`` from the points along that direction (``d_0`` before)."""
    rng = np.random.default_rng(scene)
    segments = cluttered_segments(
        rng,
        ROBOT,
        n_boxes=int(rng.integers(0, 14)),
        room=(5.0, 4.0),
        min_clearance=float(rng.uniform(0.0, 0.4)),
    )
    velocity = np.array([rng.uniform(-0.5, 0.8), rng.uniform(-0.5, 0.5), rng.uniform(-1, 1)])
    obs = synthetic_observation(segments, velocity=velocity, rng=rng)
    u = np.array([speed * math.cos(heading), speed * math.sin(heading), omega])
    v = mode().step(obs, u).v
    step = math.hypot(v[0], v[1]) * ROBOT.dt  # [m] translation over the tick
    if step == 0.0:
        return
    d0 = distance_along(obs.points, v)
    assert d0 - step >= min(D_SAFE, d0) - 1e-9


def to_robot(segments: np.ndarray, pose: np.ndarray) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rel = segments - pose[:2]
    return np.stack((c * rel[..., 0] + s * rel[..., 1], -s * rel[..., 0] + c * rel[..., 1]), -1)


def drive(
    arbitration: str,
    segments: np.ndarray,
    u: np.ndarray,
    ticks: int,
    *,
    m: ReactiveBNMode | None = None,
    path: list | None = None,
) -> np.ndarray:
    """Clearances (ticks + 1,) [m] of the footprint while the mode (``m``, or a fresh
    one with ``arbitration``) is driven from rest at the origin with ``u``; the poses
    (x [m], y [m], yaw [rad]) are appended to ``path`` when given."""
    m = m if m is not None else mode(arbitration)
    pose, velocity = np.zeros(3), np.zeros(3)
    clearance = []
    for _ in range(ticks + 1):
        obs = synthetic_observation(to_robot(segments, pose), velocity=velocity)
        clearance.append(float(footprint_clearance(np.zeros((1, 3)), obs.points, ROBOT)[0]))
        if path is not None:
            path.append(pose.copy())
        velocity = m.step(obs, u).v
        dx, dy, dyaw = arc_poses(velocity, np.array([ROBOT.dt]))[0, 0]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        pose = pose + np.array([c * dx - s * dy, s * dx + c * dy, dyaw])
    return np.array(clearance)


def doorway(ahead: float, width: float, offset: float) -> np.ndarray:
    """A wall across x with a doorway ``width`` [m] centred at y = ``offset``, its near
    face ``ahead`` [m] in front of the footprint, walls along the room's sides."""
    x = 0.3 + ahead + 0.05
    y0, y1 = offset - width / 2, offset + width / 2
    return np.concatenate(
        [
            box_segments((x, y1 + 2.0), (0.1, 4.0)),
            box_segments((x, y0 - 2.0), (0.1, 4.0)),
            box_segments((0.0, 2.5), (8.0, 0.1)),  # the room's side walls
            box_segments((0.0, -2.5), (8.0, 0.1)),
        ]
    )


@settings(max_examples=12, deadline=None)
@given(
    ahead=st.floats(0.15, 0.6),
    width=st.floats(0.72, 0.95),
    offset=st.floats(-0.06, 0.06),
    speed=st.floats(0.3, 0.8),
)
def test_from_rest_before_a_narrow_doorway_the_exclusive_mode_drives_through(
    ahead, width, offset, speed
):
    """A doorway 0.72-0.95 m wide for the 0.5 m robot (11-22 cm each side, beyond the
    protective field), the robot at rest in front of it, the stick straight ahead: the
    GOA action (the DWA) takes it through, clear of the frame. Before the DWA's clearance
    term was weighted by progress it kept the standstill for good (issue 18, P13)."""
    walls = doorway(ahead, width, offset)
    u = np.array([speed, 0.0, 0.0])
    beyond = 0.3 + ahead + 0.1 + 0.3  # [m] the whole footprint past the wall
    path: list = []
    ticks = math.ceil(beyond / (speed * ROBOT.dt)) + 40  # at u's speed, plus 2 s
    clearance = drive("exclusive", walls, u, ticks=ticks, path=path)
    assert clearance.min() >= ROBOT.protective_margin - 0.01  # DWA's tolerance inside it
    assert path[-1][0] > beyond


def test_the_unweighted_clearance_term_keeps_the_standstill_before_a_doorway():
    """The trap the progress weighting removes (why the test above can fail)."""
    old = ReactiveBNMode(ReactiveSettings(dwa=DWASettings(clearance_by_progress=False)))
    old.reset(ROBOT)
    path: list = []
    drive("exclusive", doorway(0.3, 0.75, 0.0), np.array([0.4, 0.0, 0.0]), 40, m=old, path=path)
    assert abs(path[-1][0]) < 0.05  # [m] never got going


def test_straight_at_a_wall_stops_short_of_d_safe_instead_of_creeping():
    wall = box_segments((0.3 + 1.0 + 0.05, 0.0), (0.1, 8.0))  # 1 m ahead of the footprint
    u = np.array([1.0, 0.0, 0.0])
    exclusive = drive("exclusive", wall, u, ticks=150)
    assert exclusive.min() >= D_SAFE
    assert exclusive[-1] - exclusive[-21] < 0.01  # stopped: < 1 cm in the last second
    blended = drive("blend", wall, u, ticks=150)
    assert blended.min() < D_SAFE  # (1 - beta) u kept creeping (issue 18)


@pytest.mark.parametrize("angle_deg", [30.0, 50.0, 70.0])
def test_oblique_push_into_a_wall_inside_d_safe_does_not_approach(angle_deg):
    side = box_segments((0.0, 0.25 + 0.1 + 0.05), (8.0, 0.1))  # 0.1 m to the left
    a = math.radians(angle_deg)
    u = np.array([0.6 * math.cos(a), 0.6 * math.sin(a), 0.0])
    obs = synthetic_observation(side)
    out = mode().step(obs, u)
    assert out.label == "OA"
    d0 = distance_along(obs.points, u)  # 0.1 m / sin(angle)
    if d0 <= D_SAFE:  # steep: stopped
        np.testing.assert_array_equal(out.v, np.zeros(3))
    else:  # shallow: alpha u, and along it the footprint stays beyond d_safe (3.7)
        assert d0 - math.hypot(out.v[0], out.v[1]) * ROBOT.dt >= D_SAFE
        assert out.v[1] * ROBOT.dt < 1e-6  # [m] towards the wall: nothing measurable


def test_oblique_push_towards_a_wall_keeps_clear_where_the_blend_touched():
    side = box_segments((0.0, 0.25 + 0.3 + 0.05), (8.0, 0.1))  # 0.3 m to the left
    a = math.radians(50.0)
    u = np.array([0.6 * math.cos(a), 0.6 * math.sin(a), 0.0])
    exclusive = drive("exclusive", side, u, ticks=150)
    assert exclusive.min() >= ROBOT.protective_margin
    assert drive("blend", side, u, ticks=150).min() < 0.01  # crept to the wall (issue 18)


def test_a_blocked_dwa_stops_the_robot(monkeypatch):
    y = 0.25 + 0.15 + 0.05
    corridor = np.concatenate([box_segments((0, y), (8, 0.1)), box_segments((0, -y), (8, 0.1))])
    obs = synthetic_observation(corridor, velocity=np.array([0.4, 0.0, 0.0]))
    u = np.array([0.6, 0.0, 0.0])
    blocked = DWAResult(np.zeros(3), np.zeros((1, 3)), 0.0, -math.inf, 78, 78)
    monkeypatch.setattr(reactive_bn, "dwa", lambda *args, **kwargs: blocked)
    out = mode().step(obs, u)
    assert out.label == "GOA" and out.beta == 1.0
    np.testing.assert_array_equal(out.v, np.zeros(3))
    old = mode("blend").step(obs, u)
    assert old.label == "GOA" and old.v[0] == pytest.approx((1 - old.beta) * u[0])


def test_a_creeping_pure_rotation_keeps_its_rotation_but_not_its_creep():
    points = synthetic_observation(box_segments((0.3 + 0.1 + 0.05, 0.0), (0.1, 8.0))).points
    creep = np.array([0.015, 0.0, 0.8])  # below min_translation: taken for a rotation
    np.testing.assert_array_equal(hold_creep(creep, points, ROBOT, D_SAFE), [0.0, 0.0, 0.8])
    np.testing.assert_array_equal(hold_creep(-creep, points, ROBOT, D_SAFE), -creep)  # away
    out = mode().step(synthetic_observation(box_segments((2.0, 0.0), (0.1, 8.0))), creep)
    assert out.label == "FT" and out.beta == 0.0  # far from the wall: u as given
    np.testing.assert_array_equal(out.v, creep)


def test_object_approach_keeps_the_turn_and_stops_the_approach():
    """Backing towards a wall 0.3 m behind while turning (generated scene 17's trap): OA
    stops the translation (alpha < 0.01) and keeps the turn; the blend scales both."""
    wall = box_segments((-(0.3 + 0.3 + 0.05), 0.0), (0.1, 8.0))  # 0.3 m behind
    obs = synthetic_observation(wall)
    u = np.array([-0.2, 0.0, -1.0])
    out = mode().step(obs, u)
    assert out.label == "OA"
    assert math.hypot(out.v[0], out.v[1]) * ROBOT.dt < 1e-4  # [m] per tick: stopped
    assert out.v[2] == pytest.approx(u[2])  # the corners stay clear: the turn as given
    blended = mode("blend").step(obs, u)
    assert abs(blended.v[2]) < abs(u[2])


def test_object_approach_slows_a_turn_whose_corners_would_hit():
    """A box just beside the front corner: the turn that sweeps the corner into it is
    slowed (kept out of the protective field), the opposite turn is not."""
    post = box_segments((0.3 + 0.03 + 0.05, 0.25 + 0.05 + 0.05), (0.1, 0.1))
    wall = box_segments((0.3 + 0.25 + 0.05, 0.0), (0.1, 8.0))  # ahead: the approach is OA
    obs = synthetic_observation(np.concatenate([post, wall]))
    u_into = np.array([0.2, 0.0, 1.2])  # counter-clockwise: the front-left corner swings left
    into = mode().step(obs, u_into)
    assert into.label == "OA"
    assert abs(into.v[2]) < 1.2
    away = mode().step(obs, np.array([0.2, 0.0, -1.2]))
    assert away.label == "OA" and away.v[2] == pytest.approx(-1.2)
