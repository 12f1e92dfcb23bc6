"""From a study database (or the CSV folder of ``asa export``) to tidy pandas frames.

Thesis Sec. 7.6.1.3 and 7.6.2 (spec section 7): per main trial the primary-task metrics, the
secondary questions (with the baseline block as a further level) and the NASA-TLX; Sec. 7.5
adds clearance to obstacles (Fig. 7.44b). :func:`load_study` reads the raw tables into a
:class:`StudyData`; :func:`tidy` turns it into :class:`Frames`.
"""

from __future__ import annotations

from analysis.data.frames import ASSIST_THRESHOLD, BASELINE, Frames, secondary_metrics, tidy
from analysis.data.load import TABLES, AnalysisConfig, StudyData, load_study, read_config

__all__ = [
    "ASSIST_THRESHOLD",
    "BASELINE",
    "TABLES",
    "AnalysisConfig",
    "Frames",
    "StudyData",
    "load_study",
    "read_config",
    "secondary_metrics",
    "tidy",
]
