"""The independent jobs of the offline evaluation (thesis Sec. 7.2.2, 7.3): a held-out
fold (classification and trajectory rates) and an introspection pair of task types."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy.baseline_recogniser import ExponentialBaseline
from autonomy.bayes_filter import BayesFilterRecogniser, fit_user_models, target_features
from autonomy.evaluation.classifiers import FittedClassifier, fit_method, recognise
from autonomy.evaluation.folds import EvaluationData, hard_negatives, way_points_of
from autonomy.evaluation.metrics import trajectory_rates
from autonomy.evaluation.settings import METHODS, RECOGNISERS, EvaluationSettings
from autonomy.features import FeatureScaler
from autonomy.sogp_classifier import normalised_entropy

Decision = tuple[str, str] | None  # (task type, component id), None: no decision


@dataclass(frozen=True, slots=True)
class FoldResult:
    """What one held-out fold contributes to :func:`autonomy.evaluation.evaluate`."""

    truth: list[str]  # (t,) true task type of every scored test tick
    pred: dict[str, list[str | None]]  # method -> (t,) predicted type, None: no prediction
    ok: dict[str, list[bool]]  # method -> (t,) whether the predicted target is right
    cap: float  # the SOGP's length-scale cap [standard deviations]
    claim: dict[str, float]  # task type -> the SOGP's claim threshold
    rates: dict[str, list[dict[str, float]]]  # recogniser -> per held-out run's rates
    t_cls: float  # classification [s]
    t_rec: float  # trajectory rates [s]


@dataclass(frozen=True, slots=True)
class PairResult:
    """Introspection of one training pair of task types."""

    name: str  # "<type>+<type>"
    entropy: dict[str, float]  # method -> mean normalised entropy (7.7) in [0, 1]
    seconds: float


@dataclass(frozen=True, slots=True)
class _FoldTraining:
    """The training side of a fold: standardised way points and hard negatives."""

    Z: np.ndarray  # (t, 7) standardised training way points
    y: np.ndarray  # (t,) their task type index
    groups: np.ndarray  # (t,) their runs
    Z_cand: np.ndarray  # (m, 7) every candidate, standardised on the training fold
    Z_neg: np.ndarray  # (k, 7) hard negatives
    groups_neg: np.ndarray  # (k,) their runs


def run_job(job: tuple[str, EvaluationData, Any, np.random.SeedSequence]) -> Any:
    """Run one job of :func:`autonomy.evaluation.evaluate` (top level, so a process pool
    can pickle it): ``("fold", data, k, seed)`` or ``("pair", data, (a, b), seed)``."""
    kind, data, arg, seed = job
    return fold_job(data, arg, seed) if kind == "fold" else pair_job(data, arg, seed)


def fold_job(data: EvaluationData, k: int, seed: np.random.SeedSequence) -> FoldResult:
    """Classification and trajectory rates of held-out fold ``k``."""
    # One generator each for the negatives, the user models and every classifier, so a
    # classifier's settings never change another's draws (e.g. the forests' seeds).
    neg_rng, user_rng, *method_rngs = np.random.default_rng(seed).spawn(2 + len(METHODS))
    t0 = time.perf_counter()
    train = _fold_training(data, k, neg_rng)
    test_ticks = way_points_of(data.run, data.settings.test_stride)
    ticks = test_ticks[data.fold[test_ticks] == k]
    pred: dict[str, list[str | None]] = {}
    ok: dict[str, list[bool]] = {}
    fitted: dict[str, FittedClassifier] = {}
    for method, method_rng in zip(METHODS, method_rngs, strict=True):
        f = fitted[method] = fit_method(
            method,
            train.Z,
            train.y,
            train.groups,
            settings=data.settings,
            rng=method_rng,
            negatives=train.Z_neg,
            negative_groups=train.groups_neg,
        )
        pred[method], ok[method] = _classify(data, f, train.Z_cand, ticks)
    sogp = fitted["sogp"]
    t1 = time.perf_counter()
    rates = _fold_rates(data, k, sogp, train.Z_cand, user_rng)
    return FoldResult(
        truth=data.task[ticks].tolist(),
        pred=pred,
        ok=ok,
        cap=float(sogp.model.max_length_scale),
        claim={
            data.labels[int(c)]: float(t) for c, t in zip(sogp.classes, sogp.claim, strict=True)
        },
        rates=rates,
        t_cls=t1 - t0,
        t_rec=time.perf_counter() - t1,
    )


def _fold_training(data: EvaluationData, k: int, neg_rng: np.random.Generator) -> _FoldTraining:
    """The way points outside fold ``k``, standardised on themselves, and their hard
    negatives (:func:`~autonomy.evaluation.folds.hard_negatives`) when enabled."""
    settings, run, off = data.settings, data.run, data.off
    wp = way_points_of(run, settings.stride)
    train_rows = wp[data.fold[wp] != k]
    scaler = FeatureScaler().fit(data.X_true[train_rows])
    Zc = scaler.transform(data.X_cand)
    neg_rows = (
        hard_negatives(train_rows, off, data.ids, data.target, settings.negatives_per_tick, neg_rng)
        if settings.negatives
        else np.zeros(0, dtype=int)
    )
    tick_of_cand = np.repeat(np.arange(len(off) - 1), np.diff(off))
    return _FoldTraining(
        Z=scaler.transform(data.X_true[train_rows]),
        y=data.y[train_rows],
        groups=run[train_rows],
        Z_cand=Zc,
        Z_neg=Zc[neg_rows],
        groups_neg=run[tick_of_cand[neg_rows]],
    )


def _classify(
    data: EvaluationData, f: FittedClassifier, Z_cand: np.ndarray, ticks: np.ndarray
) -> tuple[list[str | None], list[bool]]:
    """Per test tick: the predicted task type (None: no candidate claimed) and whether
    the winning candidate is the demonstrated target."""
    rows, cols = recognise(f, Z_cand, data.off, ticks)
    pred, ok = [], []
    for i, r, c in zip(ticks, rows, cols, strict=True):
        pred.append(None if r < 0 else data.labels[int(f.task_classes[c])])
        ok.append(bool(r >= 0 and data.ids[r] == data.target[i]))
    return pred, ok


def _fold_rates(
    data: EvaluationData,
    k: int,
    sogp: FittedClassifier,
    Z_cand: np.ndarray,
    user_rng: np.random.Generator,
) -> dict[str, list[dict[str, float]]]:
    """Trajectory rates (Sec. 7.2.2) of the SOGP recogniser, the Bayes filter (Ch. 4)
    and the exponential baseline (Eq. 7.5) on every tick of fold ``k``'s runs."""
    labels, run, task, target = data.labels, data.run, data.task, data.target
    train_ticks = np.flatnonzero(data.fold != k)  # every tick: the user models need points
    feats = {
        c: target_features(
            data.s[train_ticks[task[train_ticks] == c]],
            data.u_norm[train_ticks[task[train_ticks] == c]],
        )
        for c in labels
        if np.count_nonzero(task[train_ticks] == c) >= 10  # types the fold can model
    }
    user = fit_user_models(feats, rng=user_rng)
    filt = BayesFilterRecogniser(user, {c: data.kinds[c] for c in feats})
    base = ExponentialBaseline({c: data.kinds[c] for c in labels})
    rates: dict[str, list[dict[str, float]]] = {r: [] for r in RECOGNISERS}
    for r in np.unique(run[data.fold == k]):
        ticks_r = np.flatnonzero(run == r)
        truth_r = [(task[i], target[i]) for i in ticks_r]
        rows, cols = recognise(sogp, Z_cand, data.off, ticks_r)
        dec_sogp: list[Decision] = [
            (labels[int(sogp.classes[c])], data.ids[rr]) if rr >= 0 else None
            for rr, c in zip(rows, cols, strict=True)
        ]
        filt.reset()
        base.reset()
        dec_f, dec_b = [], []
        for i in ticks_r:
            a, b = int(data.off[i]), int(data.off[i + 1])
            cands = [(data.ids[j], data.ckinds[j], data.pts[j]) for j in range(a, b)]
            dec_f.append(filt.step(cands, data.u_norm[i]).decision)
            dec_b.append(base.step(cands, data.u_norm[i]).decision)
        rates["sogp"].append(trajectory_rates(dec_sogp, truth_r))
        rates["bayes_filter"].append(trajectory_rates(dec_f, truth_r))
        rates["baseline"].append(trajectory_rates(dec_b, truth_r))
    return rates


def pair_job(
    data: EvaluationData, pair: tuple[int, int], seed: np.random.SeedSequence
) -> PairResult:
    """Introspection of one training pair of task types, timed."""
    t0 = time.perf_counter()
    name, h = introspect_pair(
        data.X_true, data.y, data.run, data.labels, pair,
        settings=data.settings, rng=np.random.default_rng(seed),
    )  # fmt: skip
    return PairResult(name=name, entropy=h, seconds=time.perf_counter() - t0)


def introspect_pair(
    X: np.ndarray,
    y: np.ndarray,
    run: np.ndarray,
    labels: Sequence[str],
    pair: tuple[int, int],
    *,
    settings: EvaluationSettings,
    rng: np.random.Generator,
) -> tuple[str, dict[str, float]]:
    """Introspection (Sec. 7.3.2, Table 7.9) of one pair of task types: train on the
    pair's way points (standardised on them), query with the other types' way points
    (features against the demonstrated target); (``"<a>+<b>"``, method -> mean
    normalised entropy (7.7) in [0, 1])."""
    a, b = pair
    wp = way_points_of(run, settings.stride)
    train = wp[np.isin(y[wp], (a, b))]
    test = wp[~np.isin(y[wp], (a, b))]
    scaler = FeatureScaler().fit(X[train])
    Ztr, Zte = scaler.transform(X[train]), scaler.transform(X[test])
    h: dict[str, float] = {}
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
        h[method] = float(np.mean(normalised_entropy(f.proba(Zte))))  # Eq. (7.7)
    return f"{labels[a]}+{labels[b]}", h
