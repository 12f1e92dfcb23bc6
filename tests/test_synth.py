"""Whole synthetic studies (study/synth.py, ``asa synth``, ``asa pilot``): the database
does not depend on the number of workers, an interrupted study continues to the same
result, ``asa db check`` accepts it, bad options are refused."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.dbtools import check
from study.data.rrd import recording_summary
from study.data.storage import Base, Event, Participant, Sample, Study, Trial, open_database
from study.jobs.synth import (
    format_summary,
    participant_codes,
    run_synthetic_study,
    sanity_summary,
)

TINY = """
# every kind of phase, each as short as it goes (about 20 s of wall time per study)
[study]
name = "tiny-synth"
participants = 2
seed = 5

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"

[[phases]]
kind = "briefing"
text = "Tiny."

[[phases]]
kind = "experience"
instrument = "experience"

[[phases]]
kind = "training"
scenario = "practice_course"
duration_s = 2.0
secondary = false

[[phases]]
kind = "practice"
scenario = "practice_course"
time_limit_s = 60.0
max_collisions = 0
secondary = false
max_attempts = 1
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
timeout_s = 90.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "per_trial"

[[phases]]
kind = "debrief"
text = "Done."
"""

# when, and a session's random global key (a UUID4, which no run repeats)
WALL_CLOCK = {"created_at", "started_at", "ended_at", "uid"}
# a recording's file name begins with its study's tag, which hashes the creation time
STUDY_TAG = re.compile(r"(?<=/)[0-9a-f]{8}_(?=s\d+_)")


def _tables(db: Path) -> dict[str, list[tuple]]:
    """Every results table, rows in id order, wall-clock columns left out (and the study
    tag, derived from the creation time, cut from recording paths)."""
    engine = open_database(db, create=False)
    out = {}
    with engine.connect() as conn:
        for name, table in Base.metadata.tables.items():
            if name == "meta":
                continue
            cols = [c for c in table.c if c.name not in WALL_CLOCK]
            rows = conn.execute(select(*cols).order_by(table.c.id))
            out[name] = [
                tuple(STUDY_TAG.sub("", v) if c.name == "recording_path" else v
                      for c, v in zip(cols, r, strict=True))
                for r in rows
            ]  # fmt: skip
    engine.dispose()
    return out


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=cwd,
    )


def test_participant_codes():
    assert participant_codes(3) == ("P01", "P02", "P03")
    assert participant_codes(100)[0] == "P001" and participant_codes(100)[-1] == "P100"


def test_same_database_whatever_the_workers_and_after_an_interruption(tmp_path, seed):
    proto = tmp_path / "tiny.toml"
    proto.write_text(TINY)
    s = str(seed % 100_000)
    # two workers, through the CLI
    (tmp_path / "a").mkdir()
    done = _cli(
        "synth", "--protocol", str(proto), "--participants", "2", "--seed", s,
        "--workers", "2", "--db", str(tmp_path / "a" / "t.db"),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "[2/2]" in done.stderr and "manual" in done.stdout
    # one worker, interrupted after P01: P02 left a half-written file and a recording
    b = tmp_path / "b" / "t.db"
    first = run_synthetic_study(str(proto), b, participants=1, seed=int(s), workers=1)
    assert first.run == ("P01",)
    (b.parent / "t_work").mkdir(exist_ok=True)
    (b.parent / "t_work" / "P02.db").write_bytes(b"half a database")
    (b.parent / "t_recordings" / "P02").mkdir(parents=True)
    (b.parent / "t_recordings" / "P02" / "s1_training_0_a0.rrd").write_bytes(b"stale")
    again = run_synthetic_study(str(proto), b, participants=2, seed=int(s), workers=1)
    assert again.skipped == ("P01",) and again.run == ("P02",)
    assert not (b.parent / "t_work").exists()

    ta, tb = _tables(tmp_path / "a" / "t.db"), _tables(b)
    for name in ta:
        assert ta[name] == tb[name], name
    assert len(ta["participant"]) == 2 and len(ta["sample"]) > 1000

    for db in (tmp_path / "a" / "t.db", b):
        report = check(db)
        assert report.clean, report.text()
    engine = open_database(b, create=False)
    with Session(engine) as sess:
        people = sess.scalars(select(Participant).order_by(Participant.id)).all()
        assert [p.code for p in people] == ["P01", "P02"]
        assert all(p.kind == "synthetic" and "preferred_speed" in p.parameters for p in people)
        assert sess.scalar(select(Sample.id).where(Sample.true_task != "").limit(1))
        # synthetic participants do not learn: training is skipped, and it says so
        assert not sess.scalars(select(Trial).where(Trial.phase == "training")).all()
        done = sess.scalars(select(Event).where(Event.kind == "phase_done")).all()
        skipped = [e for e in done if e.detail.get("phase") == "training"]
        assert len(skipped) == 2 and all("not learn" in e.detail["skipped"] for e in skipped)
    engine.dispose()
    summary = sanity_summary(b)
    assert set(summary) == {"manual", "reactive_bn"}
    assert all(e["trials"] == 2 for e in summary.values())
    assert len(format_summary(summary)) == 2
    # nothing left to do
    assert run_synthetic_study(str(proto), b, participants=2, seed=int(s)).run == ()


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("participants", {"participants": 0}),
        ("workers", {"workers": 0}),
        ("seed", {"seed": -1}),
    ],
)
def test_bad_options_are_refused(tmp_path, field, kwargs):
    options = {"participants": 1, "seed": 0, "workers": 1, **kwargs}
    with pytest.raises(ValueError, match=f"^{field}: "):
        run_synthetic_study("pilot", tmp_path / "x.db", **options)
    assert not (tmp_path / "x.db").exists()


def test_an_in_memory_database_or_another_protocol_is_refused(tmp_path):
    with pytest.raises(ValueError, match="^db: "):
        run_synthetic_study("pilot", "sqlite://", participants=1, seed=0)
    db = tmp_path / "other.db"
    engine = open_database(db)
    with Session(engine) as s, s.begin():
        s.add(
            Study(
                name="other",
                protocol_text="",
                protocol_sha256="0" * 64,
                platform_version="t",
                seed=0,
            )
        )
    engine.dispose()
    with pytest.raises(ValueError, match="protocol"):
        run_synthetic_study("pilot", db, participants=1, seed=0)


def test_cli_bad_input_is_one_line_and_exit_2(tmp_path):
    done = _cli("synth", "--protocol", "pilot", "--workers", "0", "--db", str(tmp_path / "x.db"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "--workers" in done.stderr
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "something").write_text("x")
    done = _cli("pilot", "--out", str(tmp_path / "full"))
    assert done.returncode == 2 and "--out" in done.stderr


def test_no_recordings_same_rows_and_db_diff(tmp_path, seed):
    """``asa synth --no-recordings``: no recording, every row as with recordings (``asa db
    diff`` says identical, ``asa db check`` clean); a changed sample is found by the diff."""
    proto = tmp_path / "tiny.toml"
    proto.write_text(TINY)
    s = seed % 100_000
    with_rec, without = tmp_path / "rec" / "t.db", tmp_path / "norec" / "t.db"
    run_synthetic_study(str(proto), with_rec, participants=1, seed=s, workers=1)
    done = _cli(
        "synth", "--protocol", str(proto), "--participants", "1", "--seed", str(s),
        "--workers", "1", "--db", str(without), "--no-recordings",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    recorded = list(with_rec.parent.rglob("*.rrd"))
    assert recorded and not list(without.parent.rglob("*.rrd"))
    # nobody looks at a synthetic participant's camera: no frames rendered or recorded
    for path in recorded:
        entities = recording_summary(path)["entities"]
        assert not any(k.startswith("camera/") and v["rows"] for k, v in entities.items())
    engine = open_database(without, create=False)
    with Session(engine) as sess:
        assert set(sess.scalars(select(Trial.recording_path))) == {""}
    engine.dispose()
    assert check(without).clean, check(without).text()
    same = _cli("db", "diff", str(with_rec), str(without))
    assert same.returncode == 0 and "identical" in same.stdout, same.stdout + same.stderr
    # one coordinate of one sample moved by a micrometre: found, and named
    changed = tmp_path / "changed.db"
    changed.write_bytes(without.read_bytes())
    engine = open_database(changed, create=False, readonly=False)
    with engine.begin() as conn:
        conn.execute(Sample.__table__.update().where(Sample.id == 7).values(x=Sample.x + 1e-6))
    engine.dispose()
    found = _cli("db", "diff", str(without), str(changed))
    assert found.returncode == 1 and "sample" in found.stdout and "7: x:" in found.stdout
    within = _cli("db", "diff", str(without), str(changed), "--tolerance", "1e-5")
    assert within.returncode == 0, within.stdout
    # as two machines' runs differ: a few values by rounding, a trial a tick longer
    with engine.begin() as conn:
        conn.execute(Sample.__table__.update().where(Sample.id < 4).values(y=Sample.y + 3e-9))
        last = conn.execute(select(Sample.__table__).order_by(Sample.id.desc())).mappings().first()
        conn.execute(Sample.__table__.insert().values({**last, "id": last["id"] + 1}))
    engine.dispose()
    loose = _cli("db", "diff", str(without), str(changed), "--tolerance", "1e-8", "--json")
    table = json.loads(loose.stdout)["differences"][0]
    assert loose.returncode == 1 and table["table"] == "sample"
    assert table["columns"] == {"x": {"differing": 1, "largest": pytest.approx(1e-6)}}
    assert table["only_b"] == [repr(last["id"] + 1)] and table["only_a"] == []
    text = _cli("db", "diff", str(without), str(changed)).stdout
    assert "column y: 3 values differ, largest difference 3e-09" in text
    bad = _cli("db", "diff", str(without), str(tmp_path / "missing.db"))
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
