"""Benchmark group ``push``: ``asa db push`` of an offline site's study database
(:func:`study.data.push.push`).

The site's file is the shipped pilot protocol with two sites, six synthetic participants
(one with ``quick``) run without recordings at site ``lyon``; it is pushed into a fresh
PostgreSQL database (the throwaway server of :mod:`study.data.pg_local`) and into a new
SQLite file, best of three each, and pushed again into the same destination (a push that
finds everything there: the comparison cost). Rows are every row of the site's study
(participants, sessions, trials, samples, events, questions, responses, order slots).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from sqlalchemy import func, select

REPEATS = 3


def _site_file(folder: Path, participants: int) -> Path:
    """The pilot study with sites, run at site lyon into ``folder/lyon.db``."""
    import protocols
    from study.jobs.synth import run_synthetic_study

    text = (Path(protocols.__file__).parent / "pilot.toml").read_text()
    text = text.replace("\nseed = 1\n", '\nseed = 1\nsites = ["lyon", "delft"]\n', 1)
    protocol = folder / "pilot_sites.toml"
    protocol.write_text(text)
    db = folder / "lyon.db"
    run_synthetic_study(str(protocol), db, participants=participants, seed=1, workers=2,
                        record=False, site="lyon")  # fmt: skip
    return db


def _rows(db: str | Path) -> int:
    """The rows of every table but ``meta``."""
    from study.data.storage import Base, open_database

    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return sum(
                int(conn.execute(select(func.count()).select_from(t)).scalar_one())
                for name, t in Base.metadata.tables.items()
                if name != "meta"
            )
    finally:
        engine.dispose()


def _timed(src: Path, make_db: Any) -> tuple[float, float]:
    """Best of :data:`REPEATS` (first push into a new database, the same push again) [s]."""
    from study.data.push import push

    first, again = [], []
    for _ in range(REPEATS):
        dst = make_db()
        t0 = time.perf_counter()
        push(src, dst)
        first.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        report = push(src, dst)
        again.append(time.perf_counter() - t0)
        if report.changed:
            raise RuntimeError("a second push of the same file changed the destination")
    return min(first), min(again)


def run(quick: bool) -> dict[str, Any]:
    """``push_rows`` (the site's rows), per destination (``postgresql``, ``sqlite``) the
    first push's and the repeated push's seconds and rows a second."""
    from study.data import pg_local

    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="asa-bench-push-") as tmp:
        folder = Path(tmp)
        src = _site_file(folder, 1 if quick else 6)
        rows = _rows(src)
        out["push_participants"] = 1 if quick else 6
        out["push_rows"] = rows
        files = (folder / f"hub{k}.db" for k in range(REPEATS))
        with pg_local.running() as server:
            timings = {"postgresql": _timed(src, server.new_database)}
        timings["sqlite"] = _timed(src, lambda: next(files))
    for backend, (first, again) in timings.items():
        out[f"push_{backend}_s"] = round(first, 3)
        out[f"push_{backend}_rows_per_s"] = round(rows / first)
        out[f"push_{backend}_again_s"] = round(again, 3)
    return out
