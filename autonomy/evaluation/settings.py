"""Settings of the offline evaluation of recognisers (thesis Sec. 7.3, 7.4)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from autonomy.contextual import ContextualSettings
from autonomy.kind_time import KindTimeSettings
from autonomy.training import TrainSettings

_SHIPPED = TrainSettings()  # the SOGP is evaluated as `asa train` builds it
_MODE = ContextualSettings()  # the kind-and-time recogniser as the contextual mode runs it

METHODS: tuple[str, ...] = ("sogp", "svm", "knn", "rf")
KIND_TIME = "kind_time"  # the kind-and-time recogniser (autonomy.kind_time) on the SOGP
# ACR and MICAD (Sec. 7.4.1): the classifiers' Eq. (5.8) winner and the kind-and-time
# recogniser's most believed candidate
CORRESPONDENCE: tuple[str, ...] = (*METHODS, KIND_TIME)
# "baseline": Eq. (7.5), the psi form; "baseline_theta": Eq. (7.4), both tuned per fold
RECOGNISERS: tuple[str, ...] = ("sogp", KIND_TIME, "bayes_filter", "baseline", "baseline_theta")
WRONG_TARGET = "wrong_target"


@dataclass(frozen=True, slots=True)
class EvaluationSettings:
    """Settings of :func:`autonomy.evaluation.evaluate` (choices: docs/decisions.md)."""

    folds: int = 5
    seed: int = 0
    stride: int = 4  # training way points: every 4th moving tick (5 Hz)
    test_stride: int = 2  # classification scored on every 2nd held-out tick
    capacity: int = _SHIPPED.capacity  # SOGP basis vectors per class
    hyper_points: int = _SHIPPED.hyper_points  # class-balanced subsample for the evidence
    hyper_restarts: int = _SHIPPED.hyper_restarts
    max_length_scale: float = _SHIPPED.max_length_scale
    inner_folds: int = 3  # grid search: StratifiedGroupKFold by run in the training fold
    rf_trees: int = 60
    negatives: bool = True  # hard negatives (other candidates) for every classifier
    negatives_per_tick: int = _SHIPPED.negatives_per_tick  # wrong candidates per way point
    sogp_length_scale_grid: tuple[float, ...] = (_SHIPPED.max_length_scale,)  # inner-CV grid
    sogp_claim_grid: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)  # per class
    sogp_inner_folds: int = 2
    sogp_refine: bool = _SHIPPED.refine  # re-estimate each GP on its basis after the pass
    kind_time: KindTimeSettings = field(default_factory=lambda: _MODE.kind_time)
    min_input: float = _MODE.min_input  # |u_xy| (normalised) below: a tick without input

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
            raise ValueError(f"folds: must be an integer >= 2, got {self.folds!r}")
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
