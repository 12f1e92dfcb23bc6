"""The pybullet world: robot motion and limits, collisions and their episodes,
determinism, several worlds in one process."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.scenario import Scenario, parse_scenario
from sim.types import Pose2D
from sim.world import World, WorldSettings, clip_command

DT = WorldSettings().dt


def _room(size: float = 8.0) -> list[dict]:
    s = size
    return [
        {"name": "south", "from": [0, 0], "to": [s, 0]},
        {"name": "east", "from": [s, 0], "to": [s, s]},
        {"name": "north", "from": [s, s], "to": [0, s]},
        {"name": "west", "from": [0, s], "to": [0, 0]},
    ]


def open_room(size: float = 12.0) -> Scenario:
    """A closed empty square room, robot in the middle."""
    return parse_scenario(
        {"name": "open", "start": {"x": size / 2, "y": size / 2}, "walls": _room(size)}, "open"
    )


def wall_scene() -> Scenario:
    """One long wall whose west face is at x = 3.95; the robot at (2, 0) faces it."""
    return parse_scenario(
        {
            "name": "wall",
            "start": {"x": 2.0, "y": 0.0},
            "walls": [{"name": "east", "from": [4.0, -10.0], "to": [4.0, 10.0]}],
            "tables": [{"name": "table", "centre": [2.0, 5.0], "size": [1.2, 0.9]}],
        },
        "wall",
    )


def cluttered_scene(rng: np.random.Generator, size: float = 6.0) -> Scenario:
    """A closed room with random boxes, cylinders and a table, none within 1 m of the
    start in its centre."""
    start = np.array([size / 2, size / 2])
    boxes, cylinders = [], []
    while len(boxes) < 7:
        c = rng.uniform(0.6, size - 0.6, 2)
        if np.hypot(*(c - start)) > 1.3:
            boxes.append(
                {
                    "name": f"box{len(boxes)}",
                    "centre": c.tolist(),
                    "size": rng.uniform(0.2, 0.9, 2).tolist(),
                    "yaw_deg": float(rng.uniform(0, 180)),
                }
            )
    while len(cylinders) < 3:
        c = rng.uniform(0.6, size - 0.6, 2)
        if np.hypot(*(c - start)) > 1.3:
            cylinders.append(
                {
                    "name": f"cyl{len(cylinders)}",
                    "centre": c.tolist(),
                    "radius": float(rng.uniform(0.1, 0.35)),
                }
            )
    return parse_scenario(
        {
            "name": "cluttered",
            "start": {"x": float(start[0]), "y": float(start[1]), "yaw_deg": 0.0},
            "walls": _room(size),
            "boxes": boxes,
            "cylinders": cylinders,
            "tables": [
                {
                    "name": "table",
                    "centre": [size / 2, size - 1.0],
                    "size": [1.2, 0.9],
                    "yaw_deg": float(rng.uniform(0, 90)),
                }
            ],
        },
        "cluttered",
    )


def random_commands(rng: np.random.Generator, n: int, hold: int = 15) -> np.ndarray:
    """(n, 3) piecewise-constant commands, often beyond the limits."""
    levels = rng.uniform([-1.5, -1.5, -2.0], [1.5, 1.5, 2.0], (n // hold + 1, 3))
    return np.repeat(levels, hold, axis=0)[:n]


def map_velocity(world: World) -> np.ndarray:
    """True velocity (3,) in the map frame."""
    v = world.true_velocity()
    yaw = world.true_pose().yaw
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


# ---------------------------------------------------------------- geometry helpers


def _overlap_depth(a: np.ndarray, b: np.ndarray) -> float:
    """Penetration depth of two convex polygons (separating axis theorem), <= 0 if apart."""
    depth = math.inf
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for nx, ny in np.column_stack((edges[:, 1], -edges[:, 0])):
            axis = np.array([nx, ny]) / math.hypot(nx, ny)
            pa, pb = a @ axis, b @ axis
            depth = min(depth, min(pa.max(), pb.max()) - max(pa.min(), pb.min()))
    return depth


def _circle_depth(poly: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """How far a circle reaches into a convex polygon (counter-clockwise), <= 0 if apart."""
    a, b = poly, np.roll(poly, -1, axis=0)
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", centre - a, d) / np.einsum("ij,ij->i", d, d), 0, 1)
    dist = np.hypot(*(a + t[:, None] * d - centre).T).min()
    inside = np.all(d[:, 0] * (centre[1] - a[:, 1]) - d[:, 1] * (centre[0] - a[:, 0]) >= 0)
    return radius + dist if inside else radius - dist


def distance_to_element(scenario: Scenario, name: str, point: np.ndarray) -> float:
    """Distance [m] from map point (2,) to the outline of the element called ``name``."""
    for c in scenario.cylinders:
        if c.name == name:
            return abs(math.dist(c.centre, point) - c.radius)
    (box,) = [b for b in scenario.obstacle_boxes() if b.name == name]
    a = box.corners()
    d = np.roll(a, -1, axis=0) - a
    t = np.clip(np.einsum("ij,ij->i", point - a, d) / np.einsum("ij,ij->i", d, d), 0, 1)
    return float(np.hypot(*(a + t[:, None] * d - point).T).min())


def max_penetration(scenario: Scenario, pose: Pose2D) -> float:
    footprint = pose.to_map_frame(scenario.robot.footprint())
    depths = [_overlap_depth(footprint, b.corners()) for b in scenario.obstacle_boxes()]
    depths += [_circle_depth(footprint, np.array(c.centre), c.radius) for c in scenario.cylinders]
    return max(depths)


# --------------------------------------------------------------------------- tests


def test_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="dt"):
        WorldSettings(dt=0.0)
    with pytest.raises(ValueError, match="laser_backend"):
        WorldSettings(laser_backend="lidar")
    with pytest.raises(ValueError, match="contact_debounce_s"):
        WorldSettings(contact_debounce_s=-1.0)


def test_apply_refuses_malformed_commands() -> None:
    with World(open_room(), seed=0, components=()) as world:
        for bad in (np.zeros(2), np.array([0.0, np.nan, 0.0]), np.zeros((1, 3))):
            with pytest.raises(ValueError, match="apply"):
                world.apply(bad)


def test_clip_command_keeps_direction_and_limits(rng: np.random.Generator) -> None:
    for v in rng.uniform(-5, 5, (50, 3)):
        out = clip_command(v, 1.0, 1.2)
        assert math.hypot(out[0], out[1]) <= 1.0 + 1e-12
        assert abs(out[2]) <= 1.2
        # direction of travel kept: parallel to the request
        assert abs(out[0] * v[1] - out[1] * v[0]) < 1e-9
        if math.hypot(v[0], v[1]) <= 1.0:
            assert np.allclose(out[:2], v[:2])


def test_reset_puts_robot_at_start_at_rest(rng: np.random.Generator) -> None:
    scenario = open_room()
    with World(scenario, seed=1, components=()) as world:
        obs = world.reset()
        assert world.t == 0.0 and obs.t == 0.0
        assert world.true_pose() == Pose2D(scenario.start.x, scenario.start.y, 0.0)
        world.apply(np.array([1.0, 0.0, 1.0]))
        for _ in range(20):
            world.step()
        assert world.t == pytest.approx(20 * DT)
        pose = Pose2D(*rng.uniform([3, 3, -3], [9, 9, 3]))
        world.reset(pose)
        assert world.t == 0.0
        got = world.true_pose()
        assert (got.x, got.y) == pytest.approx((pose.x, pose.y))
        assert got.yaw == pytest.approx(pose.yaw)
        assert np.allclose(world.true_velocity(), 0.0)
        world.step()  # the old command was forgotten: the robot stays put
        assert np.allclose(world.true_velocity(), 0.0)


def test_speed_limits_hold_and_are_reached() -> None:
    scenario = open_room(20.0)
    robot = scenario.robot
    with World(scenario, seed=0, components=()) as world:
        world.reset(Pose2D(3.0, 3.0, 0.0))
        world.apply(np.array([5.0, 0.0, 0.0]))
        speeds = []
        for _ in range(40):
            world.step()
            speeds.append(world.true_velocity()[0])
        assert max(speeds) <= robot.max_speed + 1e-6
        assert speeds[-1] == pytest.approx(robot.max_speed, abs=1e-3)
        world.reset(Pose2D(10.0, 10.0, 0.0))
        world.apply(np.array([5.0, 5.0, 10.0]))
        for _ in range(40):
            world.step()
            v = world.true_velocity()
            assert math.hypot(v[0], v[1]) <= robot.max_speed + 1e-6
            assert abs(v[2]) <= robot.max_yaw_rate + 1e-6
        assert abs(v[2]) == pytest.approx(robot.max_yaw_rate, abs=1e-3)


def test_acceleration_limits_hold_between_ticks(rng: np.random.Generator) -> None:
    scenario = open_room(40.0)
    robot = scenario.robot
    with World(scenario, seed=0, components=()) as world:
        before = map_velocity(world)
        dv_max = robot.max_accel * DT
        dw_max = robot.max_yaw_accel * DT
        biggest = 0.0
        for v in random_commands(rng, 200, hold=6):
            world.apply(v)
            world.step()
            now = map_velocity(world)
            dv = math.hypot(*(now[:2] - before[:2]))
            assert dv <= dv_max * 1.01 + 1e-4
            assert abs(now[2] - before[2]) <= dw_max * 1.01 + 1e-4
            biggest = max(biggest, dv)
            before = now
        assert biggest > 0.9 * dv_max  # the limit was actually reached


def test_commands_are_followed_in_the_robot_frame(rng: np.random.Generator) -> None:
    """A constant robot-frame command drives an arc: the robot-frame velocity stays the
    command while the heading turns, and the centre of the arc stays put."""
    scenario = open_room(40.0)
    v = np.array([*rng.uniform(-0.7, 0.7, 2), rng.choice([-1, 1]) * rng.uniform(0.5, 1.0)])
    with World(scenario, seed=0, components=()) as world:
        world.reset(Pose2D(20.0, 20.0, float(rng.uniform(-3, 3))))
        world.apply(v)
        for _ in range(20):
            world.step()
        # the map-frame velocity is constant within a physics substep h, so at its end
        # the robot-frame velocity is off by the half-substep turn, |v| omega h / 2
        h = DT / round(DT * world.settings.physics_hz)
        tol = math.hypot(v[0], v[1]) * abs(v[2]) * h / 2 + 2e-4
        centres = []
        for _ in range(60):
            world.step()
            assert np.allclose(world.true_velocity(), v, atol=tol)
            pose = world.true_pose()
            # the centre of rotation lies at (-v_y, v_x) / omega in the robot frame
            centres.append(pose.to_map_frame(np.array([-v[1], v[0]]) / v[2])[0])
        assert np.ptp(np.array(centres), axis=0).max() < 1e-3


def test_footprint_never_enters_obstacles(rng: np.random.Generator) -> None:
    scenario = cluttered_scene(rng)
    (x0, y0), (x1, y1) = scenario.bounds
    with World(scenario, seed=int(rng.integers(1 << 31)), components=()) as world:
        for v in random_commands(rng, 500):
            world.apply(v)
            world.step()
            pose = world.true_pose()
            assert x0 <= pose.x <= x1 and y0 <= pose.y <= y1
            assert max_penetration(scenario, pose) < 0.005
        # the robot did run into things, so the check above meant something
        assert len(world.contacts()) >= 2
        for contact in world.contacts():  # at the outline of the element it names
            assert distance_to_element(scenario, contact.obstacle, contact.position) < 0.01


def _drive_until_touching(world: World, v: float, limit: int = 200) -> int:
    world.apply(np.array([v, 0.0, 0.0]))
    for tick in range(limit):
        world.step()
        if world.touching:
            return tick
    raise AssertionError("the robot never reached the wall")


def test_contact_reports_time_place_and_element() -> None:
    with World(wall_scene(), seed=0, components=()) as world:
        world.apply(np.array([0.5, 0.0, 0.0]))
        started = []
        for _ in range(200):
            t_before = world.t
            new = world.step()
            if new:
                started = new
                break
        assert len(started) == 1
        contact = started[0]
        assert contact.obstacle == "east" and contact.index == 0
        assert t_before < contact.t_start <= world.t
        assert contact.position == pytest.approx([3.95, 0.0], abs=0.3)
        assert contact.position[0] == pytest.approx(3.95, abs=0.005)
        assert math.isnan(contact.t_end)
        assert world.contacts() == [contact]
        # a table leg is named after its table (the robot fits under the top)
        world.reset(Pose2D(1.43, 3.0, math.pi / 2))
        world.apply(np.array([0.5, 0.0, 0.0]))
        for _ in range(200):
            new = world.step()
            if new:
                break
        assert new and new[0].obstacle.startswith("table.leg")


def test_push_pause_and_separate_touches_count_once_each() -> None:
    settings = WorldSettings()
    with World(wall_scene(), seed=0, settings=settings, components=()) as world:
        _drive_until_touching(world, 0.5)
        for _ in range(40):  # keep pushing for 2 s
            world.step()
            assert world.touching
        world.apply(np.zeros(3))  # pause against the wall for 1 s
        for _ in range(20):
            world.step()
            assert world.touching
        assert len(world.contacts()) == 1
        world.apply(np.array([-0.5, 0.0, 0.0]))  # back off for 1.5 s: the episode ends
        for _ in range(30):
            world.step()
        (first,) = world.contacts()
        assert first.t_start < first.t_end < world.t - settings.contact_debounce_s + 1e-9
        _drive_until_touching(world, 0.5)
        for _ in range(10):
            world.step()
        episodes = world.contacts()
        assert len(episodes) == 2
        assert [c.index for c in episodes] == [0, 1]
        assert math.isnan(episodes[1].t_end) and episodes[1].t_start > first.t_end


def test_flickering_graze_is_one_episode() -> None:
    with World(wall_scene(), seed=0, components=()) as world:
        _drive_until_touching(world, 0.2)
        flags = []
        for _ in range(12):  # back 0.1 s, forward 0.2 s: on and off the wall
            for v, ticks in ((-0.1, 2), (0.1, 4)):
                world.apply(np.array([v, 0.0, 0.0]))
                for _ in range(ticks):
                    world.step()
                    flags.append(world.touching)
        # the robot really did leave the wall and come back, each time within the debounce
        text = "".join("x" if f else "." for f in flags).strip(".")
        gaps = [len(g) for g in text.split("x") if g]
        assert len(gaps) >= 5
        assert max(gaps) * DT < WorldSettings().contact_debounce_s
        assert len(world.contacts()) == 1
        # once it stays away for longer than the debounce, the episode closes
        world.apply(np.array([-0.3, 0.0, 0.0]))
        for _ in range(20):
            world.step()
        assert not math.isnan(world.contacts()[0].t_end)


def _run(
    world: World, commands: np.ndarray, *, reset: bool = True, seed: int | None = None
) -> tuple[list, list]:
    poses, scans = [], []
    if reset:
        world.reset(seed=seed)
    for v in commands:
        world.apply(v)
        world.step()
        obs = world.sense()
        poses.append(world.true_pose().as_array())
        scans.append(np.concatenate([s.ranges for s in obs.scans] + [obs.pose.as_array()]))
    return poses, scans


def test_same_seed_same_run_different_seed_different_noise(
    rng: np.random.Generator, seed: int
) -> None:
    scenario = cluttered_scene(rng)
    commands = random_commands(rng, 120)
    with (
        World(scenario, seed=seed, components=()) as a,
        World(scenario, seed=seed, components=()) as b,
        World(scenario, seed=seed + 1, components=()) as c,
    ):
        poses_a, scans_a = _run(a, commands)
        poses_b, scans_b = _run(b, commands)
        poses_c, scans_c = _run(c, commands)
        assert np.array_equal(poses_a, poses_b) and np.array_equal(scans_a, scans_b)
        assert [x.t_start for x in a.contacts()] == [x.t_start for x in b.contacts()]
        # noise does not steer the physics: same true path, different readings
        assert np.array_equal(poses_a, poses_c)
        assert not np.allclose(scans_a[-1], scans_c[-1])
        # a reset with the seed replays the run, noise included
        again = _run(a, commands, seed=seed)
        assert np.array_equal(again[0], poses_a) and np.array_equal(again[1], scans_a)


def test_worlds_in_one_process_do_not_interfere(rng: np.random.Generator) -> None:
    scenario = cluttered_scene(rng)
    commands = random_commands(rng, 100)
    other = random_commands(rng, 100)
    with World(scenario, seed=3, components=()) as alone:
        expected = _run(alone, commands)
    with (
        World(scenario, seed=3, components=()) as a,
        World(open_room(), seed=9, components=()) as b,
    ):
        a.reset()
        got = ([], [])
        for v, w in zip(commands, other, strict=True):
            b.apply(w)
            b.step()
            b.sense()
            pose, scan = _run(a, v[None, :], reset=False)
            got[0].extend(pose)
            got[1].extend(scan)
        assert np.array_equal(got[0], expected[0]) and np.array_equal(got[1], expected[1])


def test_only_the_robot_is_checked_for_contacts() -> None:
    # the static scene's bodies never collide with each other (walls meet at corners):
    # Bullet would compute those contacts at every substep for nothing
    from sim._pybullet import pybullet as p
    from sim.scenario import load_scenario

    with World(load_scenario("cluttered_room"), seed=0, components=()) as world:
        world.reset(Pose2D(world.scenario.start.x, world.scenario.start.y, 0.0))
        world.apply(np.array([-1.0, 0.0, 0.0]))  # backwards, into the west wall
        touched = False
        for _ in range(60):
            world.step()
            touched = touched or world.touching
            contacts = p.getContactPoints(physicsClientId=world.client)
            assert all(world._robot in (c[1], c[2]) for c in contacts)
        assert touched  # the robot itself still collides


def test_close_is_idempotent() -> None:
    world = World(open_room(), seed=0, components=())
    client = world.client
    world.close()
    world.close()
    assert world.client == -1
    from sim._pybullet import pybullet

    assert not pybullet.isConnected(physicsClientId=client)


@pytest.mark.gui
def test_gui_world_steps() -> None:
    with World(open_room(), seed=0, settings=WorldSettings(gui=True), components=()) as world:
        world.apply(np.array([0.5, 0.0, 0.3]))
        for _ in range(20):
            world.step()
        assert world.true_velocity()[0] > 0.4
