"""The result of the offline evaluation (thesis Sec. 7.2.2, 7.3, 7.4): pooling the
jobs' results, the summary over repeated seeds, and the tables for people."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from autonomy.evaluation.jobs import FoldResult, PairResult
from autonomy.evaluation.metrics import confusion_with_targets, f05_with_targets
from autonomy.evaluation.settings import METHODS, RECOGNISERS, WRONG_TARGET, EvaluationSettings


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
    """The result of :func:`autonomy.evaluation.evaluate` from its jobs' results (its
    keys: see there); ``total_s`` is the wall clock [s]."""
    truth = [t for r in per_fold for t in r.truth]
    pred = {m: [p for r in per_fold for p in r.pred[m]] for m in METHODS}
    ok = {m: [x for r in per_fold for x in r.ok[m]] for m in METHODS}
    intro = {m: {p.name: p.entropy[m] for p in per_pair} for m in METHODS} if per_pair else {}
    for m in intro:
        intro[m]["mean"] = float(np.mean(list(intro[m].values())))
    f05 = {m: f05_with_targets(truth, pred[m], ok[m], labels) for m in METHODS}
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
        "introspection_entropy": {m: v["mean"] for m, v in intro.items()},
        "introspection_pairs": {
            m: {p: x for p, x in v.items() if p != "mean"} for m, v in intro.items()
        },
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
        which the SOGP's F0.5 is at least every baseline's}; ``introspection_entropy_mean``
        -> {classifier -> value}; ``trajectory_rates_mean`` -> {recogniser -> {success,
        error, null}}.
    """
    if not results:
        raise ValueError("results: need at least one evaluation result")
    keys = list(results[0]["f05"][METHODS[0]])

    def spread(values: list[float]) -> float:
        return float(np.std(values, ddof=1)) if len(values) > 1 else 0.0

    f05 = {m: {c: [r["f05"][m][c] for r in results] for c in keys} for m in METHODS}
    return {
        "seeds": [int(r["seed"]) for r in results],
        "f05_mean": {m: {c: float(np.mean(v)) for c, v in f05[m].items()} for m in METHODS},
        "f05_sd": {m: {c: spread(v) for c, v in f05[m].items()} for m in METHODS},
        "sogp_at_least_baselines": {
            c: float(np.mean([r["sogp_at_least_baselines"][c] for r in results])) for c in keys
        },
        "introspection_entropy_mean": {
            m: float(np.mean([r["introspection_entropy"][m] for r in results]))
            for m in results[0]["introspection_entropy"]
        },
        "trajectory_rates_mean": {
            rec: {
                k: float(np.mean([r["trajectory_rates"][rec][k] for r in results]))
                for k in ("success", "error", "null")
            }
            for rec in results[0]["trajectory_rates"]
        },
    }


def format_report(result: Mapping[str, Any]) -> str:
    """Human-readable tables of :func:`evaluate`'s result."""
    labels = list(result["labels"])
    lines = [
        f"{result['n_runs']} runs, {result['folds']}-fold cross-validation by run, seed "
        f"{result['seed']}; {result['n_test_ticks']} test ticks; model {result['model'] or '-'}",
        "",
        "F0.5 (right task type and right target among all candidates; thesis Table 7.6)",
    ]
    width = max(len(x) for x in [*labels, "macro"]) + 2
    lines.append(" " * width + "".join(f"{m:>8}" for m in METHODS))
    for c in [*labels, "macro"]:
        lines.append(f"{c:<{width}}" + "".join(f"{result['f05'][m][c]:8.3f}" for m in METHODS))
    for m in METHODS:
        conf = result["confusion"][m]
        lines += ["", f"confusion ({m}): rows true, columns predicted at the right target"]
        cols = conf["columns"]
        lines.append(" " * width + "".join(f"{c[:10]:>11}" for c in cols))
        for name, row in zip(conf["rows"], conf["matrix"], strict=True):
            lines.append(f"{name:<{width}}" + "".join(f"{v:11d}" for v in row))
    means = result["introspection_entropy"]
    if means:
        intro = {m: {**result["introspection_pairs"][m], "mean": means[m]} for m in METHODS}
        lines += ["", "introspection: mean normalised entropy on unseen task types (Table 7.9)"]
        pairs = [p for p in intro[METHODS[0]] if p != "mean"]
        pw = max(len(p) for p in [*pairs, "mean"]) + 2
        lines.append(" " * pw + "".join(f"{m:>8}" for m in METHODS))
        for p in [*pairs, "mean"]:
            lines.append(f"{p:<{pw}}" + "".join(f"{intro[m][p]:8.3f}" for m in METHODS))
    lines += ["", "trajectory rates on held-out runs (Sec. 7.2.2), mean over runs"]
    lines.append(f"{'':<14}{'success':>9}{'error':>9}{'null':>9}")
    for r, v in result["trajectory_rates"].items():
        lines.append(f"{r:<14}{v['success']:9.3f}{v['error']:9.3f}{v['null']:9.3f}")
    rep = result.get("repeats")
    if rep:
        seeds = rep["seeds"]
        lines += [
            "",
            f"F0.5 over {len(seeds)} seeds ({', '.join(map(str, seeds))}): mean +- sd; "
            "'sogp >=' is the share of seeds where the SOGP is at least every baseline",
        ]
        lines.append(" " * width + "".join(f"{m:>14}" for m in METHODS) + f"{'sogp >=':>9}")
        for c in [*labels, "macro"]:
            cells = "".join(
                f"{rep['f05_mean'][m][c]:8.3f}+-{rep['f05_sd'][m][c]:.3f}" for m in METHODS
            )
            lines.append(f"{c:<{width}}{cells}{rep['sogp_at_least_baselines'][c]:9.2f}")
    t = result["timings_s"]
    lines += ["", f"time: {t['total']:.1f} s"]
    return "\n".join(lines)
