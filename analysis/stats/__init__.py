"""One-way repeated-measures statistics (thesis Sec. 7.6.2; spec/algorithms.md, "Analysis").

Descriptives, the repeated-measures ANOVA, Mauchly's test of sphericity, the
Greenhouse-Geisser correction and Fisher's LSD for one metric measured once per participant
and level. Every public function takes a long-format DataFrame (one row per subject and
level) and the names of its three columns; :func:`analyse` runs the whole chain and returns
the JSON object that ``asa stats`` prints (one per metric in the report).
"""

from __future__ import annotations

from analysis.stats.anova import rm_anova
from analysis.stats.chain import GATES, analyse, gate_p, gate_source
from analysis.stats.design import RepeatedMeasures, descriptives, repeated_measures
from analysis.stats.posthoc import PAIR_COLUMNS, lsd_paired, lsd_pooled
from analysis.stats.sphericity import greenhouse_geisser, mauchly

__all__ = [
    "GATES",
    "PAIR_COLUMNS",
    "RepeatedMeasures",
    "analyse",
    "descriptives",
    "gate_p",
    "gate_source",
    "greenhouse_geisser",
    "lsd_paired",
    "lsd_pooled",
    "mauchly",
    "repeated_measures",
    "rm_anova",
]
