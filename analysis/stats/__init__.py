"""One-way repeated-measures statistics (thesis Sec. 7.6.2; spec/algorithms.md, "Analysis").

Descriptives, the repeated-measures ANOVA, Mauchly's test of sphericity, the
Greenhouse-Geisser correction and Fisher's LSD for one metric measured once per participant
and level (thesis); issue 21 adds effect sizes with CIs (effects), assumption checks
(assumptions), Holm and Bonferroni pairs (posthoc), Friedman and Wilcoxon (nonparametric),
mixed models and order effects (mixed) and APA text (apa). Every public function takes a
long-format DataFrame (one row per subject and level) and the names of its three columns;
:func:`analyse` runs the whole chain and returns the JSON object that ``asa stats`` prints
(one per metric in the report).
"""

from __future__ import annotations

from analysis.stats.anova import rm_anova
from analysis.stats.chain import (
    GATES,
    POSTHOC,
    POSTHOC_GATES,
    analyse,
    gate_p,
    gate_source,
    lsd_warning,
    posthoc_gated,
)
from analysis.stats.design import RepeatedMeasures, descriptives, repeated_measures
from analysis.stats.nonparametric import TESTS, choose_test
from analysis.stats.posthoc import PAIR_COLUMNS, lsd_paired, lsd_pooled, paired_adjusted
from analysis.stats.sphericity import greenhouse_geisser, mauchly

__all__ = [
    "GATES",
    "PAIR_COLUMNS",
    "POSTHOC",
    "POSTHOC_GATES",
    "TESTS",
    "RepeatedMeasures",
    "analyse",
    "choose_test",
    "descriptives",
    "gate_p",
    "gate_source",
    "greenhouse_geisser",
    "lsd_paired",
    "lsd_pooled",
    "lsd_warning",
    "mauchly",
    "paired_adjusted",
    "posthoc_gated",
    "repeated_measures",
    "rm_anova",
]
