"""Recognition metrics (thesis Sec. 7.2.2, 7.3): rates, F0.5, confusion matrix."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.metrics import confusion_matrix, fbeta_score

from autonomy.evaluation.metrics import confusion, f_beta, trajectory_rates

LABELS = ["door", "wall", "object", "dock"]
label = st.sampled_from(LABELS)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(label, st.one_of(st.none(), label)), min_size=1, max_size=60))
def test_rates_sum_to_one_and_count_ticks(pairs: list[tuple[str, str | None]]) -> None:
    truth = [t for t, _ in pairs]
    dec = [d for _, d in pairs]
    r = trajectory_rates(dec, truth)
    assert r["success"] + r["error"] + r["null"] == pytest.approx(1.0)
    n = len(pairs)
    assert r["success"] == pytest.approx(sum(d == t for t, d in pairs) / n)
    assert r["null"] == pytest.approx(sum(d is None for d in dec) / n)


def test_rates_on_tuple_labels() -> None:
    truth = [("doorway_crossing", "d1")] * 4
    dec = [None, ("doorway_crossing", "d2"), ("wall_following", "d1"), ("doorway_crossing", "d1")]
    assert trajectory_rates(dec, truth) == {"success": 0.25, "error": 0.5, "null": 0.25}
    with pytest.raises(ValueError, match="no ticks"):
        trajectory_rates([], [])
    with pytest.raises(ValueError, match="decisions"):
        trajectory_rates([None], [])


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(label, st.one_of(label, st.just("null"))), min_size=1, max_size=80),
    st.sampled_from([0.5, 1.0, 2.0]),
)
def test_f_beta_and_confusion_match_sklearn(pairs: list[tuple[str, str]], beta: float) -> None:
    y_true = [t for t, _ in pairs]
    y_pred = [p for _, p in pairs]
    ours = f_beta(y_true, y_pred, labels=LABELS, beta=beta)
    ref = fbeta_score(y_true, y_pred, beta=beta, labels=LABELS, average=None, zero_division=0)
    np.testing.assert_allclose([ours[k] for k in LABELS], ref, atol=1e-12)
    np.testing.assert_array_equal(
        confusion(y_true, y_pred, LABELS), confusion_matrix(y_true, y_pred, labels=LABELS)
    )


def test_f_beta_null_is_a_miss_not_a_false_alarm() -> None:
    y_true = ["door", "door", "wall"]
    y_pred = ["door", None, "wall"]
    f = f_beta(y_true, y_pred, labels=["door", "wall"])
    assert f["wall"] == pytest.approx(1.0)
    # door: P = 1, R = 1/2 -> F0.5 = 1.25 * 0.5 / (0.25 + 0.5)
    assert f["door"] == pytest.approx(1.25 * 0.5 / 0.75)
    np.testing.assert_array_equal(confusion(y_true, y_pred, ["door", "wall"]), [[1, 0], [0, 1]])
    with pytest.raises(ValueError, match="beta"):
        f_beta(y_true, y_pred, labels=["door"], beta=0.0)
