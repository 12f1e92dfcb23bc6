"""Crash-safe resume: a session killed at a random moment and resumed loses nothing that
was completed, aborts (and keeps) the trial that was running, runs it again, and passes
``asa db check``."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.dbtools import check
from study.data.storage import SessionRow, Trial, open_database
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.participants import ScriptedParticipant

PROTOCOL = """
[study]
name = "resume"
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]

[[phases]]
kind = "briefing"
text = "Test run."

[[phases]]
kind = "training"
scenario = "practice_course"
duration_s = 1.5
secondary = false
direct_view = true

[[phases]]
kind = "baseline"
questions = 2

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
block_size = 3
timeout_s = 60.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "raw"

[[phases]]
kind = "debrief"
text = "Done."
"""


class Crash(Exception):
    """Stands for the process dying."""


def _protocol(tmp_path: Path, seed: int) -> Path:
    path = tmp_path / "resume.toml"
    path.write_text(PROTOCOL.format(seed=seed % 1000), encoding="utf-8")
    return path


def _snapshot(db: Path) -> dict[int, tuple]:
    engine = open_database(db, create=False)
    with Session(engine) as s:
        rows = {
            t.id: (
                t.phase,
                t.ordinal,
                t.attempt,
                t.mode,
                t.status,
                t.completion_time_s,
                t.collisions,
                t.outcome,
                t.ended_at,
            )
            for t in s.scalars(select(Trial))
        }
    engine.dispose()
    return rows


def _check_resumed(before: dict[int, tuple], db: Path) -> None:
    after = _snapshot(db)
    for tid, row in before.items():
        if row[4] == "completed":
            assert after[tid] == row  # never repeated nor overwritten
        elif row[4] in ("running", "aborted"):
            assert after[tid][4] == "aborted"  # kept, marked aborted
            if row[4] == "aborted":
                assert after[tid] == row  # an exception already stored its end
            again = [r for i, r in after.items() if i > tid and r[:2] == row[:2]]
            assert any(r[4] == "completed" and r[2] > row[2] for r in again)
    # every (phase, ordinal) completed exactly once
    done = [r[:2] for r in after.values() if r[4] == "completed"]
    assert len(done) == len(set(done))
    assert {r[0] for r in after.values()} == {"training", "baseline", "main"}
    engine = open_database(db, create=False)
    with Session(engine) as s:
        session = s.scalars(select(SessionRow)).one()
        assert session.status == "completed" and session.resumed
    engine.dispose()
    report = check(db, verify_recordings=False)
    assert report.clean, report.text()


def test_exception_at_a_random_tick_then_resume(tmp_path, seed):
    protocol = load_protocol(_protocol(tmp_path, seed))
    db = tmp_path / "s.db"
    rng = np.random.default_rng(seed)
    crash_at = int(rng.integers(1, 400))  # ticks after the first trial completed
    state = {"first_done": False, "ticks": 0}

    def on_tick(tick, writer):
        if tick == 1 and writer.trial_id > 1:
            state["first_done"] = True
        if state["first_done"]:
            state["ticks"] += 1
            if state["ticks"] >= crash_at:
                raise Crash

    with pytest.raises(Crash):
        run_session(
            protocol,
            "P01",
            db,
            participant=ScriptedParticipant(np.random.default_rng(seed)),
            seed=seed,
            on_tick=on_tick,
        )
    before = _snapshot(db)
    # the exception stored the trial's rows and ended it as aborted, naming the error
    assert not any(r[4] == "running" for r in before.values())
    aborted = [r for r in before.values() if r[4] == "aborted"]
    assert len(aborted) == 1
    assert aborted[0][7]["aborted_reason"].startswith("error: Crash")
    assert aborted[0][8] is not None
    with pytest.raises(ValueError, match="already has a session"):
        run_session(
            protocol,
            "P01",
            db,
            participant=ScriptedParticipant(np.random.default_rng(seed)),
            seed=seed,
        )
    summary = run_session(
        protocol,
        "P01",
        db,
        participant=ScriptedParticipant(np.random.default_rng(seed)),
        seed=seed,
        resume=True,
    )
    assert summary.status == "completed" and summary.resumed
    _check_resumed(before, db)
    with pytest.raises(ValueError, match="nothing to resume"):
        run_session(
            protocol,
            "P01",
            db,
            participant=ScriptedParticipant(np.random.default_rng(seed)),
            seed=seed,
            resume=True,
        )


def _asa(*args: str) -> list[str]:
    return [sys.executable, "-m", "study.cli", *args]


def _progress(db: Path) -> tuple[int, int]:
    """(completed trials, stored samples) read directly, 0s while the schema is missing."""
    if not db.exists():
        return 0, 0
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)
        try:
            done = con.execute("SELECT count(*) FROM trial WHERE status = 'completed'")
            samples = con.execute("SELECT count(*) FROM sample")
            return int(done.fetchone()[0]), int(samples.fetchone()[0])
        finally:
            con.close()
    except sqlite3.Error:  # the schema is being created
        return 0, 0


def _kill_and_resume(tmp_path: Path, seed: int, protocol: Path) -> None:
    db = tmp_path / "k.db"
    args = [
        "--protocol", str(protocol), "--participant", "P01", "--db", str(db),
        "--seed", str(seed % 10_000),
    ]  # fmt: skip
    # the kill comes after a random number of further samples (the whole session stores
    # about 800, so the process is always still running)
    extra = int(np.random.default_rng(seed).integers(0, 450))
    proc = subprocess.Popen(
        _asa("run", *args), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        start_new_session=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        target = None
        while True:
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline
            done, samples = _progress(db)
            if target is None and done >= 1:
                target = samples + extra
            if target is not None and samples >= target:
                break
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        proc.stderr.close()
    before = _snapshot(db)
    done = subprocess.run(
        _asa("run", *args, "--resume"), capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    _check_resumed(before, db)
    done = subprocess.run(
        _asa("db", "check", "--db", str(db)), capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_sigkill_then_resume(tmp_path, seed):
    _kill_and_resume(tmp_path, seed, _protocol(tmp_path, seed))


@pytest.mark.slow
@pytest.mark.parametrize("offset", [1, 2, 3])
def test_sigkill_then_resume_many(tmp_path, seed, offset):
    _kill_and_resume(tmp_path, seed + offset, _protocol(tmp_path, seed + offset))
