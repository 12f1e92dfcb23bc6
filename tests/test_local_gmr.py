"""The local GMR of the contextual rollout (autonomy.local_gmr): EM run to convergence
against a plain reference (tests/gmr_reference.py), its stopping rule and settings, the
pooled nearest-neighbour search and the cache."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.special import logsumexp

from autonomy.contextual import ContextualSettings
from autonomy.gmr import data_scale
from autonomy.local_gmr import LocalGMR, local_gmm
from autonomy.modes import settings_from

sys.path.insert(0, str(Path(__file__).parent))
from gmr_reference import ref_local_gmm, ref_predict  # noqa: E402

# --------------------------------------------------------------------------- EM


def _blobs(rng, n=5, dim=5, gap=3.0):
    return np.vstack((rng.normal(0.0, 0.05, (n, dim)), rng.normal(gap, 0.05, (n, dim))))


def test_em_stops_before_the_cap_on_well_separated_data(rng):
    fit = local_gmm(_blobs(rng), tol=1e-4, max_iter=100)
    assert fit.converged and 2 <= fit.n_iter < 100
    np.testing.assert_allclose(np.sort(fit.means[:, 0]), [0.0, 3.0], atol=0.1)
    np.testing.assert_allclose(fit.weights, [0.5, 0.5], atol=1e-6)


@pytest.mark.parametrize("max_iter", [1, 2, 7])
def test_em_runs_to_the_cap_when_tol_is_zero(rng, max_iter):
    for local in (_blobs(rng), rng.normal(size=(10, 5))):
        fit = local_gmm(local, tol=0.0, max_iter=max_iter)
        assert fit.n_iter == max_iter and not fit.converged


def test_em_equals_the_plain_reference(rng):
    for _ in range(30):
        local = rng.normal(size=(10, 5)) * rng.uniform(0.01, 2.0, 5) + rng.uniform(-3, 3, 5)
        if rng.random() < 0.3:
            local[: int(rng.integers(2, 6))] += rng.uniform(-2, 2, 5)  # a second group
        for tol, max_iter in ((1e-4, 100), (1e-8, 100), (0.0, 6)):
            fit = local_gmm(local, tol=tol, max_iter=max_iter)
            w, mu, var, n_iter = ref_local_gmm(local, tol=tol, max_iter=max_iter)
            assert fit.n_iter == n_iter
            np.testing.assert_allclose(fit.weights, w, rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(fit.means, mu, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(fit.variances, var, rtol=1e-7, atol=1e-12)


def test_converged_fit_is_a_fixed_point_of_em(rng):
    """Run from scratch with a tighter tolerance, EM moves the log-likelihood by no more
    than the stopping rule allowed."""
    local = rng.normal(size=(10, 5)) * rng.uniform(0.05, 1.0, 5)

    def mean_loglik(w, mu, var):
        logp = np.log(w) + np.stack(
            [
                (-0.5 * ((local - m) ** 2 / v + np.log(2 * np.pi * v))).sum(axis=1)
                for m, v in zip(mu, var, strict=True)
            ],
            axis=1,
        )
        return logsumexp(logp, axis=1).mean()

    loose = local_gmm(local, tol=1e-4, max_iter=500)
    tight = local_gmm(local, tol=1e-12, max_iter=5000)
    assert loose.converged and tight.converged and tight.n_iter >= loose.n_iter
    a, b = mean_loglik(*loose[:3]), mean_loglik(*tight[:3])
    assert b >= a - 1e-9  # EM never decreases the likelihood
    assert b - a <= 1e-4 * abs(b) * max(1, tight.n_iter - loose.n_iter)


def test_fit_is_a_function_of_the_set_and_translation_equivariant(rng):
    local = rng.normal(size=(10, 5)) * rng.uniform(0.05, 1.0, 5)
    fit = local_gmm(local)
    perm = local_gmm(local[rng.permutation(10)])
    order, order_p = np.argsort(fit.means[:, 0]), np.argsort(perm.means[:, 0])
    np.testing.assert_allclose(perm.means[order_p], fit.means[order], atol=1e-10)
    np.testing.assert_allclose(perm.variances[order_p], fit.variances[order], rtol=1e-8)
    shift = rng.uniform(-5, 5, 5)
    moved = local_gmm(local + shift, scale=data_scale(local))
    np.testing.assert_allclose(moved.means, fit.means + shift, atol=1e-9)
    np.testing.assert_allclose(moved.variances, fit.variances, rtol=1e-7)


def test_coinciding_points_give_one_component():
    fit = local_gmm(np.ones((10, 5)))
    assert fit.weights.shape == (1,) and fit.n_iter == 0 and np.all(fit.variances > 0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"tol": -1e-4}, "tol"),
        ({"tol": math.nan}, "tol"),
        ({"tol": math.inf}, "tol"),
        ({"tol": "1e-4"}, "tol"),
        ({"tol": True}, "tol"),
        ({"max_iter": 0}, "max_iter"),
        ({"max_iter": 2.5}, "max_iter"),
        ({"max_iter": True}, "max_iter"),
    ],
)
def test_em_settings_are_validated(rng, kwargs, name):
    data = rng.normal(size=(30, 5))
    with pytest.raises(ValueError, match=name):
        local_gmm(data[:10], **kwargs)
    with pytest.raises(ValueError, match=name):
        LocalGMR(data, k=10, **kwargs)
    setting = {"tol": "em_tol", "max_iter": "em_max_iter"}[name]
    with pytest.raises(ValueError, match=setting):
        ContextualSettings(**{setting: kwargs[name]})


def test_the_shortened_rollout_settings_are_gone():
    for name in ("gmr_every", "em_iters"):
        with pytest.raises(ValueError, match="unknown setting"):
            settings_from(ContextualSettings, {name: 1}, where="mode 'contextual_task'")


# --------------------------------------------------------------------------- kNN, cache


def test_pooled_neighbour_search_equals_brute_force(rng):
    data = np.column_stack((rng.uniform(-2, 2, (400, 2)), rng.normal(size=(400, 3))))
    for k in (1, 3, 10, 40):
        local = LocalGMR(data, k=k)
        start = x = rng.uniform(-2.5, 2.5, 2)
        for _ in range(300):
            draw = rng.random()  # a walk, now and then a jump, or back to its start
            x = start + rng.normal(scale=0.02, size=2) if draw > 0.95 else x
            x = x + rng.normal(scale=0.02 if draw < 0.9 else 1.5, size=2)
            got = np.frombuffer(local._key(float(x[0]), float(x[1])), dtype=np.intp)
            d2 = ((data[:, :2] - x) ** 2).sum(axis=1)
            expected = np.sort(np.argsort(d2, kind="stable")[:k])
            np.testing.assert_array_equal(got, expected)
    small = LocalGMR(data[:7], k=10)  # fewer points than neighbours: all of them
    assert np.frombuffer(small._key(0.3, 0.1), dtype=np.intp).tolist() == list(range(7))


def test_predictions_are_cached_per_neighbour_set_and_counted(rng):
    data = np.column_stack((rng.uniform(-2, 2, (200, 2)), rng.normal(size=(200, 3))))
    local = LocalGMR(data, k=10, tol=1e-4, max_iter=50)
    queries = rng.uniform(-2, 2, (30, 2))
    first = [local.predict_xy(float(a), float(b)) for a, b in queries]
    fits = sum(local.n_iter_counts_)
    assert fits == len(local.cache_) <= 30 and local.n_iter_counts_[0] == 0
    again = [local.predict_xy(float(a), float(b)) for a, b in queries]
    assert again == first and sum(local.n_iter_counts_) == fits  # no new fit
    for (a, b), u in zip(queries, first, strict=True):
        expected = ref_predict(data, (a, b), k=10, tol=1e-4, max_iter=50)
        np.testing.assert_allclose(u, expected, rtol=1e-8, atol=1e-10)
