"""The mode registry (autonomy.modes) and the manual mode: every registered mode
resets and steps on a synthetic observation and returns a well-formed Assist, and
drives a short trial in every shipped scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.modes import MODES, available_modes, make_mode, register
from autonomy.types import Assist, Mode, RobotModel
from sim.scenario import available_scenarios, load_scenario
from sim.testing import cluttered_segments, synthetic_observation
from sim.types import SemanticComponent

ROBOT = RobotModel.rectangle(0.6, 0.5)


def observation(rng: np.random.Generator):
    """A cluttered synthetic room with a few semantic components in the robot frame."""
    segments = cluttered_segments(rng, ROBOT, n_boxes=8)
    components = (
        SemanticComponent(
            id="doorway_0",
            kind="doorway",
            centre=np.array([1.5, 0.3]),
            points=np.array([[1.5, -0.1], [1.5, 0.7]]),
            ends=np.array([[1.5, -0.1], [1.5, 0.7]]),
            width=0.8,
            normal=np.array([1.0, 0.0]),
        ),
        SemanticComponent(
            id="object_0",
            kind="object",
            centre=np.array([-1.0, 1.2]),
            points=np.array([[-1.0, 1.0], [-0.8, 1.2], [-1.0, 1.4], [-1.2, 1.2]]),
        ),
        SemanticComponent(
            id="wall_0",
            kind="wall",
            centre=np.array([0.0, -1.5]),
            points=np.column_stack((np.linspace(-2, 2, 21), np.full(21, -1.5))),
        ),
    )
    velocity = np.array([rng.uniform(0, 0.5), rng.uniform(-0.2, 0.2), 0.0])
    return synthetic_observation(segments, velocity=velocity, rng=rng, components=components)


def test_builtin_modes_are_registered():
    assert {"manual", "reactive_bn"} <= set(available_modes())
    assert available_modes() == sorted(MODES)


@pytest.mark.parametrize("name", available_modes())
def test_every_mode_steps_and_returns_a_well_formed_assist(name, rng):
    mode = make_mode(name)
    assert isinstance(mode, Mode) and mode.name == name
    mode.reset(ROBOT)
    for _ in range(3):
        obs = observation(rng)
        heading = rng.uniform(-math.pi, math.pi)
        u = np.array([0.6 * math.cos(heading), 0.6 * math.sin(heading), rng.uniform(-0.5, 0.5)])
        out = mode.step(obs, u)
        assert isinstance(out, Assist)
        for command in (out.v, out.g):
            assert command.shape == (3,) and np.all(np.isfinite(command))
        assert 0.0 <= out.beta <= 1.0
        assert isinstance(out.label, str) and isinstance(out.target, str)
        assert all(isinstance(k, str) and isinstance(v, float) for k, v in out.scores.items())
        assert out.predicted_path.ndim == 2 and out.predicted_path.shape[1] == 3
        assert np.all(np.isfinite(out.predicted_path))
        assert out.timings_ms["total"] >= 0.0
        assert all(t >= 0.0 for t in out.timings_ms.values())


@pytest.mark.parametrize("scenario_name", available_scenarios())
def test_every_mode_drives_a_short_trial_in_every_shipped_scenario(scenario_name, seed):
    from sim.world import World

    scenario = load_scenario(scenario_name)
    robot = RobotModel.from_spec(scenario.robot)
    for name in available_modes():
        mode = make_mode(name)
        mode.reset(robot)
        with World(scenario, seed=seed) as world:
            obs = world.reset()
            for k in range(30):
                u = np.array([0.5, 0.2 * math.sin(0.3 * k), 0.3])
                out = mode.step(obs, u)
                assert out.v.shape == (3,) and np.all(np.isfinite(out.v))
                assert 0.0 <= out.beta <= 1.0
                world.apply(out.v)
                world.step()
                obs = world.sense()
            assert world.t == pytest.approx(30 * robot.dt)


def test_robot_model_from_a_scenario():
    spec = load_scenario("cluttered_room").robot
    robot = RobotModel.from_spec(spec)
    np.testing.assert_array_equal(robot.footprint, spec.footprint())
    assert (robot.max_speed, robot.max_yaw_rate) == (spec.max_speed, spec.max_yaw_rate)
    assert robot.protective_margin == spec.protective_margin


def test_unknown_mode_lists_the_registered_names():
    with pytest.raises(ValueError, match="unknown mode 'telepathy'") as error:
        make_mode("telepathy")
    for name in available_modes():
        assert name in str(error.value)


def test_registration_refuses_a_second_factory_under_a_taken_name():
    def factory_a(**settings):
        return make_mode("manual")

    def factory_b(**settings):
        return make_mode("manual")

    try:
        assert register("_test_mode")(factory_a) is factory_a
        register("_test_mode")(factory_a)  # the same factory again is harmless
        with pytest.raises(ValueError, match="registered already"):
            register("_test_mode")(factory_b)
        assert "_test_mode" in available_modes()
        assert make_mode("_test_mode").name == "manual"
    finally:
        MODES.pop("_test_mode", None)


def test_manual_mode_takes_no_settings():
    with pytest.raises(ValueError, match="takes no settings"):
        make_mode("manual", gain=2.0)


@settings(max_examples=50, deadline=None)
@given(u=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1.2, 1.2)))
def test_manual_mode_sends_the_joystick_command(u):
    mode = make_mode("manual")
    mode.reset(ROBOT)
    obs = synthetic_observation(np.zeros((0, 2, 2)))
    out = mode.step(obs, np.array(u))
    np.testing.assert_array_equal(out.v, u)
    assert out.beta == 0.0 and out.label == "" and out.target == ""
    assert out.predicted_path.shape == (0, 3)


def test_settings_dict_hook_for_every_kind_of_mode():
    """The trial stores ``settings_dict()``: a mode's own, the registry wrapper's for a
    foreign class with a settings dataclass, ``{}`` without settings."""
    import dataclasses

    reactive = make_mode("reactive_bn", arbitration="blend")
    assert reactive.settings_dict()["arbitration"] == "blend"
    assert reactive.settings_dict()["dwa"] == dataclasses.asdict(reactive.settings.dwa)
    assert make_mode("manual").settings_dict() == {}

    @dataclasses.dataclass(frozen=True)
    class Gain:
        k: float = 2.0

    class Foreign:  # another package's mode, written before the hooks
        name = "foreign"

        def __init__(self, **kw):
            self.settings = Gain(**kw)

        def reset(self, robot):
            pass

        def step(self, obs, u):
            raise NotImplementedError

        def label_tasks(self):
            return {"x": "doorway"}

    from autonomy.modes import with_defaults

    wrapped = with_defaults(Foreign(k=3.0))
    assert wrapped.settings_dict() == {"k": 3.0}
    assert wrapped.label_tasks() == {"x": "doorway"}  # its own hook, not the default
    bare = Foreign()
    del bare.settings
    assert with_defaults(bare).settings_dict() == {}
