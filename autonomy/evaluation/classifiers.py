"""The classifiers of the offline evaluation behind one interface: the SOGP classifier
(thesis Ch. 5) and scikit-learn's SVM, k-nearest neighbours and random forest, each
tuned on the training fold; recognition over a tick's candidates (Eq. 5.8)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.calibration import CalibratedClassifierCV
from sklearn.ensemble import RandomForestClassifier
from sklearn.metrics import fbeta_score
from sklearn.model_selection import GridSearchCV, StratifiedGroupKFold
from sklearn.neighbors import KNeighborsClassifier
from sklearn.svm import SVC

from autonomy.evaluation.inner_cv import sogp_inner_cv
from autonomy.evaluation.settings import EvaluationSettings
from autonomy.sogp_classifier import SOGPClassifier, argmax_finite


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


class FittedClassifier:
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
) -> FittedClassifier:
    """Fit one classifier on standardised features ``Z`` (n, 7), integer labels ``y`` (n,).

    The baselines are grid-searched with ``StratifiedGroupKFold`` by ``groups`` (runs);
    the SOGP's kernel hyperparameters maximise the evidence, its length-scale cap and
    claim threshold come from :func:`~autonomy.evaluation.inner_cv.sogp_inner_cv`
    (``tune=False``: the first cap of the grid and the first threshold, for the
    introspection, which needs neither). ``probability`` makes the SVM Platt-scaled.
    ``negatives`` (k, 7), with their runs ``negative_groups`` (k,), are features of no
    task: target -1 in every one-vs-all GP of the SOGP, an extra "none" class (label
    ``max(y) + 1``) for the baselines.
    """
    has_neg = negatives is not None and len(negatives) > 0
    if method == "sogp":
        neg = negatives if has_neg else None
        return _fit_sogp(Z, y, groups, neg, negative_groups, settings=settings, rng=rng, tune=tune)
    none = None
    if has_neg:
        none = int(np.max(y)) + 1
        Z = np.concatenate((Z, negatives))
        y = np.concatenate((y, np.full(len(negatives), none)))
        groups = np.concatenate((groups, negative_groups))
    classes, y = np.unique(y, return_inverse=True)  # 0..c-1 for scikit-learn's scorers
    seed = int(rng.integers(2**31 - 1))
    estimator, grid = _grid(method, settings, seed)
    params = _grid_search(method, estimator, grid, Z, y, groups, len(classes), settings)
    final = estimator.set_params(**params)
    if method == "svm" and probability:
        # Platt scaling, as SVC(probability=True) (deprecated in scikit-learn 1.9)
        final = CalibratedClassifierCV(final, method="sigmoid", cv=3, ensemble=False)
    final.fit(Z, y)
    return FittedClassifier(method, final, classes[final.classes_], none)


def _fit_sogp(
    Z: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    negatives: np.ndarray | None,
    negative_groups: np.ndarray | None,
    *,
    settings: EvaluationSettings,
    rng: np.random.Generator,
    tune: bool,
) -> FittedClassifier:
    """:func:`fit_method` for the SOGP classifier (``negatives`` None or non-empty)."""
    classes, yi = np.unique(y, return_inverse=True)
    caps = settings.sogp_length_scale_grid or (settings.max_length_scale,)
    cap, claim = float(caps[0]), np.full(len(classes), settings.sogp_claim_grid[0])
    if tune and (len(caps) > 1 or len(settings.sogp_claim_grid) > 1):
        cap, claim = sogp_inner_cv(
            Z, yi, groups, negatives, negative_groups, settings=settings, rng=rng
        )
    clf = SOGPClassifier(
        capacity=settings.capacity,
        hyper_points=settings.hyper_points,
        restarts=settings.hyper_restarts,
        max_length_scale=cap,
        refine=settings.sogp_refine,
    ).fit(Z, yi, rng=rng, negatives=negatives)
    return FittedClassifier("sogp", clf, classes[clf.classes_], claim=claim[clf.classes_])


def _grid_search(
    method: str,
    estimator: Any,
    grid: dict[str, list[Any]],
    Z: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    n_classes: int,
    settings: EvaluationSettings,
) -> dict[str, Any]:
    """The grid's best parameters by macro F0.5 in a ``StratifiedGroupKFold`` by
    ``groups`` (runs); ``{}`` when an inner split cannot hold two classes."""
    n_groups = len(np.unique(groups))
    cv = StratifiedGroupKFold(n_splits=min(settings.inner_folds, max(n_groups, 2)))
    if method == "knn" and n_groups >= 2:  # no more neighbours than a training split holds
        smallest = min(len(tr) for tr, _ in cv.split(Z, y, groups=groups))
        grid["n_neighbors"] = [k for k in grid["n_neighbors"] if k <= smallest] or [1]
    if not (
        n_groups >= 2  # a grid needs >= 2 classes in every inner training split
        and all(len(np.unique(y[tr])) >= 2 for tr, _ in cv.split(Z, y, groups=groups))
    ):
        return {}
    search = GridSearchCV(
        estimator,
        grid,
        scoring=_scorer(n_classes),
        cv=cv,
        refit=False,
        n_jobs=1,
    )
    search.fit(Z, y, groups=groups)
    return search.best_params_


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


def _candidate_rows(offsets: np.ndarray, ticks: np.ndarray) -> np.ndarray:
    """The candidate rows of ``ticks``, tick by tick."""
    return np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in ticks])


def recognise(
    fitted: FittedClassifier, Z_cand: np.ndarray, offsets: np.ndarray, ticks: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (5.8) per tick of ``ticks``: (winning candidate row or -1, winning task-class
    column) over ``fitted``'s task scores of its candidates (rows of ``Z_cand``,
    standardised; entries no task claims are NaN and never win)."""
    rows = _candidate_rows(offsets, ticks)
    S = np.full((len(Z_cand), len(fitted.task_classes)), np.nan)
    S[rows] = fitted.task_scores(Z_cand[rows])
    return _decide(S, offsets, ticks)


def most_probable(
    fitted: FittedClassifier, Z_cand: np.ndarray, offsets: np.ndarray, ticks: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (5.8) per tick of ``ticks`` without abstaining: (the most probable candidate
    row, its task-class column) by ``fitted``'s scores of the task classes, claim
    thresholds and the "none" class ignored; row -1 only for a tick without candidates.
    """
    rows = _candidate_rows(offsets, ticks)
    S = np.full((len(Z_cand), len(fitted.task_classes)), np.nan)
    scores = np.asarray(fitted.scores(Z_cand[rows]), dtype=float)
    S[rows] = scores if fitted.task_cols is None else scores[:, fitted.task_cols]
    return _decide(S, offsets, ticks)
