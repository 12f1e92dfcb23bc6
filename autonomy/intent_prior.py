"""What the demonstrations say about where a task is performed (issue 40; thesis Sec.
4.2.4, 5.1-5.2, 6.2.1): the kind of component each motion primitive was demonstrated on,
how far from its target a primitive is executed, how far the driver is while still
approaching, and how the demonstrated target ranks among the nearest components.

All of it is learnt without task labels: the demonstration's target component (and so
its kind) is known from the scenario (Sec. 6.2.1), the demonstrator knows when it is
approaching and when executing, and the primitive is the DP-GMM's cluster. The
kind-and-time recogniser (:mod:`autonomy.kind_time`) reads it from the model's metadata
(``metadata["intent_prior"]``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# component kind -> the class the prior is kept for: gaps and docks never demonstrated,
# reach the primitives as doorway-like point targets (Sec. 4.2.4: docking is doorway-like
# motion at the dock)
KIND_CLASS: dict[str, int] = {"doorway": 0, "gap": 0, "dock": 0, "object": 1, "wall": 2}
KIND_CLASSES = ("passage", "object", "wall")
RANKS = 10  # ranks of the target among the nearest components kept (the mode's candidates)
MIN_DISTANCE_M = 0.05  # distances below are taken as this in the log-normal fits
SMOOTHING = 1.0  # Laplace pseudo-counts of the kind shares and ranks
# least spread of a primitive's execution distance [log m]: a scripted demonstrator keeps
# one standoff (an inspection's sd came out 0.05), people keep theirs within some 15 %
EXECUTION_SD = 0.15


def fit_intent_prior(
    labels: np.ndarray,
    target_distance: np.ndarray,
    executing: np.ndarray,
    target_kind: np.ndarray,
    target_rank: np.ndarray,
) -> dict[str, Any]:
    """The prior from the demonstrated ticks, JSON-ready.

    Parameters
    ----------
    labels : numpy.ndarray
        (n,) int primitive (cluster id) of every tick.
    target_distance : numpy.ndarray
        (n,) [m] distance from the robot to the demonstrated target point.
    executing : numpy.ndarray
        (n,) bool: the demonstrator was executing the task (not approaching it).
    target_kind : numpy.ndarray
        (n,) str kind of the demonstrated component.
    target_rank : numpy.ndarray
        (n,) int rank of the target among the tick's components by distance (0: nearest).

    Returns
    -------
    dict
        ``kind_share`` (cluster id -> shares of the kind classes :data:`KIND_CLASSES`),
        ``execution_log_distance`` (cluster id -> ``[mean, sd]`` of log distance [log m]
        while executing), ``approach_log_distance`` (``[mean, sd]`` over the approaching
        ticks), ``rank`` (:data:`RANKS` probabilities).
    """
    labels = np.asarray(labels, dtype=np.int64)
    logd = np.log(np.maximum(np.asarray(target_distance, dtype=float), MIN_DISTANCE_M))
    executing = np.asarray(executing, dtype=bool)
    kind = np.array([KIND_CLASS.get(str(k), -1) for k in target_kind])
    shares, spread = {}, {}
    for c in np.unique(labels):
        mine = labels == c
        counts = np.bincount(kind[mine & (kind >= 0)], minlength=3)[:3] + SMOOTHING
        shares[str(int(c))] = [round(float(x), 6) for x in counts / counts.sum()]
        run = logd[mine & executing]
        run = run if len(run) >= 2 else logd[mine]
        spread[str(int(c))] = _normal(run, EXECUTION_SD)
    rank = np.asarray(target_rank, dtype=np.int64)
    counts = np.bincount(rank[(rank >= 0) & (rank < RANKS)], minlength=RANKS) + SMOOTHING
    approach = logd[~executing]
    return {
        "kind_classes": list(KIND_CLASSES),
        "kind_share": shares,
        "execution_log_distance": spread,
        "approach_log_distance": _normal(approach if len(approach) >= 2 else logd),
        "rank": [round(float(x), 6) for x in counts / counts.sum()],
    }


def demonstrated_prior(
    q: np.ndarray, labels: np.ndarray, candidates: Any, executing: np.ndarray
) -> dict[str, Any]:
    """:func:`fit_intent_prior` of demonstrated ticks: each target's distance (``q[:, :2]``,
    (n, 6) task features), kind and rank among the tick's components. ``candidates`` has
    ``points`` (m, 2) [m], ``ids`` and ``kinds`` (m,) (tick ``i``'s at
    ``offsets[i]:offsets[i + 1]``) and ``target`` (n,), the demonstrated component's id
    (:class:`autonomy.training.DemoCandidates`); ``labels`` (n,) the primitives,
    ``executing`` (n,) bool."""
    n = len(q)
    kind, rank = np.full(n, "", dtype=object), np.full(n, -1, dtype=np.int64)
    points, offsets, ids = candidates.points, candidates.offsets, candidates.ids
    for i in range(n):
        a, b = int(offsets[i]), int(offsets[i + 1])
        hit = np.flatnonzero(ids[a:b] == candidates.target[i])
        if len(hit):
            order = np.argsort(np.einsum("ij,ij->i", points[a:b], points[a:b]), kind="stable")
            kind[i] = str(candidates.kinds[a + hit[0]])
            rank[i] = int(np.flatnonzero(order == hit[0])[0])
    distance = np.hypot(q[:, 0], q[:, 1])
    return fit_intent_prior(labels, distance, np.asarray(executing, dtype=bool), kind, rank)


def _normal(x: np.ndarray, least_sd: float = 0.05) -> list[float]:
    """``[mean, sd]`` of ``x``, the sd at least ``least_sd`` (0.05: a log-distance spread
    of 5 %)."""
    return [round(float(np.mean(x)), 6), round(max(float(np.std(x)), least_sd), 6)]


@dataclass(frozen=True, slots=True)
class IntentPrior:
    """The prior as arrays aligned with a classifier's classes (``J`` primitives)."""

    log_kind: np.ndarray  # (J, 3) log p(kind class | primitive)
    exec_mean: np.ndarray  # (J,) [log m] log distance while executing
    exec_sd: np.ndarray  # (J,)
    approach: tuple[float, float]  # [log m] mean and sd of log distance while approaching
    log_rank: np.ndarray  # (RANKS,) log p(target's rank)
    learnt: bool  # False: the neutral prior of a model trained before issue 40

    @classmethod
    def from_metadata(cls, metadata: dict[str, Any], classes: np.ndarray) -> IntentPrior:
        """From ``metadata["intent_prior"]`` (:func:`fit_intent_prior`); a model without it
        gets a neutral prior (equal kinds and ranks, one broad distance model)."""
        prior = metadata.get("intent_prior")
        J = len(classes)
        if not isinstance(prior, dict):
            return cls(
                np.full((J, 3), -math.log(3.0)),
                np.zeros(J),
                np.ones(J),
                (0.0, 1.0),
                np.full(RANKS, -math.log(RANKS)),
                False,
            )
        share = prior["kind_share"]
        spread = prior["execution_log_distance"]
        keys = [str(int(c)) for c in classes]
        log_kind = np.log(np.array([share[k] for k in keys], dtype=float))
        exec_ = np.array([spread[k] for k in keys], dtype=float).reshape(J, 2)
        mean, sd = (float(v) for v in prior["approach_log_distance"])
        return cls(
            log_kind,
            exec_[:, 0].copy(),
            exec_[:, 1].copy(),
            (mean, sd),
            np.log(np.asarray(prior["rank"], dtype=float)),
            True,
        )
