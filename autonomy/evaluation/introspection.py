"""Introspection on unseen task types (thesis Sec. 7.3.2, 7.4.3; Fig. 7.25, Table 7.9):
every classifier trained on a pair of task types and queried with the way points of the
others; the normalised entropy (Eq. 7.7) of its label distribution at every such point,
pooled into histograms, and the MICAD of the clusters it assigns them to. The
kind-and-time recogniser's belief, trained on the pair and replayed along the others'
runs (:func:`~autonomy.evaluation.kind_time.kind_time_unseen`), beside its belief on
held-out runs of the task types it was trained on."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy.evaluation.classifiers import fit_method
from autonomy.evaluation.correspondence import intra_cluster_dissimilarity
from autonomy.evaluation.folds import EvaluationData, way_points_of
from autonomy.evaluation.kind_time import kind_time_unseen
from autonomy.evaluation.settings import METHODS, EvaluationSettings
from autonomy.features import FeatureScaler
from autonomy.sogp_classifier import normalised_entropy

HISTOGRAM_BINS = 10  # equal bins of the normalised entropy on [0, 1] (Fig. 7.25)


@dataclass(frozen=True, slots=True)
class PairResult:
    """Introspection of one training pair of task types."""

    name: str  # "<type>+<type>"
    entropy: dict[str, float]  # method -> mean normalised entropy (7.7) in [0, 1]
    entropies: dict[str, np.ndarray]  # method -> (p,) entropy (7.7) of every test point
    micad: dict[str, float]  # method -> MICAD of the test points [standardised units]
    kt_entropies: np.ndarray  # (p,) kind_time's belief entropy (7.7) at the test points
    kt_decisive: np.ndarray  # (p,) bool: kind_time decisive there
    kt_no_task: np.ndarray  # (p,) kind_time's belief in no task there
    seconds: float


def pair_job(
    data: EvaluationData, pair: tuple[int, int], seed: np.random.SeedSequence
) -> PairResult:
    """Introspection of one training pair of task types, timed."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    name, h, micad = introspect_pair(
        data.X_true, data.y, data.run, data.labels, pair, settings=data.settings, rng=rng
    )
    kt_h, kt_decisive, kt_no_task = kind_time_unseen(data, pair, rng.spawn(1)[0])  # last
    return PairResult(
        name=name,
        entropy={m: float(np.mean(v)) for m, v in h.items()},
        entropies=h,
        micad=micad,
        kt_entropies=kt_h,
        kt_decisive=kt_decisive,
        kt_no_task=kt_no_task,
        seconds=time.perf_counter() - t0,
    )


def introspect_pair(
    X: np.ndarray,
    y: np.ndarray,
    run: np.ndarray,
    labels: Sequence[str],
    pair: tuple[int, int],
    *,
    settings: EvaluationSettings,
    rng: np.random.Generator,
) -> tuple[str, dict[str, np.ndarray], dict[str, float]]:
    """Introspection (Sec. 7.3.2, 7.4.3, Table 7.9) of one pair of task types.

    Every classifier is trained on the pair's way points (standardised on them) and
    queried with the other types' way points (features against the demonstrated
    target). Its most probable class at a query (the mode of the distribution whose
    entropy is taken) is the cluster of the query's ICAD.

    Parameters
    ----------
    X : numpy.ndarray
        (n, 7) encoded demonstrated features of every moving tick.
    y, run : numpy.ndarray
        (n,) task type index and run of every tick.
    labels : sequence of str
        Task type of every index.
    pair : tuple of int
        The two training task types.
    settings : EvaluationSettings
    rng : numpy.random.Generator

    Returns
    -------
    name : str
        ``"<a>+<b>"``.
    entropies : dict
        Method -> (p,) normalised entropy (7.7) in [0, 1] of every test point.
    micad : dict
        Method -> MICAD of the test points [standardised feature units].
    """
    a, b = pair
    wp = way_points_of(run, settings.stride)
    train = wp[np.isin(y[wp], (a, b))]
    test = wp[~np.isin(y[wp], (a, b))]
    scaler = FeatureScaler().fit(X[train])
    Ztr, Zte = scaler.transform(X[train]), scaler.transform(X[test])
    h: dict[str, np.ndarray] = {}
    micad: dict[str, float] = {}
    for method, method_rng in zip(METHODS, rng.spawn(len(METHODS)), strict=True):
        f = fit_method(
            method,
            Ztr,
            y[train],
            run[train],
            settings=settings,
            rng=method_rng,
            probability=True,
            tune=False,
        )
        p = f.proba(Zte)
        h[method] = normalised_entropy(p)  # Eq. (7.7)
        assigned = f.classes[np.argmax(p, axis=1)]
        icad = intra_cluster_dissimilarity(Zte, Ztr, y[train], assigned)
        micad[method] = float(np.mean(icad))
    return f"{labels[a]}+{labels[b]}", h, micad


def entropy_histogram(entropies: np.ndarray, bins: int = HISTOGRAM_BINS) -> dict[str, Any]:
    """Histogram (Fig. 7.25) of normalised entropies on [0, 1].

    Parameters
    ----------
    entropies : numpy.ndarray
        (p,) values in [0, 1].
    bins : int
        Equal-width bins; the last one holds 1.

    Returns
    -------
    dict
        ``edges`` (bins + 1,), ``counts`` (bins,) summing to p, ``n`` = p, ``median``
        (None for no value).
    """
    h = np.clip(np.asarray(entropies, dtype=float), 0.0, 1.0)
    edges = np.linspace(0.0, 1.0, bins + 1)
    counts, _ = np.histogram(h, bins=edges)
    return {
        "edges": [round(float(e), 6) for e in edges],
        "counts": [int(c) for c in counts],
        "n": int(len(h)),
        "median": float(np.median(h)) if len(h) else None,
    }


def entropy_rank(mean_entropy: dict[str, float], method: str = "sogp") -> int | None:
    """Rank of ``method`` among the classifiers by mean normalised entropy, 1 the
    highest (ties share the better rank); None if it was not introspected."""
    if method not in mean_entropy:
        return None
    return 1 + sum(v > mean_entropy[method] for v in mean_entropy.values())


def pool_introspection(per_pair: Sequence[PairResult]) -> dict[str, Any]:
    """The introspection part of the evaluation result: per classifier the mean
    entropy over pairs and per pair, the histogram pooled over the pairs' test points,
    MICAD over pairs and per pair, and the SOGP's entropy rank (empty without pairs)."""
    if not per_pair:
        return {
            "introspection_entropy": {},
            "introspection_pairs": {},
            "introspection_histogram": {},
            "introspection_micad": {},
            "introspection_micad_pairs": {},
            "sogp_entropy_rank": None,
        }
    pairs = {m: {p.name: p.entropy[m] for p in per_pair} for m in METHODS}
    micad = {m: {p.name: p.micad[m] for p in per_pair} for m in METHODS}
    mean = {m: float(np.mean(list(v.values()))) for m, v in pairs.items()}
    return {
        "introspection_entropy": mean,
        "introspection_pairs": pairs,
        "introspection_histogram": {
            m: entropy_histogram(np.concatenate([p.entropies[m] for p in per_pair]))
            for m in METHODS
        },
        "introspection_micad": {m: float(np.mean(list(v.values()))) for m, v in micad.items()},
        "introspection_micad_pairs": micad,
        "sogp_entropy_rank": entropy_rank(mean),
    }


def _belief_summary(
    entropies: np.ndarray, decisive: np.ndarray, no_task: np.ndarray
) -> dict[str, Any]:
    """Mean normalised entropy, its histogram (:func:`entropy_histogram`), the share of
    decisive points and the mean belief in no task (None for no point)."""
    n = len(entropies)
    return {
        "entropy": float(np.mean(entropies)) if n else None,
        "histogram": entropy_histogram(entropies),
        "decisive": float(np.mean(decisive)) if n else None,
        "no_task": float(np.mean(no_task)) if n else None,
    }


def kind_time_introspection(
    seen: tuple[np.ndarray, np.ndarray, np.ndarray], per_pair: Sequence[PairResult]
) -> dict[str, Any]:
    """The kind-and-time recogniser's belief (Eq. 7.7 over its hypotheses, the tick's
    candidates and no task) on task types it was trained on and on unseen ones.

    ``seen``: (entropy, decisive, belief in no task) (t,) at the scored test ticks of the
    held-out runs, pooled over the folds; ``unseen``: at the test points of every training
    pair, pooled, with the mean entropy per pair (``pairs``), None without pairs. Each
    has ``entropy`` (the mean over its points), ``histogram``, ``decisive`` (the share of
    points where the recogniser would assist) and ``no_task`` (the mean belief in no
    task).
    """
    out: dict[str, Any] = {"seen": _belief_summary(*seen), "unseen": None}
    if per_pair:
        unseen = _belief_summary(
            np.concatenate([p.kt_entropies for p in per_pair]),
            np.concatenate([p.kt_decisive for p in per_pair]),
            np.concatenate([p.kt_no_task for p in per_pair]),
        )
        unseen["pairs"] = {
            p.name: float(np.mean(p.kt_entropies)) if len(p.kt_entropies) else None
            for p in per_pair
        }
        out["unseen"] = unseen
    return out
