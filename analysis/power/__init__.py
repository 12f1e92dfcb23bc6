"""Simulation-based power analysis (issue 22): studies resampled from a bank of synthetic
participants (:mod:`analysis.power.resample`), power curves with binomial CIs and the
smallest sample size per planned test (:mod:`analysis.power.summary`), and the report
(:mod:`analysis.power.report`, imported on its own: the workers that resample need no
matplotlib). The bank itself is built by ``study.jobs.power`` (it drives the simulator);
this package only counts."""

from __future__ import annotations

from analysis.power.resample import (
    OMNIBUS,
    Batch,
    PlannedTests,
    check_size,
    draw_study,
    pair_key,
    resample_batch,
    slot_pools,
    study_rng,
)
from analysis.power.summary import (
    CI_LEVEL,
    TARGET_POWER,
    bank_effects,
    clopper_pearson,
    curve,
    describe_n,
    n_for_power,
    summary_lines,
    tally,
)

__all__ = [
    "CI_LEVEL",
    "OMNIBUS",
    "TARGET_POWER",
    "Batch",
    "PlannedTests",
    "bank_effects",
    "check_size",
    "clopper_pearson",
    "curve",
    "describe_n",
    "draw_study",
    "n_for_power",
    "pair_key",
    "resample_batch",
    "slot_pools",
    "study_rng",
    "summary_lines",
    "tally",
]
