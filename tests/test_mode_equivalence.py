"""The optimised reactive mode, DWA and safety layer give the same outputs as before.

The golden rows (``tests/golden/mode_equivalence.json``, made by
``tests/golden/make_mode_equivalence.py``) hold the outputs on 24 fixed synthetic cluttered
rooms, first made by the implementation *before* the per-tick optimisations (cached scanner
geometry in :func:`autonomy.reactive_bn.cell_states`, edge-wise Cyrus-Beck in
:func:`autonomy.safety.translation_distance`, inlined ``sinc`` in
:func:`autonomy.safety.arc_poses`, remembered inflated radii, one ``ndtr`` pass in
:func:`autonomy.reactive_bn.input_sector_probabilities`). The other tests compare each
optimised function with the old expression on random inputs (the old expressions are kept
here as references).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ndtr

from autonomy.reactive_bn import (
    ReactiveSettings,
    SectorGrid,
    cell_states,
    input_sector_probabilities,
    sector_grid,
)
from autonomy.safety import arc_poses, inflated_radius, translation_distance
from autonomy.types import RobotModel
from sim.testing import cluttered_segments, synthetic_observation

sys.path.insert(0, str(Path(__file__).parent / "golden"))
from make_mode_equivalence import COLUMNS, cases, golden_mode, load, outputs  # noqa: E402

GOLDEN = load()
# The rows were made on another machine. Their arithmetic goes through no BLAS sum, but
# numpy's exp and trigonometric ufuncs pick SIMD paths by CPU and may round an ulp apart
# (1e-16 relative): 1e-12 allows 10^4 ulps, far below any change of a rule (>= 1e-6).
GOLDEN_RTOL = GOLDEN_ATOL = 1e-12
SAFE_SCALE = COLUMNS.index("safe_scale")


def test_outputs_match_the_pre_optimisation_golden_rows():
    mode = golden_mode()  # arbitration "blend", as the rows were made
    labels = set()
    for (robot, obs, u), (row, label) in zip(cases(len(GOLDEN)), GOLDEN, strict=True):
        got, got_label = outputs(mode, robot, obs, u)
        np.testing.assert_allclose(got, row, rtol=GOLDEN_RTOL, atol=GOLDEN_ATOL)
        assert got_label == label
        labels.add(got_label)
    # the rows exercise the situations and the safety layer's scaling
    assert labels == {"FT", "OA", "GOA"}
    scales = [row[SAFE_SCALE] for row, _ in GOLDEN]
    assert any(x < 1 for x in scales) and any(x == 1 for x in scales)


def _old_cell_states(scans, grid: SectorGrid) -> np.ndarray:
    """The uncached inverse sensor model, as before (fresh geometry every call)."""
    fresh = SectorGrid(
        grid.cells, grid.sector, grid.counts, grid.edges, grid.resolution, grid.half, grid.lookup
    )
    return cell_states(scans, fresh)


def test_cached_scanner_geometry_gives_the_same_cell_states(rng):
    robot = RobotModel.rectangle()
    s = ReactiveSettings()
    grid = sector_grid(
        robot, zone_radius=s.zone_radius, resolution=s.grid_resolution, sector_deg=s.sector_deg
    )
    for k in range(6):
        segments = cluttered_segments(rng, robot, n_boxes=int(rng.integers(4, 12)))
        # scanners at other mounts and resolutions on some ticks: new cache keys
        obs = synthetic_observation(
            segments, rng=rng, resolution_deg=(1.0, 0.5, 1.0)[k % 3], fov_deg=(270.0, 180.0)[k % 2]
        )
        warm = cell_states(obs.scans, grid)
        np.testing.assert_array_equal(warm, _old_cell_states(obs.scans, grid))
        np.testing.assert_array_equal(cell_states(obs.scans, grid), warm)  # from the cache
    assert 1 <= len(grid.cache) <= 16


def _old_translation_distance(points, direction, robot):
    u = np.asarray(direction, dtype=float)[:2]
    u = u / np.linalg.norm(u)
    num = points @ robot.edge_normals.T - robot.edge_offsets
    den = robot.edge_normals @ u
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = num / den
    entering = den > 1e-12
    leaving = den < -1e-12
    lam_in = np.max(np.where(entering, ratio, -np.inf), axis=1, initial=0.0)
    lam_out = np.min(np.where(leaving, ratio, np.inf), axis=1, initial=np.inf)
    parallel_ok = np.all(np.where(~entering & ~leaving, num <= 0.0, True), axis=1)
    return np.where(parallel_ok & (lam_in <= lam_out), lam_in, np.inf)


@pytest.mark.parametrize(
    "robot",
    [
        RobotModel.rectangle(),
        RobotModel(np.array([[-0.3, -0.2], [0.2, -0.3], [0.4, 0.1], [0.0, 0.35], [-0.35, 0.1]])),
    ],
)
def test_translation_distance_matches_the_old_expression(rng, robot):
    points = rng.uniform(-3, 3, (400, 2))
    points[:50] = rng.uniform(-0.3, 0.3, (50, 2))  # some inside the footprint
    angles = np.concatenate((rng.uniform(-math.pi, math.pi, 20), np.arange(8) * math.pi / 4))
    for a in angles:  # the multiples of 45 degrees make edges parallel to the direction
        direction = np.array([math.cos(a), math.sin(a)]) * rng.uniform(0.1, 2.0)
        new = translation_distance(points, direction, robot)
        old = _old_translation_distance(points, direction, robot)
        np.testing.assert_array_equal(new, old)
        assert np.isfinite(new).any() and np.isinf(new).any()


def test_arc_poses_matches_numpy_sinc(rng):
    v = rng.uniform(-1.2, 1.2, (50, 3))
    v[:5, 2] = 0.0  # straight lines: the sinc at zero
    t = np.linspace(0.0, 2.0, 21)
    a = v[:, 2, None] * t
    s1 = t * np.sinc(a / np.pi)
    s2 = t * np.sin(a / 2) * np.sinc(a / (2 * np.pi))
    vx, vy = v[:, 0, None], v[:, 1, None]
    old = np.stack((vx * s1 - vy * s2, vx * s2 + vy * s1, a), axis=-1)
    np.testing.assert_array_equal(arc_poses(v, t), old)


def test_remembered_inflated_radius_is_the_robots(rng):
    robots = [RobotModel.rectangle(rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0)) for _ in range(3)]
    for robot in robots:
        for margin in rng.uniform(0.0, 0.5, 5):
            assert inflated_radius(robot, margin) == robot.inflated_radius(margin)
            assert inflated_radius(robot, margin) == robot.inflated_radius(margin)  # cached


def test_input_sector_probabilities_match_the_old_expression(rng):
    edges = -math.pi + (2 * math.pi / 72) * np.arange(73)
    for theta in rng.uniform(-math.pi, math.pi, 20):
        sigma = rng.uniform(0.05, math.pi / 2)
        shifts = (2 * math.pi * np.array([-1.0, 0.0, 1.0]))[:, None]
        upper = ndtr((edges[1:] - theta + shifts) / sigma)
        lower = ndtr((edges[:-1] - theta + shifts) / sigma)
        mass = (upper - lower).sum(axis=0)
        np.testing.assert_array_equal(
            input_sector_probabilities(theta, sigma, edges), mass / mass.sum()
        )
