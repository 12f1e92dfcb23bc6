"""Schema migrations (issue 24): a study from before the migrations upgrades with ``asa
db upgrade`` to head and takes new sessions, on SQLite and PostgreSQL; upgrading twice
changes nothing; a new database is at head; an old database is refused for writing with
the one line naming ``asa db upgrade``, an unknown revision always; no downgrade.

The version-1 study is tests/golden/v1_study.db, made with the platform before the
migrations by tests/golden/make_v1_study.py (one scripted participant's session); on
PostgreSQL its rows are copied into a database made by revision 0001 alone.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy.orm import Session

from study.data import locks, schema
from study.data.dbtools import check
from study.data.storage import SCHEMA_VERSION, Base, SessionRow, open_database
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.participants import ScriptedParticipant
from tests.cli_helpers import asa

GOLDEN = Path(__file__).parent / "golden"
# the columns revisions 0002 to 0005 add: (table, column)
ADDED = {("session", "site"), ("session", "machine"), ("study", "sites")}
ADDED |= {("participant", "site"), ("session", "uid"), ("order_slot", "site")}
ADDED |= {("sample", "lsl_clock_s"), ("sample", "input_age_ticks"), ("sample", "rtt_ms")}
# the tables revisions 0004 and 0005 add (not in the version-1 study)
ADDED_TABLES = {"lsl_stream", "lsl_chunk", "lsl_offset", "lsl_gap", "invite"}
BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]


def _golden_protocol(folder: Path) -> Path:
    spec = importlib.util.spec_from_file_location("make_v1_study", GOLDEN / "make_v1_study.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = folder / "v1-golden.toml"
    path.write_text(module.PROTOCOL, encoding="utf-8")
    return path


def _differences(db: str) -> set[tuple[str, str, str]]:
    """How the database's schema differs from the ORM's: (operation, table, column)."""
    engine = sa.create_engine(db)
    try:
        with engine.connect() as conn:
            diffs = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    finally:
        engine.dispose()
    return {
        (d[0], d[2], d[3].name)
        if d[0] == "add_column"
        else (d[0], "", re.sub(r" at 0x[0-9a-f]+", "", str(d)))  # a default function's address
        for d in diffs
    }


def _v1_file(tmp_path: Path) -> Path:
    path = tmp_path / "v1.db"
    shutil.copy(GOLDEN / "v1_study.db", path)
    return path


def _v1_server(pg_url: str) -> None:
    """A PostgreSQL database as the platform before the migrations left it: revision
    0001's tables, no ``alembic_version``, the golden study's rows."""
    engine = sa.create_engine(pg_url)
    source = sa.create_engine(f"sqlite:///{GOLDEN / 'v1_study.db'}")
    with engine.connect() as conn:
        schema.upgrade_to(conn, "0001")
        conn.exec_driver_sql("DROP TABLE alembic_version")
        conn.exec_driver_sql("DELETE FROM meta")
        target = sa.MetaData()
        target.reflect(conn)
        with source.connect() as src:
            for table in Base.metadata.sorted_tables:
                if table.name in ADDED_TABLES:
                    continue
                columns = [c for c in table.columns if (table.name, c.name) not in ADDED]
                rows = [dict(r) for r in src.execute(sa.select(*columns)).mappings()]
                if rows:
                    conn.execute(target.tables[table.name].insert(), rows)
            for table in set(Base.metadata.tables) - {"meta"} - ADDED_TABLES:
                conn.exec_driver_sql(  # the serial sequences past the copied ids
                    f"SELECT setval(pg_get_serial_sequence('{table}', 'id'), "
                    f"(SELECT max(id) FROM {table}))"
                )
        conn.commit()
    source.dispose()
    engine.dispose()


@pytest.fixture(params=BACKENDS)
def v1_db(request, tmp_path) -> str:
    """A version-1 study (no alembic_version) on each backend: a file path or a URL."""
    if request.param == "sqlite":
        return str(_v1_file(tmp_path))
    url = request.getfixturevalue("pg_url")
    _v1_server(url)
    return url


def _url(db: str) -> str:
    return db if "://" in db else f"sqlite:///{db}"


def test_the_golden_file_is_revision_0001_and_upgrades_to_the_orm_schema(tmp_path):
    """Revision 0001 is the schema create_all made before the migrations (the golden file
    was made by that code): it differs from the ORM as a database made by 0001 alone does,
    by the later revisions' columns among others; upgraded, it is the ORM's schema."""
    made = tmp_path / "made.db"
    engine = sa.create_engine(f"sqlite:///{made}")
    with engine.connect() as conn:
        schema.upgrade_to(conn, "0001")
        conn.commit()
    engine.dispose()
    at_0001 = _differences(f"sqlite:///{made}")
    assert {("add_column", *c) for c in ADDED} <= at_0001
    assert _differences(f"sqlite:///{GOLDEN / 'v1_study.db'}") == at_0001
    golden = _v1_file(tmp_path)
    engine = sa.create_engine(f"sqlite:///{golden}")
    with engine.connect() as conn:
        schema.upgrade_to(conn, "head")
        conn.commit()
    engine.dispose()
    assert _differences(f"sqlite:///{golden}") == set()


def test_a_version_1_study_upgrades_and_takes_a_session(v1_db, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a server database's local folders go to the working folder
    code, out, err = asa(capsys, "db", "upgrade", "--db", v1_db)
    assert code == 0, err
    assert out.strip() == f"{v1_db}: schema revision 0001 -> {schema.head()}"
    assert _differences(_url(v1_db)) == set()
    code, out, err = asa(capsys, "db", "upgrade", "--db", v1_db)  # twice: nothing to do
    assert code == 0 and "nothing to do" in out, err
    summary = run_session(
        load_protocol(_golden_protocol(tmp_path)),
        "P02",
        v1_db,
        participant=ScriptedParticipant(np.random.default_rng(4)),
        seed=4,
        record=False,
    )
    assert summary.status == "completed"
    engine = open_database(v1_db)
    with Session(engine) as s:
        rows = s.scalars(sa.select(SessionRow).order_by(SessionRow.id)).all()
        assert [r.site for r in rows] == [None, None]  # a study without sites
        assert all(r.uid for r in rows) and rows[0].uid != rows[1].uid  # filled by 0003
        assert rows[1].machine  # the session written after the upgrade knows its machine
        rows[0].machine = "pc-07"  # the new columns take values
        s.commit()
    engine.dispose()
    report = check(v1_db, verify_recordings=False)
    assert report.clean, report.text()
    assert report.counts["participant"] == 2 and report.counts["trial"] == 6


def test_upgrading_twice_changes_nothing(tmp_path, capsys):
    db = _v1_file(tmp_path)
    assert asa(capsys, "db", "upgrade", "--db", str(db))[0] == 0
    before = db.read_bytes()
    code, out, _ = asa(capsys, "db", "upgrade", "--db", str(db))
    assert code == 0 and f"at schema revision {schema.head()} already" in out
    assert db.read_bytes() == before


@pytest.mark.parametrize(
    "backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]
)
def test_a_new_database_is_at_head(backend, request, tmp_path):
    db = request.getfixturevalue("pg_url") if backend == "postgresql" else str(tmp_path / "n.db")
    engine = open_database(db)
    with engine.connect() as conn:
        assert schema.database_revision(conn) == schema.head()
        version = conn.exec_driver_sql("SELECT value FROM meta WHERE key = 'schema_version'")
        assert version.scalar() == str(SCHEMA_VERSION) == str(int(schema.head()))
    engine.dispose()
    assert _differences(_url(db)) == set()


def test_migrations_from_nothing_give_the_orm_schema(tmp_path):
    made = tmp_path / "made.db"
    engine = sa.create_engine(f"sqlite:///{made}")
    with engine.connect() as conn:
        schema.upgrade_to(conn, "head")
        conn.commit()
    engine.dispose()
    assert _differences(f"sqlite:///{made}") == set()


@pytest.mark.postgres
def test_migrations_from_nothing_give_the_orm_schema_on_postgres(pg_url):
    engine = sa.create_engine(pg_url)
    with engine.connect() as conn:
        schema.upgrade_to(conn, "0001")
        conn.commit()
    assert {("add_column", *c) for c in ADDED} <= _differences(pg_url)
    with engine.connect() as conn:
        schema.upgrade_to(conn, "head")
        conn.commit()
    engine.dispose()
    assert _differences(pg_url) == set()


def test_an_old_database_is_refused_for_writing_with_the_upgrade_line(tmp_path, capsys):
    db = _v1_file(tmp_path)
    before = db.read_bytes()
    line = f"{db}: schema revision 0001 is older than this platform's {schema.head()}; run "
    line += f"`asa db upgrade --db {db}` first"
    with pytest.raises(ValueError, match="asa db upgrade") as error:
        open_database(db)
    assert str(error.value).startswith(line) and "\n" not in str(error.value)
    # read-only: it cannot be read by this version (session.site is missing): the same line
    code, _, err = asa(capsys, "db", "check", "--db", str(db), "--no-verify")
    assert code == 2 and line in err and len(err.strip().splitlines()) == 1
    assert db.read_bytes() == before


def test_no_upgrade_under_a_running_session(tmp_path, capsys):
    db = _v1_file(tmp_path)
    con = sqlite3.connect(db)
    con.execute("UPDATE session SET status = 'running'")  # P01's session, interrupted ...
    con.commit()
    con.close()
    before = db.read_bytes()
    with locks.held(locks.session_lock(db, "P01"), wait=False):  # ... and live again
        code, _, err = asa(capsys, "db", "upgrade", "--db", str(db))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"{db}: 1 session(s) are running (P01); upgrade when they have ended" in err
    assert db.read_bytes() == before
    code, out, err = asa(capsys, "db", "upgrade", "--db", str(db))  # interrupted: no holder
    assert code == 0 and f"0001 -> {schema.head()}" in out, err


def test_an_unknown_revision_is_refused(tmp_path, capsys):
    db = tmp_path / "new.db"
    open_database(db).dispose()
    con = sqlite3.connect(db)
    con.execute("UPDATE alembic_version SET version_num = 'ffff'")
    con.commit()
    con.close()
    for create in (True, False):
        with pytest.raises(ValueError, match="revision ffff is not one this platform knows"):
            open_database(db, create=create)
    code, _, err = asa(capsys, "db", "upgrade", "--db", str(db))
    assert code == 2 and "upgrade asa-study" in err and len(err.strip().splitlines()) == 1


def test_no_downgrade_and_bad_input_are_one_line(tmp_path, capsys):
    db = tmp_path / "new.db"
    open_database(db).dispose()
    other = tmp_path / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE things (id INTEGER)")
    con.close()
    cases = {
        ("--db", str(db), "--to", "0001"): "no downgrade",
        ("--db", str(db), "--to", "0099"): "no schema revision '0099'",
        ("--db", str(tmp_path / "missing.db")): "no such file",
        ("--db", str(other)): "not an asa-study database",
        ("--db", "postgresql://asa@127.0.0.1:1/none"): "cannot be reached",
    }
    for args, words in cases.items():
        code, out, err = asa(capsys, "db", "upgrade", *args)
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, (args, err)
    assert not (tmp_path / "missing.db").exists()


def test_an_upgrade_that_fails_leaves_the_database_as_it_was(v1_db, capsys):
    """Every step in one transaction: 0002 fails on a column already there, and 0001's
    stamp is rolled back with it."""
    engine = sa.create_engine(_url(v1_db))
    with engine.connect() as conn:
        conn.exec_driver_sql("ALTER TABLE session ADD COLUMN machine VARCHAR(128)")
        conn.commit()
    code, _, err = asa(capsys, "db", "upgrade", "--db", v1_db)
    assert code == 2 and "cannot be upgraded" in err and len(err.strip().splitlines()) == 1
    with engine.connect() as conn:
        assert "alembic_version" not in sa.inspect(conn).get_table_names()
        columns = {c["name"] for c in sa.inspect(conn).get_columns("study")}
        assert "sites" not in columns
    engine.dispose()


def test_a_study_older_than_some_tables_gets_them_on_upgrade(tmp_path, capsys):
    """A version-1 study from before ``order_slot`` existed: revision 0001 makes the
    tables it lacks (opening it for writing used to add them)."""
    db = _v1_file(tmp_path)
    con = sqlite3.connect(db)
    con.execute("DROP TABLE order_slot")
    con.commit()
    con.close()
    assert asa(capsys, "db", "upgrade", "--db", str(db))[0] == 0
    assert _differences(f"sqlite:///{db}") == set()


def test_the_platform_knows_every_revision_shipped():
    """``schema.REVISIONS`` (read on every opening, without importing Alembic) is the
    chain in study/data/migrations/versions, and opening a study imports no Alembic."""
    from alembic.script import ScriptDirectory

    script = ScriptDirectory.from_config(schema.alembic_config())
    chain = [r.revision for r in reversed(list(script.walk_revisions()))]
    assert chain == list(schema.REVISIONS) and script.get_current_head() == schema.head()
    assert int(schema.head()) == SCHEMA_VERSION


def test_opening_a_study_imports_no_alembic(tmp_path):
    import subprocess
    import sys

    db = tmp_path / "s.db"
    open_database(db).dispose()
    code = (
        "import sys; from study.data.storage import open_database; "
        f"open_database({str(db)!r}).dispose(); open_database({str(db)!r}, create=False); "
        "print('alembic' in sys.modules)"
    )
    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root
    )
    assert out.stdout.strip() == "False"
