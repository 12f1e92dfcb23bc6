"""Issue 25: the reactive mode's compiled cell marking (autonomy/_reactive_kernels.py)
gives the same cell states as the numpy code before it (tests/reactive_reference.py), on
scans of a drive through the shipped scenes and on random scans with misses and hits
outside the zone."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from autonomy.reactive_bn import cell_states, sector_grid
from autonomy.types import RobotModel
from sim.scenario import load_scenario
from sim.world import World
from tests.reactive_reference import cell_states as reference


def test_cell_states_equal_the_reference_on_a_drive_and_random_scans(rng):
    for name in ("cluttered_room", "practice_course"):
        scenario = load_scenario(name)
        robot = RobotModel.from_spec(scenario.robot, dt=0.05)
        grid = sector_grid(robot, zone_radius=1.5, resolution=0.05, sector_deg=5.0)
        with World(scenario, seed=int(rng.integers(2**31))) as world:
            obs = world.reset()
            for _ in range(150):
                v = rng.uniform((-0.5, -0.5, -1.0), (1.0, 0.5, 1.0))
                world.apply(v)
                world.step()
                obs = world.sense()
                assert np.array_equal(cell_states(obs.scans, grid), reference(obs.scans, grid))
                # the same beams with random ranges: misses, hits inside and far outside
                scans = tuple(
                    replace(s, ranges=rng.choice([0.05, 0.7, 1.2, 3.0, s.max_range], len(s.ranges))
                            * rng.uniform(0.5, 1.0, len(s.ranges)))
                    for s in obs.scans
                )  # fmt: skip
                assert np.array_equal(cell_states(scans, grid), reference(scans, grid))
