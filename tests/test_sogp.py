"""Sparse Online GP (Csató & Opper 2002), its hyperparameters, and the one-vs-all classifier
(thesis Ch. 5, Sec. 6.2.2, 7.3)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import approx_fprime

from autonomy.gp_hyperparameters import (
    fit_hyperparameters,
    hyperparameter_bounds,
    initial_log_params,
    log_evidence,
)
from autonomy.sogp import MAX_LENGTH_SCALE, SparseOnlineGP
from autonomy.sogp_classifier import (
    SOGPClassifier,
    balanced_subsample,
    normalised_entropy,
    recognise,
)


# ----------------------------------------------------------------- references
def _kernel(A, B, ls, sf2):
    """SE-ARD kernel, written independently of the module."""
    d = (A[:, None, :] - B[None, :, :]) / ls
    return sf2 * np.exp(-0.5 * np.sum(d * d, axis=2))


def _full_gp(X, y, Xq, ls, sf2, sn2):
    """Full GP predictive mean and variance (incl. noise), Eqs. (5.6), (5.9)."""
    A = _kernel(X, X, ls, sf2) + sn2 * np.eye(len(X))
    Ks = _kernel(Xq, X, ls, sf2)
    mean = Ks @ np.linalg.solve(A, y)
    var = sf2 - np.einsum("ij,ji->i", Ks, np.linalg.solve(A, Ks.T)) + sn2
    return mean, var


class _TextbookSOGP:
    """Csató & Opper's equations on compact arrays with numpy.linalg only: slow, plain."""

    def __init__(self, capacity, ls, sf2, sn2, tol=1e-6):
        self.cap, self.ls, self.sf2, self.sn2, self.tol = capacity, ls, sf2, sn2, tol
        self.B = np.zeros((0, len(ls)))
        self.a = np.zeros(0)
        self.C = np.zeros((0, 0))
        self.Q = np.zeros((0, 0))

    def update(self, x, y):
        k = _kernel(self.B, x[None], self.ls, self.sf2)[:, 0]
        kss = self.sf2
        m = k @ self.a
        s2 = max(kss + k @ self.C @ k, 0.0)
        q = (y - m) / (s2 + self.sn2)
        r = -1.0 / (s2 + self.sn2)
        e = self.Q @ k
        gamma = kss - k @ e
        if gamma < self.tol * kss:
            eta = 1.0 / (1.0 + r * gamma)
            s = self.C @ k + e
            self.a = self.a + q * eta * s
            self.C = self.C + r * eta * np.outer(s, s)
            return
        s = np.r_[self.C @ k, 1.0]
        b = len(self.a)
        Cx = np.zeros((b + 1, b + 1))
        Cx[:b, :b] = self.C
        Qx = np.zeros((b + 1, b + 1))
        Qx[:b, :b] = self.Q
        ee = np.r_[e, -1.0]
        self.a = np.r_[self.a, 0.0] + q * s
        self.C = Cx + r * np.outer(s, s)
        self.Q = Qx + np.outer(ee, ee) / gamma
        self.B = np.vstack([self.B, x])
        if b + 1 > self.cap:
            score = self.a**2 / (np.diag(self.Q) + np.diag(self.C))
            i = int(np.argmin(score))
            keep = np.arange(b + 1) != i
            a_s, c_s, q_s = self.a[i], self.C[i, i], self.Q[i, i]
            Qs, Cs = self.Q[keep, i], self.C[keep, i]
            self.a = self.a[keep] - a_s * Qs / q_s
            self.C = (
                self.C[np.ix_(keep, keep)]
                + c_s * np.outer(Qs, Qs) / q_s**2
                - (np.outer(Qs, Cs) + np.outer(Cs, Qs)) / q_s
            )
            self.Q = self.Q[np.ix_(keep, keep)] - np.outer(Qs, Qs) / q_s
            self.B = self.B[keep]

    def predict(self, Xq):
        K = _kernel(Xq, self.B, self.ls, self.sf2)
        return K @ self.a, self.sf2 + np.einsum("ij,jk,ik->i", K, self.C, K) + self.sn2


def _smooth_3d(X):
    return np.sin(X[:, 0]) * np.cos(X[:, 1]) + 0.5 * X[:, 2]


# ------------------------------------------------------------ SOGP regression
def test_equals_full_gp_with_room_for_every_point(rng):
    X = rng.uniform(0.0, 4.0, size=(50, 3))  # spread out: every point is novel
    y = _smooth_3d(X) + 0.1 * rng.normal(size=50)
    ls, sf2, sn2 = np.array([1.0, 1.5, 0.8]), 1.3, 0.05
    gp = SparseOnlineGP(capacity=100, length_scales=ls, signal_var=sf2, noise_var=sn2).fit(X, y)
    assert gp.n_basis_ == 50  # every point became a basis vector: nothing projected
    Xq = np.vstack([X[:10], rng.uniform(-1.0, 5.0, size=(40, 3))])
    mean, var = gp.predict(Xq)
    mean_f, var_f = _full_gp(X, y, Xq, ls, sf2, sn2)
    np.testing.assert_allclose(mean, mean_f, atol=1e-6)
    np.testing.assert_allclose(var, var_f, atol=1e-6)
    # The single-point path agrees with the batch path.
    one = np.array([gp.predict(x)[0][0] for x in Xq[:5]])
    np.testing.assert_allclose(one, mean[:5], atol=1e-12)
    # C&O's parametrisation of the full posterior: alpha = A^-1 y, C = -A^-1.
    A = _kernel(X, X, ls, sf2) + sn2 * np.eye(50)
    np.testing.assert_allclose(gp.C_, -np.linalg.inv(A), atol=1e-6)


def test_equals_textbook_equations_with_deletions(rng):
    """The BLAS, in-place, compacting implementation against C&O's equations verbatim."""
    X = rng.uniform(-2.0, 2.0, size=(250, 2))
    y = np.sin(2 * X[:, 0]) + X[:, 1] ** 2 + 0.1 * rng.normal(size=250)
    ls, sf2, sn2 = np.array([0.7, 1.1]), 1.0, 0.01
    gp = SparseOnlineGP(capacity=20, length_scales=ls, signal_var=sf2, noise_var=sn2)
    ref = _TextbookSOGP(20, ls, sf2, sn2, tol=gp.novelty_tol)
    for x, t in zip(X, y, strict=True):
        gp.update(x, t)
        ref.update(x, t)
    assert gp.n_basis_ == ref.a.size == 20
    Xq = rng.uniform(-2.0, 2.0, size=(50, 2))
    m, v = gp.predict(Xq)
    m_r, v_r = ref.predict(Xq)
    np.testing.assert_allclose(m, m_r, atol=1e-8)
    np.testing.assert_allclose(v, v_r, atol=1e-8)
    order = np.lexsort(ref.B.T)
    np.testing.assert_allclose(gp.basis_[np.lexsort(gp.basis_.T)], ref.B[order], atol=1e-12)


def test_deletions_stay_close_to_full_gp_1d(rng):
    """1-D sine, 400 points, capacity 25: |mean error| < 0.01, |variance error| < 1e-3."""
    X = rng.uniform(0.0, 10.0, size=(400, 1))
    y = np.sin(X[:, 0]) + 0.1 * rng.normal(size=400)
    ls, sf2, sn2 = np.array([1.0]), 1.0, 0.01
    gp = SparseOnlineGP(capacity=25, length_scales=ls, signal_var=sf2, noise_var=sn2).fit(X, y)
    assert gp.n_basis_ <= 25
    Xq = np.linspace(0.0, 10.0, 200)[:, None]
    mean, var = gp.predict(Xq)
    mean_f, var_f = _full_gp(X, y, Xq, ls, sf2, sn2)
    assert np.max(np.abs(mean - mean_f)) < 0.01
    assert np.max(np.abs(var - var_f)) < 1e-3


def test_deletions_stay_close_to_full_gp_3d(rng):
    """3-D smooth function, 800 points, capacity 150: RMS mean error < 0.03, max < 0.15,
    variance error < 0.02 (function range about +-1.5, signal variance 1)."""
    X = rng.uniform(-2.0, 2.0, size=(800, 3))
    y = _smooth_3d(X) + 0.05 * rng.normal(size=800)
    ls, sf2, sn2 = np.array([1.2, 1.2, 2.0]), 1.0, 0.0025
    gp = SparseOnlineGP(capacity=150, length_scales=ls, signal_var=sf2, noise_var=sn2).fit(X, y)
    assert gp.n_basis_ == 150
    Xq = rng.uniform(-1.8, 1.8, size=(300, 3))
    mean, var = gp.predict(Xq)
    mean_f, var_f = _full_gp(X, y, Xq, ls, sf2, sn2)
    err = mean - mean_f
    assert np.sqrt(np.mean(err**2)) < 0.03
    assert np.max(np.abs(err)) < 0.15
    assert np.max(np.abs(var - var_f)) < 0.02


def _projected_process(X, y, B, Xq, ls, sf2, sn2):
    """Projected-process (DTC) predictive mean and variance on basis B, written
    independently: Quinonero-Candela & Rasmussen (2005), Sec. 5."""
    Kbb = _kernel(B, B, ls, sf2)
    Kbn = _kernel(B, X, ls, sf2)
    Kqb = _kernel(Xq, B, ls, sf2)
    S = np.linalg.inv(sn2 * Kbb + Kbn @ Kbn.T)
    mean = Kqb @ S @ Kbn @ y
    var = (
        sf2
        - np.einsum("ij,ji->i", Kqb, np.linalg.solve(Kbb, Kqb.T))
        + sn2 * np.einsum("ij,jk,ik->i", Kqb, S, Kqb)
        + sn2
    )
    return mean, var


def test_refine_equals_the_projected_process_on_its_basis(rng):
    X = rng.uniform(-2.0, 2.0, size=(300, 2))
    y = np.sin(2 * X[:, 0]) + X[:, 1] ** 2 + 0.1 * rng.normal(size=300)
    ls, sf2, sn2 = np.array([0.7, 1.1]), 1.0, 0.01
    gp = SparseOnlineGP(capacity=30, length_scales=ls, signal_var=sf2, noise_var=sn2).fit(X, y)
    basis = gp.basis_.copy()
    Xq = rng.uniform(-2.0, 2.0, size=(60, 2))
    online_err = np.abs(gp.predict(Xq)[0] - _projected_process(X, y, basis, Xq, ls, sf2, sn2)[0])
    gp.refine(X, y)
    np.testing.assert_array_equal(gp.basis_, basis)  # the basis is kept
    mean, var = gp.predict(Xq)
    mean_p, var_p = _projected_process(X, y, basis, Xq, ls, sf2, sn2)
    np.testing.assert_allclose(mean, mean_p, atol=1e-7)
    np.testing.assert_allclose(var, var_p, atol=1e-7)
    assert online_err.max() > 1e-3  # one online pass is not yet the fixed point
    # The refined posterior is a valid C&O state: online updates go on from it.
    gp.update(X[0], y[0])
    assert np.all(np.isfinite(gp.predict(Xq)[0]))


def test_refine_with_every_point_a_basis_vector_is_the_full_gp(rng):
    X = rng.uniform(0.0, 4.0, size=(50, 3))
    y = _smooth_3d(X) + 0.1 * rng.normal(size=50)
    ls, sf2, sn2 = np.array([1.0, 1.5, 0.8]), 1.3, 0.05
    gp = SparseOnlineGP(capacity=100, length_scales=ls, signal_var=sf2, noise_var=sn2).fit(X, y)
    assert gp.n_basis_ == 50
    gp.refine(X, y)
    Xq = np.vstack([X[:10], rng.uniform(-1.0, 5.0, size=(40, 3))])
    mean, var = gp.predict(Xq)
    mean_f, var_f = _full_gp(X, y, Xq, ls, sf2, sn2)
    np.testing.assert_allclose(mean, mean_f, atol=1e-6)
    np.testing.assert_allclose(var, var_f, atol=1e-6)


def test_refine_rejects_bad_data(rng):
    gp = SparseOnlineGP(capacity=5, length_scales=np.ones(2), signal_var=1.0, noise_var=0.1)
    X = rng.normal(size=(10, 2))
    gp.fit(X, X[:, 0])
    with pytest.raises(ValueError, match="X: expected shape"):
        gp.refine(X[:, :1], X[:, 0])
    with pytest.raises(ValueError, match="y: expected 10 targets"):
        gp.refine(X, X[:5, 0])
    with pytest.raises(ValueError, match="finite"):
        gp.refine(X, np.full(10, np.nan))


def test_variance_never_below_noise(rng):
    X = rng.normal(size=(300, 2))
    y = np.sign(X[:, 0])
    sn2 = 1e-4
    gp = SparseOnlineGP(
        capacity=30, length_scales=np.array([0.3, 0.3]), signal_var=2.0, noise_var=sn2
    )
    gp.fit(X, y)
    Xq = np.vstack([X, rng.normal(scale=10.0, size=(100, 2))])
    _, var = gp.predict(Xq)
    assert np.all(var >= sn2)
    assert np.all(np.isfinite(var))
    _, var_far = gp.predict(np.array([[1e3, -1e3]]))
    assert var_far[0] == pytest.approx(2.0 + sn2)  # the prior, far from the data


def test_empty_model_predicts_the_prior():
    gp = SparseOnlineGP(length_scales=np.ones(2), signal_var=0.7, noise_var=0.1)
    mean, var = gp.predict(np.zeros((3, 2)))
    np.testing.assert_array_equal(mean, 0.0)
    np.testing.assert_allclose(var, 0.8)


def test_update_order_does_not_matter_without_deletion(rng):
    X = rng.uniform(-3.0, 3.0, size=(40, 3))
    y = np.cos(X[:, 0]) - X[:, 1] + 0.1 * rng.normal(size=40)
    ls = np.array([1.0, 1.5, 1.0])
    settings_ = dict(capacity=60, length_scales=ls, signal_var=1.0, noise_var=0.02)
    a = SparseOnlineGP(**settings_).fit(X, y)
    perm = rng.permutation(40)
    b = SparseOnlineGP(**settings_).fit(X[perm], y[perm])
    assert a.n_basis_ == b.n_basis_ == 40
    Xq = rng.uniform(-4.0, 4.0, size=(30, 3))
    for u, w in zip(a.predict(Xq), b.predict(Xq), strict=True):
        np.testing.assert_allclose(u, w, atol=1e-8)


def test_round_trip_is_exact(rng):
    X = rng.normal(size=(200, 3))
    y = X[:, 0] * X[:, 1] + 0.1 * rng.normal(size=200)
    gp = SparseOnlineGP(capacity=40, length_scales=np.ones(3), signal_var=1.0, noise_var=0.01)
    gp.fit(X, y)
    again = SparseOnlineGP.from_dict(gp.to_dict())
    Xq = rng.normal(size=(20, 3))
    for u, w in zip(gp.predict(Xq), again.predict(Xq), strict=True):
        np.testing.assert_array_equal(u, w)
    # ... and stays identical under further online updates (with deletions).
    more = rng.normal(size=(30, 3))
    for x in more:
        gp.update(x, float(x.sum()))
        again.update(x, float(x.sum()))
    for u, w in zip(gp.predict(Xq), again.predict(Xq), strict=True):
        np.testing.assert_array_equal(u, w)
    np.testing.assert_array_equal(gp.Q_, again.Q_)


def test_reconditioning_restores_the_inverse_gram(rng):
    X = rng.uniform(-2.0, 2.0, size=(300, 3))
    y = _smooth_3d(X)
    ls = np.array([1.2, 1.2, 2.0])
    kw = dict(capacity=80, length_scales=ls, signal_var=1.0, noise_var=0.0025)
    plain = SparseOnlineGP(**kw, recondition_every=10**9).fit(X, y)
    fresh = SparseOnlineGP(**kw, recondition_every=300).fit(X, y)  # reconditions at the end
    K = _kernel(fresh.basis_, fresh.basis_, ls, 1.0)
    np.testing.assert_allclose(fresh.Q_ @ K, np.eye(fresh.n_basis_), atol=1e-5)
    # Re-conditioning touches only Q, which predictions do not use.
    Xq = rng.uniform(-2.0, 2.0, size=(20, 3))
    np.testing.assert_array_equal(plain.predict(Xq)[0], fresh.predict(Xq)[0])
    # Regular re-conditioning along the way keeps the model on track.
    often = SparseOnlineGP(**kw, recondition_every=25).fit(X, y)
    np.testing.assert_allclose(often.predict(Xq)[0], plain.predict(Xq)[0], atol=1e-3)


def test_bad_settings_and_files_raise_value_error():
    with pytest.raises(ValueError, match="length_scales"):
        SparseOnlineGP(length_scales=np.array([1.0, -1.0]), signal_var=1.0, noise_var=0.1)
    with pytest.raises(ValueError, match="noise_var"):
        SparseOnlineGP(length_scales=np.ones(2), signal_var=1.0, noise_var=0.0)
    with pytest.raises(ValueError, match="capacity"):
        SparseOnlineGP(capacity=0, length_scales=np.ones(2), signal_var=1.0, noise_var=0.1)
    gp = SparseOnlineGP(length_scales=np.ones(2), signal_var=1.0, noise_var=0.1)
    with pytest.raises(ValueError, match="x"):
        gp.update(np.zeros(3), 1.0)
    d = gp.fit(np.eye(2), np.ones(2)).to_dict()
    with pytest.raises(ValueError, match="'alpha'"):
        SparseOnlineGP.from_dict({k: v for k, v in d.items() if k != "alpha"})
    with pytest.raises(ValueError, match="'C'"):
        SparseOnlineGP.from_dict({**d, "C": np.zeros((3, 3))})


# ---------------------------------------------------------- hyperparameters
def test_log_evidence_gradient_matches_finite_differences(rng):
    X = rng.normal(size=(40, 3))
    y = np.sign(X[:, 0] + 0.5 * X[:, 1])
    for _ in range(3):
        theta = np.r_[rng.uniform(-0.5, 1.0, 3), rng.uniform(-1.0, 0.5), rng.uniform(-4.0, -1.0)]
        value, grad = log_evidence(theta, X, y)
        numeric = approx_fprime(theta, lambda t: log_evidence(t, X, y)[0], 1e-6)
        np.testing.assert_allclose(grad, numeric, rtol=1e-4, atol=1e-4 * (1 + abs(value)))


def test_log_evidence_equals_multivariate_normal(rng):
    from scipy.stats import multivariate_normal

    X = rng.normal(size=(25, 2))
    y = rng.normal(size=25)
    theta = np.log(np.array([0.8, 1.5, 1.2, 0.1]))
    A = _kernel(X, X, np.exp(theta[:2]), np.exp(theta[2])) + np.exp(theta[3]) * np.eye(25)
    expected = multivariate_normal(mean=np.zeros(25), cov=A).logpdf(y)
    assert log_evidence(theta, X, y)[0] == pytest.approx(expected, rel=1e-10)


def test_fit_hyperparameters_improves_the_evidence(rng):
    X = rng.uniform(-2.0, 2.0, size=(120, 2))
    y = np.sin(2.0 * X[:, 0]) + 0.1 * rng.normal(size=120)
    # a wide length-scale cap (the default 0.5 std is for the recogniser, see sogp.py)
    hp = fit_hyperparameters(X, y, rng=rng, restarts=2, max_length_scale=100.0)
    ls, sf2, sn2 = hp.length_scales, hp.signal_var, hp.noise_var
    theta = np.log(np.r_[ls, sf2, sn2])
    start = initial_log_params(X, y)
    assert log_evidence(theta, X, y)[0] >= log_evidence(start, X, y)[0]
    bounds = hyperparameter_bounds(X, y, max_length_scale=100.0)
    for t, (lo, hi) in zip(theta, bounds, strict=True):
        assert lo - 1e-9 <= t <= hi + 1e-9
    # The second input is irrelevant: its length scale should exceed the first's.
    assert ls[1] > ls[0]
    assert sn2 < 0.1  # the true noise variance is 0.01


# -------------------------------------------------------------- classifier
_CENTRES = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 3.0, 1.0]])


def _blobs(rng, n):
    labels = rng.integers(0, 3, size=n) * 2 + 1  # ids 1, 3, 5: not 0..c-1 on purpose
    X = _CENTRES[(labels - 1) // 2] + 0.6 * rng.normal(size=(n, 3))
    return X, labels


@pytest.fixture
def toy_classifier(rng):
    X, labels = _blobs(rng, 450)
    clf = SOGPClassifier(capacity=60, hyper_points=150, restarts=1).fit(X, labels, rng=rng)
    return clf


def test_classifier_accuracy_and_confidence(toy_classifier, rng):
    clf = toy_classifier
    np.testing.assert_array_equal(clf.classes_, [1, 3, 5])
    X, labels = _blobs(rng, 300)
    assert np.mean(clf.predict(X) == labels) > 0.9
    conf = clf.confidence(X)
    assert conf.shape == (300, 3)
    assert np.all((conf >= 0.0) & (conf <= 1.0))
    p = clf.predict_proba(X)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(p >= 0.0)


def test_classifier_introspection(toy_classifier, rng):
    clf = toy_classifier
    h_centres = normalised_entropy(clf.predict_proba(_CENTRES))
    # Far in every coordinate: ARD may (rightly) ignore a dimension that does not separate
    # the clusters, so a point far along that dimension alone is not "unlike the data".
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    far = np.vstack([corners, rng.choice([-1.0, 1.0], size=(12, 3))])
    far = far * rng.uniform(10.0, 15.0, size=far.shape) + [1.0, 1.0, 0.3]
    h_far = normalised_entropy(clf.predict_proba(far))
    assert np.all((h_far >= 0) & (h_far <= 1)) and np.all((h_centres >= 0) & (h_centres <= 1))
    assert h_far.min() > h_centres.max()
    assert h_far.min() > 0.9  # far from all data: close to the uniform distribution


def test_recognise_picks_the_candidate_nearest_a_cluster(toy_classifier, rng):
    clf = toy_classifier
    Q = np.vstack([rng.normal(scale=1.0, size=(4, 3)) + [8.0, 8.0, 8.0], _CENTRES[2]])
    Q = Q[rng.permutation(5)]
    best, cluster, beta, scores = recognise(clf, Q)
    assert scores.shape == (5, 3)
    assert np.allclose(Q[best], _CENTRES[2])
    assert cluster == 5
    assert scores[best, 2] == scores.max()
    conf = clf.confidence(Q)
    assert beta == pytest.approx(conf[best, 2])
    assert 0.5 < beta <= 1.0


def test_classifier_round_trip(toy_classifier, rng):
    again = SOGPClassifier.from_dict(toy_classifier.to_dict())
    X, _ = _blobs(rng, 50)
    np.testing.assert_array_equal(again.confidence(X), toy_classifier.confidence(X))
    np.testing.assert_array_equal(again.classes_, toy_classifier.classes_)
    with pytest.raises(ValueError, match="'models'"):
        SOGPClassifier.from_dict({**toy_classifier.to_dict(), "models": []})


def test_classifier_rejects_bad_labels(rng):
    X = rng.normal(size=(10, 2))
    with pytest.raises(ValueError, match="labels"):
        SOGPClassifier().fit(X, rng.normal(size=10), rng=rng)
    with pytest.raises(ValueError, match="labels"):
        SOGPClassifier().fit(X, np.zeros(9, dtype=int), rng=rng)


@settings(max_examples=40, deadline=None)
@given(
    counts=st.lists(st.integers(1, 60), min_size=1, max_size=5),
    size=st.integers(1, 120),
    seed=st.integers(0, 2**32 - 1),
)
def test_balanced_subsample(counts, size, seed):
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(len(counts)), counts)
    labels = labels[rng.permutation(labels.size)]
    idx = balanced_subsample(labels, size, rng=rng)
    assert idx.size == min(size, labels.size)
    assert np.unique(idx).size == idx.size
    got = np.bincount(labels[idx], minlength=len(counts))
    fair = size // len(counts)
    assert np.all(got >= np.minimum(counts, fair))


# ---------------------------------------------------------------- entropy
def test_normalised_entropy_extremes():
    for c in (2, 3, 7):
        assert normalised_entropy(np.eye(c)) == pytest.approx(np.zeros(c), abs=1e-15)
        assert normalised_entropy(np.full((2, c), 1.0 / c)) == pytest.approx(np.ones(2))
    assert normalised_entropy(np.ones((3, 1))).tolist() == [0.0, 0.0, 0.0]


@settings(max_examples=50, deadline=None)
@given(c=st.integers(2, 8), seed=st.integers(0, 2**32 - 1))
def test_normalised_entropy_in_unit_interval(c, seed):
    rng = np.random.default_rng(seed)
    p = rng.dirichlet(np.full(c, 0.5), size=10)
    h = normalised_entropy(p)
    assert np.all((h >= 0.0) & (h <= 1.0))
    expected = -np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1)), 0), axis=1) / np.log(c)
    np.testing.assert_allclose(h, np.clip(expected, 0, 1), atol=1e-12)


def test_predict_mean_equals_predict(rng):
    X = rng.normal(size=(300, 2))
    gp = SparseOnlineGP(capacity=50, length_scales=np.ones(2), signal_var=1.0, noise_var=0.05)
    gp.fit(X, np.sin(X[:, 0]))
    Xq = rng.normal(size=(7, 2))
    np.testing.assert_allclose(gp.predict_mean(Xq), gp.predict(Xq)[0], atol=1e-12)
    # The batch caches follow online updates.
    before = gp.predict(Xq)
    gp.update(Xq[0], 3.0)
    after = gp.predict(Xq)
    assert after[0][0] != before[0][0]
    np.testing.assert_allclose(after[1][:1], gp.predict(Xq[0])[1], atol=1e-12)
    np.testing.assert_allclose(gp.predict_mean(Xq), after[0], atol=1e-12)


def test_evidence_keeps_the_relevant_dimension_and_switches_off_the_others(rng):
    # ARD (Eq. 5.11): the label depends on column 0 only; the evidence makes its length
    # scale short and lets the others grow, which the result reports as switched off (or
    # binding, never silently at the bound).
    X = rng.normal(size=(120, 3)) * np.array([1.0, 5.0, 0.2])
    y = np.tanh(2.0 * X[:, 0]) + 0.1 * rng.normal(size=120)
    hp = fit_hyperparameters(X, y, rng=rng, restarts=2)
    ls = hp.length_scales / X.std(axis=0)
    assert ls[0] < 5.0 and ls[0] < ls[1] and ls[0] < ls[2]
    bounds = hyperparameter_bounds(X, y)
    for j in range(3):
        at_hi = np.log(hp.length_scales[j]) >= bounds[j][1] - 1e-6
        assert not at_hi or j in hp.switched_off or f"length_scale_{j}" in hp.binding
    for (_lo, hi), sd in zip(bounds[:3], X.std(axis=0), strict=True):
        assert np.exp(hi) == pytest.approx(MAX_LENGTH_SCALE * sd)
    with pytest.raises(ValueError, match="max_length_scale"):
        hyperparameter_bounds(X, y, max_length_scale=0.0)


def test_binding_bounds_names_parameters_the_gradient_pushes_out():
    from autonomy.gp_hyperparameters import BINDING_GRADIENT, binding_bounds

    bounds = [(-1.0, 1.0)] * 4  # two length scales, signal, noise
    theta = np.array([1.0, 1.0, 0.0, -1.0])
    flat = BINDING_GRADIENT / 2
    grad = np.array([flat, 1.0, 0.0, -1.0])  # ls0 flat at the top, ls1 pushes, noise pushes
    binding, off = binding_bounds(theta, grad, bounds)
    assert binding == ("length_scale_1", "noise_var") and off == (0,)
    assert binding_bounds(np.zeros(4), np.ones(4), bounds) == ((), ())  # interior: nothing


@pytest.mark.slow  # ~4 s alone (capacity 500, 3000 points: what reproduces the failure)
def test_near_duplicate_inputs_stay_finite(rng):
    # Held stick values (near-duplicates in the relevant inputs) under long length scales
    # elsewhere, as in the demonstrations: with the old novelty threshold (1e-6) and no
    # guard on a negative gamma, Q grew to 1e8 and the GP overflowed to NaN (measured on
    # seeds 0-2 of this very set-up).
    n = 3000
    U = np.round(rng.normal(size=(n, 3)) * 4) / 4 + 1e-3 * rng.normal(size=(n, 3))
    X = np.c_[rng.normal(size=(n, 4)), U]
    y = np.where(U[:, 0] + U[:, 1] > 0, 1.0, -1.0)
    ls = np.r_[np.full(4, 100.0), 1.3, 1.3, 2.2]
    gp = SparseOnlineGP(capacity=500, length_scales=ls, signal_var=0.5, noise_var=1e-2)
    gp.fit(X, y)
    assert np.all(np.isfinite(gp.alpha_)) and np.all(np.isfinite(gp.C_))
    mean, var = gp.predict(X[:200])
    assert np.all(np.isfinite(mean)) and np.all(var >= gp.noise_var)
    assert np.mean(np.sign(mean) == y[:200]) > 0.8


def test_a_negative_gamma_reconditions_q(rng):
    X = rng.uniform(-2.0, 2.0, size=(40, 2))
    y = np.sin(X[:, 0])
    kw = dict(capacity=100, length_scales=np.array([0.8, 0.8]), signal_var=1.0, noise_var=0.01)
    gp = SparseOnlineGP(**kw).fit(X, y)
    ref = SparseOnlineGP(**kw).fit(X, y)
    gp._Q[: gp.n_basis_, : gp.n_basis_] *= 50.0  # drifted Q: gamma < 0 for any new point
    x = np.array([0.3, -0.2])
    gp.update(x, 0.5)
    ref.update(x, 0.5)
    # without the guard the corrupted Q enters e_hat and the update of alpha
    np.testing.assert_allclose(gp.predict(X)[0], ref.predict(X)[0], atol=1e-4)


def test_hard_negatives_lower_a_wrong_candidates_score(rng):
    # Two clusters; the "wrong candidate" lies beside cluster 0, where only negatives say
    # it is no task. With them its best posterior mean must drop (and fall below 0).
    n = 60
    X = np.concatenate(
        (rng.normal((0.0, 0.0), 0.3, size=(n, 2)), rng.normal((3.0, 0.0), 0.3, size=(n, 2)))
    )
    y = np.repeat([0, 1], n)
    wrong = np.array([[0.0, 0.9]])
    neg = rng.normal(wrong[0], 0.15, size=(n, 2))
    kw = {"capacity": 200, "hyper_points": 150, "restarts": 1, "max_length_scale": 1.0}
    plain = SOGPClassifier(**kw).fit(X, y, rng=np.random.default_rng(rng.integers(2**31)))
    hard = SOGPClassifier(**kw).fit(
        X, y, rng=np.random.default_rng(rng.integers(2**31)), negatives=neg
    )
    assert hard.scores(wrong).max() < plain.scores(wrong).max()
    assert hard.scores(wrong).max() < 0.0
    # the clusters themselves are still recognised
    centres = np.array([[0.0, 0.0], [3.0, 0.0]])
    np.testing.assert_array_equal(hard.predict(centres), [0, 1])
    with pytest.raises(ValueError, match="negatives"):
        SOGPClassifier(**kw).fit(X, y, rng=rng, negatives=np.zeros((3, 5)))
