"""From a study database or CSV to tidy frames, statistics, figures and the report.

The jobs are plain functions (DESIGN.md, "Interfaces"): ``analysis.build_report`` (the
study report), ``analysis.analyse`` (the statistics of one metric), ``analysis.load_study``
(tidy frames); imported on first use.
"""

_LAZY = {
    "build_report": "analysis.report",
    "analyse": "analysis.stats",
    "load_study": "analysis.data",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'analysis' has no attribute {name!r}")
