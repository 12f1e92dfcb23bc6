"""The recogniser's products in compiled kernels (autonomy._tick_kernels, issue 25) give
what numpy's BLAS calls give (OpenBLAS, one thread, as `asa` and tests/conftest.py set
it) within the rounding of a sum of products (tests/fp.py; bit for bit where OpenBLAS runs
its Haswell kernels, whose order they repeat): the batched means ``alpha @ K``
(dgemv_n), the winner's ``C @ k`` (dgemv_t) and ``k @ (C @ k)`` (a strided ddot); the
argmax over finite means exactly; and the whole recogniser equals the numpy one
(tests/contextual_reference.py) within its tolerances, also with non-finite features.
The blend in Python floats, the rollout's lifted surface points and
the DWA's thinned points equal the numpy they replaced (signed zeros included)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from autonomy import _tick_kernels
from autonomy.arbitration import blend
from autonomy.contextual import ContextualTaskMode
from autonomy.dwa import thin_points
from autonomy.sogp_classifier import argmax_finite

sys.path.insert(0, str(Path(__file__).parent))
from contextual_reference import assert_recognition_close  # noqa: E402
from fp import assert_close, dot_tolerance  # noqa: E402


def _values(rng, shape, special=False):
    """Random floats over many magnitudes; with ``special`` some NaN, inf and zeros."""
    v = rng.normal(size=shape) * np.exp(rng.normal(size=shape) * 3)
    if special:
        mask = rng.random(shape) < 0.02
        v[mask] = rng.choice([np.nan, np.inf, -np.inf, 0.0, -0.0], size=int(mask.sum()))
    return v


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_means_equal_numpys_batched_product(rng):
    for t in range(400):
        c, b, m = int(rng.integers(1, 10)), int(rng.integers(1, 300)), int(rng.integers(2, 13))
        K = _values(rng, (c, b, m), special=t % 5 == 0)
        alpha = _values(rng, (c, 1, b))
        ref = (alpha @ K)[:, 0, :]
        got = np.empty((c, m))
        for j in range(c):
            _tick_kernels.gemv_rows(K[j], np.ascontiguousarray(alpha[j, 0]), got[j])
        tol = dot_tolerance(np.abs(alpha), np.abs(K))[:, 0, :]
        assert_close(got, ref, tol, name="gemv_rows")


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_winner_variance_products_equal_numpys(rng):
    for t in range(300):
        n = 250 if t % 4 == 0 else int(rng.integers(1, 300))
        b, m = n + int(rng.integers(0, 5)), int(rng.integers(2, 11))
        C = np.zeros((b, b))
        C[:n, :n] = _values(rng, (n, n), special=t % 7 == 0)
        K = _values(rng, (b, m))
        i = int(rng.integers(m))
        k = K[:n, i]  # a strided view, as the recogniser's K[j, :n, i]
        work = np.empty((6, b))
        work[0, :n] = k
        Ct = np.ascontiguousarray(C.T)
        _tick_kernels.gemv_dots(Ct, work[0], n, work[1], work[2:])
        ref = C[:n, :n] @ k
        assert_close(work[1, :n], ref, dot_tolerance(np.abs(C[:n, :n]), np.abs(k)), name="gemv_t")
        got = _tick_kernels.dot_strided(work[0], work[1], n)
        w = work[1, :n]  # the dot on the kernel's own C k, alone
        assert_close(got, float(k @ w), dot_tolerance(np.abs(k), np.abs(w)), name="dot_strided")


def _argmax_numpy(scores):
    """autonomy.sogp_classifier.argmax_finite before its kernel."""
    finite = np.isfinite(scores)
    if not finite.any():
        return -1, -1
    flat = int(np.argmax(np.where(finite, scores, -np.inf)))
    return divmod(flat, scores.shape[1])


def test_argmax_finite_kernel_equals_numpy(rng):
    for t in range(3000):
        shape = (int(rng.integers(0, 12)), int(rng.integers(0, 10)))
        s = np.round(_values(rng, shape, special=True), int(rng.integers(0, 3)))  # ties
        if t % 10 == 0:
            s[...] = rng.choice([np.nan, np.inf, -np.inf])
        assert argmax_finite(s) == _argmax_numpy(s)
        assert _tick_kernels.argmax_finite(np.ascontiguousarray(s.T).T) == _argmax_numpy(s)
    assert argmax_finite([[1.0, 3.0], [3.0, 2.0]]) == (0, 1)


@pytest.fixture(scope="module")
def recogniser():
    return ContextualTaskMode().runtime_.recogniser


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_recogniser_with_non_finite_features_equals_numpy(rng, recogniser):
    for t in range(60):
        z = rng.normal(size=(int(rng.integers(2, 12)), 7)) * rng.uniform(0.1, 30.0)
        rows = rng.random(len(z)) < (1.0 if t % 6 == 0 else 0.3)
        z[rows, int(rng.integers(7))] = rng.choice([np.nan, np.inf, -np.inf])
        assert_recognition_close(recogniser, z, recogniser(z), name="recogniser_non_finite")


def _blend_numpy(u, g, beta):
    """autonomy.arbitration.blend before its float path."""
    b = 0.0 if math.isnan(beta) else min(max(float(beta), 0.0), 1.0)
    u, g = np.asarray(u, dtype=float), np.asarray(g, dtype=float)
    v = (1.0 - b) * u + b * g
    return np.clip(v, np.minimum(u, g), np.maximum(u, g))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_blend_in_floats_equals_numpy(rng):
    special = [0.0, -0.0, 1.0, -1.0, 0.3, 1e-300, -5e-324, np.inf, np.nan]
    for t in range(20000):
        if t % 2:
            u, g = rng.choice(special, 3), rng.choice(special, 3)
        else:
            u, g = _values(rng, 3), _values(rng, 3)
            g[int(rng.integers(3))] = u[int(rng.integers(3))]
        beta = float(rng.choice([0.0, 1.0, 0.5, rng.random(), -0.2, 1.3, math.nan, 1 - 1e-16]))
        got, ref = blend(u, g, beta), _blend_numpy(u, g, beta)
        assert np.array_equal(got, ref, equal_nan=True)
        assert np.array_equal(np.signbit(got), np.signbit(ref))


def test_lifted_surface_points_equal_numpys(rng):
    for _ in range(2000):
        p = rng.normal(size=(int(rng.integers(0, 60)), 2)) * np.exp(rng.normal() * 5)
        ref = np.column_stack((p, np.einsum("ij,ij->i", p, p)))
        assert np.array_equal(_tick_kernels.lift_points(p), ref)


def _thin_numpy(points, cell):
    """autonomy.dwa.thin_points before its kernel."""
    if len(points) == 0:
        return points
    keys = np.floor(points / cell).astype(np.int64)
    _, first = np.unique(keys[:, 0] * 1_000_003 + keys[:, 1], return_index=True)
    return points[np.sort(first)]


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_thin_points_equal_numpys(rng):
    for t in range(3000):
        p = rng.normal(size=(int(rng.integers(0, 600)), 2)) * rng.uniform(0.01, 10)
        if t % 3 == 0:
            p = np.round(p, 1)  # many points per cell
        if t % 50 == 0 and len(p):
            p[0, int(rng.integers(2))] = rng.choice([1e300, np.inf, np.nan])  # numpy's path
        cell = float(rng.choice([0.05, 0.1, 0.3]))
        got, ref = thin_points(p, cell), _thin_numpy(p, cell)
        assert got.shape == ref.shape and np.array_equal(got, ref, equal_nan=True)
