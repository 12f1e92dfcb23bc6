"""The session engine never loses data and never shows a traceback for bad input: unusable
database files, trials that raise, failing flushes, recordings that already exist,
impossible trial specs, huge participant numbers, and the same seed giving the same data."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select, text
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from study.data.storage import (
    Event,
    Participant,
    Sample,
    SessionRow,
    Study,
    Trial,
    open_database,
)
from study.engine.protocol import parse_protocol
from study.engine.session import run_session
from study.engine.trial import TrialSpec, TrialWriter, recording_relpath
from study.participants import ScriptedParticipant
from tasks.primary import PrimarySettings

PROTOCOL = """
[study]
name = "robust"
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "{scheme}"

[[phases]]
kind = "baseline"
questions = 2

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 60.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "raw"
"""


def _protocol(seed: int, scheme: str = "full_permutation"):
    return parse_protocol(PROTOCOL.format(seed=seed % 1000, scheme=scheme), "robust.toml")


def _asa(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize("kind", ["not_sqlite", "missing_folder"])
def test_unusable_database_is_one_line_and_exit_2(tmp_path, kind):
    if kind == "not_sqlite":
        db = tmp_path / "notes.db"
        db.write_text("these are my notes, not a database\n", encoding="utf-8")
    else:
        db = tmp_path / "no" / "such" / "folder" / "s.db"
    for args in (
        ["db", "check", "--db", str(db)],
        ["run", "--protocol", "pilot", "--participant", "P01", "--db", str(db)],
    ):
        done = _asa(*args)
        assert done.returncode == 2, done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and str(db) in lines[0] and "Traceback" not in done.stderr
    if kind == "not_sqlite":  # never touched
        assert db.read_text(encoding="utf-8").startswith("these are my notes")


def test_sqlite_is_durable_and_waits_for_locks(tmp_path):
    engine = open_database(tmp_path / "s.db")
    with engine.connect() as con:
        assert con.execute(text("PRAGMA synchronous")).scalar() == 2  # FULL
        assert con.execute(text("PRAGMA busy_timeout")).scalar() >= 1000
        assert con.execute(text("PRAGMA journal_mode")).scalar() == "wal"
    engine.dispose()
    scratch = open_database(tmp_path / "scratch.db", durable=False)  # synth's work files
    with scratch.connect() as con:
        assert con.execute(text("PRAGMA synchronous")).scalar() == 0  # OFF
    scratch.dispose()


def test_trial_specs_that_could_never_end_are_refused():
    primary = PrimarySettings(route=("dock",), inspection_required=False, timeout_s=10.0)
    common = dict(phase="main", ordinal=0, attempt=0, mode="manual", seed=1, instruction="")
    TrialSpec(**common, primary=primary, secondary=None)  # fine
    with pytest.raises(ValueError, match="primary"):
        TrialSpec(**common, primary=None, secondary=None)
    with pytest.raises(ValueError, match="secondary"):
        TrialSpec(**{**common, "phase": "baseline", "mode": ""}, primary=None, secondary=None,
                  baseline=True)  # fmt: skip
    with pytest.raises(ValueError, match="camera_hz"):
        TrialSpec(**common, primary=primary, secondary=None, camera_hz=-1.0)


def test_existing_recordings_are_never_overwritten(tmp_path):
    values = {"session_id": 1, "phase": "main", "ordinal": 2, "attempt": 0}
    first = recording_relpath(tmp_path, tmp_path / "rec", "P01", values)
    assert not Path(first).is_absolute()
    (tmp_path / first).parent.mkdir(parents=True)
    (tmp_path / first).write_bytes(b"old")
    second = recording_relpath(tmp_path, tmp_path / "rec", "P01", values)
    assert second != first and not (tmp_path / second).exists()
    assert (tmp_path / first).read_bytes() == b"old"


class _Boom(Exception):
    pass


class _Failing:
    """A scripted participant whose ``act`` raises after ``after`` ticks of the main phase."""

    kind = "scripted"

    def __init__(self, rng: np.random.Generator, after: int) -> None:
        self.inner = ScriptedParticipant(rng)
        self.parameters: dict = {}
        self.after = after
        self.ticks = 0
        self.phase = ""

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def begin_trial(self, info):
        self.phase = info.phase
        self.inner.begin_trial(info)

    def act(self, obs, screen):
        if self.phase == "main":
            self.ticks += 1
            if self.ticks > self.after:
                raise _Boom("participant process died")
        return self.inner.act(obs, screen)


def test_a_trial_that_raises_keeps_its_rows_and_is_aborted(tmp_path, seed):
    rng = np.random.default_rng(seed)
    after = int(rng.integers(5, 60))
    db = tmp_path / "s.db"
    with pytest.raises(_Boom):
        run_session(_protocol(seed), "P01", db, participant=_Failing(rng, after), seed=seed)
    engine = open_database(db, create=False)
    with Session(engine) as s:
        trial = s.scalars(select(Trial).where(Trial.phase == "main")).one()
        assert trial.status == "aborted" and trial.ended_at is not None
        assert "participant process died" in trial.outcome["aborted_reason"]
        samples = s.scalars(select(Sample).where(Sample.trial_id == trial.id)).all()
        assert len(samples) == after  # every completed tick, not only the flushed ones
        ended = s.scalars(
            select(Event).where(Event.trial_id == trial.id, Event.kind == "trial_ended")
        ).one()
        assert ended.detail["status"] == "aborted"
    engine.dispose()


def test_a_failed_flush_keeps_the_buffer_for_the_next_one(tmp_path):
    engine = open_database(tmp_path / "s.db")
    with Session(engine) as s, s.begin():
        study = Study(name="t", protocol_text="", protocol_sha256="0" * 64,
                      platform_version="test", seed=0)  # fmt: skip
        s.add(study)
        s.flush()
        person = Participant(study_id=study.id, code="P01", kind="scripted", order_index=0,
                             mode_order=["manual"], seed=0)  # fmt: skip
        s.add(person)
        s.flush()
        row = SessionRow(participant_id=person.id)
        s.add(row)
        s.flush()
        values = dict(participant_id=person.id, session_id=row.id, phase="main", mode="manual",
                      ordinal=0, attempt=0, scenario="x", seed=0)  # fmt: skip
    writer = TrialWriter(engine, session_id=values["session_id"])
    trial_id = writer.start(values, lambda tid: f"rec/{tid}.rrd")
    sample = {"tick": 0, "t": 0.05, "x": 0.0, "y": 0.0, "yaw": 0.0, "u_x": 0.0, "u_y": 0.0,
              "u_w": 0.0, "v_x": 0.0, "v_y": 0.0, "v_w": 0.0, "beta": 0.0, "label": "",
              "target": "", "min_clearance_m": 1.0, "in_region": False, "true_task": "",
              "true_target": ""}  # fmt: skip
    writer.samples.append({**sample, "trial_id": trial_id})
    writer.samples.append({**sample, "trial_id": trial_id + 1000, "tick": 1})  # no such trial
    writer.event(0.1, "note")
    with pytest.raises(IntegrityError):
        writer.flush(2)
    assert len(writer.samples) == 2 and len(writer.events) == 1  # nothing forgotten
    writer.samples[1]["trial_id"] = trial_id
    writer.flush(2)
    assert not writer.samples and not writer.events
    with engine.connect() as con:
        assert con.execute(text("SELECT count(*) FROM sample")).scalar() == 2
        assert con.execute(text("SELECT count(*) FROM event WHERE kind='note'")).scalar() == 1
    engine.dispose()


def test_huge_participant_numbers_take_the_next_order_slot(tmp_path, seed):
    db = tmp_path / "s.db"
    with pytest.raises(_Boom):
        run_session(_protocol(seed), "P999999", db, participant=_Failing(
            np.random.default_rng(seed), 0), seed=seed)  # fmt: skip
    engine = open_database(db, create=False)
    with Session(engine) as s:
        person = s.scalars(select(Participant)).one()
        assert person.order_index == 0  # the code's number plays no part (issue 20)
    engine.dispose()


def _rows(db: Path) -> tuple[list, list]:
    engine = open_database(db, create=False)
    with engine.connect() as con:
        samples = con.execute(
            text(
                "SELECT trial_id, tick, t, x, y, yaw, u_x, u_y, u_w, v_x, v_y, v_w, beta "
                "FROM sample ORDER BY trial_id, tick"
            )  # fmt: skip
        ).all()
        trials = con.execute(
            text(
                "SELECT phase, mode, ordinal, attempt, seed, status, completion_time_s, "
                "collisions, score, path_length_m FROM trial ORDER BY id"
            )  # fmt: skip
        ).all()
    engine.dispose()
    return samples, trials


def test_same_protocol_code_and_seed_give_identical_data(tmp_path, seed):
    for name in ("a", "b"):
        summary = run_session(
            _protocol(seed),
            "P02",
            tmp_path / f"{name}.db",
            participant=ScriptedParticipant(np.random.default_rng(seed)),
            seed=seed,
        )
        assert summary.status == "completed"
    a, b = _rows(tmp_path / "a.db"), _rows(tmp_path / "b.db")
    assert len(a[0]) > 100 and a == b
    # the scenario's map is saved once beside the recordings, for the report
    maps = sorted(p.name for p in (tmp_path / "a_recordings" / "maps").iterdir())
    assert maps == ["practice_course.pgm", "practice_course.yaml"]
