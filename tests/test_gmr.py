"""Gaussian mixture regression, diagonal EM and the fast online GMR (thesis Sec. 4.4, Alg. 2)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.gmr import FastOnlineGMR, data_scale, em_diagonal, gmr


def _random_spd(rng, D):
    A = rng.normal(size=(D, D))
    return A @ A.T + 0.2 * np.eye(D)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), D=st.integers(2, 6))
def test_one_component_equals_gaussian_conditioning(seed, D):
    rng = np.random.default_rng(seed)
    S = _random_spd(rng, D)
    mu = rng.normal(size=D)
    perm = rng.permutation(D)
    n_in = int(rng.integers(1, D))
    ii, oo = perm[:n_in], perm[n_in:]
    x = rng.normal(size=(7, n_in)) * 2.0
    mean, cov = gmr(np.ones(1), mu[None], S[None], x, ii, oo)
    S_xx, S_yx, S_yy = S[np.ix_(ii, ii)], S[np.ix_(oo, ii)], S[np.ix_(oo, oo)]
    expected_mean = mu[oo] + (S_yx @ np.linalg.solve(S_xx, (x - mu[ii]).T)).T
    expected_cov = S_yy - S_yx @ np.linalg.solve(S_xx, S_yx.T)
    np.testing.assert_allclose(mean, expected_mean, atol=1e-9)
    for c in cov:
        np.testing.assert_allclose(c, expected_cov, atol=1e-9)


def test_mixture_is_moment_matched(rng):
    K, D = 3, 4
    w = rng.dirichlet(np.ones(K))
    mu = rng.normal(size=(K, D)) * 2.0
    S = np.stack([_random_spd(rng, D) for _ in range(K)])
    ii, oo = [0, 1], [2, 3]
    x = rng.normal(size=(5, 2))
    mean, cov = gmr(w, mu, S, x, ii, oo)
    for n in range(5):
        # Responsibilities (4.6-4.7) and per-component conditionals (4.8), by hand.
        log_h = []
        conds = []
        for k in range(K):
            Sxx = S[k][np.ix_(ii, ii)]
            d = x[n] - mu[k, ii]
            log_h.append(
                np.log(w[k])
                - 0.5 * d @ np.linalg.solve(Sxx, d)
                - 0.5 * np.linalg.slogdet(2 * np.pi * Sxx)[1]
            )
            Syx = S[k][np.ix_(oo, ii)]
            m = mu[k, oo] + Syx @ np.linalg.solve(Sxx, d)
            c = S[k][np.ix_(oo, oo)] - Syx @ np.linalg.solve(Sxx, Syx.T)
            conds.append((m, c))
        h = np.exp(np.array(log_h) - np.max(log_h))
        h /= h.sum()
        m_exp = sum(hk * m for hk, (m, _) in zip(h, conds, strict=True))
        c_exp = sum(hk * (c + np.outer(m, m)) for hk, (m, c) in zip(h, conds, strict=True))
        c_exp = c_exp - np.outer(m_exp, m_exp)
        np.testing.assert_allclose(mean[n], m_exp, atol=1e-9)
        np.testing.assert_allclose(cov[n], c_exp, atol=1e-9)
        assert np.all(np.linalg.eigvalsh(cov[n]) > 0)


def test_diagonal_input_equals_full_diagonal_matrices(rng):
    K, D = 2, 5
    w = np.array([0.3, 0.7])
    mu = rng.normal(size=(K, D))
    var = rng.uniform(0.1, 2.0, size=(K, D))
    x = rng.normal(size=(6, 2)) * 3.0
    full = np.stack([np.diag(v) for v in var])
    a = gmr(w, mu, var, x, [4, 1], [0, 2, 3])
    b = gmr(w, mu, full, x, [4, 1], [0, 2, 3])
    for u, v in zip(a, b, strict=True):
        np.testing.assert_allclose(u, v, atol=1e-10)


def test_far_query_still_finite_and_normalised(rng):
    w = np.array([0.5, 0.5])
    mu = np.array([[0.0, -1.0], [1.0, 1.0]])
    var = np.full((2, 2), 1e-4)
    mean, cov = gmr(w, mu, var, np.array([[1e4]]), [0], [1])
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))
    assert mean[0, 0] == pytest.approx(1.0)  # the nearer component takes over


def test_em_recovers_two_separated_blobs(rng):
    a = rng.normal(loc=[0.0, 0.0, 1.0], scale=0.3, size=(40, 3))
    b = rng.normal(loc=[5.0, -4.0, 2.0], scale=0.3, size=(60, 3))
    X = np.vstack([a, b])[rng.permutation(100)]
    w, mu, var = em_diagonal(X, n_components=2, rng=rng)
    order = np.argsort(mu[:, 0])
    w, mu, var = w[order], mu[order], var[order]
    np.testing.assert_allclose(mu[0], [0.0, 0.0, 1.0], atol=0.2)
    np.testing.assert_allclose(mu[1], [5.0, -4.0, 2.0], atol=0.2)
    np.testing.assert_allclose(w, [0.4, 0.6], atol=1e-6)
    assert np.all((var > 0.3**2 / 3) & (var < 0.3**2 * 3))
    assert w.sum() == pytest.approx(1.0)


def test_em_is_robust_to_tiny_and_degenerate_data(rng):
    for X in (rng.normal(size=(1, 4)), np.tile(rng.normal(size=4), (6, 1))):
        w, mu, var = em_diagonal(X, n_components=2, rng=rng, reg=1e-6)
        assert w.shape == (1,) and w[0] == 1.0
        np.testing.assert_allclose(mu[0], X[0])
        np.testing.assert_allclose(var[0], 1e-6 * X[0] ** 2)  # relative floor: mean square
    # Two distinct points, requested three components: at most two.
    X = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]])
    w, mu, var = em_diagonal(X, n_components=3, rng=rng)
    assert w.size <= 2 and np.all(np.isfinite(mu)) and np.all(var >= 1e-3 * X.var(axis=0))
    with pytest.raises(ValueError):
        em_diagonal(np.zeros((0, 2)), rng=rng)


def _f(x):
    return np.sin(x[..., 0]) + 0.3 * x[..., 1]


def test_fast_online_gmr_follows_the_function(rng):
    X = rng.uniform(0.0, 6.0, size=(1500, 2))
    y = np.c_[_f(X), np.cos(X[:, 0])] + 0.05 * rng.normal(size=(1500, 2))
    model = FastOnlineGMR(np.c_[y[:, 0], X, y[:, 1]], in_idx=[1, 2], out_idx=[0, 3], k=10)
    queries = rng.uniform(0.5, 5.5, size=(60, 2))
    pred = np.array([model.predict(q, rng=rng)[0] for q in queries])
    err = pred - np.c_[_f(queries), np.cos(queries[:, 0])]
    assert np.sqrt(np.mean(err**2)) < 0.1
    assert np.max(np.abs(err)) < 0.3
    _, cov = model.predict(queries[0], rng=rng)
    assert cov.shape == (2, 2)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_fast_online_gmr_with_few_or_duplicated_points(rng):
    data = np.array([[0.0, 1.0], [1.0, 3.0], [2.0, 5.0]])
    model = FastOnlineGMR(data, in_idx=[0], out_idx=[1], k=10)  # k > N
    mean, cov = model.predict(np.array([1.0]), rng=rng)
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))
    assert 1.0 <= mean[0] <= 5.0
    dup = np.tile([[0.5, -2.0, 7.0]], (20, 1))
    model = FastOnlineGMR(dup, in_idx=[0, 1], out_idx=[2], k=5)
    mean, cov = model.predict(np.array([3.0, 3.0]), rng=rng)
    assert mean[0] == pytest.approx(7.0)
    assert np.all(np.isfinite(cov)) and cov[0, 0] >= 0.0
    single = FastOnlineGMR(dup[:1], in_idx=[0], out_idx=[1, 2])
    mean, _ = single.predict(np.array([0.0]), rng=rng)
    np.testing.assert_allclose(mean, [-2.0, 7.0])


def test_fast_online_gmr_rejects_bad_settings():
    data = np.zeros((5, 3))
    with pytest.raises(ValueError, match="overlap"):
        FastOnlineGMR(data, in_idx=[0, 1], out_idx=[1])
    with pytest.raises(ValueError, match="column"):
        FastOnlineGMR(data, in_idx=[0], out_idx=[3])
    with pytest.raises(ValueError, match="x"):
        FastOnlineGMR(data, in_idx=[0], out_idx=[1]).predict(
            np.zeros(2), rng=np.random.default_rng(0)
        )


def test_em_and_fast_gmr_are_equivariant_to_rescaling_the_data(seed):
    # The variance floor is relative: metres or millimetres give the same model (an
    # absolute floor of 1e-6 would dominate the variances of the data scaled by 1e-3).
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.0, 6.0, size=(400, 2))
    data = np.c_[X, np.sin(X[:, 0]) + 0.05 * rng.normal(size=400)]
    data[::7, 2] = 0.25  # repeated output values, as from a held stick
    for factor in (1e-3, 1e3):
        w, mu, var = em_diagonal(data[:10], rng=np.random.default_rng(seed))
        w2, mu2, var2 = em_diagonal(data[:10] * factor, rng=np.random.default_rng(seed))
        np.testing.assert_allclose(w2, w, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(mu2, mu * factor, rtol=1e-6, atol=1e-9 * factor)
        np.testing.assert_allclose(var2, var * factor**2, rtol=1e-6)
        a = FastOnlineGMR(data, in_idx=[0, 1], out_idx=[2], k=10)
        b = FastOnlineGMR(data * factor, in_idx=[0, 1], out_idx=[2], k=10)
        for q in rng.uniform(0.5, 5.5, size=(5, 2)):
            m1, c1 = a.predict(q, rng=np.random.default_rng(seed))
            m2, c2 = b.predict(q * factor, rng=np.random.default_rng(seed))
            np.testing.assert_allclose(m2, m1 * factor, rtol=1e-6, atol=1e-9 * factor)
            np.testing.assert_allclose(c2, c1 * factor**2, rtol=1e-6)
    # k copies of one point: the floor is relative to the cluster's scale
    dup = np.tile(data[:1], (10, 1))
    _, _, var = em_diagonal(dup, rng=rng, reg=1e-3, scale=data_scale(data))
    np.testing.assert_allclose(var[0], 1e-3 * data.var(axis=0))
