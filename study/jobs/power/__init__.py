"""Simulation-based power analysis on Dask (issue 22): the participant bank
(:mod:`study.jobs.power.bank`), the engine (:mod:`study.jobs.power.cluster`) and the job
(:mod:`study.jobs.power.run`)."""

from __future__ import annotations

from study.jobs.power.run import PowerSettings, PowerSummary, run_power

__all__ = ["PowerSettings", "PowerSummary", "run_power"]
