"""Recognition metrics (thesis Sec. 7.2.2, 7.3): success, error and null rates along a
trajectory, F_beta per class (Table 7.6: F_0.5), the confusion matrix, and their
variants where "right" needs the right task type and the right target (issue 3).

A label is any hashable value (for the recognisers of :mod:`autonomy.bayes_filter`,
``(task type, component id)``); ``None`` is the null decision.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np


def trajectory_rates(
    decisions: Sequence[Hashable | None], truth: Sequence[Hashable]
) -> dict[str, float]:
    """Success, error and null rates along one trajectory (Sec. 7.2.2): the fractions of
    ticks where the correct goal is identified, a wrong goal is inferred, and no goal is
    recognised.

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
    """F_beta per class (Sec. 7.3, Table 7.6 with beta = 0.5; van Rijsbergen).

    With precision ``P = tp / (tp + fp)`` and recall ``R = tp / (tp + fn)``,
    ``F_beta = (1 + beta^2) P R / (beta^2 P + R)``; ``beta = 0.5`` weighs precision twice
    as much as recall. Equivalent call: ``sklearn.metrics.fbeta_score(y_true, y_pred,
    beta=0.5, labels=labels, average=None, zero_division=0)``; in R:
    ``MLmetrics::FBeta_Score``.

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


def f05_with_targets(
    true_task: Sequence[str],
    pred_task: Sequence[str | None],
    target_ok: Sequence[bool],
    labels: Sequence[str],
    *,
    beta: float = 0.5,
) -> dict[str, float]:
    """F_beta (Eq. 7.6) per task type where "right" needs the right type and target.

    Parameters
    ----------
    true_task, pred_task : sequence
        (n,) true and predicted task types (None: no prediction).
    target_ok : sequence of bool
        (n,) whether the predicted target is the demonstrated one.
    labels : sequence of str
        Task types to score.

    Returns
    -------
    dict
        Task type -> F_beta in [0, 1], and ``"macro"``: their mean.
    """
    t = np.asarray(true_task, dtype=object)
    p = np.asarray(pred_task, dtype=object)
    ok = np.asarray(target_ok, dtype=bool)
    b2 = beta * beta
    out: dict[str, float] = {}
    for c in labels:
        right = (p == c) & (t == c) & ok
        tp = int(right.sum())
        fp = int(((p == c) & ~right).sum())
        fn = int(((t == c) & ~right).sum())
        denom = (1.0 + b2) * tp + b2 * fn + fp
        out[c] = (1.0 + b2) * tp / denom if tp > 0 else 0.0  # Eq. (7.6)
    out["macro"] = float(np.mean([out[c] for c in labels])) if labels else 0.0
    return out


def confusion_with_targets(
    true_task: Sequence[str],
    pred_task: Sequence[str | None],
    target_ok: Sequence[bool],
    labels: Sequence[str],
) -> list[list[int]]:
    """Rows = true type; columns = predicted type at the right target, then
    ``wrong_target`` (any type at a wrong target, or no prediction); (k, k + 1) counts."""
    index = {c: i for i, c in enumerate(labels)}
    m = np.zeros((len(labels), len(labels) + 1), dtype=int)
    for t, p, ok in zip(true_task, pred_task, target_ok, strict=True):
        i = index.get(t)
        if i is None:
            continue
        j = index.get(p) if (ok and p is not None) else None
        m[i, len(labels) if j is None else j] += 1
    return m.tolist()
