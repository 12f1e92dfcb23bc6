"""The session engine end to end: a short protocol, the scripted participant, every phase,
storage, recordings, ``asa db check`` and ``asa export``; refusals and forcing."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from autonomy.modes import available_modes
from questionnaires import nasa_tlx
from study.data.dbtools import check, export
from study.data.storage import (
    Event,
    Participant,
    Question,
    Response,
    Sample,
    SessionRow,
    Study,
    Trial,
    open_database,
)
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.engine.trial import ExperimenterControl
from study.participants import ScriptedParticipant
from study.types import ScreenState

FAST = """
[study]
name = "fast"
participants = 2
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"
hidden = true

[[phases]]
kind = "briefing"
text = "Test run."

[[phases]]
kind = "experience"
instrument = "experience"

[[phases]]
kind = "training"
scenario = "practice_course"
duration_s = 2.0
secondary = false
direct_view = true

[[phases]]
kind = "practice"
scenario = "practice_course"
time_limit_s = 40.0
max_collisions = 0
secondary = false
max_attempts = 2
on_fail = "continue"
order = "assigned"

[[phases]]
kind = "baseline"
questions = 3

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
block_size = 3
timeout_s = 60.0
end_on_collision = false

[phases.after_trial]
instrument = "nasa_tlx"
weights = "per_trial"

[[phases]]
kind = "debrief"
text = "Done."
"""


def write_protocol(folder: Path, seed: int, name: str = "fast.toml", text: str = FAST) -> Path:
    path = folder / name
    path.write_text(text.format(seed=seed % 1000), encoding="utf-8")
    return path


class Watching:
    """A scripted participant that keeps every screen it was shown."""

    kind = "scripted"

    def __init__(self, rng: np.random.Generator) -> None:
        self.inner = ScriptedParticipant(rng)
        self.parameters = self.inner.parameters
        self.screens: list[ScreenState] = []

    def __getattr__(self, name: str):
        return getattr(self.inner, name)

    def act(self, obs, screen):
        self.screens.append(screen)
        return self.inner.act(obs, screen)


@pytest.fixture(scope="module")
def session_run(tmp_path_factory):
    import os

    seed = int(os.environ.get("ASA_TEST_SEED", "20261123"))
    folder = tmp_path_factory.mktemp("session")
    protocol = load_protocol(write_protocol(folder, seed))
    db = folder / "study.db"
    lines: list[str] = []
    who = Watching(np.random.default_rng(seed))
    summary = run_session(protocol, "P02", db, participant=who, seed=seed, progress=lines.append)
    return protocol, db, summary, who, lines


def test_whole_session_runs_every_phase(session_run):
    protocol, db, summary, who, lines = session_run
    assert summary.status == "completed"
    # the study's first participant takes slot 0 whatever its code (issue 20): permutation 0
    assert summary.mode_order == ("manual", "reactive_bn")
    engine = open_database(db, create=False)
    with Session(engine) as s:
        trials = s.scalars(select(Trial).order_by(Trial.id)).all()
        phases = [t.phase for t in trials]
        assert phases[:2] == ["training", "training"]
        assert "baseline" in phases
        assert [t.mode for t in trials if t.phase == "main"] == ["manual", "reactive_bn"]
        assert {t.status for t in trials} == {"completed"}
        practice = [t for t in trials if t.phase == "practice"]
        assert {t.ordinal for t in practice} == {0, 1}
        for t in practice:  # repeated only while not passed, at most max_attempts
            same = [p for p in practice if p.ordinal == t.ordinal]
            assert len(same) <= 2
            assert all(not p.outcome["passed"] for p in same[:-1])
        mains = [t for t in trials if t.phase == "main"]
        assert all(t.completed_task for t in mains)
        assert all(
            t.score == pytest.approx(t.completion_time_s + 60.0 * t.collisions) for t in mains
        )
        for t in trials:
            n = s.scalar(select(func.count()).select_from(Sample).where(Sample.trial_id == t.id))
            t_max = s.scalar(select(func.max(Sample.t)).where(Sample.trial_id == t.id))
            assert abs(n - t_max * 20) <= 1  # 20 samples per simulated second
            kinds = set(s.scalars(select(Event.kind).where(Event.trial_id == t.id)))
            assert {"trial_started", "trial_ended"} <= kinds
        mains_kinds = set(s.scalars(select(Event.kind).where(Event.trial_id == mains[0].id)))
        assert "dock_reached" in mains_kinds
        baseline = next(t for t in trials if t.phase == "baseline")
        questions = s.scalars(select(Question).where(Question.trial_id == baseline.id)).all()
        assert len(questions) == 3
        assert all(q.response is not None and q.answer_time_s > 0 for q in questions)
        assert baseline.outcome["secondary"]["shown"] == 3
        for t in mains:
            items = set(s.scalars(select(Response.item).where(Response.trial_id == t.id)))
            assert set(nasa_tlx.SUBSCALE_IDS) <= items
            assert len([i for i in items if i.startswith("pair:")]) == 15
        experience = s.scalars(select(Response).where(Response.instrument == "experience")).all()
        assert len(experience) == 6
        done = [
            e.detail["phase"] for e in s.scalars(select(Event).where(Event.kind == "phase_done"))
        ]
        assert done == ["briefing", "experience", "debrief"]
        person = s.scalars(select(Participant)).one()
        assert person.kind == "scripted" and person.order_index == 0
        assert s.scalars(select(SessionRow)).one().status == "completed"
    engine.dispose()
    assert any("main #0 mode manual" in line for line in lines)


def test_mode_name_is_never_on_the_screen(session_run):
    *_, who, _ = session_run
    assert len(who.screens) > 1000
    names = available_modes()
    for screen in who.screens[::7]:
        for f in fields(ScreenState):
            value = getattr(screen, f.name)
            if isinstance(value, str):
                assert not any(name in value for name in names), (f.name, value)
    assert {s.phase for s in who.screens} == {"training", "practice", "baseline", "main"}
    assert any(s.question for s in who.screens if s.phase == "baseline")


def test_recordings_verify_and_db_check_is_clean(session_run):
    _, db, *_ = session_run
    report = check(db)
    assert report.clean, report.text()
    assert report.counts["trials_checked"] == report.counts["trial"]
    rrd = sorted((db.parent / "study_recordings" / "P02").glob("*.rrd"))
    assert len(rrd) == report.counts["trial"]


def test_cli_db_check_and_export(session_run, tmp_path):
    _, db, *_ = session_run
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "study.cli",
            "db",
            "check",
            "--db",
            str(db),
            "--json",
            "--no-verify",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert json.loads(done.stdout)["clean"] is True
    written = export(db, tmp_path / "csv")
    assert set(written) == {
        "meta",
        "study",
        "participant",
        "session",
        "trial",
        "sample",
        "event",
        "question",
        "response",
        "order_slot",
    }
    with open(tmp_path / "csv" / "trial.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == written["trial"]
    assert all(isinstance(json.loads(r["outcome"]), dict) for r in rows)
    with open(tmp_path / "csv" / "sample.csv", encoding="utf-8") as f:
        assert sum(1 for _ in f) == written["sample"] + 1


ABORT_ONLY = """
[study]
name = "{name}"
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]

[[phases]]
kind = "briefing"
text = "Hello."

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
block_size = 3
timeout_s = 30.0
"""


def _aborting(protocol, code, db, seed, **kw):
    control = ExperimenterControl()
    control.abort("test abort")
    return run_session(
        protocol,
        code,
        db,
        participant=ScriptedParticipant(np.random.default_rng(seed)),
        control=control,
        **kw,
    )


def test_abort_second_session_force_and_protocol_sha(tmp_path, seed):
    protocol = load_protocol(
        write_protocol(tmp_path, seed, "a.toml", ABORT_ONLY.replace("{name}", "a"))
    )
    db = tmp_path / "s.db"
    first = _aborting(protocol, "P01", db, seed)
    assert first.status == "aborted"
    assert [t.status for t in first.trials] == ["aborted"]
    with pytest.raises(ValueError, match="already has a session"):
        _aborting(protocol, "P01", db, seed)
    forced = _aborting(protocol, "P01", db, seed, force=True)
    assert forced.forced and forced.session_id != first.session_id
    other = load_protocol(
        write_protocol(tmp_path, seed + 1, "b.toml", ABORT_ONLY.replace("{name}", "b"))
    )
    with pytest.raises(ValueError, match="protocol_sha256"):
        _aborting(other, "P02", db, seed)
    third = _aborting(other, "P02", db, seed, force=True)
    engine = open_database(db, create=False)
    with Session(engine) as s:
        rows = s.scalars(select(SessionRow).order_by(SessionRow.id)).all()
        assert [r.forced for r in rows] == [False, True, True]
        assert "nothing was deleted" in rows[1].note
        assert "protocol" in rows[2].note
        assert rows[2].id == third.session_id
        assert s.scalar(select(func.count()).select_from(Study)) == 1
        trials = s.scalars(select(Trial)).all()
        assert len(trials) == 3 and all(t.outcome["aborted_reason"] == "test abort" for t in trials)
    engine.dispose()
    with pytest.raises(ValueError, match="participant code"):
        _aborting(protocol, "P 1;", db, seed)


def test_cli_refuses_human_input_and_bad_code(tmp_path):
    base = [
        sys.executable,
        "-m",
        "study.cli",
        "run",
        "--protocol",
        "pilot",
        "--db",
        str(tmp_path / "x.db"),
    ]
    done = subprocess.run(
        base + ["--participant", "P01", "--input", "human"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert "--input human" in done.stderr and len(done.stderr.strip().splitlines()) == 1
    done = subprocess.run(
        base + ["--participant", "P/01"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2 and "participant code" in done.stderr


@pytest.mark.slow
def test_full_pilot_protocol_session(tmp_path, seed):
    """The shipped pilot.toml through every phase, all three modes."""
    protocol = load_protocol("pilot")
    db = tmp_path / "pilot.db"
    lines: list[str] = []
    summary = run_session(
        protocol,
        "P01",
        db,
        participant=ScriptedParticipant(np.random.default_rng(seed)),
        seed=seed,
        progress=lines.append,
    )
    assert summary.status == "completed", lines
    report = check(db)
    assert report.clean, report.text()
    engine = open_database(db, create=False)
    with Session(engine) as s:
        mains = s.scalars(select(Trial).where(Trial.phase == "main")).all()
        assert len(mains) == len(protocol.modes)
        assert all(t.completed_task for t in mains), lines
        assert all(t.outcome["inspection_done"] for t in mains)
        assert all(t.outcome["secondary"]["shown"] >= 5 for t in mains)
        assert s.scalar(select(func.count()).select_from(Question)) > 10
    engine.dispose()
