"""Benchmark group ``storage``: the study database under the trial loop's writes, on
SQLite and on a local PostgreSQL server (issue 24).

Rows are the trial loop's own: a :class:`study.engine.events.TrialWriter` buffers one
sample row per 20 Hz tick and commits every ``FLUSH_EVERY_TICKS`` ticks (one simulated
second). ``sample_rows_per_s``: one writer writing a trial's samples as fast as it can.
``concurrent_sessions``: K sessions in K processes, each writing one second's batch of
samples every wall second for ``DURATION_S``; a level is sustained when every batch of
every session was committed within ``MAX_LAG_S`` of the second it ended, without an
error. The PostgreSQL server is started for the run (:mod:`study.data.pg_local`) and
stopped after. The figures are listed in :func:`run`.
"""

from __future__ import annotations

import multiprocessing
import queue
import tempfile
import time
from pathlib import Path
from typing import Any

from sqlalchemy import Engine
from sqlalchemy.orm import Session

from study.data.storage import Participant, SessionRow, Study, open_database
from study.engine.events import TrialWriter
from study.engine.trial import FLUSH_EVERY_TICKS

TICK_S = 0.05  # [s] the control tick (20 Hz)
LEVELS = (1, 2, 4, 8, 16)  # concurrent sessions tried, up to 16 (issue 24)
DURATION_S = 10.0  # [s] wall time each concurrent session writes; quick: 4
MAX_LAG_S = 1.0  # [s] a batch committed later than this after its second is too late
ROWS = 20_000  # sample rows of the single writer; quick: 4,000


def _sample(trial_id: int, tick: int) -> dict[str, Any]:
    """One tick's sample row, with values of the usual kinds."""
    t = tick * TICK_S
    return {
        "trial_id": trial_id, "tick": tick, "t": t, "x": 1.0 + 0.01 * tick, "y": 2.0,
        "yaw": 0.1, "u_x": 0.5, "u_y": 0.0, "u_w": 0.1, "v_x": 0.45, "v_y": 0.0,
        "v_w": 0.08, "beta": 0.3, "label": "doorway_crossing", "target": "doorway_1",
        "min_clearance_m": 0.42, "in_region": tick % 2 == 0, "true_task": "doorway_crossing",
        "true_target": "doorway_1",
    }  # fmt: skip


def _sessions(engine: Engine, n: int) -> list[tuple[int, int]]:
    """One study with ``n`` participants and a session each: ``(participant id, session
    id)`` per session."""
    with Session(engine) as s, s.begin():
        study = Study(
            name="storage-bench", protocol_text="", protocol_sha256="0" * 64,
            platform_version="bench", seed=0,
        )  # fmt: skip
        s.add(study)
        s.flush()
        out = []
        for k in range(n):
            person = Participant(
                study_id=study.id, code=f"S{k + 1:02d}", kind="synthetic", parameters={},
                order_index=k, mode_order=["manual"], seed=k,
            )  # fmt: skip
            s.add(person)
            s.flush()
            row = SessionRow(participant_id=person.id)
            s.add(row)
            s.flush()
            out.append((person.id, row.id))
    return out


def _writer(engine: Engine, person_id: int, session_id: int) -> TrialWriter:
    writer = TrialWriter(engine, session_id)
    values = {
        "participant_id": person_id, "session_id": session_id, "phase": "main",
        "mode": "manual", "ordinal": 0, "attempt": 0, "scenario": "bench", "seed": 0,
    }  # fmt: skip
    writer.start(values, lambda trial_id: "")
    return writer


def sample_rows_per_s(db: str, rows: int) -> float:
    """Sample rows a second one writer commits, in the trial loop's batches."""
    engine = open_database(db)
    try:
        ((person_id, session_id),) = _sessions(engine, 1)
        writer = _writer(engine, person_id, session_id)
        start = time.perf_counter()
        for tick in range(1, rows + 1):
            writer.samples.append(_sample(writer.trial_id, tick))
            if tick % FLUSH_EVERY_TICKS == 0:
                writer.flush(tick)
        return rows / (time.perf_counter() - start)
    finally:
        engine.dispose()


def _session(db: str, ids: tuple[int, int], duration: float, barrier: Any, out: Any) -> None:
    """One concurrent session (in its own process, with its own engine): a batch a
    wall second; puts ``(largest lag [s], batches, error or "")`` on ``out``."""
    engine = open_database(db)
    lag, batches, error = 0.0, 0, ""
    try:
        writer = _writer(engine, *ids)
        barrier.wait()
        start, tick = time.perf_counter(), 0
        while (batches + 1) <= duration:
            due = start + batches + 1  # this batch's second ends
            time.sleep(max(0.0, due - time.perf_counter()))
            for _ in range(FLUSH_EVERY_TICKS):
                tick += 1
                writer.samples.append(_sample(writer.trial_id, tick))
            writer.flush(tick)
            lag = max(lag, time.perf_counter() - due)
            batches += 1
    except Exception as exc:  # reported, not raised: the figure counts it
        error = f"{type(exc).__name__}: {exc}"
    finally:
        engine.dispose()
        out.put((lag, batches, error))


def _collect(procs: list[Any], out: Any, deadline: float) -> list[tuple[float, int, str]]:
    """The sessions' results; a process that died without one counts as an error."""
    results: list[tuple[float, int, str]] = []
    while len(results) < len(procs) and time.monotonic() < deadline:
        try:
            results.append(out.get(timeout=1.0))
        except queue.Empty:
            if not any(p.is_alive() for p in procs) and out.empty():
                break
    dead = [p.exitcode for p in procs if p.exitcode not in (0, None)]
    missing = len(procs) - len(results)
    results += [(0.0, 0, f"a session process ended without a result (exit {dead})")] * missing
    return results


def concurrent_level(db: str, sessions: int, duration: float) -> dict[str, Any]:
    """``sessions`` concurrent sessions on a new study in ``db``: the largest lag [s],
    the batches written and the errors."""
    engine = open_database(db)
    try:
        ids = _sessions(engine, sessions)
    finally:
        engine.dispose()
    ctx = multiprocessing.get_context("spawn")
    barrier, out = ctx.Barrier(sessions), ctx.Queue()
    procs = [ctx.Process(target=_session, args=(db, pair, duration, barrier, out)) for pair in ids]
    for p in procs:
        p.start()
    results = _collect(procs, out, deadline=time.monotonic() + 300 + duration)
    for p in procs:
        p.join(timeout=60)
    return {
        "max_lag_s": round(max(r[0] for r in results), 4),
        "batches": sum(r[1] for r in results),
        "errors": [r[2] for r in results if r[2]],
    }


def concurrent_sessions(make_db: Any, duration: float) -> dict[str, Any]:
    """The levels of :data:`LEVELS` in turn (each on a fresh database from
    ``make_db()``) until one is not sustained: per level its result, and the largest
    sustained level (0 if none)."""
    levels, best = {}, 0
    for k in LEVELS:
        result = concurrent_level(make_db(), k, duration)
        levels[str(k)] = result
        if result["errors"] or result["max_lag_s"] > MAX_LAG_S:
            break
        best = k
    return {"sustained": best, "levels": levels}


def _backend(make_db: Any, quick: bool) -> dict[str, Any]:
    return {
        "sample_rows_per_s": round(sample_rows_per_s(make_db(), ROWS // 5 if quick else ROWS)),
        "concurrent_sessions": concurrent_sessions(make_db, 4.0 if quick else DURATION_S),
    }


def run(quick: bool) -> dict[str, Any]:
    """Per backend (``sqlite``, ``postgresql``): ``sample_rows_per_s`` and
    ``concurrent_sessions`` (``sustained``: the most 20 Hz sessions, of 1, 2, 4, 8, 16,
    whose every batch committed within ``MAX_LAG_S``; per level ``max_lag_s``,
    ``batches``, ``errors``); ``storage_sqlite_concurrent_sessions`` and
    ``storage_postgresql_concurrent_sessions`` the sustained levels."""
    from study.data import pg_local

    with tempfile.TemporaryDirectory(prefix="asa-bench-storage-") as tmp:
        files = (Path(tmp) / f"s{k}.db" for k in range(100))
        sqlite = _backend(lambda: str(next(files)), quick)
        with pg_local.running() as server:
            postgresql = _backend(server.new_database, quick)
    return {
        "storage": {"sqlite": sqlite, "postgresql": postgresql},
        "storage_sqlite_rows_per_s": sqlite["sample_rows_per_s"],
        "storage_postgresql_rows_per_s": postgresql["sample_rows_per_s"],
        "storage_sqlite_concurrent_sessions": sqlite["concurrent_sessions"]["sustained"],
        "storage_postgresql_concurrent_sessions": postgresql["concurrent_sessions"]["sustained"],
    }
