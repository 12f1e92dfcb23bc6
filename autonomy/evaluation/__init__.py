"""Offline evaluation of contextual-task recognition on held-out demonstrations (thesis
Sec. 7.2.2, 7.3, 7.4; issue 3, "Offline evaluation").

Task classification by cross-validation by run of the SOGP classifier (Ch. 5) against
an SVM, k-nearest neighbours and a random forest (F0.5, Table 7.6; ACR and MICAD,
Sec. 7.4.1, also of the kind-and-time recogniser on the fold's SOGP); introspection on
unseen task types (normalised entropy, Eq. 7.7, its histograms, Fig. 7.25, and MICAD,
Table 7.9; the kind-and-time recogniser's belief on seen and unseen task types);
success, error and null rates along held-out runs of the SOGP recogniser, the
kind-and-time recogniser, the Bayes filter (Ch. 4) and the exponential baseline in both
forms (Eqs. 7.4, 7.5), tuned on the training runs. Choices where the thesis is silent:
docs/decisions.md; measured figures: docs/results.md.
"""

from autonomy.evaluation.classifiers import FittedClassifier, fit_method
from autonomy.evaluation.correspondence import correspondence_rates, intra_cluster_dissimilarity
from autonomy.evaluation.cross_validation import evaluate
from autonomy.evaluation.folds import (
    EvaluationData,
    candidate_features,
    check_demonstrations,
    hard_negatives,
    run_folds,
    way_points_of,
)
from autonomy.evaluation.introspection import PairResult, entropy_histogram, entropy_rank
from autonomy.evaluation.jobs import FoldResult
from autonomy.evaluation.kind_time import Replay, fit_prior, replay_run
from autonomy.evaluation.metrics import confusion_with_targets, f05_with_targets
from autonomy.evaluation.report import summarise_repeats
from autonomy.evaluation.settings import (
    CORRESPONDENCE,
    KIND_TIME,
    METHODS,
    RECOGNISERS,
    WRONG_TARGET,
    EvaluationSettings,
)
from autonomy.evaluation.text import format_report

__all__ = [
    "CORRESPONDENCE",
    "KIND_TIME",
    "METHODS",
    "RECOGNISERS",
    "WRONG_TARGET",
    "EvaluationData",
    "EvaluationSettings",
    "FittedClassifier",
    "FoldResult",
    "PairResult",
    "Replay",
    "candidate_features",
    "check_demonstrations",
    "confusion_with_targets",
    "correspondence_rates",
    "entropy_histogram",
    "entropy_rank",
    "evaluate",
    "f05_with_targets",
    "fit_method",
    "fit_prior",
    "format_report",
    "hard_negatives",
    "intra_cluster_dissimilarity",
    "replay_run",
    "run_folds",
    "summarise_repeats",
    "way_points_of",
]
