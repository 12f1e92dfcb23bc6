"""PostgreSQL as a study database (issue 24): a synthetic study written through ``asa
synth --db URL`` and checked, exported, reported and planned from the server as from
SQLite; a session writing its ticks straight to the server; timestamps UTC-aware on both
backends; a bad URL is one line and exit status 2. The server is real (study/data/pg_local.py)."""

from __future__ import annotations

import csv
import datetime as dt
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy
from sqlalchemy.orm import Session

from study.data import server_locks
from study.data.dbtools import check
from study.data.storage import Study, get_study, open_database
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.jobs.synth import run_synthetic_study
from study.participants import ScriptedParticipant
from tests.cli_helpers import asa
from tests.mini_protocol import mini_protocol

pytestmark = pytest.mark.postgres

REPO = Path(__file__).resolve().parents[1]

# the smallest study with every kind of row: questions, TLX responses, two modes
MINI = mini_protocol(name="mini-pg", participants=2, baseline_questions=3, timeout_s=60.0, tlx=True)


def _asa(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``asa args`` in a fresh process, run from ``cwd`` with this checkout's packages."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args],
        capture_output=True, text=True, timeout=600, cwd=cwd, env=env,
    )  # fmt: skip


def _csv_rows(folder: Path) -> dict[str, list[list[str]]]:
    out = {}
    for path in sorted(folder.glob("*.csv")):
        with path.open(newline="") as f:
            out[path.stem] = list(csv.reader(f))
    return out


def test_a_synthetic_study_on_postgres_as_on_sqlite(pg_url, tmp_path, capsys, monkeypatch):
    """``asa synth`` into the server (in its own process, with worker processes), then
    ``asa db check``, ``export``, ``report`` and ``plan`` on the URL; the exported tables
    have the rows of the same study run into SQLite."""
    proto = tmp_path / "mini.toml"
    proto.write_text(MINI)
    done = _asa("synth", "--protocol", str(proto), "--participants", "2", "--seed", "3",
                "--workers", "2", "--db", pg_url, cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "2 participants run" in done.stdout
    lite = tmp_path / "lite" / "s.db"
    run_synthetic_study(str(proto), lite, participants=2, seed=3, workers=1, record=False)
    # the recordings are local, beside the server database's stand-in name
    name = pg_url.rsplit("/", 1)[1]
    assert list((tmp_path / f"{name}_recordings").rglob("*.rrd"))

    monkeypatch.chdir(tmp_path)  # where the recordings are found
    code, out, err = asa(capsys, "db", "check", "--db", pg_url)
    assert code == 0 and "clean" in out, out + err
    for db, folder in ((pg_url, "pg"), (str(lite), "lite")):
        code, _, err = asa(capsys, "export", "--db", db, "--out", str(tmp_path / folder))
        assert code == 0, err
    pg, sqlite = _csv_rows(tmp_path / "pg"), _csv_rows(tmp_path / "lite")
    assert {k: len(v) for k, v in pg.items()} == {k: len(v) for k, v in sqlite.items()}
    assert len(pg["sample"]) > 100 and len(pg["participant"]) == 3  # with the header row
    # the per-tick rows went through the server unchanged (same ids, same values), and so
    # did every other row but where and when (asa db diff)
    assert pg["sample"] == sqlite["sample"]
    code, out, err = asa(capsys, "db", "diff", pg_url, str(lite))
    assert code == 0 and "identical" in out, out + err

    code, _, err = asa(capsys, "report", "--db", pg_url, "--out", str(tmp_path / "report"))
    assert code == 0, err
    assert (tmp_path / "report" / "report.html").stat().st_size > 1000

    code, out, err = asa(capsys, "plan", "--db", pg_url)
    assert code == 0, err
    assert "2 order slots issued" in out
    assert "P01" in out and "P02" in out and "completed" in out


def test_a_session_writes_its_ticks_to_the_server(pg_url, tmp_path):
    """The session engine's own writer (per-tick samples, events, the outcome) on the
    server, then ``asa db check`` finds it whole."""
    proto = tmp_path / "mini.toml"
    proto.write_text(MINI)
    summary = run_session(
        load_protocol(proto),
        "P01",
        pg_url,
        participant=ScriptedParticipant(np.random.default_rng(3)),
        seed=3,
        recordings=tmp_path / "rec",
    )
    assert summary.status == "completed"
    report = check(pg_url, verify_recordings=False)
    assert report.clean, report.text()
    assert report.counts["sample"] > 100 and report.counts["trial"] == 3  # baseline, 2 main


def test_a_session_lock_is_seen_on_the_server_and_dies_with_its_process(pg_url, tmp_path):
    """A process holding participant P07's session lock (study/data/server_locks.py): seen
    and named from another connection, a session for P07 is refused, and the lock is gone
    once the holder is killed."""
    hold = (
        "import sys, time\n"
        "from study.data import server_locks as L\n"
        "with L.held(sys.argv[1], L.session_lock('P07'), wait=False):\n"
        "    print('held', flush=True)\n"
        "    time.sleep(120)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen(
        [sys.executable, "-c", hold, pg_url], stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        assert child.stdout.readline().strip() == "held"
        name = server_locks.session_lock("P07")
        engine = sqlalchemy.create_engine(pg_url)
        with engine.connect() as conn:
            assert server_locks.is_held(conn, name)
            assert server_locks.holder(conn, name).startswith(f"{child.pid} on ")
        proto = tmp_path / "mini.toml"
        proto.write_text(MINI)
        with pytest.raises(ValueError, match=f"P07 is running in another process .pid {child.pid}"):
            run_session(load_protocol(proto), "P07", pg_url, seed=1,
                        participant=ScriptedParticipant(np.random.default_rng(1)))  # fmt: skip
    finally:
        child.kill()
        child.wait()
    deadline = time.monotonic() + 10
    with engine.connect() as conn:
        while server_locks.is_held(conn, name) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not server_locks.is_held(conn, name)
    engine.dispose()
    with server_locks.held(pg_url, name, wait=False):
        pass


def _in_child(engine, out) -> None:
    """The studies the child sees and its server connection's backend pid."""
    with Session(engine) as s:
        backend = s.execute(sqlalchemy.text("SELECT pg_backend_pid()")).scalar()
        out.put((len(s.scalars(sqlalchemy.select(Study)).all()), backend))


def test_a_forked_child_never_uses_the_parents_connection(pg_url):
    """An engine opened before a fork: the child gets a connection of its own (the
    parent's pooled one, whose socket both would share, is dropped in the child), and the
    parent's connection still works afterwards."""
    import multiprocessing

    engine = open_database(pg_url)
    with Session(engine) as s, s.begin():
        s.add(Study(name="t", protocol_text="", protocol_sha256="0" * 64,
                    platform_version="t", seed=0))  # fmt: skip
        parent_pid = s.execute(sqlalchemy.text("SELECT pg_backend_pid()")).scalar()
    ctx = multiprocessing.get_context("fork")
    out = ctx.Queue()
    child = ctx.Process(target=_in_child, args=(engine, out))
    child.start()
    child.join(30)
    assert child.exitcode == 0
    studies, child_backend = out.get(timeout=5)
    assert studies == 1 and child_backend != parent_pid
    with Session(engine) as s:
        assert s.execute(sqlalchemy.text("SELECT pg_backend_pid()")).scalar() == parent_pid
        assert get_study(s).name == "t"
    engine.dispose()


def test_the_write_lock_holds_on_an_empty_database(pg_url):
    """While one transaction holds the study's write lock on a database without a study
    row, another one waits for it (here: gives up after its lock timeout)."""
    from study.data.ledger import lock_study

    engine = open_database(pg_url)
    with Session(engine) as first, first.begin():
        lock_study(first)
        assert get_study(first) is None
        with Session(engine) as second, second.begin():
            second.execute(sqlalchemy.text("SET LOCAL lock_timeout = '300ms'"))
            with pytest.raises(sqlalchemy.exc.OperationalError, match="lock timeout"):
                lock_study(second)
    with Session(engine) as third, third.begin():
        lock_study(third)  # free again once the first has committed
    engine.dispose()


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_timestamps_are_utc_aware_when_read_back(backend, pg_url, tmp_path):
    db = pg_url if backend == "postgresql" else str(tmp_path / "t.db")
    if backend == "postgresql":  # a server that answers in another zone
        with sqlalchemy.create_engine(pg_url).connect() as conn:
            name = pg_url.rsplit("/", 1)[1]
            conn.exec_driver_sql(f"ALTER DATABASE {name} SET timezone TO 'America/New_York'")
            conn.commit()
    written = dt.datetime(2026, 3, 29, 1, 30, 15, 123456, tzinfo=dt.timezone(dt.timedelta(hours=2)))
    engine = open_database(db)
    with Session(engine) as s, s.begin():
        s.add(Study(name="t", protocol_text="", protocol_sha256="0" * 64,
                    platform_version="t", seed=0, created_at=written))  # fmt: skip
    engine.dispose()
    engine = open_database(db, create=False)
    with Session(engine) as s:
        read = get_study(s).created_at
    engine.dispose()
    assert read == written and read.utcoffset() == dt.timedelta(0)
    assert read.tzinfo == dt.UTC


def test_a_bad_url_is_one_line_and_exit_2(pg_server, tmp_path, capsys, monkeypatch):
    from study.data import pg_local as pg

    monkeypatch.chdir(tmp_path)
    wrong_port = f"postgresql://asa@127.0.0.1:{pg._free_port()}/nothing"
    for url, says in (
        (wrong_port, "cannot be used as a study database"),
        (f"postgresql+nosuchdriver://asa@127.0.0.1:{pg_server.port}/x", "not a database URL"),
    ):
        for args in (("db", "check", "--db", url), ("plan", "--db", url)):
            code, _, err = asa(capsys, *args)
            lines = err.strip().splitlines()
            assert code == 2 and len(lines) == 1, err
            assert url in lines[0] and says in lines[0] and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []
