"""Concurrent writers on one SQLite study (issue 20, Done when): two ``asa synth`` and four
``asa run`` processes started together; afterwards every participant is complete or absent,
``asa db check`` is clean and every order slot is issued once. Also: a second synthetic
study waits for the first, a merge refuses an unfinished participant, a session cannot run
twice at once, and the study's identity is checked on every write."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data import locks
from study.data.dbtools import check
from study.data.merge import merge_participant
from study.data.storage import OrderSlot, Participant, SessionRow, Study, open_database
from study.engine.counterbalance import balance
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.jobs.synth import run_synthetic_study
from study.participants.scripted import ScriptedParticipant
from tests.mini_protocol import mini_protocol

# the smallest study that still has questionnaires: two main trials of 2 s, no camera
MINI = mini_protocol(camera_hz=0, experience=True, tlx=True)

RUN_CODES = ("golf", "x7y", "P000", "hotel-2")  # codes of every shape, beside P01..P04


def _mini(tmp_path: Path) -> Path:
    path = tmp_path / "mini.toml"
    path.write_text(MINI)
    return path


def _asa(*args: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    return subprocess.Popen(
        [sys.executable, "-m", "study.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def test_two_synths_and_four_runs_on_one_study(tmp_path, seed):
    proto, db = str(_mini(tmp_path)), tmp_path / "study.db"
    s = str(seed % 1000)
    synth = ["synth", "--protocol", proto, "--participants", "2", "--seed", s,
             "--workers", "1", "--db", str(db)]  # fmt: skip
    procs = [_asa(*synth), _asa(*synth)]
    procs += [
        _asa("run", "--protocol", proto, "--participant", code, "--db", str(db),
             "--input", "synthetic")
        for code in RUN_CODES
    ]  # fmt: skip
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (_out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err
    assert sum("waiting" in err for _, err in outs[:2]) <= 1
    assert any("2 participant(s) already in" in err for _, err in outs[:2])

    report = check(db)
    assert report.clean, report.text()
    engine = open_database(db, create=False)
    with Session(engine) as sess:
        assert len(sess.scalars(select(Study)).all()) == 1  # one study row, made once
        people = sess.scalars(select(Participant)).all()
        assert {p.code for p in people} == {"P01", "P02", *RUN_CODES}
        assert {r.status for r in sess.scalars(select(SessionRow))} == {"completed"}
        slots = sess.scalars(select(OrderSlot).order_by(OrderSlot.slot)).all()
        assert [r.slot for r in slots] == list(range(6))  # every slot issued once
        assert {r.code for r in slots} == {p.code for p in people}
        assert all(r.status == "issued" for r in slots)
        by_code = {p.code: p for p in people}
        assert all(by_code[r.code].order_index == r.slot % 2 for r in slots)
        assert balance([p.mode_order for p in people], scheme="full_permutation")["balanced"]
        # the two synthetic studies did not mix: P01, P02 merged once each, in order
        merged = sorted((p.id, p.code) for p in people if "synthetic_study_seed" in p.parameters)
        assert [c for _, c in merged] == ["P01", "P02"]
    engine.dispose()
    assert not (tmp_path / "study_work").exists()


def test_a_second_synth_waits_for_the_first(tmp_path, seed):
    db = tmp_path / "s.db"
    lines: list[str] = []
    lock = locks.synth_lock(db)
    with locks.held(lock, wait=False):
        assert locks.is_held(lock)
        with pytest.raises(locks.LockHeld):
            with locks.held(lock, wait=False):
                pass
    assert not locks.is_held(lock)
    # held by another process: the synthetic study says so and waits
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from pathlib import Path; from study.data import locks\n"
         f"with locks.held(Path({str(lock)!r}), wait=False):\n"
         "    print('held', flush=True); time.sleep(3)"],
        stdout=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])},
    )  # fmt: skip
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    start = time.perf_counter()
    summary = run_synthetic_study(
        str(_mini(tmp_path)), db, participants=1, seed=seed % 1000, progress=lines.append
    )
    holder.wait(timeout=60)
    assert any("another synthetic study" in line and "waiting" in line for line in lines)
    assert time.perf_counter() - start > 1.0 and summary.run == ("P01",)


def test_a_merge_takes_only_a_finished_participant(tmp_path, seed):
    protocol = load_protocol(str(_mini(tmp_path)))
    work = tmp_path / "P01.db"
    run_session(protocol, "P01", work, participant=ScriptedParticipant(
        np.random.default_rng(seed)), seed=seed, lock=False, slot=0)  # fmt: skip
    engine = open_database(work)
    with Session(engine) as s, s.begin():
        s.scalars(select(SessionRow)).one().status = "running"  # half-finished
    engine.dispose()
    dst = open_database(tmp_path / "study.db")
    with pytest.raises(ValueError, match="not finished"):
        merge_participant(work, dst, src_folder=tmp_path, dst_folder=tmp_path)
    dst.dispose()


def test_a_session_cannot_run_twice_at_once(tmp_path, seed):
    protocol = load_protocol(str(_mini(tmp_path)))
    db = tmp_path / "s.db"
    with locks.held(locks.session_lock(db, "P01"), wait=False):
        with pytest.raises(ValueError, match="running in another process"):
            run_session(protocol, "P01", db, participant=ScriptedParticipant(
                np.random.default_rng(seed)))  # fmt: skip


def test_the_study_identity_is_checked_on_every_write(tmp_path, seed):
    proto = _mini(tmp_path)
    db = tmp_path / "s.db"
    s = seed % 1000
    run_synthetic_study(str(proto), db, participants=1, seed=s)
    with pytest.raises(ValueError, match=r"synthetic_study_seed': the study has \d+, this run"):
        run_synthetic_study(str(proto), db, participants=2, seed=s + 1)
    forced = run_synthetic_study(str(proto), db, participants=2, seed=s + 1, force=True)
    assert forced.run == ("P02",)
    engine = open_database(db, create=False, readonly=False)
    with Session(engine) as sess:
        rows = sess.scalars(select(SessionRow).order_by(SessionRow.id)).all()
        assert [r.forced for r in rows] == [False, True]
        assert "synthetic_study_seed" in rows[1].note and str(s + 1) in rows[1].note
        sess.scalars(select(Study)).one().platform_version = "0.0.1"
        sess.commit()
    engine.dispose()
    protocol = load_protocol(str(proto))
    who = ScriptedParticipant(np.random.default_rng(seed))
    with pytest.raises(ValueError, match=r"'study.platform_version': the study has 0.0.1"):
        run_session(protocol, "golf", db, participant=who)
    summary = run_session(protocol, "golf", db, participant=who, force=True)
    assert summary.forced and "platform_version" in summary.note
    result = subprocess.run(
        [sys.executable, "-m", "study.cli", "synth", "--protocol", str(proto),
         "--participants", "2", "--seed", str(s + 2), "--db", str(db)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 2 and "Traceback" not in result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert str(db) in line and f"has {s}, this run {s + 2}" in line and "--force" in line
