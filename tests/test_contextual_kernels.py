"""The compiled contextual step (autonomy._kernels, issue 25) gives what the numpy/Python
code before it gave (tests/contextual_reference.py, kept verbatim): the local EM fit, the
pooled kNN and the fit cache of the fast online GMR, the rollout (Alg. 3), the recogniser,
the candidates' features and the tracking controller, on seeded random inputs and on ticks
recorded from a synthetic trial (tests/golden/contextual_ticks.npz, made by
tests/golden/make_contextual_ticks.py). Values agree within the rounding of another
summation order (tests/fp.py; bit for bit where OpenBLAS runs its Haswell kernels, whose
order the kernels repeat), decisions exactly unless taken at a near-tie."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from scipy.spatial import cKDTree

from autonomy import _kernels, _tick_kernels
from autonomy.contextual import ContextualTaskMode, rollout
from autonomy.features import encode, task_features
from autonomy.local_gmr import LocalGMR, _features, _fit
from autonomy.tracking import TrackingSettings, track
from autonomy.types import RobotModel, as_candidates
from sim.types import SemanticComponent

sys.path.insert(0, str(Path(__file__).parent))
from contextual_reference import (  # noqa: E402
    RefLocalGMR,
    _nearest_candidates,
    assert_recognition_close,
    ref_rollout,
    ref_track,
)
from fp import PIPELINE_RTOL, assert_pipeline_close  # noqa: E402

TICKS = Path(__file__).parent / "golden" / "contextual_ticks.npz"
ROBOT = RobotModel(
    np.array([[-0.3, -0.25], [0.3, -0.25], [0.3, 0.25], [-0.3, 0.25]]), max_speed=0.6
)

# --------------------------------------------------------------------------- arithmetic


@njit(cache=True)
def _mul_add(a, b, c):
    return a * b + c


def test_kernels_do_not_fuse_multiply_and_add(rng):
    a, b, c = rng.normal(size=(3, 2000)) * np.exp(rng.normal(size=(3, 2000)))
    assert all(_mul_add(x, y, z) == x * y + z for x, y, z in zip(a, b, c, strict=True))
    fused = [_kernels.fma(x, y, z) for x, y, z in zip(a, b, c, strict=True)]
    assert fused != (a * b + c).tolist()  # fma is the single rounding


def test_hypot_and_fsum_are_cpythons(rng):
    xy = rng.normal(size=(20000, 2)) * np.exp(rng.normal(size=(20000, 2)) * 4)
    xy[:50, 0] = 0.0
    xy[50:60, 1] = math.inf
    assert [_kernels.py_hypot(x, y) for x, y in xy] == [math.hypot(x, y) for x, y in xy]
    for _ in range(2000):
        v = rng.normal(size=int(rng.integers(1, 40))) * np.exp(rng.normal(size=1) * 6)
        assert _kernels.fsum(v, len(v)) == math.fsum(v.tolist())


# --------------------------------------------------------------------------- local GMR


def _local_set(rng, k):
    local = rng.normal(size=(k, 5)) * rng.uniform(0.01, 2.0, 5) + rng.uniform(-3, 3, 5)
    if rng.random() < 0.3:
        local[: int(rng.integers(1, k))] += rng.uniform(-2, 2, 5)  # a second group
    if rng.random() < 0.05:
        local[:] = local[0]  # all points coincide
    return local


@pytest.mark.parametrize("k", [2, 3, 10, 40])
def test_em_fit_equals_the_python_fit(rng, k):
    lw, mu, var = np.empty(2), np.empty((2, 5)), np.empty((2, 5))
    for n in range(150):
        local = _local_set(rng, k)
        phi = np.ascontiguousarray(_features(local - local.mean(axis=0)))
        floor = 1e-3 * rng.uniform(0.1, 2.0, 5)
        tol, max_iter = ((1e-4, 100), (1e-8, 100), (0.0, 6))[n % 3]
        params, n_iter, _ = _fit(phi, floor.tolist(), tol, max_iter)
        ncomp, n_iter_k = _kernels.fit(phi, floor, tol, max_iter, lw, mu, var)
        assert (ncomp, n_iter_k) == (len(params), n_iter)
        for c, (log_w, m, v, _) in enumerate(params):
            assert_pipeline_close(lw[c], log_w, name="em.log_w")
            assert_pipeline_close(mu[c], m, name="em.mu")
            assert_pipeline_close(var[c], v, name="em.var")


@pytest.mark.parametrize("k", [1, 3, 10, 40])
def test_local_gmr_equals_the_python_gmr(rng, k):
    """Walks with jumps through pools, the cache and the tree: the same neighbour sets,
    predictions, fit counts and cache contents."""
    n = int(rng.integers(k, 600))
    data = np.column_stack((rng.uniform(-2, 2, (n, 2)), rng.normal(size=(n, 3))))
    new, old = LocalGMR(data, k=k, cache_size=80), RefLocalGMR(data, k=k, cache_size=80)
    start = x = rng.uniform(-2.5, 2.5, 2)
    for _ in range(400):
        draw = rng.random()
        x = start + rng.normal(scale=0.02, size=2) if draw > 0.95 else x
        x = x + rng.normal(scale=0.02 if draw < 0.9 else 1.5, size=2)
        sx, sy = float(x[0]), float(x[1])
        assert new._key(sx, sy) == old._key(sx, sy)
        assert_pipeline_close(new.predict_xy(sx, sy), old.predict_xy(sx, sy), name="gmr")
        assert len(new.cache_) == len(old.cache_)
    assert new.n_iter_counts_.tolist() == old.n_iter_counts_


def test_pool_fetch_equals_the_tree_query(rng):
    """The kernel's brute-force pool: the cKDTree's points, in its order, and its radius,
    on the shipped model's primitives (queries near and far from the data)."""
    mode = ContextualTaskMode()
    for gmr in mode.runtime_.gmrs:
        tree, x = cKDTree(gmr.inputs_), gmr.inputs_
        for _ in range(40):
            c = x[rng.integers(len(x))] + rng.normal(scale=rng.choice([0.01, 0.3, 2.0]), size=2)
            dist, idx = tree.query(c, k=gmr.pool_size)
            near = gmr.fetch_pool(float(c[0]), float(c[1]))
            slot = gmr._lru[0]
            assert gmr._pidx[slot].tolist() == idx.tolist()
            assert gmr._meta[slot, 2] == dist[-1]
            assert near.tolist() == sorted(idx[: gmr.k].tolist())


# --------------------------------------------------------------------------- the mode


@pytest.fixture(scope="module")
def mode():
    mode = ContextualTaskMode()
    mode.reset(ROBOT)
    return mode


def _reference_runtime(runtime):
    gmrs = tuple(
        RefLocalGMR(g.points_, k=g.k, tol=g.tol, max_iter=g.max_iter) for g in runtime.gmrs
    )
    return dataclasses.replace(runtime, gmrs=gmrs)


def _random_component(rng, n):
    if rng.random() < 0.4:
        centre = rng.uniform(-4, 4, 2)
        return SemanticComponent(f"d{n}", "doorway", centre, np.empty((0, 2)))
    p = int(rng.integers(1, 40))
    points = rng.uniform(-4, 4, 2) + rng.normal(scale=0.4, size=(p, 2))
    return SemanticComponent(f"o{n}", "object", points.mean(axis=0), points)


def _features_ref(mode, components, u):
    targets, chosen = _nearest_candidates(components, mode.settings.candidates)
    z = mode.runtime_.model.scaler.transform(encode(task_features(targets[chosen], u)))
    return chosen, z


def _features_new(mode, components, u):
    targets = np.ascontiguousarray(components.target_points(), dtype=float).reshape(-1, 2)
    n = min(mode.settings.candidates, len(targets))
    chosen, z = np.empty(n, dtype=np.int64), np.empty((n, 7))
    scaler = mode.runtime_.model.scaler
    _tick_kernels.candidate_features(targets, n, u, scaler.mean_, scaler.scale_, z, chosen)
    return chosen, z


def _check_tick(mode, ref_runtime, components, u):
    """Candidates, recognition, rollout and tracking of one tick, kernels vs reference."""
    chosen, z = _features_new(mode, components, u)
    chosen_ref, z_ref = _features_ref(mode, components, u)
    assert np.array_equal(chosen, chosen_ref)
    assert_pipeline_close(z, z_ref, name="features")
    got = mode.runtime_.recogniser(z)
    if not assert_recognition_close(mode.runtime_.recogniser, z, got, name="tick"):
        return  # a near-tie: the two winners' rollouts are not comparable
    i, cluster = got[:2]
    if i < 0:
        return
    component, s = components[int(chosen[i])], mode.settings
    path, dists = rollout(mode.runtime_, cluster, component, ROBOT, s)
    path_ref, dists_ref = ref_rollout(ref_runtime, cluster, component, ROBOT, s)
    _assert_rollouts_close(path, dists, path_ref, dists_ref, s.mahalanobis_stop)
    if len(path):
        kw = {"max_speed": 0.6, "max_yaw_rate": 1.2, "settings": s.tracking}
        assert_pipeline_close(track(path, s.dt, **kw), ref_track(path, s.dt, **kw), name="track")


def _assert_rollouts_close(path, dists, path_ref, dists_ref, stop) -> None:
    """Rollouts within :data:`fp.PIPELINE_RTOL`; of unequal length only where the shorter
    one stopped on a Mahalanobis distance within the tolerance of the threshold (Eq. 6.3),
    the common steps close."""
    k = min(len(dists), len(dists_ref))
    assert_pipeline_close(dists[:k], dists_ref[:k], name="rollout.dists")
    assert_pipeline_close(path[: k - 1], path_ref[: k - 1], name="rollout.path")
    if len(dists) != len(dists_ref):
        assert abs(dists_ref[k - 1] - stop) <= PIPELINE_RTOL * max(stop, 1.0)
    else:
        assert_pipeline_close(path, path_ref, name="rollout.path")


def test_ticks_on_random_scenes_equal_the_reference(rng, mode):
    ref_runtime = _reference_runtime(mode.runtime_)
    for n in range(60):
        components = as_candidates([_random_component(rng, m) for m in range(rng.integers(1, 25))])
        u = rng.uniform(-1, 1, 3) * (rng.random(3) < 0.9)
        _check_tick(mode, ref_runtime, components, u)
        if n % 10 == 0:
            _check_tick(mode, ref_runtime, components, u)  # warm pools and cache


def test_recorded_ticks_equal_the_reference(mode):
    data = np.load(TICKS)
    ref_runtime = _reference_runtime(mode.runtime_)
    t_end, s_end = np.cumsum(data["target_counts"]), np.cumsum(data["surface_counts"])
    for n, u in enumerate(data["u"]):
        targets = data["targets"][t_end[n] - data["target_counts"][n] : t_end[n]]
        surface = data["surface"][s_end[n] - data["surface_counts"][n] : s_end[n]]
        items = [
            SemanticComponent(f"t{m}", "doorway", t, np.empty((0, 2)))
            for m, t in enumerate(targets)
        ]
        chosen, z = _features_new(mode, as_candidates(items), u)
        i = mode.runtime_.recogniser(z)[0]
        if len(surface):  # the recognised target's surface in its place
            t = items[int(chosen[i])]
            items[int(chosen[i])] = SemanticComponent(t.id, "object", t.centre, surface)
        _check_tick(mode, ref_runtime, as_candidates(items), u)


def test_recogniser_equals_the_reference_on_random_features(rng, mode):
    recogniser = mode.runtime_.recogniser
    for _ in range(40):
        z = rng.normal(size=(int(rng.integers(1, 12)), 7)) * rng.uniform(0.1, 3.0)
        assert_recognition_close(recogniser, z, recogniser(z), name="recogniser_random")


def test_candidates_with_ties_and_zero_input(mode):
    targets = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, 0.0], [2.0, 2.0]] * 3)
    items = [
        SemanticComponent(f"c{m}", "doorway", t, np.empty((0, 2))) for m, t in enumerate(targets)
    ]
    for u in (np.zeros(3), np.array([0.3, -0.2, 0.1]), np.array([0.0, 0.0, 0.7])):
        for n in (1, 4, 10, 15):
            components = as_candidates(items[:n])
            got = _features_new(mode, components, u)
            ref = _features_ref(mode, components, u)
            assert np.array_equal(got[0], ref[0])  # ties broken by order, exactly
            assert_pipeline_close(got[1], ref[1], name="features_ties")


# --------------------------------------------------------------------------- tracking


def _random_path(rng):
    k = int(rng.integers(1, 61))
    kind = rng.random()
    step = rng.normal(scale=0.03, size=(k, 2)) + rng.normal(scale=0.03, size=2)
    if kind < 0.15:
        step[:] = 0.0  # a pure rotation
    elif kind < 0.25:
        step[: k // 2] = 0.0  # standing, then moving (zero spans)
    yaw = np.cumsum(rng.normal(scale=0.3, size=k)) + rng.choice([0.0, 3.0, -3.0])
    return np.column_stack((np.cumsum(step, axis=0), yaw))


def test_track_equals_the_numpy_controller(rng):
    for _ in range(3000):
        path = _random_path(rng)
        settings = TrackingSettings(
            lookahead_m=float(rng.choice([0.05, 0.4, 2.0])),
            min_time_s=float(rng.choice([0.05, 0.5])),
        )
        kw = {"max_speed": 0.6, "max_yaw_rate": float(rng.choice([0.3, 1.2])), "settings": settings}
        dt = float(rng.choice([0.05, 0.1]))
        assert_pipeline_close(track(path, dt, **kw), ref_track(path, dt, **kw), name="track")
    assert np.array_equal(
        track(np.empty((0, 3)), 0.05, max_speed=0.6, max_yaw_rate=1.2), np.zeros(3)
    )
