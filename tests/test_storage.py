"""The study database: created with its schema version, WAL on SQLite, foreign databases refused."""

from __future__ import annotations

import sqlite3

import pytest
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from study.data.storage import (
    SCHEMA_VERSION,
    Meta,
    Participant,
    Study,
    get_study,
    open_database,
)


def _study(session: Session) -> Study:
    study = Study(
        name="s", protocol_text="x", protocol_sha256="0" * 64, platform_version="t", seed=1
    )
    session.add(study)
    session.flush()
    return study


def test_new_database_has_schema_version_and_wal(tmp_path):
    path = tmp_path / "study.db"
    engine = open_database(path)
    with Session(engine) as s:
        assert s.get(Meta, "schema_version").value == str(SCHEMA_VERSION)
        assert get_study(s) is None
    assert sqlite3.connect(path).execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_reopen_keeps_data_and_participant_codes_are_unique(tmp_path):
    path = tmp_path / "study.db"
    with Session(open_database(path)) as s, s.begin():
        study = _study(s)
        s.add(Participant(study_id=study.id, code="P01", kind="synthetic", order_index=0, seed=1))
    with Session(open_database(path)) as s:
        assert get_study(s).participants[0].code == "P01"
        s.add(
            Participant(study_id=get_study(s).id, code="P01", kind="human", order_index=1, seed=2)
        )
        with pytest.raises(IntegrityError):
            s.flush()


def test_foreign_or_newer_databases_are_refused(tmp_path):
    foreign = tmp_path / "foreign.db"
    con = sqlite3.connect(foreign)
    con.execute("CREATE TABLE results (x REAL)")
    con.commit()
    with pytest.raises(ValueError, match="not an asa-study database"):
        open_database(foreign)

    newer = tmp_path / "newer.db"
    open_database(newer)
    con = sqlite3.connect(newer)
    con.execute(
        "UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 1),)
    )
    con.commit()
    with pytest.raises(ValueError, match="schema_version"):
        open_database(newer)


def test_missing_database_without_create(tmp_path):
    with pytest.raises(FileNotFoundError):
        open_database(tmp_path / "nope.db", create=False)
