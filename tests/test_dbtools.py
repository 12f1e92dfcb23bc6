"""``asa db check`` finds what is wrong with a study database; ``asa export`` writes CSVs."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from study.data.dbtools import check, export
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.participants import ScriptedParticipant

PROTOCOL = """
[study]
name = "check"
seed = 5

[modes]
names = ["manual", "reactive_bn"]

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
"""


@pytest.fixture(scope="module")
def clean_db(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dbtools")
    path = folder / "check.toml"
    path.write_text(PROTOCOL, encoding="utf-8")
    summary = run_session(
        load_protocol(path),
        "P01",
        folder / "study.db",
        participant=ScriptedParticipant(np.random.default_rng(3)),
        seed=3,
    )
    assert summary.status == "completed"
    return folder


def _copy(clean: Path, tmp_path: Path) -> Path:
    target = tmp_path / "copy"
    shutil.copytree(clean, target)
    return target / "study.db"


def _sql(db: Path, statement: str) -> None:
    con = sqlite3.connect(db)
    con.execute("PRAGMA foreign_keys=OFF")
    con.execute(statement)
    con.commit()
    con.close()


def test_clean_database_is_clean(clean_db):
    report = check(clean_db / "study.db")
    assert report.clean, report.text()
    assert report.counts["trials_checked"] == 2
    assert report.as_dict()["clean"] is True


@pytest.mark.parametrize(
    ("statement", "expected"),
    [
        ("DELETE FROM sample WHERE trial_id = 1", "has no samples"),
        ("DELETE FROM sample WHERE trial_id = 1 AND tick BETWEEN 10 AND 14", "not contiguous"),
        ("UPDATE trial SET status = 'running' WHERE id = 2", "still running"),
        ("DELETE FROM response WHERE trial_id = 2", "NASA-TLX ratings missing"),
        ("DELETE FROM event WHERE kind = 'trial_ended'", "missing events trial_ended"),
        ("UPDATE trial SET collisions = NULL WHERE id = 1", "without its outcome fields"),
        (
            "INSERT INTO sample (trial_id, tick, t, x, y, yaw, u_x, u_y, u_w, v_x, v_y, v_w,"
            " beta, label, target, min_clearance_m, in_region, true_task, true_target)"
            " VALUES (99, 0, 0.05, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, '', '', 1, 0, '', '')",
            "refers to a missing row 99",
        ),
    ],
)
def test_check_finds_each_fault(clean_db, tmp_path, statement, expected):
    db = _copy(clean_db, tmp_path)
    _sql(db, statement)
    report = check(db, verify_recordings=False)
    assert not report.clean
    assert any(expected in p for p in report.problems), report.problems


def test_check_finds_missing_and_broken_recordings(clean_db, tmp_path):
    db = _copy(clean_db, tmp_path)
    files = sorted((db.parent / "study_recordings" / "P01").glob("*.rrd"))
    files[0].unlink()
    data = files[1].read_bytes()
    files[1].write_bytes(data[: len(data) // 3])
    report = check(db)
    assert any("is missing" in p for p in report.problems)
    assert any("trial 2" in p and "rerun" in p for p in report.problems), report.problems
    assert sum("is missing" in p for p in check(db, verify_recordings=False).problems) == 1


def _asa(capsys, *args: str) -> tuple[int, str, str]:
    """Run the ``asa`` CLI in this process: (exit status, stdout, stderr)."""
    from study.cli import main

    capsys.readouterr()
    try:
        main(list(args))
        code = 0
    except SystemExit as exit_:
        code = int(exit_.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_exit_status(clean_db, tmp_path, capsys):
    db = _copy(clean_db, tmp_path)
    assert _asa(capsys, "db", "check", "--db", str(db), "--no-verify")[0] == 0
    _sql(db, "DELETE FROM sample WHERE trial_id = 2")
    code, out, _ = _asa(capsys, "db", "check", "--db", str(db), "--no-verify", "--json")
    assert code == 1
    report = json.loads(out)
    assert report["clean"] is False and report["problems"]
    other = tmp_path / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE things (id INTEGER)")
    con.close()
    code, _, err = _asa(capsys, "db", "check", "--db", str(other))
    assert code == 2 and "not an asa-study database" in err
    code, _, err = _asa(
        capsys, "export", "--db", str(tmp_path / "missing.db"), "--out", str(tmp_path / "o")
    )
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_export_one_csv_per_table(clean_db, tmp_path):
    written = export(clean_db / "study.db", tmp_path / "out")
    for name, n in written.items():
        with open(tmp_path / "out" / f"{name}.csv", encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == n
    with open(tmp_path / "out" / "participant.csv", encoding="utf-8", newline="") as f:
        row = next(csv.DictReader(f))
    assert json.loads(row["mode_order"]) in (["manual", "reactive_bn"], ["reactive_bn", "manual"])
    assert json.loads(row["parameters"])["speed"] > 0
