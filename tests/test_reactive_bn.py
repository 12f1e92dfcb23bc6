"""The reactive Bayesian-network mode (autonomy.reactive_bn) and the arbitration it
uses (autonomy.arbitration): properties for any seed, and the three situations in
small scenes seen by two simulated 270-degree scanners (sim.testing)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.arbitration import blend
from autonomy.modes import make_mode
from autonomy.reactive_bn import (
    FREE,
    OCCUPIED,
    SITUATIONS,
    UNKNOWN,
    ReactiveBNMode,
    ReactiveSettings,
    cell_states,
    input_sector_probabilities,
    oa_attenuation,
    sector_occupancy,
    situation_posteriors,
)
from autonomy.types import RobotModel
from sim.testing import box_segments, cluttered_segments, synthetic_observation

ROBOT = RobotModel.rectangle(0.6, 0.5)
SETTINGS = ReactiveSettings()


def mode(arbitration: str = "exclusive") -> ReactiveBNMode:
    m = ReactiveBNMode(ReactiveSettings(arbitration=arbitration))
    m.reset(ROBOT)
    return m


def wall_ahead(clearance: float) -> np.ndarray:
    """A long wall across the robot's path, ``clearance`` [m] in front of the footprint."""
    return box_segments((0.3 + clearance + 0.05, 0.0), (0.1, 8.0))


def corridor(clearance: float = 0.15) -> np.ndarray:
    """Walls along the robot's sides, ``clearance`` [m] from the footprint."""
    y = 0.25 + clearance + 0.05
    return np.concatenate([box_segments((0, y), (8, 0.1)), box_segments((0, -y), (8, 0.1))])


# ------------------------------------------------------------------ arbitration


finite = st.floats(-10, 10, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(
    u=st.tuples(finite, finite, finite), g=st.tuples(finite, finite, finite), beta=st.floats(0, 1)
)
def test_blend_lies_between_u_and_g(u, g, beta):
    u, g = np.array(u), np.array(g)
    v = blend(u, g, beta)
    assert np.all(v >= np.minimum(u, g)) and np.all(v <= np.maximum(u, g))


def test_blend_ends_and_clipping():
    u, g = np.array([0.5, -0.2, 0.3]), np.array([0.0, 0.4, -1.0])
    np.testing.assert_array_equal(blend(u, g, 0.0), u)
    np.testing.assert_array_equal(blend(u, g, 1.0), g)
    np.testing.assert_array_equal(blend(u, g, 3.0), g)
    np.testing.assert_array_equal(blend(u, g, -1.0), u)
    np.testing.assert_array_equal(blend(u, g, math.nan), u)
    np.testing.assert_allclose(blend(u, g, 0.25), 0.75 * u + 0.25 * g)


# ------------------------------------------------------------- OA attenuation


@settings(max_examples=100, deadline=None)
@given(d_safe=st.floats(0, 1), a=st.floats(0, 5), b=st.floats(0, 5))
def test_oa_attenuation_is_zero_up_to_d_safe_then_rises_towards_one(d_safe, a, b):
    assert oa_attenuation(d_safe, d_safe) == 0.0
    assert oa_attenuation(d_safe - a, d_safe) == 0.0
    lo, hi = sorted((a, b))
    alpha_lo = oa_attenuation(d_safe + lo, d_safe)
    alpha_hi = oa_attenuation(d_safe + hi, d_safe)
    assert 0.0 <= alpha_lo <= alpha_hi < 1.0
    if 0.05 < lo < hi - 1e-3:
        assert alpha_lo < alpha_hi  # strictly rising where float resolution allows
    assert oa_attenuation(d_safe + 1e6, d_safe) == pytest.approx(1.0, abs=1e-5)
    assert oa_attenuation(math.inf, d_safe) == 1.0


def test_oa_attenuation_matches_eq_3_7():
    d = np.array([0.1, 0.3, 0.65, 1.15])
    np.testing.assert_allclose(
        oa_attenuation(d, 0.15), [0.0, math.exp(-1 / 0.15), math.exp(-2.0), math.exp(-1.0)]
    )


# ------------------------------------------------------------ the probability models


@settings(max_examples=60, deadline=None)
@given(theta=st.floats(-math.pi, math.pi), sigma_deg=st.floats(0.5, 90))
def test_input_model_is_a_distribution_peaked_at_the_input(theta, sigma_deg):
    edges = mode().grid_.edges
    p = input_sector_probabilities(theta, math.radians(sigma_deg), edges)
    assert p.shape == (len(edges) - 1,)
    assert np.all(p >= 0) and p.sum() == pytest.approx(1.0)
    # the sector containing the input has the most mass (up to rounding at its edges)
    j = min(int((theta + math.pi) // math.radians(SETTINGS.sector_deg)), len(p) - 1)
    if np.min(np.abs(edges - theta)) > 1e-6:
        assert p[j] >= p.max() * (1 - 1e-9)


def test_input_model_wraps_around_pi():
    edges = mode().grid_.edges
    sigma = math.radians(10)
    p = input_sector_probabilities(math.pi, sigma, edges)
    # the mass straddles +-pi evenly: first and last sectors, and mirror pairs
    np.testing.assert_allclose(p, p[::-1], atol=1e-12)
    near = input_sector_probabilities(math.pi - 1e-9, sigma, edges)
    far = input_sector_probabilities(-math.pi + 1e-9, sigma, edges)
    np.testing.assert_allclose(near, far, atol=1e-6)
    # the normal's mass over one 5-degree sector centred on the input
    centre = input_sector_probabilities(math.radians(2.5), sigma, edges)
    half = math.radians(2.5) / sigma
    assert centre.max() == pytest.approx(math.erf(half / math.sqrt(2)), rel=1e-9)


@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_situation_posteriors_sum_to_one(data):
    n = 72
    raw = np.array(data.draw(st.lists(st.floats(0, 1), min_size=n, max_size=n)))
    p_input = raw / raw.sum() if raw.sum() > 0 else np.full(n, 1 / n)
    p_sector = np.array(data.draw(st.lists(st.floats(0, 1), min_size=n, max_size=n)))
    post = situation_posteriors(p_input, p_sector)
    assert post.shape == (3,) and np.all(post >= 0)
    assert post.sum() == pytest.approx(1.0)


def test_environment_model_free_space_and_shadow():
    grid = mode().grid_
    free = synthetic_observation(np.zeros((0, 2, 2)))
    assert np.all(cell_states(free.scans, grid) == FREE)
    assert np.all(sector_occupancy(free.scans, grid) == 0.0)
    # a wall 0.3 m ahead: cells behind it unknown, cells hit occupied, in front free
    obs = synthetic_observation(wall_ahead(0.3))
    state = cell_states(obs.scans, grid)
    x = grid.cells[:, 0]
    face = 0.3 + 0.3
    assert np.all(state[x < face - 0.06] == FREE)
    assert np.all(state[x > face + 0.06] == UNKNOWN)
    assert np.any(state == OCCUPIED)
    assert np.all(np.abs(x[state == OCCUPIED] - face) <= 0.06)
    # p(s_j = Occ) = share of the sector's cells not free (3.13), from the cells directly
    p = sector_occupancy(obs.scans, grid)
    expected = np.bincount(grid.sector, weights=(state != FREE), minlength=len(p)) / grid.counts
    np.testing.assert_allclose(p, expected)
    ahead = int((0.0 + math.pi) // math.radians(SETTINGS.sector_deg))
    behind = 0
    assert 0.5 < p[ahead] < 1.0 and p[behind] == 0.0


# ------------------------------------------------------------------ the situations


def random_observation(seed: int) -> object:
    rng = np.random.default_rng(seed)
    segments = cluttered_segments(rng, ROBOT, n_boxes=int(rng.integers(0, 14)), room=(5.0, 4.0))
    velocity = np.array([rng.uniform(-0.5, 0.8), rng.uniform(-0.5, 0.5), rng.uniform(-1, 1)])
    return synthetic_observation(segments, velocity=velocity, rng=rng)


@settings(max_examples=30, deadline=None)
@given(
    scene=st.integers(0, 2**32 - 1),
    u=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1.2, 1.2)),
)
def test_posteriors_sum_to_one_and_beta_in_unit_interval(scene, u):
    u = np.array(u)
    obs = random_observation(scene)
    out = mode("blend").step(obs, u)
    post = np.array([out.scores[s] for s in SITUATIONS])
    assert post.sum() == pytest.approx(1.0) and np.all(post >= 0)
    assert 0.0 <= out.beta <= 1.0
    assert out.label in SITUATIONS
    if math.hypot(u[0], u[1]) >= SETTINGS.min_translation:
        assert out.beta == pytest.approx(post.max())
        assert out.label == SITUATIONS[int(np.argmax(post))]
    # exclusive: the same recognition, v = g alone, beta 0 (u as given) or 1 (g replaces u)
    ex = mode("exclusive").step(obs, u)
    assert ex.label == out.label and ex.scores.keys() == out.scores.keys()
    np.testing.assert_array_equal([ex.scores[s] for s in SITUATIONS], post)
    np.testing.assert_array_equal(ex.v, ex.g)
    assert ex.beta == (0.0 if ex.label == "FT" and np.array_equal(ex.g, u) else 1.0)
    np.testing.assert_allclose(ex.v, blend(u, ex.g, ex.beta))
    assert 0.0 <= out.scores["p_occ"] <= 1.0
    np.testing.assert_allclose(out.v, blend(u, out.g, out.beta))
    assert np.all(np.isfinite(out.v))


def test_free_space_is_free_travel():
    obs = synthetic_observation(box_segments((0, 0), (2 * SETTINGS.zone_radius + 1.0,) * 2))
    for u in ([0.8, 0.0, 0.0], [0.2, -0.6, 0.4], [-0.5, 0.5, 0.0]):
        out = mode().step(obs, np.array(u))
        assert out.label == "FT"
        np.testing.assert_array_equal(out.g, u)
        np.testing.assert_allclose(out.v, u)
        assert out.scores["p_occ"] == 0.0


@pytest.mark.parametrize("clearance", [0.05, 0.15, 0.3, 0.4])
def test_driving_at_a_wall_in_the_zone_is_object_approach(clearance):
    obs = synthetic_observation(wall_ahead(clearance))
    u = np.array([0.6, 0.0, 0.0])
    out = mode("blend").step(obs, u)
    assert out.label == "OA"
    assert out.scores["d"] == pytest.approx(clearance, abs=1e-6)
    assert out.v[0] < u[0]  # slower towards the wall
    assert out.v[0] == pytest.approx(u[0] * (1 - out.beta + out.beta * out.scores["alpha"]))
    ex = mode("exclusive").step(obs, u)  # alpha u alone (3.6), zero within d_safe (3.7)
    assert ex.label == "OA" and ex.beta == 1.0
    np.testing.assert_array_equal(ex.v, ex.scores["alpha"] * u)
    if clearance <= SETTINGS.d_safe:
        np.testing.assert_array_equal(ex.v, np.zeros(3))


def test_driving_into_free_space_between_obstacles_is_obstacle_avoidance():
    obs = synthetic_observation(corridor(0.15), velocity=np.array([0.4, 0.0, 0.0]))
    out = mode().step(obs, np.array([0.6, 0.0, 0.0]))
    assert out.label == "GOA"
    assert out.scores["p_occ"] > 0.5
    assert out.v[0] > 0.4  # the DWA keeps the user's heading and speed up
    assert out.predicted_path.shape[1] == 3 and len(out.predicted_path) > 1


def test_pure_rotation_passes_through():
    for segments in (corridor(0.1), wall_ahead(0.2), np.zeros((0, 2, 2))):
        out = mode().step(synthetic_observation(segments), np.array([0.0, 0.0, 0.9]))
        assert out.label == "FT" and out.beta == 0.0
        np.testing.assert_array_equal(out.v, [0.0, 0.0, 0.9])
        assert out.scores["FT"] == 1.0 and math.isnan(out.scores["d"])


def test_no_memory_between_ticks(rng):
    observations = [random_observation(int(s)) for s in rng.integers(0, 2**32, 3)]
    observations.append(synthetic_observation(corridor(0.15), velocity=np.array([0.3, 0, 0])))
    observations.append(synthetic_observation(wall_ahead(0.2)))
    inputs = [np.array([0.6, 0.1, 0.2]), np.array([0.0, -0.5, 0.0])]
    pairs = list(itertools.product(range(len(observations)), range(len(inputs))))
    m = mode()
    first = {k: m.step(observations[k[0]], inputs[k[1]]) for k in pairs}
    for order in (pairs[::-1], [pairs[i] for i in rng.permutation(len(pairs))]):
        for k in order:
            out = m.step(observations[k[0]], inputs[k[1]])
            np.testing.assert_array_equal(out.v, first[k].v)
            assert out.label == first[k].label and out.beta == first[k].beta
            for key, value in first[k].scores.items():
                assert out.scores[key] == value or (
                    math.isnan(value) and math.isnan(out.scores[key])
                )


def test_settings_are_validated_and_reach_the_mode():
    assert SETTINGS.arbitration == "exclusive"
    for bad in ("mix", "Exclusive", None):
        with pytest.raises(ValueError, match="reactive_bn setting arbitration: .*exclusive, blend"):
            ReactiveSettings(arbitration=bad)
    with pytest.raises(ValueError, match="setting arbitration"):
        make_mode("reactive_bn", arbitration="max")
    assert make_mode("reactive_bn", arbitration="blend").settings.arbitration == "blend"
    with pytest.raises(ValueError, match="sector_deg"):
        ReactiveSettings(sector_deg=7.0)
    with pytest.raises(ValueError, match="sigma_deg"):
        ReactiveSettings(sigma_deg=0.0)
    with pytest.raises(ValueError, match="zone_radius"):
        ReactiveBNMode(ReactiveSettings(zone_radius=0.3)).reset(ROBOT)
    with pytest.raises(ValueError, match="allowed: sector_deg"):
        make_mode("reactive_bn", sector=5)
    m = make_mode("reactive_bn", sigma_deg=20.0, dwa={"horizon_s": 1.0})
    assert m.settings.sigma_deg == 20.0 and m.settings.dwa.horizon_s == 1.0
    with pytest.raises(ValueError, match="DWA setting horizon_s"):
        make_mode("reactive_bn", dwa={"horizon_s": -1.0})
    with pytest.raises(RuntimeError, match="reset"):
        ReactiveBNMode().step(synthetic_observation(corridor()), np.zeros(3))
