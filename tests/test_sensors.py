"""The robot's sensors: laser ranges against geometry, the exact caster against a brute
force and against pybullet's own ray test, noise models, IMU, components, camera."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim.scenario import Scenario, parse_scenario
from sim.sensors import cast, cross_section, scene_solids
from sim.types import Pose2D, SemanticComponent
from sim.world import World, WorldSettings

WALL_X = 4.95  # west face of the wall in wall_scene()


def with_laser_sigma(scenario: Scenario, sigma: float) -> Scenario:
    lasers = tuple(dataclasses.replace(las, sigma=sigma) for las in scenario.robot.lasers)
    return dataclasses.replace(scenario, robot=dataclasses.replace(scenario.robot, lasers=lasers))


def wall_scene(sigma: float) -> Scenario:
    """A single 40 m wall facing -x, nothing else."""
    scenario = parse_scenario(
        {
            "name": "wall",
            "bounds": [[-10.0, -25.0], [10.0, 25.0]],
            "start": {"x": 0.0, "y": 0.0},
            "walls": [{"name": "wall", "from": [5.0, -20.0], "to": [5.0, 20.0]}],
        },
        "wall",
    )
    return with_laser_sigma(scenario, sigma)


def random_scene(rng: np.random.Generator) -> Scenario:
    """Random boxes, cylinders and a table in a closed 8 m room."""
    walls = [
        {"name": "s", "from": [0, 0], "to": [8, 0]},
        {"name": "e", "from": [8, 0], "to": [8, 8]},
        {"name": "n", "from": [8, 8], "to": [0, 8]},
        {"name": "w", "from": [0, 8], "to": [0, 0]},
    ]
    boxes = [
        {
            "name": f"b{i}",
            "centre": rng.uniform(0.5, 7.5, 2).tolist(),
            "size": rng.uniform(0.1, 1.2, 2).tolist(),
            "yaw_deg": float(rng.uniform(0, 180)),
            "height": float(rng.choice([0.1, 0.8])),  # some lower than the lasers
        }
        for i in range(8)
    ]
    cylinders = [
        {"name": f"c{i}", "centre": rng.uniform(0.5, 7.5, 2).tolist(), "radius": 0.05 + i / 10}
        for i in range(4)
    ]
    tables = [{"name": "t", "centre": rng.uniform(1, 7, 2).tolist(), "size": [1.2, 0.9]}]
    return parse_scenario(
        {
            "name": "random",
            "start": {"x": 4.0, "y": 4.0},
            "walls": walls,
            "boxes": boxes,
            "cylinders": cylinders,
            "tables": tables,
        },
        "random",
    )


def inside_anything(scenario: Scenario, point: np.ndarray, height: float, margin: float) -> bool:
    for b in scenario.obstacle_boxes():
        if b.height <= height:
            continue
        local = Pose2D(b.centre[0], b.centre[1], b.yaw).to_robot_frame(point)[0]
        if abs(local[0]) < b.size[0] / 2 + margin and abs(local[1]) < b.size[1] / 2 + margin:
            return True
    return any(
        math.dist(c.centre, point) < c.radius + margin
        for c in scenario.cylinders
        if c.height > height
    )


def brute_force_ranges(
    scenario: Scenario, origin: np.ndarray, angles: np.ndarray, height: float, max_range: float
) -> np.ndarray:
    """Every beam against every edge and circle the plane at ``height`` cuts."""
    edges = []
    for b in scenario.obstacle_boxes():
        if b.height > height:
            c = b.corners()
            edges += [(c[i], c[(i + 1) % 4]) for i in range(4)]
    ranges = np.full(len(angles), max_range)
    for k, a in enumerate(angles):
        d = np.array([math.cos(a), math.sin(a)])
        for p, q in edges:
            e = q - p
            den = d[0] * (-e[1]) - d[1] * (-e[0])
            if abs(den) < 1e-12:
                continue
            w = p - origin
            t = (w[0] * (-e[1]) - w[1] * (-e[0])) / den
            s = (d[0] * w[1] - d[1] * w[0]) / den
            if t >= 0 and 0 <= s <= 1:
                ranges[k] = min(ranges[k], t)
        for c in scenario.cylinders:
            if c.height <= height:
                continue
            w = np.array(c.centre) - origin
            along = w @ d
            disc = c.radius**2 - (w @ w - along**2)
            if disc >= 0 and along - math.sqrt(disc) >= 0:
                ranges[k] = min(ranges[k], along - math.sqrt(disc))
    return ranges


def test_scene_solids_are_the_scenario(rng: np.random.Generator) -> None:
    scenario = random_scene(rng)
    solids = scene_solids(scenario)
    names = [s.name for s in solids]
    assert len(set(names)) == len(names)
    parts = [f"t.leg{i}" for i in range(4)] + ["t.top"]
    expected = [e.name for e in (*scenario.walls, *scenario.boxes, *scenario.cylinders)]
    assert sorted(names) == sorted(expected + parts)
    for solid in solids:
        assert solid.z[0] < solid.z[1]
        centre = np.array([*solid.centre, sum(solid.z) / 2])
        assert solid.distance(centre) == 0.0
        # straight above the top by 0.3 m
        assert solid.distance(centre + [0, 0, (solid.z[1] - solid.z[0]) / 2 + 0.3]) == (
            pytest.approx(0.3)
        )
        # 0.2 m beyond the side, along the solid's own x axis
        reach = solid.radius or solid.size[0] / 2
        side = centre + (reach + 0.2) * np.array([math.cos(solid.yaw), math.sin(solid.yaw), 0])
        assert solid.distance(side) == pytest.approx(0.2)
    top = solids[names.index("t.top")]
    assert top.z == pytest.approx((0.75, 0.79))  # the default table: top from 0.75 m, 4 cm


def test_cast_equals_brute_force(rng: np.random.Generator) -> None:
    scenario = random_scene(rng)
    height = 0.2
    section = cross_section(scenario, height)
    origins = []
    while len(origins) < 6:
        origin = rng.uniform(0.2, 7.8, 2)
        if not inside_anything(scenario, origin, height, 0.01):
            origins.append(origin)
    origins = np.array(origins)
    firsts = rng.uniform(-4, 4, len(origins))
    n = int(rng.integers(2, 400))
    step = float(rng.uniform(0.1, 1.0)) * 2 * math.pi / (n - 1)
    max_range = float(rng.uniform(2, 12))
    together = cast(section, origins, firsts, step, n, max_range)
    assert together.shape == (len(origins), n)
    for origin, first, got in zip(origins, firsts, together, strict=True):
        want = brute_force_ranges(scenario, origin, first + step * np.arange(n), height, max_range)
        assert np.allclose(got, want, atol=1e-9)
        # one fan at a time gives the same as all at once
        assert np.array_equal(cast(section, origin[None], [first], step, n, max_range)[0], got)


def test_cross_section_sees_what_the_plane_cuts() -> None:
    scenario = parse_scenario(
        {
            "name": "heights",
            "start": {"x": 0.0, "y": 0.0},
            "boxes": [{"name": "low", "centre": [2.0, 0.0], "size": [0.4, 0.4], "height": 0.1}],
            "cylinders": [{"name": "c", "centre": [0.0, 2.0], "radius": 0.2, "height": 0.5}],
            "tables": [{"name": "t", "centre": [-2.0, 0.0], "size": [1.0, 0.8], "height": 0.75}],
        },
        "heights",
    )
    low = cross_section(scenario, 0.2)  # table legs and the cylinder
    assert len(low.edge_a) == 4 * 4 and len(low.radii) == 1
    top = cross_section(scenario, 0.77)  # the table top only
    assert len(top.edge_a) == 4 and len(top.radii) == 0
    # at the top's height a beam along -x meets the top's edge at x = -1.5
    r = cast(top, np.zeros((1, 2)), [math.pi], 0.01, 1, 8.0)
    assert r[0, 0] == pytest.approx(1.5)


def test_backends_agree(rng: np.random.Generator) -> None:
    """The exact caster against pybullet's rayTestBatch on the world's own bodies: the
    scene was built where the scenario says, and the robot never sees itself."""
    scenario = with_laser_sigma(random_scene(rng), 0.0)
    robot = scenario.robot
    analytic = World(scenario, seed=0, components=())
    bullet = World(
        scenario, seed=0, settings=WorldSettings(laser_backend="pybullet"), components=()
    )
    with analytic, bullet:
        poses = 0
        while poses < 8:
            pose = Pose2D(*rng.uniform([0.5, 0.5, -math.pi], [7.5, 7.5, math.pi]))
            clear = pose.to_map_frame(
                np.vstack([robot.footprint(), [las.position for las in robot.lasers]])
            )
            if any(inside_anything(scenario, p, 0.2, 0.05) for p in clear):
                continue
            a = np.concatenate([s.ranges for s in analytic.reset(pose).scans])
            b = np.concatenate([s.ranges for s in bullet.reset(pose).scans])
            close = np.abs(a - b) < 0.015  # Bullet's ray test is good to about a centimetre
            assert close.mean() > 0.97
            poses += 1


def test_laser_range_to_a_wall(rng: np.random.Generator) -> None:
    sigma = float(rng.uniform(0.005, 0.03))
    scenario = wall_scene(sigma)
    errors = []
    with World(scenario, seed=int(rng.integers(1 << 31)), components=()) as world:
        for _ in range(3):
            yaw = float(rng.uniform(-0.3, 0.3))
            distance = float(rng.uniform(0.5, 5.0))
            front = scenario.robot.lasers[0]
            # put the front laser at `distance` from the wall's face
            mount = Pose2D(0.0, 0.0, yaw).to_map_frame(np.array(front.position))[0]
            pose = Pose2D(WALL_X - distance - mount[0], float(rng.uniform(-2, 2)), yaw)
            obs = world.reset(pose)
            for spec, scan in zip(scenario.robot.lasers, obs.scans, strict=True):
                origin = pose.to_map_frame(np.array(spec.position))[0]
                phi = pose.yaw + scan.angles
                with np.errstate(divide="ignore"):
                    expected = np.where(np.cos(phi) > 0, (WALL_X - origin[0]) / np.cos(phi), np.inf)
                hit_y = origin[1] + expected * np.sin(phi)
                sees = (expected < spec.max_range - 6 * sigma) & (np.abs(hit_y) < 19.0)
                blind = (expected > spec.max_range + 6 * sigma) | (np.abs(hit_y) > 21.0)
                errors.append(scan.ranges[sees] - expected[sees])
                assert np.all(scan.ranges[blind] == spec.max_range)
    errors = np.concatenate(errors)
    assert len(errors) > 300
    assert np.mean(np.abs(errors) <= 4 * sigma) > 0.99
    assert np.all(np.abs(errors) <= 6 * sigma)
    assert 0.8 * sigma < errors.std() < 1.2 * sigma


def test_noise_free_ranges_are_exact_and_clipped() -> None:
    scenario = wall_scene(0.0)
    front = scenario.robot.lasers[0]
    with World(scenario, seed=0, components=()) as world:
        obs = world.reset(Pose2D(WALL_X - 3.0 - front.position[0], 0.0, 0.0))
        ahead = int(np.argmin(np.abs(obs.scans[0].angles)))
        assert obs.scans[0].ranges[ahead] == pytest.approx(3.0, abs=1e-9)
        # the laser 1 cm from the wall reads its minimum range
        obs = world.reset(Pose2D(WALL_X - 0.01 - front.position[0], 0.0, 0.0))
        assert obs.scans[0].ranges[ahead] == front.min_range


def test_points_are_the_hits_in_the_robot_frame(rng: np.random.Generator) -> None:
    scenario = random_scene(rng)
    with World(scenario, seed=1, components=()) as world:
        obs = world.reset()
        expected = np.vstack([s.points() for s in obs.scans])
        assert np.allclose(obs.points, expected)
        assert len(obs.points) > 100
        # each front-laser point lies where an exact beam from the laser towards it ends
        pose = world.true_pose()
        spec = scenario.robot.lasers[0]
        on_map = pose.to_map_frame(obs.scans[0].points())
        origin = pose.to_map_frame(np.array(spec.position))[0]
        angles = np.arctan2(on_map[:, 1] - origin[1], on_map[:, 0] - origin[0])
        exact = cast(
            cross_section(scenario, spec.height),
            np.repeat([origin], len(angles), 0),
            angles,
            1.0,
            1,
            spec.max_range,
        )[:, 0]
        dist = np.hypot(*(on_map - origin).T)
        assert np.allclose(dist, exact, atol=6 * spec.sigma + 1e-6)


def test_pose_estimate_and_imu_noise(rng: np.random.Generator) -> None:
    scenario = parse_scenario(
        {
            "name": "open",
            "bounds": [[0.0, -1.0], [40.0, 40.0]],
            "start": {"x": 20.0, "y": 20.0},
            "walls": [{"name": "far", "from": [0, 0], "to": [40, 0]}],
            "robot": {"pose_sigma": [0.02, 0.01], "imu_sigma": [0.03, 0.1]},
        },
        "open",
    )
    s_xy, s_yaw = scenario.robot.pose_sigma
    s_gyro, s_acc = scenario.robot.imu_sigma
    pose_err, gyro_err, acc_err = [], [], []
    with World(scenario, seed=int(rng.integers(1 << 31)), components=()) as world:
        world.reset()
        before = world.true_velocity()
        yaw_before = world.true_pose().yaw
        for tick in range(300):
            if tick % 10 == 0:
                world.apply(rng.uniform([-1, -1, -1.2], [1, 1, 1.2]))
            world.step()
            obs = world.sense()
            true = world.true_pose()
            err = obs.pose.as_array() - true.as_array()
            err[2] = math.remainder(err[2], 2 * math.pi)
            pose_err.append(err)
            vel = world.true_velocity()
            gyro_err.append(obs.imu.yaw_rate - vel[2])
            assert obs.velocity[2] == obs.imu.yaw_rate
            # acceleration: finite difference of the map-frame velocity, in the robot frame
            v_now = Pose2D(0, 0, true.yaw).to_map_frame(vel[:2])[0]
            v_then = Pose2D(0, 0, yaw_before).to_map_frame(before[:2])[0]
            accel = Pose2D(0, 0, true.yaw).to_robot_frame((v_now - v_then) / world.settings.dt)
            acc_err.append(obs.imu.accel - accel[0])
            before, yaw_before = vel, true.yaw
    pose_err, acc_err = np.array(pose_err), np.array(acc_err)
    for got, sigma in (
        (pose_err[:, 0], s_xy),
        (pose_err[:, 1], s_xy),
        (pose_err[:, 2], s_yaw),
        (np.array(gyro_err), s_gyro),
        (acc_err[:, 0], s_acc),
        (acc_err[:, 1], s_acc),
    ):
        assert np.all(np.abs(got) < 6 * sigma)
        assert 0.8 * sigma < got.std() < 1.2 * sigma


def test_components_are_seen_from_the_estimated_pose() -> None:
    from sim.semantics import derive_components

    door = SemanticComponent(
        id="doorway_0",
        kind="doorway",
        centre=np.array([3.0, 1.0]),
        points=np.array([[3.0, 0.6], [3.0, 1.4]]),
        ends=np.array([[3.0, 0.6], [3.0, 1.4]]),
        width=0.8,
        normal=np.array([1.0, 0.0]),
    )
    scenario = wall_scene(0.01)
    with World(scenario, seed=4, components=(door,)) as world:
        obs = world.reset(Pose2D(1.0, 2.0, 0.5))
        (seen,) = obs.components
        expected = door.transformed(obs.pose)
        assert seen.id == "doorway_0"
        assert np.allclose(seen.centre, expected.centre)
        assert np.allclose(seen.ends, expected.ends)
        assert np.allclose(seen.normal, expected.normal)
    with World(scenario, seed=4) as world:  # derived from the geometry
        obs = world.reset()
        derived = derive_components(scenario)
        assert [c.id for c in obs.components] == [c.id for c in derived]
        for got, c in zip(obs.components, derived, strict=True):
            assert np.allclose(got.points, c.transformed(obs.pose).points)


def test_camera_sees_the_red_cylinder() -> None:
    scenario = parse_scenario(
        {
            "name": "red",
            "bounds": [[-3.0, -3.0], [4.0, 3.0]],
            "start": {"x": 0.0, "y": 0.0},
            "cylinders": [
                {"name": "red", "centre": [2.5, 0.0], "radius": 0.25, "colour": [0.9, 0.1, 0.1]}
            ],
        },
        "red",
    )
    cam = scenario.robot.camera
    with World(scenario, seed=0, components=()) as world:
        image = world.camera_image()
        assert image.shape == (cam.height_px, cam.width, 3) and image.dtype == np.uint8
        rgb = image.astype(int)
        red = (
            (rgb[..., 0] > 100) & (rgb[..., 0] > 2 * rgb[..., 1]) & (rgb[..., 0] > 2 * rgb[..., 2])
        )
        assert red.sum() > 200
        cols = np.flatnonzero(red.any(axis=0))
        assert cols.min() < cam.width / 2 < cols.max()  # straight ahead: in the middle
        world.reset(Pose2D(0.0, 0.0, math.pi))  # facing away
        rgb = world.camera_image().astype(int)
        red = (
            (rgb[..., 0] > 100) & (rgb[..., 0] > 2 * rgb[..., 1]) & (rgb[..., 0] > 2 * rgb[..., 2])
        )
        assert red.sum() == 0
        # the tail camera (Sec. 7.5, Fig. 7.42) looks backwards: now it sees the cylinder
        rgb = world.camera_image("tail").astype(int)
        red = (
            (rgb[..., 0] > 100) & (rgb[..., 0] > 2 * rgb[..., 1]) & (rgb[..., 0] > 2 * rgb[..., 2])
        )
        assert red.sum() > 200
        with pytest.raises(ValueError, match="front, tail"):
            world.camera_image("side")


def test_sensing_at_rest_reuses_the_geometry_and_redraws_the_noise(rng) -> None:
    scenario = with_laser_sigma(random_scene(rng), 0.01)
    seed = int(rng.integers(1 << 31))
    worlds = World(scenario, seed=seed, components=()), World(scenario, seed=seed, components=())
    with worlds[0] as cached, worlds[1] as fresh:
        start = Pose2D(4.0, 4.0, float(rng.uniform(-3, 3)))
        for world in (cached, fresh):
            world.reset(start)
        before = None
        for _ in range(4):
            for world in (cached, fresh):
                world.apply(np.zeros(3))
                world.step()
            fresh._ranges_key = None  # forget the cached cast: the same observation
            a, b = cached.sense(), fresh.sense()
            assert cached.true_pose() == fresh.true_pose()
            for sa, sb in zip(a.scans, b.scans, strict=True):
                assert np.array_equal(sa.ranges, sb.ranges)
            assert np.array_equal(a.points, b.points)
            if before is not None:  # at rest, but each tick draws its own noise
                assert not np.array_equal(a.scans[0].ranges, before)
            before = a.scans[0].ranges
        # moved: the ranges are those of the new pose
        pose = Pose2D(3.0, 5.0, float(rng.uniform(-3, 3)))
        noise_free = World(with_laser_sigma(scenario, 0.0), seed=0, components=())
        with noise_free:
            noise_free.sense()
            want = noise_free.reset(pose).scans[0].ranges
        got = cached.reset(pose).scans[0].ranges
        assert np.max(np.abs(got - want)) < 0.1
