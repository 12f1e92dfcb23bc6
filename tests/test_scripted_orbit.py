"""The scripted driver's inspection (study.participants.scripted): it orbits until the
inspection counts as the task counts it (tasks.inspection), and does not insist on an
orbit entry the robot will not reach."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.scene import Cylinder
from sim.types import Pose2D
from study.participants.scripted import (
    ORBIT_EXTRA,
    ScriptedParticipant,
    ScriptedSettings,
    _OrbitLeg,
    _PathLeg,
)
from tasks.primary import PrimarySettings, inspection_tracker

OBJECT = Cylinder("bin", (0.0, 0.0), 0.25, 0.7, (0.9, 0.1, 0.1))
LEG = _OrbitLeg(centre=(0.0, 0.0), radius=1.05, direction=1, arc=math.radians(120))


def at(phi: float) -> Pose2D:
    """On the orbit at polar angle ``phi`` [rad], facing the object."""
    return Pose2D(LEG.radius * math.cos(phi), LEG.radius * math.sin(phi), phi + math.pi)


def orbit_until_done(watch: bool, offset_deg: float) -> float:
    """Drive the (counter-clockwise) orbit kinematically from polar angle 0; before it,
    drift on the approach swept ``offset_deg`` of the task's visit (negative: the other
    way). Returns the visit's net arc [deg] when the driver ends the orbit."""
    p = ScriptedParticipant(np.random.default_rng(0))
    tracker = inspection_tracker(OBJECT, PrimarySettings())
    p._watch = tracker if watch else None
    sideways = np.array([0.0, -0.3, 0.0])  # facing the centre, -y is counter-clockwise
    steps = round(abs(offset_deg) / 5)
    for k in range(steps + 1):  # the drift ends at angle 0
        tracker.update(at(math.radians(offset_deg * (k / steps - 1) if steps else 0.0)), sideways)
    phi = 0.0
    for _ in range(2000):
        u = p._follow_orbit(at(phi), LEG)
        if u is None:
            return math.degrees(tracker.visit_arc)
        phi += 0.3 / LEG.radius * 0.05  # one tick along the orbit
        tracker.update(at(phi), sideways)  # p._watch, when watching
    raise AssertionError("the orbit never ended")


def test_the_orbit_goes_on_until_the_visit_counts():
    """Approach drift swept 40 degrees the other way: the planned 120 degrees leave the
    visit at 80 (the task's 90 missed); watching, the driver goes on until it counts."""
    assert orbit_until_done(watch=False, offset_deg=-40) < 90.0
    assert orbit_until_done(watch=True, offset_deg=-40) >= 90.0


def test_the_orbit_ends_as_soon_as_the_visit_counts():
    """Drift the same way already swept 50 degrees: the orbit ends at 90, not 170."""
    assert 90.0 <= orbit_until_done(watch=True, offset_deg=50) < 100.0


def test_the_orbit_gives_up_a_quarter_turn_beyond_its_plan():
    p = ScriptedParticipant(np.random.default_rng(0))
    p._watch = inspection_tracker(OBJECT, PrimarySettings())  # never satisfied here
    pose = Pose2D(LEG.radius, 0.0, math.pi)
    p._follow_orbit(pose, LEG)
    p._swept = LEG.arc + ORBIT_EXTRA - 1e-6
    assert p._follow_orbit(pose, LEG) is not None
    p._swept = LEG.arc + ORBIT_EXTRA
    assert p._follow_orbit(pose, LEG) is None


def test_the_entry_is_given_up_after_entry_tries_stuck_episodes():
    p = ScriptedParticipant(np.random.default_rng(0), settings=ScriptedSettings(entry_tries=2))
    entry = _PathLeg(np.zeros((3, 2)), None, True, face=(0.0, 0.0))
    goal = _PathLeg(np.zeros((3, 2)), 0.0, True)
    near, far = Pose2D(0.3, 0.0, 0.0), Pose2D(2.0, 0.0, 0.0)
    p._stuck = 1
    assert not p._give_up_entry(entry, near)
    p._stuck = 2
    assert p._give_up_entry(entry, near)
    assert not p._give_up_entry(goal, near) and not p._give_up_entry(LEG, near)
    assert not p._give_up_entry(entry, far) and p._stuck == 0  # far away: forgotten


def test_turning_in_place_under_a_translation_command_counts_as_stuck():
    """Generated scene 19 (issue 20's scenes bench): the reactive mode's OA passed only the
    turn while the driver pushed backwards for 540 s; the turns reset the stuck clock, so
    the orbit's entry was never given up. Only translation counts as moving now."""
    s = ScriptedSettings()
    p = ScriptedParticipant(np.random.default_rng(0), settings=s)
    p._still_since, p._still_at, p._backoff_until = 0.0, (0.0, 0.0, 0.0), -math.inf
    u, t, yaw = np.array([-0.15, 0.0, 0.4]), 0.0, 0.0
    while p._stuck == 0 and t < 5.0:  # the heading turns 0.02 rad a tick, no translation
        t, yaw = t + 0.05, yaw + 0.02
        out = p._unstick(t, Pose2D(0.005, 0.0, yaw), u)
    assert p._stuck == 1 and t == pytest.approx(s.stuck_s, abs=0.06)
    assert out[0] > 0  # it backs away from where it pushed
    q = ScriptedParticipant(np.random.default_rng(0), settings=s)
    q._still_since, q._still_at, q._backoff_until = 0.0, (0.0, 0.0, 0.0), -math.inf
    for k in range(1, 100):  # translating: never stuck
        q._unstick(0.05 * k, Pose2D(0.01 * k, 0.0, 0.0), u)
    assert q._stuck == 0
