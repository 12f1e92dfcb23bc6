"""``asa calibrate``: a synthetic population fitted to a study's people (issue 39)."""

from study.jobs.calibrate.run import CalibrateSettings, CalibrationSummary, run_calibration

__all__ = ["CalibrateSettings", "CalibrationSummary", "run_calibration"]
