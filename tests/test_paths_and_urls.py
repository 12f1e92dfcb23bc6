"""Issue 20, files: ``--db`` paths and URLs as written, empty and foreign files refused
untouched, read-only studies, no race on a fresh database, no overwrites without
``--force``, names that cannot become paths, recordings named by study, the viewer on
localhost only."""

from __future__ import annotations

import hashlib
import multiprocessing
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from fixtures_db import FixtureSettings, make_study_db
from sqlalchemy import inspect, select
from sqlalchemy.orm import Session

from analysis.data.load import load_study
from study.cli import main
from study.data.dbfile import ro_uri
from study.data.storage import (
    SCHEMA_VERSION,
    Meta,
    Study,
    database_file,
    database_url,
    open_database,
)

SMALL = FixtureSettings(
    n_participants=2, samples=40, questions=4, baseline_questions=4, incomplete=False
)


def asa(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """Run ``asa args`` in this process: (exit status, stdout, stderr)."""
    try:
        main(list(args))
        code = 0
    except SystemExit as stop:
        code = int(stop.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(code: int, err: str) -> str:
    """The one error line of a refused command (progress lines before it are allowed)."""
    assert code == 2, err
    errors = [line for line in err.strip().splitlines() if line.startswith("asa: error")]
    assert len(errors) == 1 and err.strip().endswith(errors[0]), err
    assert "Traceback" not in err
    return errors[0]


def fingerprint(path: Path) -> tuple[str, int, int]:
    """(SHA-256, size, mtime in ns) of a file."""
    stat = path.stat()
    return hashlib.sha256(path.read_bytes()).hexdigest(), stat.st_size, stat.st_mtime_ns


def side_files(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir() if p.name.startswith(path.name + "-"))


@pytest.fixture
def study_db(tmp_path: Path, seed: int) -> Path:
    return make_study_db(tmp_path / "study.db", np.random.default_rng(seed), settings=SMALL)


# ---------------------------------------------------------------- --db as written


def test_urls_are_taken_as_written_and_paths_become_sqlite_urls(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert database_url("postgresql://host/db") == "postgresql://host/db"
    assert database_url("x.db") == f"sqlite:///{tmp_path / 'x.db'}"
    assert database_file("sqlite:///x.db") == tmp_path / "x.db"
    assert database_file("sqlite:////abs/y.db") == Path("/abs/y.db")
    assert database_file("sqlite:///file:z.db?mode=ro&uri=true") == tmp_path / "z.db"


def test_a_sqlite_url_opens_the_file_not_a_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    engine = open_database("sqlite:///x.db")
    engine.dispose()
    assert (tmp_path / "x.db").is_file() and not (tmp_path / "sqlite:").exists()
    code, out, err = asa(capsys, "db", "check", "--db", "sqlite:///x.db", "--no-verify")
    assert code == 1 and "no study row" in out, err  # an empty study: checked, not refused
    assert not (tmp_path / "sqlite:").exists()


@pytest.mark.parametrize(
    ("url", "says"),
    [
        ("postgresql://host/db", "driver"),
        ("mysql://user@host/db", "driver"),
        ("nosuchdb://host/db", "not a database URL"),
    ],
)
def test_a_url_whose_driver_is_missing_is_one_line(tmp_path, monkeypatch, capsys, url, says):
    monkeypatch.chdir(tmp_path)
    for args in (("db", "check", "--db", url), ("export", "--db", url, "--out", "csv")):
        line = one_line_error(*asa(capsys, *args)[::2])
        assert url in line and says in line
    assert list(tmp_path.iterdir()) == []  # not taken as a path


# ---------------------------------------------------------------- empty and foreign files


def _foreign_files(folder: Path) -> dict[str, Path]:
    empty = folder / "empty.db"
    empty.write_bytes(b"")
    text = folder / "notes.db"
    text.write_text("not a database at all\n" * 20, encoding="utf-8")
    other = folder / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE results (x REAL)")
    con.commit()
    con.close()
    bare = folder / "bare.db"  # an SQLite file without any table
    con = sqlite3.connect(bare)
    con.execute("PRAGMA user_version = 3")
    con.close()
    return {"empty": empty, "text": text, "other": other, "bare": bare}


def test_empty_and_foreign_files_are_refused_and_left_untouched(tmp_path, capsys):
    files = _foreign_files(tmp_path)
    before = {name: fingerprint(path) for name, path in files.items()}
    for name, path in files.items():
        for create in (True, False):
            with pytest.raises(ValueError, match=str(path)):
                open_database(path, create=create)
        for args in (
            ("db", "check", "--db", str(path)),
            ("export", "--db", str(path), "--out", str(tmp_path / f"csv_{name}")),
            ("report", "--db", str(path), "--out", str(tmp_path / f"rep_{name}")),
        ):
            one_line_error(*asa(capsys, *args)[::2])
        assert fingerprint(path) == before[name], name
        assert side_files(path) == [], name


def test_a_folder_given_as_database_is_one_line(tmp_path, capsys):
    line = one_line_error(*asa(capsys, "db", "check", "--db", str(tmp_path))[::2])
    assert "folder" in line


# ---------------------------------------------------------------- fresh database race


def _open_at_once(path: str, start: multiprocessing.synchronize.Event, out: multiprocessing.Queue):
    start.wait()
    try:
        engine = open_database(path)
        with Session(engine) as s:
            version = s.get(Meta, "schema_version")
        engine.dispose()
        out.put("ok" if version is not None else "no version")
    except Exception as error:  # noqa: BLE001 - reported to the parent
        out.put(f"{type(error).__name__}: {error}")


def test_processes_opening_a_fresh_database_at_once_all_see_one_study(tmp_path):
    ctx = multiprocessing.get_context("fork")
    for round_ in range(3):
        path = tmp_path / f"fresh{round_}.db"
        start, out = ctx.Event(), ctx.Queue()
        procs = [ctx.Process(target=_open_at_once, args=(str(path), start, out)) for _ in range(6)]
        for p in procs:
            p.start()
        start.set()
        results = [out.get(timeout=60) for _ in procs]
        for p in procs:
            p.join(timeout=60)
        assert results == ["ok"] * len(procs), results
        engine = open_database(path, create=False)
        assert set(inspect(engine).get_table_names()) >= {"meta", "study", "trial"}
        engine.dispose()
        assert not [p for p in tmp_path.iterdir() if p.name.endswith(".creating")]


def test_a_new_database_is_whole_and_stamped(tmp_path):
    path = tmp_path / "new.db"
    open_database(path).dispose()
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    assert con.execute("SELECT value FROM meta").fetchone() == (str(SCHEMA_VERSION),)
    assert con.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    con.close()


# ---------------------------------------------------------------- read-only studies


def test_read_only_opening_writes_nothing(study_db):
    assert ro_uri(study_db).endswith("immutable=1")
    before = fingerprint(study_db)
    engine = open_database(study_db, create=False)
    with Session(engine) as s:
        assert s.scalars(select(Study)).one().seed == 7061
        s.add(Meta(key="x", value="y"))
        with pytest.raises(Exception, match="readonly|read-only|query_only"):
            s.commit()
    engine.dispose()
    assert fingerprint(study_db) == before
    assert side_files(study_db) == []


def test_a_read_only_study_can_be_checked_exported_and_reported(study_db, tmp_path, capsys):
    study_db.chmod(0o444)
    study_db.parent.chmod(0o555)  # root ignores both: the read-only opening is what counts
    try:
        before = fingerprint(study_db)
        code, out, err = asa(capsys, "db", "check", "--db", str(study_db), "--no-verify")
        assert code in (0, 1) and "Traceback" not in err, err
        assert "trial" in out
        out_csv = tmp_path.parent / f"{tmp_path.name}_csv"
        code, out, err = asa(capsys, "export", "--db", str(study_db), "--out", str(out_csv))
        assert code == 0, err
        assert (out_csv / "trial.csv").is_file()
        assert len(load_study(study_db).tables["trial"]) > 0  # what `asa report` reads
        assert fingerprint(study_db) == before
        assert side_files(study_db) == []
    finally:
        study_db.parent.chmod(0o755)
        study_db.chmod(0o644)


@pytest.mark.slow
def test_a_read_only_study_can_be_reported(study_db, tmp_path, capsys):
    study_db.chmod(0o444)
    try:
        before = fingerprint(study_db)
        report = tmp_path / "report"
        code, out, err = asa(capsys, "report", "--db", str(study_db), "--out", str(report))
        assert code == 0, err
        assert (report / "results.json").is_file()
        assert fingerprint(study_db) == before
        assert side_files(study_db) == []
    finally:
        study_db.chmod(0o644)


def test_a_study_in_use_is_read_through_its_wal(study_db):
    writer = open_database(study_db)
    with Session(writer) as s, s.begin():
        s.scalars(select(Study)).one().name = "renamed while open"
    try:
        assert ro_uri(study_db).endswith("mode=ro")  # the -wal file holds the commit
        reader = open_database(study_db, create=False)
        with Session(reader) as s:
            assert s.scalars(select(Study)).one().name == "renamed while open"
        reader.dispose()
    finally:
        writer.dispose()
