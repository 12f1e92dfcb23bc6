"""The result of the offline evaluation (thesis Sec. 7.2.2, 7.3, 7.4): pooling the
jobs' results and the summary over repeated seeds (tables for people:
:mod:`autonomy.evaluation.text`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from autonomy.evaluation.introspection import (
    PairResult,
    entropy_rank,
    kind_time_introspection,
    pool_introspection,
)
from autonomy.evaluation.jobs import FoldResult
from autonomy.evaluation.metrics import confusion_with_targets, f05_with_targets
from autonomy.evaluation.settings import (
    CORRESPONDENCE,
    METHODS,
    RECOGNISERS,
    WRONG_TARGET,
    EvaluationSettings,
)


def pool_results(
    per_fold: Sequence[FoldResult],
    per_pair: Sequence[PairResult],
    *,
    labels: list[str],
    settings: EvaluationSettings,
    n_runs: int,
    model: str,
    total_s: float,
) -> dict[str, Any]:
    """The result of :func:`autonomy.evaluation.evaluate` from its jobs' results;
    ``total_s`` is the wall clock [s].

    Its keys: ``f05`` (classifier -> task type or "macro" -> F0.5 with the right
    target, Table 7.6); ``confusion``; ``acr`` (classifier or ``kind_time`` -> mean over
    held-out runs of the correspondence rate, Sec. 7.4.1), ``correspondence_rates`` (the
    same keys -> run -> CR), ``micad`` (the same keys -> mean ICAD over test ticks,
    standardised feature units); the introspection on unseen task types
    (:func:`~autonomy.evaluation.introspection.pool_introspection`):
    ``introspection_entropy``, ``introspection_pairs``, ``introspection_histogram``,
    ``introspection_micad``, ``introspection_micad_pairs``, ``sogp_entropy_rank``, and the
    kind-and-time recogniser's (:func:`~autonomy.evaluation.introspection.
    kind_time_introspection`): ``kind_time_introspection``; ``trajectory_rates``
    (recogniser -> success, error, null); the settings and sizes; ``timings_s``.
    """
    truth = [t for r in per_fold for t in r.truth]
    pred = {m: [p for r in per_fold for p in r.pred[m]] for m in METHODS}
    ok = {m: [x for r in per_fold for x in r.ok[m]] for m in METHODS}
    f05 = {m: f05_with_targets(truth, pred[m], ok[m], labels) for m in METHODS}
    cr = {m: {run: v for r in per_fold for run, v in r.cr[m].items()} for m in CORRESPONDENCE}
    icad = {m: np.concatenate([r.icad[m] for r in per_fold]) for m in CORRESPONDENCE}
    return {
        "f05": f05,
        "sogp_at_least_baselines": {
            c: all(f05["sogp"][c] >= f05[m][c] for m in METHODS[1:]) for c in [*labels, "macro"]
        },
        "confusion": {
            m: {
                "rows": labels,
                "columns": [*labels, WRONG_TARGET],
                "matrix": confusion_with_targets(truth, pred[m], ok[m], labels),
            }
            for m in METHODS
        },
        "acr": {m: float(np.mean(list(cr[m].values()))) for m in CORRESPONDENCE},  # 7.4.1
        "micad": {m: float(np.mean(icad[m])) if len(icad[m]) else None for m in CORRESPONDENCE},
        "correspondence_rates": cr,
        **pool_introspection(per_pair),
        "kind_time_introspection": kind_time_introspection(
            (
                np.concatenate([r.kt_entropy for r in per_fold]),
                np.concatenate([r.kt_decisive for r in per_fold]),
                np.concatenate([r.kt_no_task for r in per_fold]),
            ),
            per_pair,
        ),
        "negatives": bool(settings.negatives),
        "sogp_length_scale_cap": [r.cap for r in per_fold],
        "sogp_claim_threshold": [r.claim for r in per_fold],
        "trajectory_rates": _mean_rates(per_fold),
        "n_runs": int(n_runs),
        "n_test_ticks": int(len(truth)),
        "folds": int(settings.folds),
        "seed": int(settings.seed),
        "model": model,
        "labels": labels,
        "timings_s": {  # seconds inside the jobs, summed (CPU-like), and the wall clock
            "classification": round(sum(r.t_cls for r in per_fold), 2),
            "trajectory_rates": round(sum(r.t_rec for r in per_fold), 2),
            "kind_time": round(sum(r.t_kt for r in per_fold), 2),  # its introspection: below
            "introspection": round(sum(p.seconds for p in per_pair), 2),
            "total": round(total_s, 2),
        },
    }


def _mean_rates(per_fold: Sequence[FoldResult]) -> dict[str, dict[str, float]]:
    """Recogniser -> success, error and null rates, each the mean over held-out runs."""
    rec_rates = {rec: [x for r in per_fold for x in r.rates[rec]] for rec in RECOGNISERS}
    return {
        r: {
            key: float(np.mean([x[key] for x in rates])) if rates else float("nan")
            for key in ("success", "error", "null")
        }
        for r, rates in rec_rates.items()
    }


SIDES = ("seen", "unseen")  # the kind-and-time belief on trained and on unseen task types


def _spread(values: Sequence[float]) -> float:
    """Sample standard deviation (ddof 1); 0 for a single value."""
    return float(np.std(values, ddof=1)) if len(values) > 1 else 0.0


def _mean_sd(results: Sequence[Mapping[str, Any]], key: str) -> tuple[dict, dict]:
    """Mean and sd over ``results`` of ``result[key]`` -> {name -> number}; names with
    a missing value (None) in some result are left out."""
    names = list(results[0][key])
    values = {n: [r[key][n] for r in results] for n in names}
    values = {n: v for n, v in values.items() if all(x is not None for x in v)}
    return (
        {n: float(np.mean(v)) for n, v in values.items()},
        {n: _spread(v) for n, v in values.items()},
    )


def summarise_repeats(results: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Mean and spread of :func:`evaluate` results repeated with different seeds.

    One seed fixes one fold assignment and one draw of the negatives, subsamples and
    forests; the F0.5 of one classifier moves by a few hundredths between seeds, about
    as much as the classifiers differ on some task types, so a comparison worth
    publishing needs several.

    Parameters
    ----------
    results : sequence of dict
        :func:`evaluate` results on the same demonstrations, one per seed.

    Returns
    -------
    dict
        ``seeds``; ``f05_mean`` and ``f05_sd`` -> {classifier -> {task type or
        "macro" -> value}} (sample standard deviation, 0 for one result);
        ``sogp_at_least_baselines`` -> {task type or "macro" -> share of the results in
        which the SOGP's F0.5 is at least every baseline's}; ``acr_mean``, ``acr_sd``,
        ``micad_mean``, ``micad_sd``, ``introspection_entropy_mean``,
        ``introspection_entropy_sd``, ``introspection_micad_mean``,
        ``introspection_micad_sd`` -> {classifier -> value} (``acr`` and ``micad`` also
        ``kind_time``); ``sogp_entropy_rank``: the SOGP's rank by the mean entropy over the
        seeds (1 the highest); ``kind_time_entropy_mean``, ``kind_time_entropy_sd`` ->
        {"seen", "unseen" -> the kind-and-time belief's mean entropy}; ``trajectory_rates_mean``
        -> {recogniser -> {success, error, null}}.
    """
    if not results:
        raise ValueError("results: need at least one evaluation result")
    keys = list(results[0]["f05"][METHODS[0]])
    f05 = {m: {c: [r["f05"][m][c] for r in results] for c in keys} for m in METHODS}
    out: dict[str, Any] = {
        "seeds": [int(r["seed"]) for r in results],
        "f05_mean": {m: {c: float(np.mean(v)) for c, v in f05[m].items()} for m in METHODS},
        "f05_sd": {m: {c: _spread(v) for c, v in f05[m].items()} for m in METHODS},
        "sogp_at_least_baselines": {
            c: float(np.mean([r["sogp_at_least_baselines"][c] for r in results])) for c in keys
        },
    }
    for key in ("acr", "micad", "introspection_entropy", "introspection_micad"):
        out[f"{key}_mean"], out[f"{key}_sd"] = _mean_sd(results, key)
    out["sogp_entropy_rank"] = entropy_rank(out["introspection_entropy_mean"])
    belief = [
        {side: (r["kind_time_introspection"][side] or {}).get("entropy") for side in SIDES}
        for r in results
    ]
    out["kind_time_entropy_mean"], out["kind_time_entropy_sd"] = _mean_sd(
        [{"entropy": b} for b in belief], "entropy"
    )
    out["trajectory_rates_mean"] = {
        rec: {
            k: float(np.mean([r["trajectory_rates"][rec][k] for r in results]))
            for k in ("success", "error", "null")
        }
        for rec in results[0]["trajectory_rates"]
    }
    return out
