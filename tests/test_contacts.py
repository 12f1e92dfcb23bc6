"""Contacts behave like a holonomic base sliding along an obstacle (issue 19): a scrape
does not turn the robot, commands keep working while it touches, and a collision
episode ends when the robot moves away."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autonomy.modes import make_mode
from sim.scenario import Scenario, parse_scenario
from sim.types import Pose2D
from sim.world import World, WorldSettings

DT = WorldSettings().dt
CRATE_CENTRE = np.array([5.0, 4.0])  # [m]
CRATE_SIZE = (0.6, 1.2)  # [m] along its own x and y
WALL_X = 6.95  # [m] west face of the east wall of the room below


def _room(size: float = 8.0) -> list[dict]:
    s = size
    return [
        {"name": "south", "from": [0, 0], "to": [s, 0]},
        {"name": "east", "from": [s - 1, 0], "to": [s - 1, s]},
        {"name": "north", "from": [s, s], "to": [0, s]},
        {"name": "west", "from": [0, s], "to": [0, 0]},
    ]


def crate_scene(yaw_rad: float) -> Scenario:
    """A closed room with one crate (0.6 m x 1.2 m) turned by ``yaw_rad`` at CRATE_CENTRE."""
    crate = {
        "name": "crate",
        "centre": CRATE_CENTRE.tolist(),
        "size": list(CRATE_SIZE),
        "yaw_deg": math.degrees(yaw_rad),
    }
    return parse_scenario(
        {"name": "crate", "start": {"x": 2.0, "y": 2.0}, "walls": _room(), "boxes": [crate]},
        "crate",
    )


def _rot(angle: float, v: np.ndarray) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def scrape_start(robot_yaw: float, crate_yaw: float, side: int, length_m: float) -> Pose2D:
    """The pose from which a pure sideways move (robot-frame v_y of sign ``side``) brings
    the robot's leading front corner onto the crate's west face, a quarter of the way
    along it, after ``length_m`` [m] of travel; robot and crate faces are parallel when
    both yaws are 0."""
    hx, hy = CRATE_SIZE[0] / 2, CRATE_SIZE[1] / 2
    meet = CRATE_CENTRE + _rot(crate_yaw, np.array([-hx, -side * hy / 2]))
    corner = _rot(robot_yaw, np.array([0.3, side * 0.25]))  # leading front corner
    direction = _rot(robot_yaw, np.array([0.0, float(side)]))
    x, y = meet - corner - length_m * direction
    return Pose2D(float(x), float(y), robot_yaw)


@pytest.mark.parametrize("askew", ["robot", "crate"])
def test_sideways_scrape_along_a_crate_keeps_heading_and_moves(
    rng: np.random.Generator, askew: str
) -> None:
    """Manual mode, pure v_y along a crate at a small angle: the leading corner rubs the
    crate's face and then its far corner rubs the robot's front, as when a participant
    strafes past furniture. The heading stays put and the robot keeps going."""
    mode = make_mode("manual")
    for low, high in ((2.0, 6.0), (6.0, 10.0), (10.0, 15.0)):
        side = int(rng.choice([-1, 1]))
        angle = math.radians(rng.uniform(low, high))  # between the robot's front and the face
        speed = float(rng.uniform(0.3, 1.0))  # [m/s]
        # the robot turned away from the face, or the crate turned into the robot's path
        robot_yaw, crate_yaw = (-side * angle, 0.0) if askew == "robot" else (0.0, side * angle)
        scenario = crate_scene(crate_yaw)
        start = scrape_start(robot_yaw, crate_yaw, side, length_m=0.4)
        ticks = round(2.4 / speed / DT)  # past the crate's far end
        with World(scenario, seed=int(rng.integers(1 << 31)), components=()) as world:
            obs = world.reset(start)
            u = np.array([0.0, side * speed, 0.0])
            turned, touched = 0.0, 0
            for _ in range(ticks):
                world.apply(mode.step(obs, u).v)
                world.step()
                obs = world.sense()
                turned = max(turned, abs(world.true_pose().yaw - start.yaw))
                touched += world.touching
            assert touched >= 3 and [c.obstacle for c in world.contacts()] == ["crate"]
            assert math.degrees(turned) < 5.0
            pose = world.true_pose()
            direction = _rot(start.yaw, np.array([0.0, float(side)]))
            advance = float(np.dot([pose.x - start.x, pose.y - start.y], direction))
            # the commanded travel less the acceleration ramp; sliding along a face at
            # 15 degrees keeps cos^2(15 deg) = 0.93 of it
            commanded = speed * ticks * DT - speed**2 / (2 * scenario.robot.max_accel)
            assert advance > 0.85 * commanded


def wall_room() -> Scenario:
    """A closed empty room whose east wall's west face is at x = WALL_X."""
    return parse_scenario({"name": "wall", "start": {"x": 3.0, "y": 4.0}, "walls": _room()}, "wall")


def _push_into_wall(world: World, rng: np.random.Generator) -> tuple[Pose2D, float]:
    """Reset the robot facing the east wall at 15-60 degrees and drive it forward into the
    wall until it touches, then push on for 0.5 s; returns the start pose and the speed."""
    heading = float(rng.choice([-1, 1]) * math.radians(rng.uniform(15.0, 60.0)))
    speed = float(rng.uniform(0.3, 0.8))  # [m/s]
    start = Pose2D(WALL_X - 0.8, 4.0, heading)
    world.reset(start)
    world.apply(np.array([speed, 0.0, 0.0]))
    for _ in range(round(4.0 / DT)):
        world.step()
        if world.touching:
            break
    assert world.touching, "the robot never reached the wall"
    for _ in range(round(0.5 / DT)):
        world.step()
    return start, speed


def test_pushing_obliquely_into_a_wall_slides_and_turns_on_command(
    rng: np.random.Generator,
) -> None:
    """Driving forward into a wall at an angle slides along it at the command's component
    along the wall, with the heading held; a turn towards the wall commanded while still
    pushing (the corners pressing into it) turns the robot as it would in free space."""
    for _ in range(3):
        with (
            World(wall_room(), seed=int(rng.integers(1 << 31)), components=()) as world,
            World(wall_room(), seed=0, components=()) as free,
        ):
            start, speed = _push_into_wall(world, rng)
            pose = world.true_pose()
            assert abs(pose.yaw - start.yaw) < math.radians(1.0)
            along_wall = world.true_velocity()[:2] @ [math.sin(pose.yaw), math.cos(pose.yaw)]
            assert along_wall == pytest.approx(speed * math.sin(start.yaw), abs=0.02)
            # the same turn in the middle of the room, from rest at the same heading
            free.reset(Pose2D(3.0, 4.0, pose.yaw))
            # towards facing the wall, so the corners press into it and it keeps pushing
            omega = -math.copysign(rng.uniform(0.6, 1.2), start.yaw)  # [rad/s]
            command = np.array([speed, 0.0, omega])
            world.apply(command)
            free.apply(command)
            touching = 0
            for _ in range(round(1.0 / DT)):
                world.step()
                free.step()
                touching += world.touching
                turned = world.true_pose().yaw - pose.yaw
                turned_free = free.true_pose().yaw - pose.yaw
                assert abs(turned - turned_free) < math.radians(2.0)
            assert touching >= round(0.5 / DT)  # the turn happened against the wall
            assert abs(turned) > 0.5 * abs(omega)


def corridor(width_m: float) -> Scenario:
    """A closed corridor 6 m long and ``width_m`` [m] wide between its walls' faces,
    along x at y = 0."""
    h = width_m / 2 + 0.05  # wall centre lines (walls 0.1 m thick)
    walls = [
        {"name": "south", "from": [0, -h], "to": [6, -h]},
        {"name": "north", "from": [6, h], "to": [0, h]},
        {"name": "west", "from": [0, h], "to": [0, -h]},
        {"name": "east", "from": [6, -h], "to": [6, h]},
    ]
    return parse_scenario({"name": "corridor", "start": {"x": 1.0, "y": 0.0}, "walls": walls}, "c")


def test_turning_against_both_walls_of_a_corridor_keeps_driving(
    rng: np.random.Generator,
) -> None:
    """Driving along a corridor barely wider than the robot while commanding a turn: the
    corners press into both walls, the heading stays what the corridor allows, and the
    robot still drives on (a contact's friction would hold it as the yaw motor presses)."""
    for _ in range(3):
        width = float(rng.uniform(0.52, 0.7))  # [m] the robot is 0.5 m wide
        speed = float(rng.uniform(0.3, 0.8))  # [m/s]
        omega = float(rng.choice([-1, 1]) * rng.uniform(0.6, 1.2))  # [rad/s]
        scenario = corridor(width)
        with World(scenario, seed=int(rng.integers(1 << 31)), components=()) as world:
            world.apply(np.array([speed, 0.0, omega]))
            touched = 0
            for _ in range(round(2.0 / DT)):
                world.step()
                touched += world.touching
                corners = world.true_pose().to_map_frame(scenario.robot.footprint())
                assert np.abs(corners[:, 1]).max() < width / 2 + 0.005  # inside the walls
            assert touched >= round(1.0 / DT)
            # the heading the corridor allows: length sin(yaw) + width cos(yaw) <= width
            robot = scenario.robot
            yaw = abs(world.true_pose().yaw)
            assert robot.length * math.sin(yaw) + robot.width * math.cos(yaw) < width + 0.01
            commanded = speed * 2.0 - speed**2 / (2 * robot.max_accel)
            assert world.true_pose().x - scenario.start.x > 0.8 * math.cos(yaw) * commanded


def _clearance_to_wall(world: World) -> float:
    """Gap [m] between the footprint and the east wall's face (< 0 when overlapping)."""
    corners = world.true_pose().to_map_frame(world.scenario.robot.footprint())
    return WALL_X - float(corners[:, 0].max())


def test_contact_episode_ends_when_the_robot_moves_away(rng: np.random.Generator) -> None:
    """Into a wall at an angle, pushing and turning towards it, then straight away: the
    episode's last touch is the tick the footprint separates from the wall (within a
    tick or two), and the episode closes ``contact_debounce_s`` later."""
    settings = WorldSettings()
    for _ in range(3):
        with World(wall_room(), seed=int(rng.integers(1 << 31)), components=()) as world:
            start, speed = _push_into_wall(world, rng)
            omega = -math.copysign(rng.uniform(0.0, 1.2), start.yaw)  # [rad/s] to the wall
            world.apply(np.array([speed, 0.0, omega]))
            for _ in range(round(0.5 / DT)):
                world.step()
            world.apply(np.array([speed, 0.0, 0.0]))  # stop turning (the yaw ramp: 0.3 s)
            for _ in range(round(0.4 / DT)):
                world.step()
            assert world.touching
            away = float(rng.uniform(0.2, 0.8))  # [m/s] in the map frame, straight west
            yaw = world.true_pose().yaw
            world.apply(np.array([-away * math.cos(yaw), away * math.sin(yaw), 0.0]))
            t_apart = math.nan  # end of the first tick with the footprint clear of the wall
            t_closed = math.nan  # end of the tick at which the episode got its t_end
            for _ in range(round((1.0 + settings.contact_debounce_s) / DT)):
                world.step()
                apart = _clearance_to_wall(world) > settings.contact_tolerance_m
                if apart and math.isnan(t_apart):
                    t_apart = world.t
                if not math.isnan(t_apart):
                    assert apart and not world.touching  # it really left
                if math.isnan(t_closed) and math.isfinite(world.contacts()[0].t_end):
                    t_closed = world.t
            (episode,) = world.contacts()
            assert t_apart - 2 * DT <= episode.t_end <= t_apart
            # closed at the first tick ending at least the debounce after the last touch
            assert t_closed - DT < episode.t_end + settings.contact_debounce_s <= t_closed + 1e-9
