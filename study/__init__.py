"""The study: protocols, counterbalancing, sessions, participants, storage,
recording and the ``asa`` command line.

The jobs of the command line are plain functions first (DESIGN.md, "Interfaces"):
``study.run_session`` (one participant's session), ``study.run_synthetic_study`` (a whole
study of synthetic participants), ``study.run_pilot`` (a pilot study and its report),
``study.run_power`` (a simulation-based power analysis on Dask, with ``study.PowerSettings``),
``study.load_protocol``; they are imported on first use, so ``import study`` stays light.
"""

import os
from importlib.metadata import PackageNotFoundError, version

# pygame prints a banner to stdout on import, which would corrupt `asa ... --json` output
# (the screen's modules and the camera's worker process import it); keep it quiet.
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

try:
    __version__ = version("asa-study")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"


_LAZY = {
    "run_session": "study.engine.session",
    "run_synthetic_study": "study.jobs.synth",
    "run_pilot": "study.jobs.pilot",
    "run_power": "study.jobs.power",
    "PowerSettings": "study.jobs.power",
    "load_protocol": "study.engine.protocol",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'study' has no attribute {name!r}")
