"""Folds by run, way points, candidate features and hard negatives of the offline
evaluation (thesis Sec. 6.1, 7.3.1)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy.evaluation.settings import EvaluationSettings
from autonomy.features import encode, wrap_angle


def candidate_features(
    points: np.ndarray, offsets: np.ndarray, u_norm: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Task features (Sec. 6.1) of every candidate of every tick, vectorised.

    Equals ``autonomy.features.task_features(points[a:b], u_norm[i])`` tick by tick.

    Parameters
    ----------
    points : numpy.ndarray
        (m, 2) candidate target points [m], robot frame, ticks' candidates contiguous.
    offsets : numpy.ndarray
        (n + 1,) tick ``i``'s candidates are rows ``offsets[i]:offsets[i + 1]``.
    u_norm : numpy.ndarray
        (n, 3) commands in normalised (-1, 1) units.

    Returns
    -------
    q : numpy.ndarray
        (m, 6) ``(s_x, s_y, theta, v_x, v_y, omega)``.
    tick : numpy.ndarray
        (m,) the tick of every row.
    """
    counts = np.diff(offsets)
    tick = np.repeat(np.arange(len(counts)), counts)
    u = u_norm[tick]
    speed = np.hypot(u[:, 0], u[:, 1])
    dist = np.hypot(points[:, 0], points[:, 1])
    theta = wrap_angle(np.arctan2(u[:, 1], u[:, 0]) - np.arctan2(points[:, 1], points[:, 0]))
    q = np.empty((len(points), 6))
    q[:, 0:2] = points
    q[:, 2] = np.where((speed >= 1e-6) & (dist >= 1e-9), theta, 0.0)
    q[:, 3:6] = u
    return q, tick


def way_points_of(run: np.ndarray, stride: int) -> np.ndarray:
    """Rows that are every ``stride``-th tick of their run (from its first), sorted."""
    run = np.asarray(run)
    n = len(run)
    starts = np.concatenate(([True], run[1:] != run[:-1])) if n else np.zeros(0, dtype=bool)
    first = np.maximum.accumulate(np.where(starts, np.arange(n), 0))
    return np.flatnonzero((np.arange(n) - first) % stride == 0)


def run_folds(run_task: Sequence[str], folds: int, rng: np.random.Generator) -> np.ndarray:
    """Fold of every run: each task type's runs shuffled and dealt round-robin.

    Parameters
    ----------
    run_task : sequence of str
        (r,) task type of every run.
    folds : int
        Number of folds, 2 <= folds <= r.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray
        (r,) fold index 0..folds-1 of every run; every fold is non-empty.
    """
    run_task = np.asarray(run_task)
    fold = np.empty(len(run_task), dtype=int)
    k = 0
    for task in sorted(set(run_task.tolist())):
        idx = np.flatnonzero(run_task == task)
        for j in rng.permutation(idx):
            fold[j] = k % folds
            k += 1
    return fold


def hard_negatives(
    ticks: np.ndarray,
    offsets: np.ndarray,
    ids: np.ndarray,
    target: np.ndarray,
    per_tick: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Candidate rows used as hard negatives: at each tick of ``ticks``, up to
    ``per_tick`` of its candidates that are not the demonstrated target, drawn at random.

    Parameters
    ----------
    ticks : numpy.ndarray
        (t,) training ticks.
    offsets : numpy.ndarray
        (n + 1,) candidate rows of tick ``i``: ``offsets[i]:offsets[i + 1]``.
    ids : numpy.ndarray
        (m,) candidate ids; ``target`` (n,) the demonstrated component of every tick.
    per_tick : int
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray
        Sorted candidate rows (features of the other components at the same tick, with
        the same command).
    """
    out: list[np.ndarray] = []
    for i in np.asarray(ticks):
        a, b = int(offsets[i]), int(offsets[i + 1])
        wrong = a + np.flatnonzero(ids[a:b] != target[i])
        if len(wrong) > per_tick:
            wrong = rng.choice(wrong, size=per_tick, replace=False)
        out.append(wrong)
    return np.sort(np.concatenate(out)) if out else np.zeros(0, dtype=int)


def _sorted_candidates(
    demos: Any, normals: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Candidates of every tick sorted by distance (stable): points, ids, kinds, normals
    (zeros without ``normals``), offsets."""
    off = np.asarray(demos.cand_offsets, dtype=np.int64)
    pts = np.asarray(demos.cand_points, dtype=float)
    ids = np.asarray(demos.cand_ids).astype(str)
    kinds = np.asarray(demos.cand_kinds).astype(str)
    nrm = np.zeros_like(pts) if normals is None else np.asarray(normals, dtype=float)
    if nrm.shape != pts.shape:
        raise ValueError(f"normals: need the candidates' shape {pts.shape}, got {nrm.shape}")
    counts = np.diff(off)
    tick = np.repeat(np.arange(len(counts)), counts)
    order = np.lexsort((np.hypot(pts[:, 0], pts[:, 1]), tick))
    return pts[order], ids[order], kinds[order], nrm[order], off


def check_demonstrations(demos: Any, where: str) -> None:
    """ValueError naming ``where`` if the demonstrations cannot be evaluated."""
    n = len(np.asarray(demos.q))
    if n == 0:
        raise ValueError(f"{where}: no moving ticks in these demonstrations")
    tasks = sorted(set(np.asarray(demos.task).astype(str).tolist()))
    if len(tasks) < 2:
        raise ValueError(
            f"{where}: need demonstrations of at least 2 task types to evaluate, got {tasks}"
        )


@dataclass(frozen=True)
class EvaluationData:
    """Everything a fold or pair job needs (picklable, for a process pool); ``n`` moving
    ticks, ``m`` candidates."""

    settings: EvaluationSettings
    kinds: dict[str, str]
    labels: list[str]
    run: np.ndarray  # (n,) run of every moving tick
    task: np.ndarray  # (n,) true task type
    target: np.ndarray  # (n,) demonstrated component id
    y: np.ndarray  # (n,) task type index
    u_norm: np.ndarray  # (n, 3)
    s: np.ndarray  # (n, 2) demonstrated target point
    q: np.ndarray  # (n, 6) task features against the demonstrated target
    executing: np.ndarray  # (n,) bool: the demonstrator executes its task (not approaching)
    fold: np.ndarray  # (n,) fold of every tick
    pts: np.ndarray  # (m, 2) candidate points, sorted by distance within a tick
    ids: np.ndarray  # (m,)
    ckinds: np.ndarray  # (m,)
    normals: np.ndarray  # (m, 2) passage normals, robot frame (zeros: none known)
    off: np.ndarray  # (n + 1,)
    X_cand: np.ndarray  # (m, 7) encoded candidate features
    X_true: np.ndarray  # (n, 7) encoded demonstrated features


def prepare_data(
    demos: Any,
    *,
    kinds: Mapping[str, str],
    settings: EvaluationSettings,
    fold_rng: np.random.Generator,
    normals: np.ndarray | None = None,
) -> EvaluationData:
    """The demonstrations as arrays, with every run's fold and the candidates' features.

    Parameters
    ----------
    demos : Demonstrations-like
        See :func:`autonomy.evaluation.evaluate`.
    kinds : mapping of str to str
        Task type -> the component kind it targets.
    settings : EvaluationSettings
    fold_rng : numpy.random.Generator
        Draws the folds (:func:`run_folds`).
    normals : numpy.ndarray, optional
        (m, 2) passage normals of the candidates (robot frame, ``demos``' candidate
        order); None: zeros, so the kind-and-time recogniser's axis cue is off.

    Raises
    ------
    ValueError
        ``settings.folds`` above the number of runs.
    """
    run = np.asarray(demos.run)
    task = np.asarray(demos.task).astype(str)
    labels = sorted(set(task.tolist()))
    label_index = {c: i for i, c in enumerate(labels)}
    run_ids = np.unique(run)
    if settings.folds > len(run_ids):
        raise ValueError(
            f"folds: must be between 2 and the number of runs ({len(run_ids)}), got "
            f"{settings.folds}"
        )
    run_task = [task[run == r][0] for r in run_ids]
    fold_of_run = dict(
        zip(run_ids.tolist(), run_folds(run_task, settings.folds, fold_rng), strict=True)
    )
    u_norm = np.asarray(demos.u_norm, dtype=float)
    pts, ids, ckinds, nrm, off = _sorted_candidates(demos, normals)
    q_cand, _ = candidate_features(pts, off, u_norm)
    q = np.asarray(demos.q, dtype=float)
    return EvaluationData(
        settings=settings,
        kinds=dict(kinds),
        labels=labels,
        run=run,
        task=task,
        target=np.asarray(demos.target).astype(str),
        y=np.array([label_index[t] for t in task]),
        u_norm=u_norm,
        s=np.asarray(demos.s, dtype=float),
        q=q,
        executing=np.asarray(demos.phase).astype(str) != "approach",
        fold=np.array([fold_of_run[r] for r in run.tolist()]),
        pts=pts,
        ids=ids,
        ckinds=ckinds,
        normals=nrm,
        off=off,
        X_cand=encode(q_cand),
        X_true=encode(q),
    )
