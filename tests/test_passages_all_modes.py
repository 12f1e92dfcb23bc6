"""Every mode lets a participant through every doorway and gap of every shipped scene when
they drive straight and centred (issue 19).

The robot starts at rest on a passage's axis, facing through it, up to 1.2 m before it
(:func:`sim.lanes.straight_lanes`); the stick is held straight ahead, no turn, at a careful
0.4 m/s and at the keyboard's full W (1.0 m/s), in a real ``sim.world.World`` (pybullet
physics, noisy lasers), ticked as the trial loop ticks it (``mode.step``, ``world.apply``,
``world.step``, ``world.sense``); once the whole footprint is past the passage the stick is
let go for a second. Pass: through within twice the time the commanded speed needs plus
5 s, and no contact episode at all. The contextual mode's yield and safety rules may slow
a centred pass, never block it.

A lane is driven when a straight, centred pass can keep the robot's protective margin and
leaves room to stop beyond it (the braking distance from full speed); a passage without
such a lane is named by :func:`test_every_passage_has_a_straight_lane`. The default run
drives the practice course (the practice doorway of issue 19); the other scenes are
``slow``. Where a confident recognition of another task has turned the contextual mode's
robot off the axis into the protective field, its yield to the dynamic window's twist
nearest the user's slides it back (before, five lanes of cluttered_room stopped there).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pytest

from autonomy.modes import make_mode
from autonomy.types import RobotModel
from sim.lanes import StraightLane, straight_lanes
from sim.scenario import Scenario, available_scenarios, load_scenario
from sim.semantics import derive_components
from sim.world import World
from study.engine.clocks import DT

MODES = ("manual", "reactive_bn", "contextual_task")
SPEEDS = (0.4, 1.0)  # [m/s] a careful push; the keyboard's W (full deflection)
DEFAULT_SCENES = ("practice_course",)  # the rest are slow
LET_GO_S = 1.0  # [s] after the pass, the stick released
# passages no straight, centred lane leads through (checked by the test below)
NO_STRAIGHT_LANE = {
    # a diagonal gap facing wall_x4_middle: from the west the lane ends 0.125 m before the
    # wall (no room to stop), from the east the approach runs through it
    ("cluttered_room", "gap_2"),
}


@functools.cache
def _components(name: str) -> tuple[Scenario, tuple]:
    scenario = load_scenario(name)
    return scenario, derive_components(scenario)


@functools.cache
def _scene(name: str) -> tuple[Scenario, tuple, dict[tuple[str, float], StraightLane]]:
    scenario, components = _components(name)
    lanes = straight_lanes(scenario, components=components)
    return scenario, components, {(lane.component, lane.side): lane for lane in lanes}


def _drivable(scenario: Scenario, lane: StraightLane) -> str:
    """Why ``lane`` cannot be driven straight and centred ("" when it can)."""
    robot = scenario.robot
    braking = robot.max_speed**2 / (2 * robot.max_accel)  # [m] from full speed
    if lane.clearance_m < robot.protective_margin - 1e-3:
        return f"{lane.clearance_m:.3f} m clearance, under the protective margin"
    if lane.run_out_m < braking:
        return f"{lane.run_out_m:.3f} m beyond it, less than the {braking:.2f} m to stop"
    return ""


def _passage_ids(name: str) -> list[str]:
    return [c.id for c in _components(name)[1] if c.kind in ("doorway", "gap")]


def _cases() -> list:
    out = []
    for name in available_scenarios():
        slow = () if name in DEFAULT_SCENES else (pytest.mark.slow,)
        for passage in _passage_ids(name):
            for side in (1.0, -1.0):
                for mode in MODES:
                    for speed in SPEEDS:
                        marks = slow
                        case = (name, passage, side, mode, speed)
                        key = f"{name}-{passage}-{'+' if side > 0 else '-'}-{mode}-{speed:g}"
                        out.append(pytest.param(*case, id=key, marks=marks))
    return out


@dataclass(frozen=True, slots=True)
class Pass:
    through: bool
    travelled_m: float  # [m] along the lane when the stick was let go or time ran out
    t_s: float  # [s] simulated
    contacts: tuple[str, ...]  # elements touched


@pytest.fixture(scope="module")
def worlds():
    """One world per scene, reset for every pass; closed at the end."""
    made: dict[str, World] = {}
    yield made
    for world in made.values():
        world.close()


def drive(world: World, lane: StraightLane, mode_name: str, speed: float, seed: int) -> Pass:
    """The straight, centred pass along ``lane`` at ``speed`` [m/s] in the mode."""
    scenario = world.scenario
    mode = make_mode(mode_name)
    mode.reset(RobotModel.from_spec(scenario.robot, dt=DT))
    obs = world.reset(lane.start, seed=seed)
    start = np.array([lane.start.x, lane.start.y])
    heading = np.array([math.cos(lane.start.yaw), math.sin(lane.start.yaw)])
    u = np.array([speed, 0.0, 0.0])
    travelled = 0.0
    for _ in range(round((2.0 * lane.through_m / speed + 5.0) / DT)):
        world.apply(mode.step(obs, u).v)
        world.step()
        obs = world.sense()
        pose = world.true_pose()
        travelled = float((np.array([pose.x, pose.y]) - start) @ heading)
        if travelled >= lane.through_m:
            break
    t = world.t
    for _ in range(round(LET_GO_S / DT)):
        world.apply(mode.step(obs, np.zeros(3)).v)
        world.step()
        obs = world.sense()
    contacts = tuple(c.obstacle for c in world.contacts())
    return Pass(travelled >= lane.through_m, travelled, t, contacts)


@pytest.mark.parametrize(("name", "passage", "side", "mode", "speed"), _cases())
def test_a_straight_centred_pass_gets_through(name, passage, side, mode, speed, seed, worlds):
    scenario, components, lanes = _scene(name)
    lane = lanes[(passage, side)]
    why = _drivable(scenario, lane)
    if why:
        pytest.skip(f"{name} {passage} from side {side:+g}: no straight lane ({why})")
    if name not in worlds:
        worlds[name] = World(scenario, seed=seed, components=components)
    result = drive(worlds[name], lane, mode, speed, seed)
    assert result.through and not result.contacts, (
        f"{mode} at {speed} m/s through {name} {passage} (side {side:+g}): {result}, lane {lane}"
    )


@pytest.mark.parametrize("name", available_scenarios())
def test_every_passage_has_a_straight_lane(name):
    """A passage without a straight, centred lane is untested above: those are named."""
    scenario, _, lanes = _scene(name)
    without = {
        (name, passage)
        for passage in {p for p, _ in lanes}
        if all(_drivable(scenario, lanes[(passage, side)]) for side in (1.0, -1.0))
    }
    assert without == {k for k in NO_STRAIGHT_LANE if k[0] == name}
