"""Sec. 7.5's clearance from the laser (tasks.clearance): the range from the robot's centre,
never below the footprint's clearance, and its per-trial statistics."""

from __future__ import annotations

import math

import numpy as np

from tasks.clearance import RangeStats, lrf_range
from tasks.geometry import footprint_clearance
from tasks.primary import CLEARANCE_BIN_EDGES_M

FOOTPRINT = np.array([[-0.3, -0.25], [0.3, -0.25], [0.3, 0.25], [-0.3, 0.25]])


def test_lrf_range_is_the_nearest_hit_from_the_centre_and_bounds_the_footprint_clearance(rng):
    points = rng.uniform(-5, 5, size=(200, 2))
    r = lrf_range(points)
    assert math.isclose(r, float(np.hypot(points[:, 0], points[:, 1]).min()))
    # the footprint contains the centre: its clearance is never larger than the range
    assert footprint_clearance(points, FOOTPRINT) <= r + 1e-12
    assert lrf_range(np.empty((0, 2))) == math.inf


def test_range_stats_match_numpy_and_fill_the_clearance_bins(rng):
    values = rng.uniform(0.2, 3.0, size=300)
    stats = RangeStats()
    for v in values:
        stats.add(float(v))
    stats.add(math.inf)  # nothing in range: the overflow bin only
    stats.add(math.nan)  # no measurement: not counted
    s = stats.summary()
    assert math.isclose(s["mean_m"], values.mean()) and math.isclose(s["std_m"], values.std())
    assert math.isclose(s["min_m"], values.min())
    assert s["samples"] == 301 and len(s["histogram"]) == len(CLEARANCE_BIN_EDGES_M)
    assert s["histogram"][-1] == int((values >= 2.0).sum()) + 1
    assert RangeStats().summary()["mean_m"] is None
