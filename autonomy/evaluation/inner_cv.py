"""The SOGP classifier's inner cross-validation in the offline evaluation: its
length-scale cap and a claim threshold per class, chosen on the training fold by the
baselines' grid-search score (thesis Sec. 5.3, 7.3.1)."""

from __future__ import annotations

import numpy as np
from sklearn.metrics import fbeta_score
from sklearn.model_selection import StratifiedGroupKFold

from autonomy.evaluation.settings import EvaluationSettings
from autonomy.sogp_classifier import SOGPClassifier

# per cap of the grid, per inner split: (validation means (v, c), validation labels (v,))
_Fits = list[list[tuple[np.ndarray, np.ndarray]]]


def sogp_inner_cv(
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
    fits = _inner_fits(Za, ya, list(cv.split(Za, ya, groups=ga)), caps, none, settings, rng)
    if not fits[0]:
        return float(caps[0]), first
    labels = list(range(none + (1 if has_neg else 0)))
    best: tuple[float, int, np.ndarray] = (-np.inf, 0, first)
    for i in range(len(caps)):
        claim = _coordinate_ascent(fits[i], first.copy(), grid, none, labels)
        value = _score(fits[i], claim, none, labels)
        if value > best[0]:
            best = (value, i, claim)
    return float(caps[best[1]]), best[2]


def _inner_fits(
    Za: np.ndarray,
    ya: np.ndarray,
    splits: list[tuple[np.ndarray, np.ndarray]],
    caps: tuple[float, ...],
    none: int,
    settings: EvaluationSettings,
    rng: np.random.Generator,
) -> _Fits:
    """One SOGP classifier per cap and inner split (label ``none``: negatives); its
    posterior means on the split's validation rows, -inf for a class it lacks."""
    fits: _Fits = [[] for _ in caps]
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
    return fits


def _score(
    fits: list[tuple[np.ndarray, np.ndarray]], claim: np.ndarray, none: int, labels: list[int]
) -> float:
    """Summed macro F0.5 over the inner splits of the decision under ``claim`` (c,)."""
    total = 0.0
    for means, truth in fits:
        M = np.where(means >= claim, means, -np.inf)
        pred = np.where(np.isfinite(M.max(axis=1)), np.argmax(M, axis=1), none)
        total += fbeta_score(truth, pred, beta=0.5, average="macro", labels=labels, zero_division=0)
    return total


def _coordinate_ascent(
    fits: list[tuple[np.ndarray, np.ndarray]],
    claim: np.ndarray,
    grid: np.ndarray,
    none: int,
    labels: list[int],
) -> np.ndarray:
    """The claim thresholds (c,), class by class from ``claim``, two sweeps over the
    classes; ``claim`` is updated in place and returned."""
    for _sweep in range(2):
        for c in range(none):
            values = []
            for t in grid:
                claim[c] = t
                values.append(_score(fits, claim, none, labels))
            claim[c] = grid[int(np.argmax(values))]  # first maximum: ties early
    return claim
