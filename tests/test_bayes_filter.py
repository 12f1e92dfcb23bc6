"""Recursive Bayesian filter with GMR user models (thesis Ch. 4); the exponential
baseline's tests are in test_baseline_recogniser.py."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.bayes_filter import (
    BayesFilterRecogniser,
    TaskUserModel,
    n_parameters,
    target_features,
)

KINDS = {"doorway_crossing": "doorway", "wall_following": "wall", "object_inspection": "object"}


def doorway_data(rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Driving at the target: theta ~ 0, psi narrowing as the robot gets close."""
    d = rng.uniform(0.3, 4.0, n)
    psi = rng.normal(0.0, 0.15 + 0.1 * d)
    theta = rng.normal(0.0, 0.15, n)
    return np.column_stack([d, psi, theta])


def wall_data(rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Wall abeam (psi ~ +-pi/2), input along it (theta ~ -+pi/2), either side."""
    side = rng.choice([-1.0, 1.0], n)
    d = rng.normal(0.8, 0.15, n)
    psi = side * np.pi / 2 + rng.normal(0.0, 0.1, n)
    theta = -side * np.pi / 2 + rng.normal(0.0, 0.1, n)
    return np.column_stack([d, psi, theta])


def fitted(rng: np.random.Generator, X: np.ndarray, h: int = 3) -> TaskUserModel:
    return TaskUserModel(max_components=h).fit(X, rng=rng)


# ------------------------------------------------------------------- features and user model


def test_target_features_geometry() -> None:
    s = np.array([[2.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    f = target_features(s, np.array([1.0, 0.0, 0.3]))
    np.testing.assert_allclose(f[:, 0], [2.0, 1.0, 1.0])
    np.testing.assert_allclose(f[:, 1], [0.0, np.pi / 2, np.pi])
    np.testing.assert_allclose(f[:, 2], [0.0, -np.pi / 2, np.pi])  # wrapped to (-pi, pi]


def test_n_parameters_eq_4_12() -> None:
    # (h - 1) + h (d + d (d + 1) / 2): 1 component in 3-D is 3 means + 6 covariances
    assert n_parameters(1, 3) == 9
    assert n_parameters(2, 3) == 19
    assert n_parameters(10, 3) == 99


@pytest.mark.parametrize("true_h", [1, 2, 3])
def test_bic_picks_true_number_of_components(rng: np.random.Generator, true_h: int) -> None:
    centres = np.array([[1.0, -1.5, 1.5], [2.5, 0.0, 0.0], [4.0, 1.5, -1.5]])[:true_h]
    parts = []
    for c in centres:
        A = rng.normal(0.0, 0.3, (3, 3))
        cov = A @ A.T + 0.02 * np.eye(3)  # random full covariance, well inside one cluster
        parts.append(rng.multivariate_normal(c, cov, 300))
    X = np.vstack(parts)
    model = TaskUserModel(max_components=5).fit(X, rng=rng)
    assert model.n_components_ == true_h
    assert model.bic_.shape == (5,)
    assert int(np.argmin(model.bic_)) + 1 == true_h
    np.testing.assert_allclose(model.weights_.sum(), 1.0)


def test_likelihood_positive_finite_and_normalised(rng: np.random.Generator) -> None:
    model = fitted(rng, doorway_data(rng))
    d = np.array([0.5, 2.0, 3.5, 100.0, 0.0])
    psi = np.array([0.0, 0.3, -1.0, 3.0, -3.1])
    theta = np.array([0.0, -0.2, 2.5, -3.0, 3.1])
    p = model.likelihood(d, psi, theta)
    assert p.shape == (5,)
    assert np.all(np.isfinite(model.log_likelihood(d, psi, theta)))  # even far off the data
    assert np.all(np.isfinite(p[:3])) and np.all(p[:3] > 0)
    assert p[0] > p[2]  # on the demonstrated pattern beats off it
    # a conditional density over (psi, theta): integrates to ~1 at any d in the data
    g = np.linspace(-np.pi, np.pi, 241)
    P, T = np.meshgrid(g, g, indexing="ij")
    step = g[1] - g[0]
    for dist in (0.7, 2.0, 3.5):
        dens = model.likelihood(np.full(P.size, dist), P.ravel(), T.ravel())
        assert dens.sum() * step * step == pytest.approx(1.0, abs=0.03)


def test_user_model_rejects_bad_input(rng: np.random.Generator) -> None:
    with pytest.raises(ValueError, match="n, 3"):
        TaskUserModel().fit(np.zeros((20, 2)), rng=rng)
    with pytest.raises(ValueError, match="at least"):
        TaskUserModel().fit(rng.normal(size=(5, 3)), rng=rng)
    X = doorway_data(rng, 50)
    X[3, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        TaskUserModel().fit(X, rng=rng)


# ------------------------------------------------------------------------------- filter


def doorway_filter(rng: np.random.Generator, **kw: float) -> BayesFilterRecogniser:
    models = {"doorway_crossing": fitted(rng, doorway_data(rng))}
    return BayesFilterRecogniser(models, KINDS, **kw)


def test_converges_to_the_candidate_the_input_points_at(rng: np.random.Generator) -> None:
    filt = doorway_filter(rng, stay=1.0)
    a, b = np.array([2.0, 0.4]), np.array([1.2, -1.6])
    cands = [("door_a", "doorway", a), ("door_b", "doorway", b), ("box", "object", b)]
    u = np.array([*(0.4 * a / np.linalg.norm(a)), 0.0])
    for _ in range(40):
        out = filt.step(cands, u)
        np.testing.assert_allclose(out.belief.sum(), 1.0)
    assert out.states == (("doorway_crossing", "door_a"), ("doorway_crossing", "door_b"))
    assert out.decision == ("doorway_crossing", "door_a")
    assert out.belief[0] > 0.99
    assert out.confidence == pytest.approx(out.belief[0])


def test_recognises_the_task_type(rng: np.random.Generator) -> None:
    models = {
        "doorway_crossing": fitted(rng, doorway_data(rng)),
        "wall_following": fitted(rng, wall_data(rng)),
    }
    filt = BayesFilterRecogniser(models, KINDS)
    cands = [("door", "doorway", np.array([3.0, 0.0])), ("wall", "wall", np.array([0.0, 0.8]))]
    for _ in range(20):
        out = filt.step(cands, np.array([0.3, 0.0, 0.0]))  # along the wall: wall following
    assert out.decision == ("wall_following", "wall")
    filt.reset()
    cands = [("door", "doorway", np.array([2.0, 0.1])), ("wall", "wall", np.array([2.5, 0.0]))]
    for _ in range(20):
        out = filt.step(cands, np.array([0.3, 0.015, 0.0]))  # wall dead ahead: not following
    assert out.decision == ("doorway_crossing", "door")


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_belief_sums_to_one_as_candidates_come_and_go(case_seed: int) -> None:
    rng = np.random.default_rng(case_seed)
    filt = BayesFilterRecogniser(
        {"doorway_crossing": _SHARED_MODEL}, KINDS, stay=float(rng.uniform(0.5, 1.0))
    )
    pool = [f"door_{k}" for k in range(6)]
    for _ in range(15):
        ids = rng.choice(pool, size=int(rng.integers(0, 5)), replace=False)
        cands = [(str(i), "doorway", rng.uniform(-4, 4, 2)) for i in ids]
        u = rng.normal(size=3) * rng.choice([0.0, 1.0])
        out = filt.step(cands, u)
        assert len(out.states) == len(ids) == out.belief.size
        if len(ids):
            np.testing.assert_allclose(out.belief.sum(), 1.0)
            assert np.all(out.belief >= 0)
            assert 0.0 <= out.confidence <= 1.0
            assert out.confidence == pytest.approx(out.belief.max())
        else:
            assert out.decision is None and out.confidence == 0.0
        assert set(filt.belief_) == set(out.states)


_SHARED_MODEL = TaskUserModel(max_components=2).fit(
    doorway_data(np.random.default_rng(7)), rng=np.random.default_rng(8)
)


def test_candidates_appearing_and_disappearing(rng: np.random.Generator) -> None:
    filt = doorway_filter(rng, stay=1.0, new_prior=0.01)
    a, b = np.array([2.0, 0.3]), np.array([1.0, -2.0])
    u = np.array([*(a / np.linalg.norm(a)), 0.0])
    for _ in range(10):
        out = filt.step([("a", "doorway", a), ("b", "doorway", b)], u)
    ratio = out.belief[0] / out.belief[1]
    # a new candidate enters with new_prior; the others keep their proportions
    out = filt.step([("a", "doorway", a), ("b", "doorway", b), ("c", "doorway", b)], np.zeros(3))
    assert not out.updated
    np.testing.assert_allclose(out.belief[2], 0.01)
    np.testing.assert_allclose(out.belief[0] / out.belief[1], ratio)
    ratio_bc = out.belief[1] / out.belief[2]
    # the winner leaves: the rest is renormalised and keeps its proportions
    out = filt.step([("b", "doorway", b), ("c", "doorway", b)], np.zeros(3))
    assert ("doorway_crossing", "a") not in filt.belief_
    np.testing.assert_allclose(out.belief.sum(), 1.0)
    np.testing.assert_allclose(out.belief[0] / out.belief[1], ratio_bc)
    # everyone leaves and comes back: a fresh uniform prior
    filt.step([], u)
    out = filt.step([("a", "doorway", a), ("b", "doorway", b)], np.zeros(3))
    np.testing.assert_allclose(out.belief, [0.5, 0.5])
    assert out.decision == ("doorway_crossing", "a")  # 0.5 >= null_threshold, first wins


def test_transition_spreads_belief_back(rng: np.random.Generator) -> None:
    filt = doorway_filter(rng, stay=0.95)
    a, b = np.array([2.0, 0.3]), np.array([1.0, -2.0])
    cands = [("a", "doorway", a), ("b", "doorway", b), ("c", "doorway", -a)]
    u = np.array([*(a / np.linalg.norm(a)), 0.0])
    for _ in range(30):
        filt.step(cands, u)
    before = filt.step(cands, np.zeros(3)).belief
    for _ in range(200):
        out = filt.step(cands, np.zeros(3))  # no input: prediction only, Eq. (4.14)
    assert before[0] > out.belief[0]
    np.testing.assert_allclose(out.belief, 1 / 3, atol=1e-3)  # back to uniform
    assert out.decision is None  # 1/3 < 0.5


def test_filter_rejects_bad_settings(rng: np.random.Generator) -> None:
    models = {"doorway_crossing": _SHARED_MODEL}
    with pytest.raises(ValueError, match="stay"):
        BayesFilterRecogniser(models, KINDS, stay=0.0)
    with pytest.raises(ValueError, match="kind"):
        BayesFilterRecogniser({"gap_crossing": _SHARED_MODEL}, KINDS)
    filt = BayesFilterRecogniser(models, KINDS)
    p = np.array([1.0, 0.0])
    with pytest.raises(ValueError, match="unique"):
        filt.step([("a", "doorway", p), ("a", "doorway", p)], np.ones(3))
