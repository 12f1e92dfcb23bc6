"""How closely two contextual-task models recognise alike on the same ticks (issue 36):
a model rebuilt from the shipped model's recipe on another machine against the shipped
one. Each model scores every tick's candidates with its own scaler and SOGP classifier
(Eqs. 5.6-5.10); the winners (candidate and primitive) and blend weights are compared."""

from __future__ import annotations

from typing import Any

import numpy as np

from autonomy.contextual import Recogniser
from autonomy.evaluation.folds import candidate_features
from autonomy.features import encode


def recognitions(
    model: Any, points: np.ndarray, offsets: np.ndarray, u_norm: np.ndarray, ticks: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The winning candidate (row within its tick, -1 for none), primitive id and blend
    weight of ``model`` on each of ``ticks``.

    Parameters
    ----------
    model : autonomy.model.ContextualModel
    points : numpy.ndarray
        (m, 2) candidate target points [m], robot frame, ticks' candidates contiguous.
    offsets : numpy.ndarray
        (n + 1,) tick ``i``'s candidates are rows ``offsets[i]:offsets[i + 1]``.
    u_norm : numpy.ndarray
        (n, 3) commands in normalised (-1, 1) units.
    ticks : numpy.ndarray
        (k,) the ticks to recognise on.

    Returns
    -------
    candidate, primitive : numpy.ndarray
        (k,) int.
    beta : numpy.ndarray
        (k,) blend weights in [0, 1] (Eq. 5.10).
    """
    q, _ = candidate_features(points, offsets, u_norm)
    Z = model.scaler.transform(encode(q))
    recogniser = Recogniser(model.sogp)
    out = np.full((3, len(ticks)), -1.0)
    for n, t in enumerate(ticks):
        a, b = int(offsets[t]), int(offsets[t + 1])
        if b > a:
            i, cluster, beta, _ = recogniser(Z[a:b])
            out[:, n] = (i, cluster, beta)
    return out[0].astype(np.int64), out[1].astype(np.int64), out[2]


def recognition_agreement(
    model_a: Any,
    model_b: Any,
    points: np.ndarray,
    offsets: np.ndarray,
    u_norm: np.ndarray,
    *,
    stride: int = 1,
) -> dict[str, Any]:
    """How often ``model_a`` and ``model_b`` pick the same candidate and primitive, and how
    far their blend weights differ, on every ``stride``-th tick with candidates (arrays
    as :func:`recognitions`).

    Returns
    -------
    dict
        ``ticks``; ``winner_agreement`` (share with the same candidate and primitive);
        ``beta_difference`` ``{"p50", "p99", "max"}`` of ``|beta_a - beta_b|`` over the
        ticks where the winners agree.
    """
    has = np.flatnonzero(np.diff(offsets) > 0)[:: max(int(stride), 1)]
    ca, pa, ba = recognitions(model_a, points, offsets, u_norm, has)
    cb, pb, bb = recognitions(model_b, points, offsets, u_norm, has)
    same = (ca == cb) & (pa == pb)
    gap = np.abs(ba - bb)[same]
    quantile = (lambda p: float(np.quantile(gap, p))) if len(gap) else (lambda p: 0.0)
    return {
        "ticks": int(len(has)),
        "winner_agreement": float(same.mean()) if len(has) else 1.0,
        "beta_difference": {"p50": quantile(0.5), "p99": quantile(0.99), "max": quantile(1.0)},
    }
