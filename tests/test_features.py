"""Task features (thesis Sec. 6.1): the angle, vectorisation, encoding and the scaler."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.features import FeatureScaler, encode, task_features, wrap_angle

angles = st.floats(-np.pi, np.pi, allow_nan=False)
lengths = st.floats(0.05, 5.0, allow_nan=False)


def _polar(r: float, a: float) -> np.ndarray:
    return np.array([r * np.cos(a), r * np.sin(a)])


@settings(max_examples=60, deadline=None)
@given(a=angles, r=lengths, speed=st.floats(0.05, 1.0), omega=st.floats(-1.0, 1.0))
def test_theta_zero_when_driving_straight_at_the_target(a, r, speed, omega):
    s = _polar(r, a)
    u = np.r_[_polar(speed, a), omega]
    q = task_features(s[None], u)
    assert q.shape == (1, 6)
    assert abs(q[0, 2]) < 1e-9
    np.testing.assert_array_equal(q[0, :2], s)
    np.testing.assert_array_equal(q[0, 3:], u)


@settings(max_examples=60, deadline=None)
@given(a=angles, r=lengths, speed=st.floats(0.05, 1.0))
def test_theta_is_plus_minus_half_pi_sideways_and_pi_away(a, r, speed):
    s = _polar(r, a)
    left = task_features(s, np.r_[_polar(speed, a + np.pi / 2), 0.0])[0, 2]
    right = task_features(s, np.r_[_polar(speed, a - np.pi / 2), 0.0])[0, 2]
    away = task_features(s, np.r_[_polar(speed, a + np.pi), 0.0])[0, 2]
    assert left == pytest.approx(np.pi / 2, abs=1e-9)
    assert right == pytest.approx(-np.pi / 2, abs=1e-9)
    # Driving away is at the wrap point: it must come out as +pi or, within rounding, -pi.
    assert abs(abs(away) - np.pi) < 1e-9


@settings(max_examples=80, deadline=None)
@given(a_s=angles, a_u=angles, r=lengths, speed=st.floats(0.05, 1.0))
def test_theta_is_the_wrapped_signed_difference(a_s, a_u, r, speed):
    theta = task_features(_polar(r, a_s), np.r_[_polar(speed, a_u), 0.3])[0, 2]
    assert -np.pi < theta <= np.pi
    # Same angle modulo 2 pi as a_u - a_s.
    assert np.cos(theta) == pytest.approx(np.cos(a_u - a_s), abs=1e-9)
    assert np.sin(theta) == pytest.approx(np.sin(a_u - a_s), abs=1e-9)


def test_wrap_angle_half_open_interval():
    w = wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 0.0, 2 * np.pi + 0.1]))
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    assert w[0] == np.pi and w[1] == np.pi  # exactly -pi maps to +pi
    np.testing.assert_allclose(np.abs(w[2:4]), np.pi)  # +-3 pi in floats: rounding decides
    np.testing.assert_allclose(w[5], 0.1, atol=1e-12)


def test_theta_is_zero_without_translational_input(rng):
    s = rng.normal(size=(5, 2))
    for u in (np.zeros(3), np.array([0.0, 0.0, 0.8]), np.array([1e-9, -1e-9, -0.5])):
        assert np.all(task_features(s, u)[:, 2] == 0.0)
    # Robot centre on the target: no direction either.
    assert task_features(np.zeros(2), np.array([0.5, 0.2, 0.0]))[0, 2] == 0.0


def test_vectorised_equals_per_candidate_loop(rng):
    targets = rng.normal(scale=3.0, size=(25, 2))
    for _ in range(5):
        u = rng.uniform(-1, 1, size=3)
        q = task_features(targets, u)
        loop = np.vstack([task_features(t, u) for t in targets])
        np.testing.assert_array_equal(q, loop)


def test_encode_scales_the_angle_by_the_speed_and_keeps_other_columns(rng):
    targets = rng.normal(size=(30, 2))
    u = rng.uniform(-1, 1, size=3)
    q = task_features(targets, u)
    z = encode(q)
    assert z.shape == (30, 7)
    np.testing.assert_allclose(np.hypot(z[:, 2], z[:, 3]), np.hypot(u[0], u[1]), atol=1e-12)
    np.testing.assert_allclose(np.arctan2(z[:, 3], z[:, 2]), q[:, 2], atol=1e-12)
    np.testing.assert_array_equal(z[:, :2], q[:, :2])
    np.testing.assert_array_equal(z[:, 4:], q[:, 3:])
    np.testing.assert_array_equal(encode(q[0]), z[0])


def test_feature_shape_errors():
    with pytest.raises(ValueError, match="targets"):
        task_features(np.zeros((3, 3)), np.zeros(3))
    with pytest.raises(ValueError, match="u"):
        task_features(np.zeros((3, 2)), np.zeros(2))
    with pytest.raises(ValueError, match="q"):
        encode(np.zeros((4, 5)))


def test_scaler_standardises_and_round_trips(rng):
    X = rng.normal(loc=[1.0, -3.0, 0.0, 5.0], scale=[0.1, 4.0, 1.0, 1.0], size=(200, 4))
    X[:, 2] = 7.0  # constant column: centred, never blown up
    scaler = FeatureScaler().fit(X)
    Z = scaler.transform(X)
    np.testing.assert_allclose(Z.mean(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(Z[:, [0, 1, 3]].std(axis=0), 1.0, rtol=1e-12)
    assert scaler.scale_[2] == 1.0
    np.testing.assert_allclose(scaler.inverse_transform(Z), X, atol=1e-12)
    again = FeatureScaler.from_dict(scaler.to_dict())
    np.testing.assert_array_equal(again.transform(X), Z)


def test_scaler_rejects_bad_input_and_files():
    with pytest.raises(ValueError, match="finite"):
        FeatureScaler().fit(np.array([[0.0, np.nan]]))
    with pytest.raises(ValueError, match="'scale'"):
        FeatureScaler.from_dict({"mean": np.zeros(3)})
    with pytest.raises(ValueError, match="positive"):
        FeatureScaler.from_dict({"mean": np.zeros(2), "scale": np.array([1.0, 0.0])})
    with pytest.raises(RuntimeError):
        FeatureScaler().transform(np.zeros((1, 2)))


def test_encoded_angle_is_defined_and_continuous_at_zero_translational_input(rng):
    targets = rng.normal(scale=2.0, size=(12, 2))
    w = rng.uniform(-1, 1)
    z0 = encode(task_features(targets, np.array([0.0, 0.0, w])))
    np.testing.assert_array_equal(z0[:, 2:4], 0.0)  # (0, 0): no input direction
    assert np.all(np.isfinite(z0))
    # Approaching zero input from any direction tends to the same encoding.
    for _ in range(5):
        a = rng.uniform(-np.pi, np.pi)
        tiny = 1e-7 * np.array([np.cos(a), np.sin(a), 0.0]) + np.array([0.0, 0.0, w])
        np.testing.assert_allclose(encode(task_features(targets, tiny)), z0, atol=1e-6)
