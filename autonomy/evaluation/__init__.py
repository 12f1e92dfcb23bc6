"""Offline evaluation of contextual-task recognition on held-out demonstrations (thesis
Sec. 7.2.2, 7.3, 7.4; spec sections 3 and 5; issue 3, "Offline evaluation").

:func:`evaluate` takes demonstrations (duck-typed: the fields of
``study.jobs.demonstrations.Demonstrations``) and reports

- **task classification** (Sec. 7.3.1, Tables 7.2-7.6): cross-validation *by run* (a run's
  ticks are never split between training and test) of the SOGP classifier (Ch. 5) against
  scikit-learn's SVM (RBF kernel), k-nearest neighbours and random forest, each
  grid-searched with an inner cross-validation by run (``StratifiedGroupKFold``: runs
  kept whole, task types balanced) on the training fold. All four see the same encoded,
  standardised features (``autonomy.features``; the scaler is learnt on the training
  fold) and the same labels. At test time every
  candidate component of a tick yields a feature; the classifier's best score over
  candidates x classes (Eq. 5.8) gives the task type *and* the target, and a
  classification is correct only when both are right (Sec. 7.3.1). F0.5 per task type and
  macro, and the confusion matrix;
- **introspection** (Sec. 7.3.2, 7.4.3, Table 7.9): for each of the 6 pairs of the four
  demonstrated task types, train on the pair and query with the features (against the
  demonstrated target) of the other two; the mean normalised entropy (Eq. 7.7) of the
  two-class distribution, per classifier;
- **trajectory rates** (Sec. 7.2.2): success, error and null rates along each held-out
  run of the SOGP recogniser, the recursive Bayesian filter (Ch. 4) and the
  exponential-confidence baseline (Eq. 7.5), averaged over runs.

Decisions where the thesis and the spec are silent:

- Labels. Table 7.6 scores the Chapter-5 classifier, which is trained on the task types
  (Sec. 7.3: "the classifiers are trained" on the four task types; Table 7.2's rows and
  columns are the task types), so the labels here are the *true task types*, for every
  classifier. The DP-GMM clusters of ``asa train`` are not used: they mix task types (see
  ``asa train``'s summary), and a per-cluster F0.5 would not be comparable with Table 7.6.
- Folds. The runs of each task type are shuffled (the ``seed``) and dealt round-robin to
  the folds, so that every fold holds every task type when it has at least ``folds``
  runs (a stratified ``GroupKFold``); ``folds`` must lie in [2, number of runs]
  (ValueError otherwise).
- Ticks. Training uses way points, every ``stride``-th moving tick of a run (4: the 5 Hz
  of the thesis's demonstrations, Sec. 7.3 footnote 11); classification is scored on every
  ``test_stride``-th tick (2) of the held-out runs; the trajectory rates on every tick
  (the Bayes filter is recursive).
- Candidates: all components the demonstration recorded at the tick, sorted by distance,
  so ties between candidates (frequent for the probability outputs of KNN and RF) go to
  the nearest. The target must be the demonstrated component's id.
- Scores. SOGP: posterior means (Eq. 5.6, the score of Eq. 5.8); SVM: the one-vs-rest
  decision function; KNN and RF: class probabilities. A non-finite score never wins.
- F0.5 (Eq. 7.6) per task type c counts, with "right" meaning right task type and right
  target: ``tp`` right predictions of c; ``fp`` predictions of c that are not right (also
  the right type at a wrong target); ``fn`` ticks of true type c not predicted right.
  Macro = unweighted mean over the task types. The confusion matrix has rows = true type,
  columns = predicted type at the right target, plus a column ``wrong_target``.
- Hard negatives (a decision beyond the thesis, ``negatives``, on by default), applied
  identically to every classifier: at every training way point, ``negatives_per_tick``
  (2) of the *other* candidate components of the same tick (their target points, the
  same command), drawn at random (:func:`hard_negatives`), are examples of "no task":
  target -1 in every one-vs-all GP of the SOGP, an extra "none" class for SVM, KNN and
  RF. Trained on the demonstrated target's features alone, nothing tells a classifier
  that another candidate's feature at the same tick is *not* the task, and most SOGP
  losses were wrong targets. Two per tick (of 6-11) keeps the run short.
- Abstention: a candidate counts only when a task claims it -- SOGP: a class claims
  it when its posterior mean reaches the class's claim threshold (0 is the thesis's
  rule, confidence (5.10) >= 1/2; the thresholds come from the inner cross-validation
  below), and the largest claiming mean wins; a baseline trained with negatives: its
  argmax class is not "none". When no candidate of
  a tick is claimed there is no prediction (a false negative, never a false positive:
  "better no assistance than wrong assistance", Sec. 7.4).
- Inner grid search scored by macro F0.5 of the plain classification against the
  demonstrated target, over the task types and, with negatives, the "none" class (the
  candidate search is the outer evaluation's). Grids (small, to
  keep the run short): SVM ``C`` in {1, 10, 100} x ``gamma`` in {"scale", 1.0}; KNN
  ``n_neighbors`` in {5, 15, 45} x ``weights`` in {uniform, distance}; RF (60 trees)
  ``max_depth`` in {None, 12} x ``min_samples_leaf`` in {1, 5}. The SOGP's kernel
  hyperparameters maximise the evidence (Sec. 7.3.1) under a length-scale cap; the cap
  (``sogp_length_scale_grid``, 2.0 standard deviations) and a claim threshold per task
  type (``sogp_claim_grid``, 0 to 0.6 in steps of 0.1, chosen type by type by
  coordinate ascent: the baselines' "none" class draws a boundary of its own against
  each task class, the thresholds are the SOGP's counterpart) are chosen by the same
  inner score (``sogp_inner_folds`` = 2 folds by run), on the training fold only; the
  choices are reported per fold (``sogp_length_scale_cap``, ``sogp_claim_threshold``
  -> {task type -> threshold}).
- Capacity (1200 basis vectors per GP), evidence subsample (1000 points) and the
  refined posterior (``sogp_refine``: after the online pass every GP's posterior is
  re-estimated from all its training points on the basis the pass chose,
  ``SparseOnlineGP.refine``, the fixed point of repeated online sweeps): the
  evaluation's own, not the shipped model's (250 and 300, no refinement; a run-time
  budget: a model file under 5 MB and a cheap tick). It measures what the SOGP
  classifier can do, and that rises with the capacity towards the full GP. Measured on
  fixed folds (seed 0, negatives, cap 2.0, threshold 0), SOGP F0.5 doorway / bypass /
  inspection / wall: capacity 250 (300 evidence points) .58/.49/.81/.71; 600 (1000)
  .66/.56/.86/.75; 1200 (1000) .70/.62/.88/.77; the full GP on all ~7,900 training
  points with the same hyperparameters .74/.65/.88/.78. Caps 1.0, 3.0, 4.0 and 8.0 did
  worse than 2.0, and one hard negative per tick worse than two. On the evaluation's
  own folds, with the best threshold per type picked on the test folds (an upper
  bound, for comparison only): capacity 600 .75/.58/.89/.82, refined .80/.60/.90/.82;
  1200 refined .81/.61/.90/.83; the full GP .82/.63/.90/.83. On 7,986 points the
  refinement costs 0.3 s per GP at capacity 600 and 0.9 s at 1200, the online pass 1.4 s
  and 9.2 s.
- Tried and not kept (same upper-bound measure, F0.5 doorway / bypass / inspection /
  wall). On the full GP (evidence hyperparameters: .82/.63/.90/.83): an isotropic
  length scale of 0.7, 1.0 or 1.4 standard deviations instead of the evidence's
  .83/.61/.89/.84, .82/.62/.89/.82, .82/.60/.89/.79; an evidence subsample of 2000
  .80/.62/.90/.83; the noise variance x0.3 .80/.62/.89/.83. On the SOGP (capacity 1200
  refined: .81/.61/.90/.83): capacity 1700 with the online pass over half the points
  (40 % slower) .83/.61/.90/.83; abstaining when another candidate scores within .2 of
  the winner .82/.62/.91/.84. Ranking the candidates by the confidence (5.10) instead
  of the mean, with the thresholds on the confidence (.5 to .95), gained .014 on object
  bypass in this measure, but in ``asa evaluate --repeats 3`` its means fell (doorway
  .773, inspection .865, macro .761 against .790, .880, .770; bypass .618 and wall .787
  against .617 and .792). A fifth one-vs-all GP for the hard negatives ("none": +1 on
  them, -1 on the task points), the candidates ranked by a class's mean minus the none
  GP's (the full GP, seed 0): with every threshold at 0, .734/.643/.871/.840 against the
  plain means' .749/.627/.872/.827; with the thresholds per type picked on the test
  folds, .822/.630/.904/.837 against .818/.630/.897/.829 -- no gain on object bypass
  once the other types' thresholds rise, for a fifth GP to train.
- Introspection probabilities: SOGP, the normalised confidences (5.10,
  ``SOGPClassifier.predict_proba``); SVM, Platt scaling (``CalibratedClassifierCV(...,
  method="sigmoid", ensemble=False)``, what ``SVC(probability=True)`` did) with the grid's
  best parameters on the pair; KNN and RF, ``predict_proba``. Pairs are named
  ``"<type>+<type>"`` (the training pair). JSON: ``introspection_entropy`` -> {classifier
  -> mean over the six pairs} (issue 3's shape), ``introspection_pairs`` -> {classifier ->
  {pair -> mean entropy}}; ``sogp_at_least_baselines`` -> {task type -> whether the
  SOGP's F0.5 is at least every baseline's}.
- SOGP recogniser along a run: the fold's SOGP classifier with Eq. (5.8) over the tick's
  candidates (as the contextual mode recognises), among the entries that reach their
  class's claim threshold; the decision is null when none does. The
  Bayes filter's user models (BIC, Eq. 4.11) are fitted on every tick of the training
  fold's runs per task type; the baseline uses its default scales.
- Jobs: every fold and every introspection pair is an independent job with its own
  ``numpy.random.SeedSequence`` spawned from ``seed`` (the folds' assignment has the
  first), so :func:`evaluate`'s ``map_fn`` may run them in worker processes (``asa
  evaluate --workers``) and the result is the same for any number of workers. Within a
  job, the negatives, the user models and every classifier draw from generators of
  their own (spawned from the job's), so one classifier's settings never change
  another's draws (they did: a change to the SOGP moved the forests' seeds, and their
  F0.5 by up to .015).
- Speed: a fold job costs 100-150 s of CPU (the SOGP most of it, half of that its
  inner cross-validation), an introspection pair about 8 s: some 9-14 CPU-minutes, run by
  ``asa evaluate`` in as many worker processes as CPUs. Measured on this 2-core machine
  with 2 workers, quiet: 7 min 57 s wall (13 min 19 s user CPU); again at 2c7a009, the
  same results, 5 min 22 s wall (9 min 6 s user CPU).
- Result (``asa evaluate``, seed 0, 48 runs): F0.5 doorway / bypass / inspection / wall
  / macro: SOGP .785/.640/.891/.815/.783, SVM .768/.649/.830/.810/.764, KNN
  .720/.587/.841/.774/.731, RF .738/.617/.858/.828/.760. The SOGP leads the macro,
  doorway crossing and object inspection; it trails the SVM on object bypass by .009 and
  the RF on wall following by .013. Those gaps are within what the random draws alone
  move: drawing the hard negatives and the forests' seeds afresh (the same code
  otherwise) moved the SVM's bypass F0.5 from .624 to .649 and the RF's wall F0.5 from
  .818 to .828. Introspection entropy RF .51, SOGP .49, SVM .43, KNN .16 (with the
  previous draws: SOGP .52, RF .51).
- Over three seeds (``asa evaluate --repeats 3``: seeds 0-2, 23 min wall on 2 workers),
  F0.5 mean +- sd, SOGP / SVM / KNN / RF: doorway .790+-.014 / .773+-.006 / .732+-.010 /
  .741+-.006; bypass .617+-.032 / .626+-.037 / .584+-.027 / .605+-.029; inspection
  .880+-.025 / .832+-.010 / .843+-.014 / .853+-.012; wall .792+-.019 / .787+-.030 /
  .764+-.015 / .805+-.023; macro .770+-.019 / .754+-.017 / .731+-.014 / .751+-.016. The
  SOGP is at least every baseline in 3 of 3 seeds on the macro and object inspection,
  2 of 3 on doorway crossing, and in none on object bypass (the SVM) or wall following
  (the RF), by about .01 on average: its gaps there are small but systematic.
  Introspection entropy, mean: RF .504, SOGP .501, SVM .427, KNN .158.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.calibration import CalibratedClassifierCV
from sklearn.ensemble import RandomForestClassifier
from sklearn.metrics import fbeta_score
from sklearn.model_selection import GridSearchCV, StratifiedGroupKFold
from sklearn.neighbors import KNeighborsClassifier
from sklearn.svm import SVC

from autonomy.baseline_recogniser import ExponentialBaseline
from autonomy.bayes_filter import BayesFilterRecogniser, fit_user_models, target_features
from autonomy.features import FeatureScaler, encode, wrap_angle
from autonomy.evaluation.metrics import trajectory_rates
from autonomy.sogp import MAX_LENGTH_SCALE
from autonomy.sogp_classifier import SOGPClassifier, argmax_finite, normalised_entropy

METHODS: tuple[str, ...] = ("sogp", "svm", "knn", "rf")
RECOGNISERS: tuple[str, ...] = ("sogp", "bayes_filter", "baseline")
WRONG_TARGET = "wrong_target"


@dataclass(frozen=True, slots=True)
class EvaluationSettings:
    """Settings of :func:`evaluate` (values: see the module docstring)."""

    folds: int = 5
    seed: int = 0
    stride: int = 4  # training way points: every 4th moving tick (5 Hz)
    test_stride: int = 2  # classification scored on every 2nd held-out tick
    capacity: int = 1200  # SOGP basis vectors per class
    hyper_points: int = 1000  # class-balanced subsample for the GP evidence
    hyper_restarts: int = 1
    max_length_scale: float = MAX_LENGTH_SCALE
    inner_folds: int = 3  # grid search: StratifiedGroupKFold by run in the training fold
    rf_trees: int = 60
    negatives: bool = True  # hard negatives (other candidates) for every classifier
    negatives_per_tick: int = 2  # wrong candidates drawn per training way point
    sogp_length_scale_grid: tuple[float, ...] = (2.0,)  # inner-CV choice of the cap
    sogp_claim_grid: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)  # per class
    sogp_inner_folds: int = 2
    sogp_refine: bool = True  # re-estimate each GP on its basis after the online pass

    def __post_init__(self) -> None:
        for name in (
            "stride",
            "test_stride",
            "capacity",
            "hyper_points",
            "hyper_restarts",
            "rf_trees",
            "negatives_per_tick",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"evaluation setting {name}: must be an integer >= 1")
        if not (isinstance(self.folds, int) and self.folds >= 2):
            raise ValueError(f"--folds: must be an integer >= 2, got {self.folds!r}")
        if not (isinstance(self.inner_folds, int) and self.inner_folds >= 2):
            raise ValueError("evaluation setting inner_folds: must be an integer >= 2")
        if not (isinstance(self.sogp_inner_folds, int) and self.sogp_inner_folds >= 2):
            raise ValueError("evaluation setting sogp_inner_folds: must be an integer >= 2")
        if not all(isinstance(v, int | float) and v > 1e-2 for v in self.sogp_length_scale_grid):
            raise ValueError(
                "evaluation setting sogp_length_scale_grid: every value must be a number > 0.01"
            )
        claims = self.sogp_claim_grid
        if not (
            len(claims) >= 1
            and all(isinstance(v, int | float) and math.isfinite(v) and -1 < v < 1 for v in claims)
        ):
            raise ValueError(
                "evaluation setting sogp_claim_grid: need at least one threshold, each a "
                "number in (-1, 1) (a posterior mean of +-1 targets)"
            )


# --------------------------------------------------------------------------- features


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


# --------------------------------------------------------------------------- metrics


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


# --------------------------------------------------------------------------- classifiers


def _scorer(n_classes: int):
    """Macro F0.5 over all ``n_classes`` labels (0..c-1), also on an inner split that
    lacks some of them (scikit-learn's string scorer then guesses a binary problem)."""
    labels = list(range(n_classes))

    def score(estimator: Any, X: np.ndarray, y: np.ndarray) -> float:
        return float(
            fbeta_score(
                y, estimator.predict(X), beta=0.5, average="macro", labels=labels, zero_division=0
            )
        )

    return score


def _grid(method: str, settings: EvaluationSettings, seed: int):
    if method == "svm":
        return SVC(kernel="rbf"), {"C": [1.0, 10.0, 100.0], "gamma": ["scale", 1.0]}
    if method == "knn":
        return KNeighborsClassifier(), {
            "n_neighbors": [5, 15, 45],
            "weights": ["uniform", "distance"],
        }
    if method == "rf":
        rf = RandomForestClassifier(n_estimators=settings.rf_trees, random_state=seed, n_jobs=1)
        return rf, {"max_depth": [None, 12], "min_samples_leaf": [1, 5]}
    raise ValueError(f"unknown method {method!r}")


class _Fitted:
    """A fitted classifier with a uniform interface: ``scores`` (candidates x classes)
    for Eq. (5.8)-style recognition, ``task_scores`` (the task columns, rows no task
    claims set to NaN) and ``proba`` for the introspection. ``none`` is the label of the
    hard negatives' extra class (baselines only), if any."""

    def __init__(
        self,
        method: str,
        model: Any,
        classes: np.ndarray,
        none: int | None = None,
        *,
        claim: float | Sequence[float] = 0.0,
    ):
        self.method = method
        self.model = model
        # SOGP: per class, the least posterior mean with which it claims a feature
        self.claim = np.broadcast_to(np.asarray(claim, dtype=float), (len(classes),)).copy()
        self.classes = classes
        self.none_col = None if none is None else int(np.flatnonzero(classes == none)[0])
        self.task_cols = np.flatnonzero(classes != none) if none is not None else None
        self.task_classes = classes if none is None else classes[self.task_cols]

    def task_scores(self, Z: np.ndarray) -> np.ndarray:
        """(n, c_tasks) scores of the task classes, NaN where the class does not claim
        the feature (SOGP: its posterior mean is below its ``claim`` threshold, 0 being a
        confidence (5.10) below 1/2), and whole rows NaN where no task claims it (a
        baseline with negatives: its argmax is the "none" class)."""
        S = np.asarray(self.scores(Z), dtype=float)
        if self.method == "sogp":
            S = np.where(S >= self.claim, S, np.nan)
            claimed = ~np.all(np.isnan(S), axis=1)
        elif self.none_col is not None:
            claimed = np.argmax(S, axis=1) != self.none_col
        else:
            claimed = np.ones(len(S), dtype=bool)
        T = S if self.task_cols is None else S[:, self.task_cols]
        T = np.array(T, dtype=float)
        T[~claimed] = np.nan
        return T

    def scores(self, Z: np.ndarray) -> np.ndarray:
        if self.method == "sogp":
            return self.model.scores(Z)  # Eq. (5.6)
        if self.method == "svm":
            d = self.model.decision_function(Z)
            return np.column_stack((-d, d)) if d.ndim == 1 else d  # binary: one column
        return self.model.predict_proba(Z)

    def proba(self, Z: np.ndarray) -> np.ndarray:
        return self.model.predict_proba(Z)


def fit_method(
    method: str,
    Z: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    *,
    settings: EvaluationSettings,
    rng: np.random.Generator,
    probability: bool = False,
    negatives: np.ndarray | None = None,
    negative_groups: np.ndarray | None = None,
    tune: bool = True,
) -> _Fitted:
    """Fit one classifier on standardised features ``Z`` (n, 7), integer labels ``y`` (n,).

    The baselines are grid-searched with ``StratifiedGroupKFold`` by ``groups`` (runs);
    the SOGP's kernel hyperparameters maximise the evidence, its length-scale cap and
    claim threshold come from :func:`_sogp_inner_cv` (``tune=False``: the first cap of
    the grid and the first threshold, for the introspection, which needs neither).
    ``probability`` makes the SVM Platt-scaled. ``negatives`` (k, 7), with their runs
    ``negative_groups`` (k,), are features of no task: target -1 in every one-vs-all GP
    of the SOGP, an extra "none" class (label ``max(y) + 1``) for the baselines.
    """
    has_neg = negatives is not None and len(negatives) > 0
    if method == "sogp":
        classes, yi = np.unique(y, return_inverse=True)
        caps = settings.sogp_length_scale_grid or (settings.max_length_scale,)
        cap, claim = float(caps[0]), np.full(len(classes), settings.sogp_claim_grid[0])
        if tune and (len(caps) > 1 or len(settings.sogp_claim_grid) > 1):
            cap, claim = _sogp_inner_cv(
                Z,
                yi,
                groups,
                negatives if has_neg else None,
                negative_groups,
                settings=settings,
                rng=rng,
            )
        clf = SOGPClassifier(
            capacity=settings.capacity,
            hyper_points=settings.hyper_points,
            restarts=settings.hyper_restarts,
            max_length_scale=cap,
            refine=settings.sogp_refine,
        ).fit(Z, yi, rng=rng, negatives=negatives if has_neg else None)
        return _Fitted(method, clf, classes[clf.classes_], claim=claim[clf.classes_])
    none = None
    if has_neg:
        none = int(np.max(y)) + 1
        Z = np.concatenate((Z, negatives))
        y = np.concatenate((y, np.full(len(negatives), none)))
        groups = np.concatenate((groups, negative_groups))
    classes, y = np.unique(y, return_inverse=True)  # 0..c-1 for scikit-learn's scorers
    seed = int(rng.integers(2**31 - 1))
    estimator, grid = _grid(method, settings, seed)
    n_groups = len(np.unique(groups))
    cv = StratifiedGroupKFold(n_splits=min(settings.inner_folds, max(n_groups, 2)))
    if method == "knn" and n_groups >= 2:  # no more neighbours than a training split holds
        smallest = min(len(tr) for tr, _ in cv.split(Z, y, groups=groups))
        grid["n_neighbors"] = [k for k in grid["n_neighbors"] if k <= smallest] or [1]
    if n_groups >= 2 and all(  # a grid needs >= 2 classes in every inner training split
        len(np.unique(y[tr])) >= 2 for tr, _ in cv.split(Z, y, groups=groups)
    ):
        search = GridSearchCV(
            estimator,
            grid,
            scoring=_scorer(len(classes)),
            cv=cv,
            refit=False,
            n_jobs=1,
        )
        search.fit(Z, y, groups=groups)
        params = search.best_params_
    else:
        params = {}
    final = estimator.set_params(**params)
    if method == "svm" and probability:
        # Platt scaling, as SVC(probability=True) (deprecated in scikit-learn 1.9)
        final = CalibratedClassifierCV(final, method="sigmoid", cv=3, ensemble=False)
    final.fit(Z, y)
    return _Fitted(method, final, classes[final.classes_], none)


def _sogp_inner_cv(
    Z: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    negatives: np.ndarray | None,
    negative_groups: np.ndarray | None,
    *,
    settings: EvaluationSettings,
    rng: np.random.Generator,
) -> tuple[float, np.ndarray]:
    """The SOGP's length-scale cap (``settings.sogp_length_scale_grid``) and its claim
    threshold per class (``settings.sogp_claim_grid``; (c,) for the classes ``0..c-1`` of
    ``y``) with the best macro F0.5 (task types and "none") in an inner
    ``StratifiedGroupKFold`` by run on the training fold: the baselines' grid-search
    score, with the SOGP's own decision (the largest posterior mean among the classes
    that reach their threshold; "none" when no class does). One fit per cap and inner
    split; the thresholds are applied to its scores and chosen class by class
    (coordinate ascent from all at the first threshold, two sweeps). Ties go to the
    earlier grid entry."""
    has_neg = negatives is not None and len(negatives) > 0
    none = int(np.max(y)) + 1
    Za = np.concatenate((Z, negatives)) if has_neg else Z
    ya = np.concatenate((y, np.full(len(negatives), none))) if has_neg else y
    ga = np.concatenate((groups, negative_groups)) if has_neg else groups
    caps = settings.sogp_length_scale_grid or (settings.max_length_scale,)
    grid = np.asarray(settings.sogp_claim_grid, dtype=float)
    first = np.full(none, grid[0])
    n_groups = len(np.unique(ga))
    if n_groups < 2:
        return float(caps[0]), first
    cv = StratifiedGroupKFold(n_splits=min(settings.sogp_inner_folds, n_groups))
    splits = list(cv.split(Za, ya, groups=ga))
    labels = list(range(none + (1 if has_neg else 0)))
    fits: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in caps]
    for tr, va in splits:
        pos = tr[ya[tr] != none]
        if len(np.unique(ya[pos])) < 2:
            continue
        neg = tr[ya[tr] == none]
        for i, cap in enumerate(caps):
            clf = SOGPClassifier(
                capacity=settings.capacity,
                hyper_points=settings.hyper_points,
                restarts=settings.hyper_restarts,
                max_length_scale=float(cap),
                refine=settings.sogp_refine,
            ).fit(Za[pos], ya[pos], rng=rng, negatives=Za[neg] if len(neg) else None)
            means = np.full((len(va), none), -np.inf)  # a class the split lacks never wins
            means[:, clf.classes_] = clf.scores(Za[va])
            fits[i].append((means, ya[va]))
    if not fits[0]:
        return float(caps[0]), first

    def score(i: int, claim: np.ndarray) -> float:
        total = 0.0
        for means, truth in fits[i]:
            M = np.where(means >= claim, means, -np.inf)
            pred = np.where(np.isfinite(M.max(axis=1)), np.argmax(M, axis=1), none)
            total += fbeta_score(
                truth, pred, beta=0.5, average="macro", labels=labels, zero_division=0
            )
        return total

    best: tuple[float, int, np.ndarray] = (-np.inf, 0, first)
    for i in range(len(caps)):
        claim = first.copy()
        for _sweep in range(2):
            for c in range(none):
                values = []
                for t in grid:
                    claim[c] = t
                    values.append(score(i, claim))
                claim[c] = grid[int(np.argmax(values))]  # first maximum: ties early
        value = score(i, claim)
        if value > best[0]:
            best = (value, i, claim)
    return float(caps[best[1]]), best[2]


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


def _decide(scores: np.ndarray, offsets: np.ndarray, ticks: np.ndarray):
    """Per tick: (winning candidate row, winning class column) over its candidates."""
    rows = np.empty(len(ticks), dtype=int)
    cols = np.empty(len(ticks), dtype=int)
    for n, i in enumerate(ticks):
        a, b = int(offsets[i]), int(offsets[i + 1])
        r, c = argmax_finite(scores[a:b]) if b > a else (-1, -1)
        rows[n] = a + r if r >= 0 else -1
        cols[n] = c
    return rows, cols


# --------------------------------------------------------------------------- evaluation


def _candidate_rows(offsets: np.ndarray, ticks: np.ndarray) -> np.ndarray:
    """The candidate rows of ``ticks``, tick by tick."""
    return np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in ticks])


def _recognise(
    fitted: _Fitted, Z_cand: np.ndarray, offsets: np.ndarray, ticks: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_decide` over ``fitted``'s task scores of the candidates of ``ticks`` (rows
    of ``Z_cand``, standardised; entries no task claims are NaN and never win)."""
    rows = _candidate_rows(offsets, ticks)
    S = np.full((len(Z_cand), len(fitted.task_classes)), np.nan)
    S[rows] = fitted.task_scores(Z_cand[rows])
    return _decide(S, offsets, ticks)


def _sorted_candidates(demos: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Candidates of every tick sorted by distance (stable): points, ids, kinds, offsets."""
    off = np.asarray(demos.cand_offsets, dtype=np.int64)
    pts = np.asarray(demos.cand_points, dtype=float)
    ids = np.asarray(demos.cand_ids).astype(str)
    kinds = np.asarray(demos.cand_kinds).astype(str)
    counts = np.diff(off)
    tick = np.repeat(np.arange(len(counts)), counts)
    order = np.lexsort((np.hypot(pts[:, 0], pts[:, 1]), tick))
    return pts[order], ids[order], kinds[order], off


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
class _Data:
    """Everything a fold or pair job needs (picklable, for a process pool)."""

    settings: EvaluationSettings
    kinds: dict[str, str]
    labels: list[str]
    run: np.ndarray  # (n,) run of every moving tick
    task: np.ndarray  # (n,) true task type
    target: np.ndarray  # (n,) demonstrated component id
    y: np.ndarray  # (n,) task type index
    u_norm: np.ndarray  # (n, 3)
    s: np.ndarray  # (n, 2) demonstrated target point
    fold: np.ndarray  # (n,) fold of every tick
    pts: np.ndarray  # (m, 2) candidate points, sorted by distance within a tick
    ids: np.ndarray  # (m,)
    ckinds: np.ndarray  # (m,)
    off: np.ndarray  # (n + 1,)
    X_cand: np.ndarray  # (m, 7) encoded candidate features
    X_true: np.ndarray  # (n, 7) encoded demonstrated features


def _fold_job(data: _Data, k: int, seed: np.random.SeedSequence) -> dict[str, Any]:
    """Classification and trajectory rates of held-out fold ``k``."""
    settings, labels = data.settings, data.labels
    run, task, target, off, ids = data.run, data.task, data.target, data.off, data.ids
    # One generator each for the negatives, the user models and every classifier, so a
    # classifier's settings never change another's draws (e.g. the forests' seeds).
    neg_rng, user_rng, *method_rngs = np.random.default_rng(seed).spawn(2 + len(METHODS))
    t0 = time.perf_counter()
    wp = way_points_of(run, settings.stride)
    test_ticks = way_points_of(run, settings.test_stride)
    train_rows = wp[data.fold[wp] != k]
    scaler = FeatureScaler().fit(data.X_true[train_rows])
    Ztr = scaler.transform(data.X_true[train_rows])
    ytr, gtr = data.y[train_rows], run[train_rows]
    Zc = scaler.transform(data.X_cand)
    neg_rows = (
        hard_negatives(train_rows, off, ids, target, settings.negatives_per_tick, neg_rng)
        if settings.negatives
        else np.zeros(0, dtype=int)
    )
    tick_of_cand = np.repeat(np.arange(len(off) - 1), np.diff(off))
    Zneg, gneg = Zc[neg_rows], run[tick_of_cand[neg_rows]]
    ticks = test_ticks[data.fold[test_ticks] == k]
    out: dict[str, Any] = {"truth": task[ticks].tolist(), "pred": {}, "ok": {}}
    fitted: dict[str, _Fitted] = {}
    for method, method_rng in zip(METHODS, method_rngs, strict=True):
        f = fitted[method] = fit_method(
            method,
            Ztr,
            ytr,
            gtr,
            settings=settings,
            rng=method_rng,
            negatives=Zneg,
            negative_groups=gneg,
        )
        rows, cols = _recognise(f, Zc, off, ticks)
        pred, ok = [], []
        for i, r, c in zip(ticks, rows, cols, strict=True):
            pred.append(None if r < 0 else labels[int(f.task_classes[c])])
            ok.append(bool(r >= 0 and ids[r] == target[i]))
        out["pred"][method], out["ok"][method] = pred, ok
    sogp = fitted["sogp"]
    out["cap"] = float(sogp.model.max_length_scale)
    out["claim"] = {labels[int(c)]: float(t) for c, t in zip(sogp.classes, sogp.claim, strict=True)}
    t1 = time.perf_counter()
    # trajectory rates on every tick of the held-out runs
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
        rows, cols = _recognise(sogp, Zc, off, ticks_r)
        dec_sogp: list[tuple[str, str] | None] = [
            (labels[int(sogp.classes[c])], ids[rr]) if rr >= 0 else None
            for rr, c in zip(rows, cols, strict=True)
        ]
        filt.reset()
        base.reset()
        dec_f, dec_b = [], []
        for i in ticks_r:
            a, b = int(off[i]), int(off[i + 1])
            cands = [(ids[j], data.ckinds[j], data.pts[j]) for j in range(a, b)]
            dec_f.append(filt.step(cands, data.u_norm[i]).decision)
            dec_b.append(base.step(cands, data.u_norm[i]).decision)
        rates["sogp"].append(trajectory_rates(dec_sogp, truth_r))
        rates["bayes_filter"].append(trajectory_rates(dec_f, truth_r))
        rates["baseline"].append(trajectory_rates(dec_b, truth_r))
    out["rates"] = rates
    out["t_cls"], out["t_rec"] = t1 - t0, time.perf_counter() - t1
    return out


def _pair_job(
    data: _Data, pair: tuple[int, int], seed: np.random.SeedSequence
) -> tuple[str, dict[str, float], float]:
    """Introspection of one training pair of task types: (name, method -> mean
    normalised entropy on the other types' way points, seconds)."""
    t0 = time.perf_counter()
    name, h = _introspect_pair(
        data.X_true, data.y, data.run, data.labels, pair,
        settings=data.settings, rng=np.random.default_rng(seed),
    )  # fmt: skip
    return name, h, time.perf_counter() - t0


def _job(job: tuple[str, _Data, Any, np.random.SeedSequence]) -> Any:
    """Run one job of :func:`evaluate` (top level, so a process pool can pickle it)."""
    kind, data, arg, seed = job
    return _fold_job(data, arg, seed) if kind == "fold" else _pair_job(data, arg, seed)


def evaluate(
    demos: Any,
    *,
    kinds: Mapping[str, str],
    settings: EvaluationSettings | None = None,
    model: str = "",
    where: str = "demonstrations",
    map_fn: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
) -> dict[str, Any]:
    """Cross-validated recognition quality on demonstrations (see the module docstring).

    Parameters
    ----------
    demos : Demonstrations-like
        ``q`` (n, 6), ``u_norm`` (n, 3), ``run`` (n,), ``task`` (n,), ``target`` (n,),
        ``s`` (n, 2), ``cand_offsets`` (n + 1,), ``cand_points`` (m, 2), ``cand_ids``
        (m,), ``cand_kinds`` (m,): moving ticks, runs contiguous.
    kinds : mapping of str to str
        Task type -> the component kind it targets (``tasks.contextual.TARGET_KIND``).
    settings : EvaluationSettings, optional
    model : str
        The model file the caller names (reported only; the evaluation trains its own).
    where : str
        Names the demonstrations in error messages.
    map_fn : callable, optional
        ``map``-like: applied to the independent jobs (one per fold, one per
        introspection pair) and returning their results in order; e.g. a process
        pool's ``map``. The result does not depend on it: every job draws from its own
        ``numpy.random.SeedSequence`` spawned from ``settings.seed``.

    Returns
    -------
    dict
        ``f05``, ``confusion``, ``introspection_entropy``, ``trajectory_rates``,
        ``n_runs``, ``folds``, ``seed``, ``model``, ``labels``, ``timings_s``.
    """
    settings = EvaluationSettings() if settings is None else settings
    check_demonstrations(demos, where)
    t_start = time.perf_counter()
    run = np.asarray(demos.run)
    task = np.asarray(demos.task).astype(str)
    labels = sorted(set(task.tolist()))
    label_index = {c: i for i, c in enumerate(labels)}
    run_ids = np.unique(run)
    if settings.folds > len(run_ids):
        raise ValueError(
            f"--folds: must be between 2 and the number of runs ({len(run_ids)}), got "
            f"{settings.folds}"
        )
    pairs = list(itertools.combinations(range(len(labels)), 2)) if len(labels) >= 3 else []
    seeds = np.random.SeedSequence(settings.seed).spawn(1 + settings.folds + len(pairs))
    run_task = [task[run == r][0] for r in run_ids]
    folds_of_runs = run_folds(run_task, settings.folds, np.random.default_rng(seeds[0]))
    fold_of_run = dict(zip(run_ids.tolist(), folds_of_runs, strict=True))
    u_norm = np.asarray(demos.u_norm, dtype=float)
    pts, ids, ckinds, off = _sorted_candidates(demos)
    q_cand, _ = candidate_features(pts, off, u_norm)
    data = _Data(
        settings=settings,
        kinds=dict(kinds),
        labels=labels,
        run=run,
        task=task,
        target=np.asarray(demos.target).astype(str),
        y=np.array([label_index[t] for t in task]),
        u_norm=u_norm,
        s=np.asarray(demos.s, dtype=float),
        fold=np.array([fold_of_run[r] for r in run.tolist()]),
        pts=pts,
        ids=ids,
        ckinds=ckinds,
        off=off,
        X_cand=encode(q_cand),
        X_true=encode(np.asarray(demos.q, dtype=float)),
    )
    jobs = [("fold", data, k, seeds[1 + k]) for k in range(settings.folds)]
    jobs += [("pair", data, p, seeds[1 + settings.folds + i]) for i, p in enumerate(pairs)]
    results = list(map_fn(_job, jobs))
    per_fold, per_pair = results[: settings.folds], results[settings.folds :]

    truth = [t for r in per_fold for t in r["truth"]]
    pred = {m: [p for r in per_fold for p in r["pred"][m]] for m in METHODS}
    ok = {m: [x for r in per_fold for x in r["ok"][m]] for m in METHODS}
    rec_rates = {rec: [x for r in per_fold for x in r["rates"][rec]] for rec in RECOGNISERS}
    intro = {m: {name: h[m] for name, h, _ in per_pair} for m in METHODS} if per_pair else {}
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
        "sogp_length_scale_cap": [r["cap"] for r in per_fold],
        "sogp_claim_threshold": [r["claim"] for r in per_fold],
        "trajectory_rates": {
            r: {
                key: float(np.mean([x[key] for x in rates])) if rates else float("nan")
                for key in ("success", "error", "null")
            }
            for r, rates in rec_rates.items()
        },
        "n_runs": int(len(run_ids)),
        "n_test_ticks": int(len(truth)),
        "folds": int(settings.folds),
        "seed": int(settings.seed),
        "model": model,
        "labels": labels,
        "timings_s": {  # seconds inside the jobs, summed (CPU-like), and the wall clock
            "classification": round(sum(r["t_cls"] for r in per_fold), 2),
            "trajectory_rates": round(sum(r["t_rec"] for r in per_fold), 2),
            "introspection": round(sum(t for _, _, t in per_pair), 2),
            "total": round(time.perf_counter() - t_start, 2),
        },
    }


def _introspect_pair(
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


def summarise_repeats(results: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Mean and spread of :func:`evaluate` results repeated with different seeds.

    One seed fixes one fold assignment and one draw of the negatives, subsamples and
    forests; the F0.5 of one classifier moves by a few hundredths between seeds, about
    as much as the classifiers differ on some task types, so a comparison worth
    publishing needs several (``asa evaluate --repeats``).

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


# --------------------------------------------------------------------------- report


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
