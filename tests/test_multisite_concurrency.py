"""Concurrent sessions on one study database (issue 24): eight ``asa run`` processes,
synthetic participants, started together on one PostgreSQL study (four at each of two
sites) and then on one SQLite study (no sites): every run ends well (no lock error reaches
the user), no sample row is lost (each finished trial holds one sample per tick it ran),
every order slot of each site's ledger is issued once, each site balanced, and ``asa db
check`` is clean. On PostgreSQL a writer killed by SIGKILL mid-trial is
resumed and its session completes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from study.data.dbtools import check
from study.data.storage import OrderSlot, Participant, Sample, SessionRow, Trial, open_database
from study.engine.counterbalance import balance
from tests.mini_protocol import mini_protocol

SESSIONS = 8


def _protocol(tmp_path: Path, timeout_s: float, sites: tuple[str, ...] = ()) -> str:
    path = tmp_path / "multisite.toml"
    path.write_text(
        mini_protocol(name="multisite", participants=8, seed=11, sites=sites, camera_hz=0,
                      timeout_s=timeout_s)
    )  # fmt: skip
    return str(path)


def _run(protocol: str, db: str, code: str, *extra: str, cwd: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    return subprocess.Popen(
        [sys.executable, "-m", "study.cli", "run", "--protocol", protocol, "--participant",
         code, "--db", db, "--input", "synthetic", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=cwd,
    )  # fmt: skip


def _check_study(
    db: str, codes: list[str], *, balanced: bool = True, sites: dict[str, str] | None = None
) -> None:
    """Clean, every session completed, every sample stored; each site's slots (``sites``:
    code -> site; none: one ledger) issued once and balanced."""
    report = check(db, verify_recordings=False)
    assert report.clean, report.text()
    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            people = s.scalars(select(Participant)).all()
            assert sorted(p.code for p in people) == sorted(codes)
            assert {r.status for r in s.scalars(select(SessionRow))} == {"completed"}
            slots = s.scalars(select(OrderSlot).order_by(OrderSlot.slot)).all()
            assert sorted(r.code for r in slots) == sorted(codes)
            site_of = sites or {code: "" for code in codes}
            for site in set(site_of.values()):
                mine = [r for r in slots if r.site == site]
                assert [r.slot for r in mine] == list(range(len(mine)))  # each issued once
                assert {r.code for r in mine} == {c for c, x in site_of.items() if x == site}
                orders = [p.mode_order for p in people if (p.site or "") == site]
                assert balance(orders, scheme="full_permutation")["balanced"] == balanced
            for trial in s.scalars(select(Trial).where(Trial.status != "aborted")):
                rows = s.scalar(
                    select(func.count()).select_from(Sample).where(Sample.trial_id == trial.id)
                )
                assert rows == trial.outcome["ticks"], (trial.id, rows, trial.outcome)
    finally:
        engine.dispose()


@pytest.mark.parametrize(
    "backend",
    [
        pytest.param("postgresql", marks=pytest.mark.postgres),
        "sqlite",
    ],
)
def test_eight_sessions_at_once(backend, tmp_path, request, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a server study's recordings are in the working folder
    db = request.getfixturevalue("pg_url") if backend == "postgresql" else str(tmp_path / "s.db")
    codes = [f"S{k + 1}" for k in range(SESSIONS)]
    sites = (
        {c: ("lyon", "delft")[k % 2] for k, c in enumerate(codes)} if backend != "sqlite" else {}
    )
    protocol = _protocol(tmp_path, 2.0, tuple(dict.fromkeys(sites.values())))
    procs = [
        _run(protocol, db, code, *(["--site", sites[code]] if sites else []), cwd=tmp_path)
        for code in codes
    ]
    for p in procs:
        _, err = p.communicate(timeout=900)
        assert p.returncode == 0, err
        assert "locked" not in err.lower() and "deadlock" not in err.lower(), err
    _check_study(db, codes, sites=sites or None)


def _samples(db: str) -> int:
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return int(conn.execute(select(func.count()).select_from(Sample)).scalar_one())
    finally:
        engine.dispose()


@pytest.mark.postgres
def test_a_killed_writer_resumes(pg_url, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    protocol = _protocol(tmp_path, 60.0)
    proc = _run(protocol, pg_url, "K1", cwd=tmp_path)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if _samples(pg_url) >= 100:  # mid-trial: 5 s of its first trial stored
                break
        except (ValueError, FileNotFoundError):
            pass  # the study is not made yet
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()[1]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)
    resumed = _run(protocol, pg_url, "K1", "--resume", cwd=tmp_path)
    _, err = resumed.communicate(timeout=900)
    assert resumed.returncode == 0, err
    _check_study(pg_url, ["K1"], balanced=False)  # one of the two orders
    engine = open_database(pg_url, create=False)
    try:
        with Session(engine) as s:
            statuses = [t.status for t in s.scalars(select(Trial).order_by(Trial.id))]
    finally:
        engine.dispose()
    assert statuses[0] == "aborted" and statuses.count("aborted") == 1, statuses  # the killed
    assert len(statuses) == 3  # ... then both main trials, the first one again
