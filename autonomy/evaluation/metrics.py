"""Recognition metrics: success, error and null rates along a trajectory (thesis Sec.
7.2.2), F_beta per class (Sec. 7.3, Table 7.6: F_0.5) and the confusion matrix.

Along a test trajectory every tick's decision is compared with the truth (Sec. 7.2.2):

- success rate: fraction of ticks where the correct goal is identified,
- error rate: fraction where a wrong goal is inferred,
- null rate: fraction where no goal is recognised,

so the three sum to 1. A label is any hashable value; for the recognisers of
:mod:`autonomy.bayes_filter` it is ``(task type, component id)``, so a success needs both
the right task type and the right target (issue 3). ``None`` is the null decision.

F_beta for class ``c`` (van Rijsbergen), with precision ``P = tp / (tp + fp)`` and recall
``R = tp / (tp + fn)``:

    F_beta = (1 + beta^2) P R / (beta^2 P + R)

``beta = 0.5`` weighs precision twice as much as recall. Equivalent call:
``sklearn.metrics.fbeta_score(y_true, y_pred, beta=0.5, labels=labels, average=None,
zero_division=0)``; in R: ``MLmetrics::FBeta_Score``.

Decisions where the thesis is silent:

- A class with no true and no predicted instance, or with ``tp = 0``, gets F = 0
  (scikit-learn's ``zero_division=0``).
- Predictions outside ``labels`` (a null decision, or a class not evaluated) count as false
  negatives of the true class and as nobody's false positive; the confusion matrix leaves
  them out, as scikit-learn's ``confusion_matrix(labels=...)`` does.
- A trajectory with no ticks is rejected (the rates would be undefined).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np


def trajectory_rates(
    decisions: Sequence[Hashable | None], truth: Sequence[Hashable]
) -> dict[str, float]:
    """Success, error and null rates along one trajectory (Sec. 7.2.2).

    Parameters
    ----------
    decisions : sequence
        (n,) recognised label per tick, ``None`` for a null decision.
    truth : sequence
        (n,) true label per tick.

    Returns
    -------
    dict
        ``success``, ``error``, ``null``: fractions of ticks in [0, 1], summing to 1.
    """
    if len(decisions) != len(truth):
        raise ValueError(
            f"trajectory_rates: {len(decisions)} decisions for {len(truth)} true labels"
        )
    n = len(truth)
    if n == 0:
        raise ValueError("trajectory_rates: the trajectory has no ticks")
    null = sum(1 for d in decisions if d is None)
    success = sum(1 for d, t in zip(decisions, truth, strict=True) if d is not None and d == t)
    return {"success": success / n, "error": (n - null - success) / n, "null": null / n}


def confusion(
    y_true: Sequence[Hashable], y_pred: Sequence[Hashable | None], labels: Sequence[Hashable]
) -> np.ndarray:
    """Confusion matrix, rows true and columns predicted in ``labels`` order.

    Parameters
    ----------
    y_true, y_pred : sequence
        (n,) labels; pairs with either label outside ``labels`` are left out.
    labels : sequence
        (k,) distinct classes.

    Returns
    -------
    numpy.ndarray
        (k, k) int counts; equals ``sklearn.metrics.confusion_matrix(y_true, y_pred,
        labels=labels)``.
    """
    if len(y_true) != len(y_pred):
        raise ValueError(f"confusion: {len(y_true)} true labels for {len(y_pred)} predictions")
    index = {lab: i for i, lab in enumerate(labels)}
    if len(index) != len(labels):
        raise ValueError("confusion: labels must be distinct")
    m = np.zeros((len(labels), len(labels)), dtype=int)
    for t, p in zip(y_true, y_pred, strict=True):
        i, j = index.get(t), index.get(p)
        if i is not None and j is not None:
            m[i, j] += 1
    return m


def f_beta(
    y_true: Sequence[Hashable],
    y_pred: Sequence[Hashable | None],
    *,
    labels: Sequence[Hashable],
    beta: float = 0.5,
) -> dict[Hashable, float]:
    """F_beta per class (Sec. 7.3, Table 7.6 with beta = 0.5).

    Parameters
    ----------
    y_true, y_pred : sequence
        (n,) true and predicted labels (``None`` or any label outside ``labels`` is a
        prediction of no evaluated class).
    labels : sequence
        (k,) classes to score.
    beta : float
        > 0; weight of recall relative to precision.

    Returns
    -------
    dict
        Class -> F_beta in [0, 1].
    """
    if beta <= 0:
        raise ValueError(f"f_beta: beta must be > 0, got {beta}")
    if len(y_true) != len(y_pred):
        raise ValueError(f"f_beta: {len(y_true)} true labels for {len(y_pred)} predictions")
    b2 = beta * beta
    out: dict[Hashable, float] = {}
    for lab in labels:
        tp = sum(1 for t, p in zip(y_true, y_pred, strict=True) if t == lab and p == lab)
        fp = sum(1 for t, p in zip(y_true, y_pred, strict=True) if t != lab and p == lab)
        fn = sum(1 for t, p in zip(y_true, y_pred, strict=True) if t == lab and p != lab)
        # (1 + b^2) P R / (b^2 P + R) = (1 + b^2) tp / ((1 + b^2) tp + b^2 fn + fp)
        denom = (1.0 + b2) * tp + b2 * fn + fp
        out[lab] = (1.0 + b2) * tp / denom if tp > 0 else 0.0
    return out
