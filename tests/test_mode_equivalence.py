"""The optimised reactive mode, DWA and safety layer give the same outputs as before.

``GOLDEN`` holds the outputs of the implementation *before* the per-tick optimisations
(cached scanner geometry in :func:`autonomy.reactive_bn.cell_states`, edge-wise Cyrus-Beck
in :func:`autonomy.safety.translation_distance`, inlined ``sinc`` in
:func:`autonomy.safety.arc_poses`, remembered inflated radii, one ``ndtr`` pass in
:func:`autonomy.reactive_bn.input_sector_probabilities`) on 24 fixed synthetic cluttered
rooms (:func:`sim.testing.cluttered_segments`; if that generator's draws change,
regenerate the rows with the pre-optimisation code, ``git show`` of the commit before it).
The other tests compare each optimised function with the old expression on random
inputs (the old expressions are kept here as references).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from autonomy.dwa import dwa
from autonomy.reactive_bn import (
    ReactiveBNMode,
    ReactiveSettings,
    SectorGrid,
    cell_states,
    input_sector_probabilities,
    sector_grid,
)
from autonomy.safety import arc_poses, inflated_radius, safe_command, translation_distance
from autonomy.types import RobotModel
from sim.testing import cluttered_segments, synthetic_observation

nan, inf = math.nan, math.inf

# per case: reactive v (3), beta, p_occ, d, DWA v (3), DWA clearance, DWA n_checked,
# safe_command(u) v (3) and scale, safe_command(1.5 DWA v) scale, reactive label
GOLDEN = [
    (
        -0.009817777501249474,
        0.00190032758648598,
        0.047790810986454435,
        0.0,
        1.0,
        nan,
        0.504883346052515,
        0.07592328429724512,
        -0.1677315772117121,
        0.21297454447632191,
        1.0,
        -0.009817777501249474,
        0.00190032758648598,
        0.047790810986454435,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.5716505674008148,
        -0.2049746586929169,
        -0.32533610289617865,
        0.875,
        0.875,
        4.573455857335163,
        0.6278274239893983,
        -0.2516742250531613,
        -0.3476367343693107,
        0.14176674355833474,
        1.0,
        0.1784125712807299,
        0.12192230582879368,
        -0.16923168258425436,
        1.0,
        1.0,
        "GOA",
    ),
    (
        0.22116963699973816,
        -0.3151318684957433,
        -0.11982339152952641,
        0.8749999606504133,
        0.875,
        2.191312946666834,
        0.26963185083378527,
        -0.26983557626643184,
        0.022803366474418774,
        0.27497429340419177,
        1.0,
        -0.08549587909124573,
        -0.45780420002025785,
        -0.8097385208884765,
        0.7241379310344828,
        1.0,
        "GOA",
    ),
    (
        -0.14407539570936595,
        0.11062010070603727,
        -0.6959018429248507,
        0.4442365678819016,
        0.6875,
        0.3139164547212412,
        0.5491765940421699,
        0.11062010070603727,
        -0.6130494987992652,
        0.29765055300293103,
        1.0,
        -0.2766493415788994,
        0.04383060594012797,
        -0.3019752200757449,
        0.3962264150943396,
        1.0,
        "GOA",
    ),
    (
        -0.05936946648704072,
        -0.13852726231485657,
        -0.014053424771720011,
        0.6363795753927376,
        0.8181818181818182,
        0.22067300851891575,
        -0.03442981525445776,
        -0.07648839995057655,
        -0.022338303888268907,
        0.05997612415704785,
        2.0,
        -0.05150843123707516,
        -0.1235513749384201,
        0.00022305618814688621,
        0.5,
        1.0,
        "GOA",
    ),
    (
        -0.2580464110340647,
        -0.20123312685880573,
        -0.7947146710456002,
        1.0,
        0.0,
        5.05428991599746,
        0.633412844100158,
        0.030857261153132226,
        -0.018866929903964158,
        0.08614616120510105,
        1.0,
        -0.2580464110340647,
        -0.20123312685880573,
        -0.7947146710456002,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.00786488251668722,
        0.006176052379854606,
        -1.0716728349126023,
        0.0,
        0.625,
        nan,
        0.6971110534476394,
        -0.1919935058500651,
        -0.030705014240435202,
        0.19121186252877073,
        1.0,
        0.00786488251668722,
        0.006176052379854606,
        -1.0716728349126023,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.38816323794917024,
        0.10997014980965426,
        0.3432076163982576,
        0.9999999995286604,
        1.0,
        0.9953082067263379,
        0.38816323768146166,
        0.10997014990573376,
        0.3432076161371603,
        0.23575779506158656,
        1.0,
        0.9561370755010207,
        -0.09387328429700038,
        0.8971550064747806,
        1.0,
        1.0,
        "GOA",
    ),
    (
        0.08325913764872225,
        -0.12587774108253594,
        -0.3049626660238142,
        0.5396266642139949,
        0.8125,
        0.3606347216350221,
        0.4222980277924825,
        0.18992103211457498,
        -0.01321703289247661,
        0.2867569519217677,
        1.0,
        0.09511039434725058,
        -0.14379540711090744,
        -0.3483716051574908,
        0.53125,
        1.0,
        "OA",
    ),
    (
        0.01517065792317133,
        0.4286031939471711,
        -1.1001699292653382,
        0.9375,
        0.0625,
        0.761154325747149,
        0.05933024375078008,
        -0.18776107554153446,
        -0.4490171876760087,
        0.6593792562772472,
        1.0,
        0.01517065792317133,
        0.4286031939471711,
        -1.1001699292653382,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.05632279224622236,
        0.09332081302572219,
        -0.44544290550160537,
        1.0,
        0.0,
        2.5976791033089652,
        0.05632279224622236,
        0.2109950073475426,
        -0.44544290550160537,
        0.6978816237190456,
        1.0,
        0.05632279224622236,
        0.09332081302572219,
        -0.44544290550160537,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.07954028628213322,
        -0.12087044338682643,
        -0.6314943495558545,
        0.624954591771254,
        0.375,
        4.066648802679561,
        -0.07954028628213322,
        -0.12087044338682643,
        0.2335127957341408,
        0.37216526217339196,
        1.0,
        -0.07954028628213322,
        -0.12087044338682643,
        -0.6314943495558545,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.0005490308542024513,
        -0.009984916881032797,
        0.7775857076626183,
        0.0,
        0.5625,
        nan,
        -0.1936254163337249,
        -0.32524766896175455,
        0.342888952564334,
        0.1613962554053352,
        1.0,
        -0.0005490308542024513,
        -0.009984916881032797,
        0.7775857076626183,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.18831163903859977,
        0.6193420516033041,
        -0.31632721917803297,
        1.0,
        0.0,
        1.0886885940703817,
        0.5149568902733522,
        -0.10035014040632947,
        0.29685335184946543,
        0.4197786503388251,
        1.0,
        -0.18831163903859977,
        0.6193420516033041,
        -0.31632721917803297,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.22830653439737744,
        -0.03132408049439203,
        -0.4652874322610595,
        0.949998943013556,
        0.05,
        1.4643809176315876,
        -0.18162069187416463,
        0.01253863601228708,
        0.2661708371364406,
        inf,
        1.0,
        -0.22830653439737744,
        -0.03132408049439203,
        -0.4652874322610595,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.09762921666506343,
        0.3589691290738579,
        -0.6100895825581372,
        0.6875,
        0.6875,
        0.9533206200478274,
        -0.03179878964857691,
        0.285160514221397,
        -0.5699793601895389,
        0.20404873800284304,
        1.0,
        0.38237083055507215,
        0.521348081749272,
        -0.6983320717690532,
        1.0,
        1.0,
        "GOA",
    ),
    (
        -0.6475112768079081,
        0.31950488943711425,
        1.1013299283376796,
        1.0,
        0.0,
        1.443255615040958,
        0.39342474818882034,
        0.24419760584276465,
        -0.20535338693793376,
        inf,
        1.0,
        -0.6475112768079081,
        0.31950488943711425,
        1.1013299283376796,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.11721176694021528,
        0.23872651009192786,
        -0.6328545918777423,
        0.625,
        0.625,
        0.9970623225439517,
        0.14542856376391092,
        0.022480463757399344,
        -0.5120521436298768,
        0.1136941113773437,
        1.0,
        0.07018377223405589,
        0.599136587316142,
        -0.8341920056241848,
        1.0,
        1.0,
        "GOA",
    ),
    (
        -0.007908722225276856,
        -0.006119813131412748,
        0.6854725283768774,
        0.0,
        0.6363636363636364,
        nan,
        -0.07116024414490242,
        -0.2824924342980747,
        0.10094322147766371,
        0.24369130940214617,
        1.0,
        -0.007908722225276856,
        -0.006119813131412748,
        0.6854725283768774,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.8837928650894804,
        0.26408438399551765,
        -0.3096801429696734,
        0.7486411612869948,
        0.25,
        0.7316891033375,
        -0.08627328498803918,
        0.011779135497631904,
        -0.3096801429696734,
        inf,
        1.0,
        -0.8837928650894804,
        0.26408438399551765,
        -0.3096801429696734,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.10216815406728252,
        0.6583431620809956,
        0.9012192990182852,
        0.8666666666666667,
        0.13333333333333333,
        3.3378033168280288,
        0.35484302082850283,
        0.07107850865034412,
        0.45972974547405593,
        0.563564646935313,
        1.0,
        -0.10216815406728252,
        0.6583431620809956,
        0.9012192990182852,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.029489698243620053,
        0.03563648911072465,
        -0.6404018496871055,
        1.0,
        0.0,
        4.065106639527457,
        0.5173854665507535,
        0.18531887707383285,
        0.15971825276901697,
        0.20123493000268883,
        1.0,
        0.029489698243620053,
        0.03563648911072465,
        -0.6404018496871055,
        1.0,
        1.0,
        "FT",
    ),
    (
        -0.130675900300639,
        0.39785746898692215,
        -0.8969989434882448,
        0.49999497945496635,
        0.5,
        2.4831212794094446,
        -0.04564246391501861,
        -0.10129517272927899,
        -0.48965148448888146,
        0.3154617497335177,
        1.0,
        -0.130675900300639,
        0.39785746898692215,
        -0.8969989434882448,
        1.0,
        1.0,
        "FT",
    ),
    (
        0.5482625297940167,
        -0.005002930544483711,
        0.6736470321873045,
        0.8006862089665701,
        0.8125,
        0.7826153092007719,
        0.5793436751222827,
        -0.1359054803290003,
        0.6336353885546804,
        0.10945181258461537,
        1.0,
        0.311560630945022,
        0.3832748272513615,
        0.6139794861696792,
        0.7358490566037735,
        1.0,
        "GOA",
    ),
]


def _cases():
    rng = np.random.default_rng(20261123)
    robot = RobotModel.rectangle()
    for k in range(len(GOLDEN)):
        segments = cluttered_segments(rng, robot, n_boxes=int(rng.integers(6, 16)))
        velocity = np.array(
            [rng.uniform(-0.3, 0.8), rng.uniform(-0.4, 0.4), rng.uniform(-0.5, 0.5)]
        )
        obs = synthetic_observation(segments, velocity=velocity, rng=rng)
        heading = rng.uniform(-math.pi, math.pi)
        speed = rng.uniform(0.0, 1.0) if k % 6 else 0.01  # every sixth: a pure rotation
        u = np.array([speed * math.cos(heading), speed * math.sin(heading), rng.uniform(-1.2, 1.2)])
        yield robot, obs, u


def test_outputs_match_the_pre_optimisation_golden_rows():
    mode = ReactiveBNMode()
    labels = set()
    for (robot, obs, u), row in zip(_cases(), GOLDEN, strict=True):
        if mode.robot_ is None:
            mode.reset(robot)
        a = mode.step(obs, u)
        r = dwa(u, obs.points, obs.velocity, robot)
        v_safe, scale = safe_command(u, obs.points, robot)
        _, scale2 = safe_command(r.v * 1.5, obs.points, robot, horizon_s=1.0)
        got = [*a.v, a.beta, a.scores["p_occ"], a.scores["d"], *r.v, r.clearance, r.n_checked]
        got += [*v_safe, scale, scale2]
        np.testing.assert_allclose(got, row[:-1], rtol=1e-12, atol=1e-12)
        assert a.label == row[-1]
        labels.add(a.label)
    # the rows exercise the situations and the safety layer's scaling
    assert labels == {"FT", "OA", "GOA"}
    assert any(row[14] < 1 for row in GOLDEN) and any(row[14] == 1 for row in GOLDEN)


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
