"""Benchmark group ``report``: wall seconds of :func:`analysis.report.build_report`.

``report_s`` is the wall time of a full report (every metric, every figure, PNG and SVG) on
an 18-participant, 3-mode database written by the test suite's generator
(``tests/fixtures_db.py``, 240 samples and 20 questions per main trial, seeded); generating
the database is not timed. ``report_db_s`` is the generation time, for reference. The
generator lives with the tests, so this group needs the source checkout (the project is
installed editable); without it the group raises ``ValueError``.
"""

from __future__ import annotations

import importlib.util
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

N_PARTICIPANTS = 18
SEED = 7061


def _generator():
    path = Path(__file__).resolve().parents[2] / "tests" / "fixtures_db.py"
    if not path.is_file():
        raise ValueError(
            f"benchmark group 'report': needs {path} (the source checkout's test generator)"
        )
    spec = importlib.util.spec_from_file_location("asa_fixtures_db", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    assert spec.loader is not None  # a file spec always has a loader
    spec.loader.exec_module(module)
    return module


def run(quick: bool = False) -> dict:
    """``report_s`` (and ``report_db_s``, ``report_figure_files``); ``quick`` uses 6
    participants instead of 18."""
    fixtures = _generator()
    n = 6 if quick else N_PARTICIPANTS
    settings = replace(fixtures.FixtureSettings(), n_participants=n)
    from analysis.report import build_report

    with tempfile.TemporaryDirectory(prefix="asa-bench-report-") as tmp:
        db = Path(tmp) / "study.db"
        t0 = time.perf_counter()
        fixtures.make_study_db(db, np.random.default_rng(SEED), settings=settings)
        t1 = time.perf_counter()
        paths = build_report(db, Path(tmp) / "report")
        t2 = time.perf_counter()
    return {
        "report_participants": n,
        "report_s": round(t2 - t1, 3),
        "report_db_s": round(t1 - t0, 3),
        "report_metrics": len(paths.metrics),
        "report_figure_files": len(paths.figures),
    }
