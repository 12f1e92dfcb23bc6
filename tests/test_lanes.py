"""Straight, centred lanes through doorways and gaps (sim.lanes, issue 19) and the
passages' extent along their axis (sim.semantics.passage_extent)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.lanes import straight_lanes
from sim.scenario import load_scenario
from sim.semantics import derive_components, passage_extent


@pytest.fixture(scope="module")
def doorways():
    scenario = load_scenario("demo_doorway_crossing")
    return scenario, derive_components(scenario)


def test_a_doorway_in_a_thin_wall_ends_where_the_wall_does(doorways):
    scenario, components = doorways
    for comp in components:
        if comp.kind == "doorway":  # walls 0.1 m thick: the first free probe is 0.1 m out
            assert passage_extent(scenario, comp) == (0.1, 0.1)


def test_lanes_start_on_the_axis_and_leave_the_doorways_clearance(doorways):
    scenario, components = doorways
    lanes = straight_lanes(scenario, components=components)
    passages = [c for c in components if c.kind in ("doorway", "gap")]
    assert [(lane.component, lane.side) for lane in lanes] == [
        (c.id, side) for c in passages for side in (1.0, -1.0)
    ]
    half_length, width = scenario.robot.length / 2, scenario.robot.width
    for lane, comp in zip(lanes, [c for c in passages for _ in (0, 1)], strict=True):
        heading = lane.side * np.asarray(comp.normal)
        start = np.array([lane.start.x, lane.start.y])
        np.testing.assert_allclose(start, comp.centre - 1.2 * heading, atol=1e-9)
        assert lane.start.yaw == pytest.approx(math.atan2(heading[1], heading[0]))
        assert lane.through_m == pytest.approx(1.2 + 0.1 + half_length)
        assert lane.clearance_m == pytest.approx((comp.width - width) / 2, abs=2e-4)
        assert lane.run_out_m == 1.0


def test_an_approach_through_an_obstacle_has_no_clearance():
    """cluttered_room's gap_2 faces wall_x4_middle: from the east the approach runs through
    the wall, from the west the lane ends 0.125 m before it."""
    scenario = load_scenario("cluttered_room")
    components = derive_components(scenario)
    lanes = {
        (lane.component, lane.side): lane
        for lane in straight_lanes(scenario, components=components)
    }
    assert lanes[("gap_2", -1.0)].clearance_m == 0.0
    assert lanes[("gap_2", 1.0)].run_out_m == pytest.approx(0.125)
    assert lanes[("doorway_0", 1.0)].clearance_m == pytest.approx(0.125, abs=2e-4)
