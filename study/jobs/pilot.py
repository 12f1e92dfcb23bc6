"""The pilot: a synthetic study of a protocol into a fresh folder, its database check,
report and sanity summary (``asa pilot``; thesis section 7.6)."""

from __future__ import annotations

import datetime as dt
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from study.data.dbtools import CheckReport
from study.participants.population import Population


@dataclass(frozen=True, slots=True)
class PilotResult:
    """What :func:`run_pilot` made, and where."""

    out: Path  # the pilot's folder
    db: Path  # out / "pilot.db"
    recordings: Path  # out / "pilot_recordings"
    report_html: Path  # the report's HTML page
    check: CheckReport  # the database check
    summary: dict[str, dict[str, Any]]  # study.jobs.synth.sanity_summary
    study_s: float  # [s] wall time of the synthetic study
    report_s: float  # [s] wall time of the report
    total_s: float  # [s] wall time of the whole pilot


def pilot_folder(out: Path | None) -> Path:
    """``out``, or ``pilot-<UTC timestamp>`` in the working folder when ``None``.

    Raises
    ------
    ValueError
        ``out`` exists and is not an empty folder.
    """
    if out is None:
        stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%d-%H%M%S")
        out = Path(f"pilot-{stamp}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"out: {out} exists and is not an empty folder; choose a new one")
    return out


def run_pilot(
    out: Path | None = None,
    *,
    participants: int = 18,
    workers: int | None = None,
    seed: int = 0,
    protocol: str | Path = "thesis-7-6",
    progress: Callable[[str], None] | None = None,
    population: Population | None = None,
) -> PilotResult:
    """Run a synthetic pilot study of ``protocol`` into a new folder and report on it.

    Parameters
    ----------
    out : Path, optional
        The pilot's folder, new or empty; default ``pilot-<UTC timestamp>/`` here. It
        receives ``pilot.db``, ``pilot_recordings/`` and ``report/``.
    participants : int
        Synthetic participants (the thesis had 18).
    workers : int, optional
        Worker processes; default the number of CPUs.
    seed : int
        The pilot's seed.
    protocol : str or Path
        A shipped protocol's name or a protocol file.
    progress : callable, optional
        Receives one line per step.
    population : Population, optional
        The synthetic population model; default ``Population()``.

    Returns
    -------
    PilotResult

    Raises
    ------
    ValueError
        A bad protocol, ``out`` not new or empty, or a bad option (naming the parameter).
    """
    from analysis.report import build_report
    from study.data.dbtools import check
    from study.engine.protocol import load_protocol
    from study.jobs.synth import run_synthetic_study, sanity_summary

    start = time.perf_counter()
    say = progress if progress is not None else (lambda line: None)
    p = load_protocol(protocol)
    out = pilot_folder(out)
    w = workers if workers is not None else (os.cpu_count() or 1)
    out.mkdir(parents=True, exist_ok=True)
    db = out / "pilot.db"
    say(f"{participants} synthetic participants of {p.name} with {w} workers into {out}/")
    study = run_synthetic_study(
        p, db, participants=participants, seed=seed, workers=w, progress=say,
        population=population,
    )  # fmt: skip
    say("checking the database")
    report = check(db)
    say("writing the report")
    paths = build_report(db, out / "report", progress=say)
    total_s = time.perf_counter() - start
    return PilotResult(
        out=out,
        db=db,
        recordings=out / "pilot_recordings",
        report_html=paths.html,
        check=report,
        summary=sanity_summary(db),
        study_s=study.wall_s,
        report_s=paths.seconds,
        total_s=total_s,
    )


def pilot_lines(result: PilotResult) -> list[str]:
    """Where everything is, the check's verdict, the times and the sanity summary."""
    from study.jobs.synth import format_summary

    clean = result.check.clean
    return [
        f"pilot folder:  {result.out.resolve()}",
        f"database:      {result.db.resolve()}",
        f"recordings:    {result.recordings.resolve()}",
        f"report:        {result.report_html.resolve()}",
        f"database check: {'clean' if clean else 'PROBLEMS (above)'}",
        f"time: study {result.study_s:.0f} s, report {result.report_s:.0f} s, "
        f"total {result.total_s:.0f} s",
        "sanity summary (main trials, per mode):",
        *format_summary(result.summary),
    ]
