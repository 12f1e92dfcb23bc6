"""The independent jobs of the offline evaluation (thesis Sec. 7.2.2, 7.3, 7.4): a
held-out fold (classification, correspondence and trajectory rates) and an introspection
pair of task types (:mod:`autonomy.evaluation.introspection`)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy.baseline_recogniser import ExponentialBaseline, LabelledTicks, tune_exponential
from autonomy.bayes_filter import BayesFilterRecogniser, fit_user_models, target_features
from autonomy.evaluation.classifiers import FittedClassifier, fit_method, most_probable, recognise
from autonomy.evaluation.correspondence import correspondence_rates, intra_cluster_dissimilarity
from autonomy.evaluation.folds import EvaluationData, hard_negatives, way_points_of
from autonomy.evaluation.introspection import pair_job
from autonomy.evaluation.kind_time import kind_time_fold
from autonomy.evaluation.metrics import trajectory_rates
from autonomy.evaluation.settings import KIND_TIME, METHODS, RECOGNISERS
from autonomy.features import FeatureScaler

Decision = tuple[str, str] | None  # (task type, component id), None: no decision
Job = tuple[str, EvaluationData, Any, np.random.SeedSequence]


@dataclass(frozen=True, slots=True)
class FoldResult:
    """What one held-out fold contributes to :func:`autonomy.evaluation.evaluate`."""

    truth: list[str]  # (t,) true task type of every scored test tick
    pred: dict[str, list[str | None]]  # method -> (t,) predicted type, None: no prediction
    ok: dict[str, list[bool]]  # method -> (t,) whether the predicted target is right
    # CORRESPONDENCE (the methods and kind_time) -> held-out run -> correspondence rate
    cr: dict[str, dict[str, float]]
    icad: dict[str, np.ndarray]  # the same keys -> (t,) ICAD of the test ticks [standardised]
    cap: float  # the SOGP's length-scale cap [standard deviations]
    claim: dict[str, float]  # task type -> the SOGP's claim threshold
    rates: dict[str, list[dict[str, float]]]  # recogniser -> per held-out run's rates
    kt_entropy: np.ndarray  # (t,) kind_time's belief entropy (7.7) at the scored test ticks
    kt_decisive: np.ndarray  # (t,) bool: kind_time decisive there
    kt_no_task: np.ndarray  # (t,) kind_time's belief in no task there
    t_cls: float  # classification [s]
    t_rec: float  # trajectory rates of the other recognisers [s]
    t_kt: float  # the kind-and-time recogniser: prior, replay, its rates and ACR [s]


@dataclass(frozen=True, slots=True)
class _FoldTraining:
    """The training side of a fold: standardised way points and hard negatives."""

    Z: np.ndarray  # (t, 7) standardised training way points
    y: np.ndarray  # (t,) their task type index
    groups: np.ndarray  # (t,) their runs
    Z_cand: np.ndarray  # (m, 7) every candidate, standardised on the training fold
    Z_neg: np.ndarray  # (k, 7) hard negatives
    groups_neg: np.ndarray  # (k,) their runs


def run_job(job: Job) -> Any:
    """Run one job of :func:`autonomy.evaluation.evaluate` (top level, so a process pool
    can pickle it): ``("fold", data, k, seed)`` or ``("pair", data, (a, b), seed)``."""
    kind, data, arg, seed = job
    return fold_job(data, arg, seed) if kind == "fold" else pair_job(data, arg, seed)


def run_numbered_job(numbered: tuple[int, Job]) -> tuple[int, Any]:
    """:func:`run_job` of ``(i, job)``, returning ``(i, result)``: a pool may hand the
    results back in any order."""
    i, job = numbered
    return i, run_job(job)


def fold_job(data: EvaluationData, k: int, seed: np.random.SeedSequence) -> FoldResult:
    """Classification, correspondence (Sec. 7.4.1) and trajectory rates of held-out
    fold ``k``."""
    # One generator each for the negatives, the user models and every classifier, so a
    # classifier's settings never change another's draws (e.g. the forests' seeds).
    neg_rng, user_rng, *method_rngs = np.random.default_rng(seed).spawn(2 + len(METHODS))
    t0 = time.perf_counter()
    train = _fold_training(data, k, neg_rng)
    test_ticks = way_points_of(data.run, data.settings.test_stride)
    ticks = test_ticks[data.fold[test_ticks] == k]
    pred: dict[str, list[str | None]] = {}
    ok: dict[str, list[bool]] = {}
    cr: dict[str, dict[str, float]] = {}
    icad: dict[str, np.ndarray] = {}
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
        cr[method], icad[method] = _correspondence(data, f, train, ticks)
    sogp = fitted["sogp"]
    t1 = time.perf_counter()
    rates = _fold_rates(data, k, sogp, train.Z_cand, user_rng)
    t2 = time.perf_counter()
    kt = kind_time_fold(data, k, sogp, train.Z_cand, train.Z, train.y)
    cr[KIND_TIME], icad[KIND_TIME], rates[KIND_TIME] = kt.cr, kt.icad, kt.rates
    return FoldResult(
        truth=data.task[ticks].tolist(),
        pred=pred,
        ok=ok,
        cr=cr,
        icad=icad,
        cap=float(sogp.model.max_length_scale),
        claim={
            data.labels[int(c)]: float(t) for c, t in zip(sogp.classes, sogp.claim, strict=True)
        },
        rates={r: rates[r] for r in RECOGNISERS},
        kt_entropy=kt.entropy,
        kt_decisive=kt.decisive,
        kt_no_task=kt.no_task,
        t_cls=t1 - t0,
        t_rec=t2 - t1,
        t_kt=time.perf_counter() - t2,
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


def _correspondence(
    data: EvaluationData, f: FittedClassifier, train: _FoldTraining, ticks: np.ndarray
) -> tuple[dict[str, float], np.ndarray]:
    """CR of every held-out run and ICAD of every test tick (Sec. 7.4.1): the most
    probable candidate (Eq. 5.8, never abstaining) against the demonstrated target, and
    its feature's mean distance to the training way points of the task type it is
    assigned to (the hard negatives belong to no cluster)."""
    rows, cols = most_probable(f, train.Z_cand, data.off, ticks)
    hit = (rows >= 0) & (data.ids[np.maximum(rows, 0)] == data.target[ticks])
    found = rows >= 0
    icad = intra_cluster_dissimilarity(
        train.Z_cand[rows[found]], train.Z, train.y, f.task_classes[cols[found]]
    )
    return correspondence_rates(hit, data.run[ticks]), icad


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
    and the exponential baseline in both forms (Eqs. 7.5, 7.4; scales and threshold tuned
    on the training fold's runs) on every tick of fold ``k``'s runs (the kind-and-time
    recogniser's: :func:`~autonomy.evaluation.kind_time.kind_time_fold`)."""
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
    kinds = {c: data.kinds[c] for c in labels}
    training = _labelled_ticks(data, train_ticks)
    bases = {
        rec: ExponentialBaseline(kinds, settings=tune_exponential(training, kinds=kinds, form=form))
        for rec, form in (("baseline", "psi"), ("baseline_theta", "theta"))
    }
    rates: dict[str, list[dict[str, float]]] = {r: [] for r in RECOGNISERS if r != KIND_TIME}
    for r in np.unique(run[data.fold == k]):
        ticks_r = np.flatnonzero(run == r)
        truth_r = [(task[i], target[i]) for i in ticks_r]
        rows, cols = recognise(sogp, Z_cand, data.off, ticks_r)
        dec_sogp: list[Decision] = [
            (labels[int(sogp.classes[c])], data.ids[rr]) if rr >= 0 else None
            for rr, c in zip(rows, cols, strict=True)
        ]
        filt.reset()
        dec: dict[str, list[Decision]] = {"bayes_filter": [], **{rec: [] for rec in bases}}
        for i in ticks_r:
            a, b = int(data.off[i]), int(data.off[i + 1])
            cands = [(data.ids[j], data.ckinds[j], data.pts[j]) for j in range(a, b)]
            dec["bayes_filter"].append(filt.step(cands, data.u_norm[i]).decision)
            for rec, base in bases.items():
                dec[rec].append(base.step(cands, data.u_norm[i]).decision)
        rates["sogp"].append(trajectory_rates(dec_sogp, truth_r))
        for rec, decisions in dec.items():
            rates[rec].append(trajectory_rates(decisions, truth_r))
    return rates


def _labelled_ticks(data: EvaluationData, rows: np.ndarray) -> LabelledTicks:
    """Ticks ``rows`` with their candidates, for :func:`tune_exponential`."""
    a, b = data.off[rows], data.off[rows + 1]
    cand = np.concatenate([np.arange(x, y) for x, y in zip(a, b, strict=True)] or [[]])
    cand = cand.astype(int)
    return LabelledTicks(
        points=data.pts[cand],
        offsets=np.r_[0, np.cumsum(b - a)],
        ids=data.ids[cand],
        kinds=data.ckinds[cand],
        u=data.u_norm[rows],
        task=data.task[rows],
        target=data.target[rows],
        run=data.run[rows],
    )
