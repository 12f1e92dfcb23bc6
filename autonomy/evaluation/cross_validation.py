"""Cross-validated recognition quality on demonstrations (thesis Sec. 7.2.2, 7.3, 7.4):
the folds and introspection pairs as independent jobs, pooled into one result."""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

from autonomy.evaluation.folds import check_demonstrations, prepare_data
from autonomy.evaluation.jobs import run_numbered_job
from autonomy.evaluation.report import pool_results
from autonomy.evaluation.settings import EvaluationSettings


def evaluate(
    demos: Any,
    *,
    kinds: Mapping[str, str],
    settings: EvaluationSettings | None = None,
    model: str = "",
    where: str = "demonstrations",
    map_fn: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
    progress: Callable[[int, int], None] | None = None,
    normals: np.ndarray | None = None,
) -> dict[str, Any]:
    """Cross-validated recognition quality on demonstrations (thesis Sec. 7.2.2, 7.3,
    7.4): F0.5, ACR and MICAD by cross-validation by run of the SOGP classifier and three
    baselines, ACR and MICAD of the kind-and-time recogniser on the fold's SOGP, their
    introspection entropy (mean, histogram) and MICAD on unseen task types for every
    training pair of task types (the kind-and-time recogniser's belief entropy on seen
    and unseen types), and the trajectory rates of five recognisers.

    Parameters
    ----------
    demos : Demonstrations-like
        ``q`` (n, 6), ``u_norm`` (n, 3), ``run`` (n,), ``task`` (n,), ``target`` (n,),
        ``s`` (n, 2), ``phase`` (n,) (``"approach"`` or the task's own), ``cand_offsets``
        (n + 1,), ``cand_points`` (m, 2), ``cand_ids`` (m,), ``cand_kinds`` (m,): moving
        ticks, runs contiguous (the fields of ``study.jobs.demonstrations.Demonstrations``).
    kinds : mapping of str to str
        Task type -> the component kind it targets (``tasks.contextual.TARGET_KIND``).
    settings : EvaluationSettings, optional
    model : str
        The model file the caller names (reported only; the evaluation trains its own).
    where : str
        Names the demonstrations in error messages.
    map_fn : callable, optional
        ``map``-like: applied to the independent jobs (one per fold, one per
        introspection pair), returning one result per job in any order (a process
        pool's ``map``, or an iterator over its jobs as they complete). The result does
        not depend on it: every job draws from its own ``numpy.random.SeedSequence``
        spawned from ``settings.seed``.
    progress : callable, optional
        ``progress(done, total)``, called once per job as ``map_fn`` hands back its
        result: ``done`` = 1, 2, ..., ``total`` (folds + pairs).
    normals : numpy.ndarray, optional
        (m, 2) passage normals of the candidates in the robot frame, in ``demos``'
        candidate order (``study.jobs.demonstrations.candidate_normals``); None: zeros, so
        the kind-and-time recogniser's axis cue is off.

    Returns
    -------
    dict
        ``f05``, ``sogp_at_least_baselines``, ``confusion``, ``acr``, ``micad``,
        ``correspondence_rates``, ``introspection_entropy``, ``introspection_pairs``,
        ``introspection_histogram``, ``introspection_micad``,
        ``introspection_micad_pairs``, ``sogp_entropy_rank``,
        ``kind_time_introspection``, ``negatives``,
        ``sogp_length_scale_cap``, ``sogp_claim_threshold``, ``trajectory_rates``,
        ``n_runs``, ``n_test_ticks``, ``folds``, ``seed``, ``model``, ``labels``,
        ``timings_s`` (meanings: :func:`autonomy.evaluation.report.pool_results`).

    Raises
    ------
    ValueError
        Naming ``where``: no moving ticks or fewer than 2 task types; ``folds`` above
        the number of runs.
    """
    settings = EvaluationSettings() if settings is None else settings
    check_demonstrations(demos, where)
    t_start = time.perf_counter()
    # Child 0 draws the folds, children 1.. the jobs: the same children as one spawn of
    # them all, as SeedSequence numbers its children in order.
    root = np.random.SeedSequence(settings.seed)
    data = prepare_data(
        demos,
        kinds=kinds,
        settings=settings,
        fold_rng=np.random.default_rng(root.spawn(1)[0]),
        normals=normals,
    )
    n = len(data.labels)
    pairs = list(itertools.combinations(range(n), 2)) if n >= 3 else []
    seeds = root.spawn(settings.folds + len(pairs))
    jobs = [("fold", data, k, seeds[k]) for k in range(settings.folds)]
    jobs += [("pair", data, p, seeds[settings.folds + i]) for i, p in enumerate(pairs)]
    results = _run_jobs(jobs, map_fn, progress)
    return pool_results(
        results[: settings.folds],
        results[settings.folds :],
        labels=data.labels,
        settings=settings,
        n_runs=len(np.unique(data.run)),
        model=model,
        total_s=time.perf_counter() - t_start,
    )


def _run_jobs(
    jobs: list[Any],
    map_fn: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]],
    progress: Callable[[int, int], None] | None,
) -> list[Any]:
    """Every job's result in job order, whatever order ``map_fn`` hands them back in;
    ``progress(done, total)`` after each."""
    results: list[Any] = [None] * len(jobs)
    for done, (i, result) in enumerate(map_fn(run_numbered_job, enumerate(jobs)), start=1):
        results[i] = result
        if progress is not None:
            progress(done, len(jobs))
    return results
