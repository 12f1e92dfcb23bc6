"""``asa db push`` (issue 24): offline sites' SQLite files pushed into one study database,
SQLite -> SQLite and SQLite -> PostgreSQL (a real server, study/data/pg_local.py).

Two sites' files with scripted participants (a tiny protocol, no recordings): both
sites' participants and ledgers in one study, ``asa db check`` clean; a second push
changes nothing; a conflict is one line naming the participant and writes nothing; a
session pushed aborted and resumed since replaces its earlier push; a running session is
held back; bad input is one line and exit status 2."""

from __future__ import annotations

import hashlib
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import func, select

from study.data.pushdata import read_people, session_views
from study.data.storage import Base, open_database
from study.engine.clocks import ExperimenterControl
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.engine.sites import Place
from study.participants import ScriptedParticipant
from tests.cli_helpers import asa
from tests.mini_protocol import mini_protocol

REPO = Path(__file__).resolve().parents[1]
# the smallest study with every kind of row (questions, responses outside and inside
# trials, two modes) at two sites; trials end at a 2 s time limit
MINI = mini_protocol(
    name="mini-push", sites=("lyon", "delft"), experience=True, baseline_questions=1, tlx=True
)


class _Crash(Exception):
    """A machine going down mid-trial."""


def _session(protocol, db: Path, code: str, site: str, rng, *, stop_at: int | None = None,
             crash_at: int | None = None, resume: bool = False) -> None:  # fmt: skip
    """One scripted session of ``code`` at ``site`` into ``db``: aborted by the
    experimenter at tick ``stop_at`` or cut off by a crash at ``crash_at``."""
    control = ExperimenterControl()
    seed = int(rng.integers(0, 2**31))

    def on_tick(tick: int, _writer) -> None:
        if tick == stop_at:
            control.abort("power cut")
        if tick == crash_at:
            raise _Crash

    driver = ScriptedParticipant(np.random.default_rng(seed))
    try:
        run_session(protocol, code, db, participant=driver, seed=seed, record=False,
                    place=Place(site, f"{site}-1"), control=control, on_tick=on_tick,
                    resume=resume)  # fmt: skip
    except _Crash:
        pass


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The protocol and two sites' files: lyon (L01, L02 completed; L03 aborted by the
    experimenter mid-trial) and delft (D01, D02 completed); the study seeded from
    ``ASA_TEST_SEED``."""
    import os

    rng = np.random.default_rng(int(os.environ.get("ASA_TEST_SEED", "20261123")))
    folder = tmp_path_factory.mktemp("sites")
    (folder / "mini.toml").write_text(MINI)
    protocol = load_protocol(folder / "mini.toml")
    lyon, delft = folder / "lyon" / "lyon.db", folder / "delft" / "delft.db"
    lyon.parent.mkdir()
    delft.parent.mkdir()
    for code in ("L01", "L02"):
        _session(protocol, lyon, code, "lyon", rng)
    _session(protocol, lyon, "L03", "lyon", rng, stop_at=int(rng.integers(5, 30)))
    for code in ("D01", "D02"):
        _session(protocol, delft, code, "delft", rng)
    return {"protocol": protocol, "lyon": lyon, "delft": delft, "rng": rng, "folder": folder}


def _copy(db: Path, to: Path) -> Path:
    """A copy of the SQLite file ``db`` at ``to`` (its folder made)."""
    to.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(db, to)
    return to


def _counts(db: str | Path) -> dict[str, int]:
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return {
                name: int(conn.execute(select(func.count()).select_from(t)).scalar_one())
                for name, t in Base.metadata.tables.items()
            }
    finally:
        engine.dispose()


def _views(db: str | Path) -> dict[str, dict]:
    """Every participant's sessions as compared by a push (global keys, no ids)."""
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return {code: session_views(rows) for code, rows in read_people(conn).items()}
    finally:
        engine.dispose()


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _pushed(capsys, src: Path, dst: str | Path, *extra: str) -> dict:
    code, out, err = asa(capsys, "db", "push", "--from", str(src), "--to", str(dst), "--json",
                         *extra)  # fmt: skip
    assert code == 0, err
    return json.loads(out)


def _two_sites(capsys, study, hub: str | Path, monkeypatch) -> None:
    """Push both sites into ``hub`` and check the study there."""
    first = _pushed(capsys, study["lyon"], hub)
    assert first["study_created"] and first["totals"]["participants"] == 3
    second = _pushed(capsys, study["delft"], hub)
    assert not second["study_created"] and second["totals"]["participants"] == 2
    code, out, err = asa(capsys, "db", "check", "--db", str(hub), "--no-verify")
    assert code == 0 and "clean" in out, out + err
    code, out, err = asa(capsys, "plan", "--db", str(hub), "--json")
    assert code == 0, err
    ledger = {(r["site"], r["slot"]): r["code"] for r in json.loads(out)["slots"]}
    assert ledger == {("lyon", 0): "L01", ("lyon", 1): "L02", ("lyon", 2): "L03",
                      ("delft", 0): "D01", ("delft", 1): "D02"}  # fmt: skip
    views = _views(hub)
    assert views == {**_views(study["lyon"]), **_views(study["delft"])}


def _again_changes_nothing(capsys, study, hub: str | Path, twin: Path) -> None:
    """Pushing both files again: nothing written (row counts, and ``asa db diff`` against
    ``twin``, the same pushes into a file, identical before and after)."""
    before = _counts(hub)
    for site in ("lyon", "delft"):
        again = _pushed(capsys, study[site], hub)
        assert not again["changed"] and again["totals"]["participants_already_there"] >= 2
        assert {p["action"] for p in again["participants"]} == {"already there"}
    code, out, err = asa(capsys, "db", "push", "--from", str(study["lyon"]), "--to", str(hub))
    assert code == 0 and "everything was already there" in out, err
    assert _counts(hub) == before
    code, out, err = asa(capsys, "db", "diff", str(hub), str(twin))
    assert code == 0 and "identical" in out, out + err


def test_two_sites_pushed_into_one_file_and_again(study, tmp_path, capsys, monkeypatch):
    hub = tmp_path / "hub" / "study.db"
    hub.parent.mkdir()
    dry = _pushed(capsys, study["lyon"], hub, "--dry-run")
    assert dry["dry_run"] and dry["totals"]["participants"] == 3 and not hub.exists()
    _two_sites(capsys, study, hub, monkeypatch)
    alone = tmp_path / "alone" / "lyon.db"
    alone.parent.mkdir()
    _pushed(capsys, study["lyon"], alone)  # a first push keeps every row as it was
    code, out, err = asa(capsys, "db", "diff", str(study["lyon"]), str(alone))
    assert code == 0 and "identical" in out, out + err
    twin = _copy(hub, tmp_path / "twin.db")
    digest = _digest(hub)
    dry = _pushed(capsys, study["lyon"], hub, "--dry-run")
    assert not dry["changed"] and _digest(hub) == digest
    _again_changes_nothing(capsys, study, hub, twin)


def test_a_resumed_session_replaces_its_aborted_push(study, tmp_path, capsys):
    lyon = _copy(study["lyon"], tmp_path / "lyon" / "lyon.db")
    hub = tmp_path / "hub.db"
    _pushed(capsys, lyon, hub)
    before = _views(hub)["L03"]
    assert [v.fields["status"] for v in before.values()] == ["aborted"]
    _session(study["protocol"], lyon, "L03", "lyon", study["rng"], resume=True)
    report = _pushed(capsys, lyon, hub)
    people = {p["code"]: p for p in report["participants"]}
    assert people["L03"]["action"] == "updated" and "replaced" in people["L03"]["detail"]
    assert {people[c]["action"] for c in ("L01", "L02")} == {"already there"}
    assert _views(hub) == _views(lyon)  # as if pushed once, after the resumption
    code, out, err = asa(capsys, "db", "check", "--db", str(hub), "--no-verify")
    assert code == 0 and "clean" in out, out + err
    assert not _pushed(capsys, lyon, hub)["changed"]


def test_a_running_session_is_held_back(study, tmp_path, capsys):
    lyon = _copy(study["lyon"], tmp_path / "lyon" / "lyon.db")
    rng = study["rng"]
    _session(study["protocol"], lyon, "L04", "lyon", rng, crash_at=int(rng.integers(5, 30)))
    hub = tmp_path / "hub.db"
    code, out, err = asa(capsys, "db", "push", "--from", str(lyon), "--to", str(hub))
    assert code == 0, err
    held = [line for line in err.splitlines() if "held back" in line]
    assert len(held) == 1 and "L04" in held[0] and "interrupted" in held[0], err
    assert "1 participant held back" in out and "a later push takes them" in out
    assert set(_views(hub)) == {"L01", "L02", "L03"}
    _session(study["protocol"], lyon, "L04", "lyon", rng, resume=True)
    report = _pushed(capsys, lyon, hub)
    assert [p["code"] for p in report["participants"] if p["action"] == "pushed"] == ["L04"]
    assert _views(hub) == _views(lyon)


def _refused(capsys, src: Path, dst: str | Path, *says: str) -> str:
    """A push refused with one line on stderr holding ``says``, exit status 2."""
    code, out, err = asa(capsys, "db", "push", "--from", str(src), "--to", str(dst))
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    for words in says:
        assert words in lines[0], lines[0]
    return lines[0]


def test_a_conflict_writes_nothing(study, tmp_path, capsys):
    hub = tmp_path / "hub.db"
    _pushed(capsys, study["lyon"], hub)
    digest = _digest(hub)
    # another machine at lyon gave the code L01 to someone else (another seed) ...
    other = tmp_path / "lyon-2" / "lyon.db"
    other.parent.mkdir()
    _session(study["protocol"], other, "L01", "lyon", study["rng"])
    _refused(capsys, other, hub, "participant L01", "field 'participant.seed'",
             "nothing was pushed", str(other))  # fmt: skip
    # ... or gave out lyon's slot 0 again, to a new code
    third = tmp_path / "lyon-3" / "lyon.db"
    third.parent.mkdir()
    _session(study["protocol"], third, "L07", "lyon", study["rng"])
    _refused(capsys, third, hub, "participant L07", "L01 holds it there", "order_slot.slot")
    # ... or L02's trial data differ (a changed outcome in a copy)
    changed = _copy(study["lyon"], tmp_path / "lyon-4" / "lyon.db")
    with sqlite3.connect(changed) as conn:
        conn.execute(
            "UPDATE trial SET collisions = collisions + 1 WHERE phase = 'main' AND "
            "participant_id = (SELECT id FROM participant WHERE code = 'L02')"
        )
    _refused(capsys, changed, hub, "participant L02", "field 'trial.collisions'")
    assert _digest(hub) == digest


def test_bad_input_is_one_line(study, tmp_path, capsys):
    hub = tmp_path / "hub.db"
    lyon = study["lyon"]
    _refused(capsys, tmp_path / "nothing.db", hub, "nothing.db: no such file")
    text = tmp_path / "notes.db"
    text.write_text("not a database\n")
    _refused(capsys, text, hub, "notes.db")
    _refused(capsys, lyon, text, "notes.db")
    _refused(capsys, lyon, lyon, "is the database being pushed")
    old = _copy(REPO / "tests" / "golden" / "v1_study.db", tmp_path / "v1" / "old.db")
    _refused(capsys, old, hub, "older than this platform", "asa db upgrade")
    digest = _digest(old)
    _refused(capsys, lyon, old, "older than this platform", "asa db upgrade")
    code, _, err = asa(capsys, "db", "push", "--from", str(lyon), "--to", str(old), "--dry-run")
    assert code == 2 and "asa db upgrade" in err and _digest(old) == digest
    assert not hub.exists()
    other = tmp_path / "other" / "other.db"
    other.parent.mkdir()
    protocol = load_protocol(_write(tmp_path / "other.toml", MINI.replace("seed = 5", "seed = 6")))
    _session(protocol, other, "L01", "lyon", study["rng"])
    _pushed(capsys, lyon, hub)
    _refused(capsys, other, hub, "another study", "field 'study.protocol_sha256'")


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.postgres
def test_two_sites_pushed_into_a_server(study, pg_url, tmp_path, capsys, monkeypatch):
    """Both sites into one PostgreSQL study, as into a file (the same rows, the same
    ids: ``asa db diff`` identical); again: nothing changes; a conflict writes nothing; a
    resumed session replaces its push; a running one is held back."""
    monkeypatch.chdir(tmp_path)
    dry = _pushed(capsys, study["lyon"], pg_url, "--dry-run")
    assert dry["study_created"] and _tables(pg_url) == []
    _two_sites(capsys, study, pg_url, monkeypatch)
    twin = tmp_path / "twin.db"
    for site in ("lyon", "delft"):
        _pushed(capsys, study[site], twin)
    report = _pushed(capsys, study["lyon"], pg_url)
    assert "stay beside" in report["recordings"]
    _again_changes_nothing(capsys, study, pg_url, twin)
    other = tmp_path / "lyon-2" / "lyon.db"
    other.parent.mkdir()
    _session(study["protocol"], other, "L02", "lyon", study["rng"])
    _refused(capsys, other, pg_url, "participant L02", "on the server", "nothing was pushed")
    code, out, err = asa(capsys, "db", "diff", pg_url, str(twin))
    assert code == 0 and "identical" in out, out + err
    lyon = _copy(study["lyon"], tmp_path / "lyon" / "lyon.db")
    rng = study["rng"]
    _session(study["protocol"], lyon, "L03", "lyon", rng, resume=True)
    _session(study["protocol"], lyon, "L04", "lyon", rng, crash_at=int(rng.integers(5, 30)))
    code, out, err = asa(capsys, "db", "push", "--from", str(lyon), "--to", pg_url)
    assert code == 0 and "L04 held back" in err and "replaced" in out, out + err
    assert _views(pg_url)["L03"] == _views(lyon)["L03"]
    code, out, err = asa(capsys, "db", "check", "--db", pg_url, "--no-verify")
    assert code == 0 and "clean" in out, out + err


def _tables(url: str) -> list[str]:
    import sqlalchemy

    engine = sqlalchemy.create_engine(url)
    try:
        return sqlalchemy.inspect(engine).get_table_names()
    finally:
        engine.dispose()


def _stored(db: str | Path, query: str) -> list[tuple]:
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return [tuple(r) for r in conn.exec_driver_sql(query)]
    finally:
        engine.dispose()


def test_recording_paths_and_platform_version(study, tmp_path, capsys):
    """Into a file in another folder a recording path is rewritten relative to it (the
    file is not copied); a site on another platform version is pushed, with a note."""
    lyon = _copy(study["lyon"], tmp_path / "site" / "lyon.db")
    with sqlite3.connect(lyon) as conn:
        conn.execute("UPDATE trial SET recording_path = 'lyon_recordings/t' || id || '.rrd'")
    hub = tmp_path / "hub" / "deep" / "study.db"
    hub.parent.mkdir(parents=True)
    report = _pushed(capsys, lyon, hub)
    assert "not copied" in report["recordings"]
    paths = {p for (p,) in _stored(hub, "SELECT recording_path FROM trial")}
    assert paths and all(p.startswith("../../site/lyon_recordings/t") for p in paths), paths
    assert not (hub.parent / "lyon_recordings").exists()
    other = _copy(study["delft"], tmp_path / "delft" / "delft.db")
    with sqlite3.connect(other) as conn:
        conn.execute("UPDATE study SET platform_version = '0.0.1-site'")
    code, out, err = asa(capsys, "db", "push", "--from", str(other), "--to", str(hub))
    assert code == 0, err
    assert "platform version 0.0.1-site" in out and "2 new participants" in out
    (version,) = _stored(hub, "SELECT platform_version FROM study")[0]
    assert version != "0.0.1-site"  # the destination keeps its own study row


def test_a_slot_reissued_after_an_exclusion_is_taken_over(study, tmp_path, capsys):
    """L01 excluded at the site and pushed; the site gives its slot to L05 (the ledger's
    reissue); the push hands the server's slot to L05, the earlier holder kept."""
    protocol, rng = study["protocol"], study["rng"]
    site = tmp_path / "site" / "lyon.db"
    site.parent.mkdir()
    _session(protocol, site, "L01", "lyon", rng, stop_at=int(rng.integers(5, 30)))
    with sqlite3.connect(site) as conn:  # as a failed practice ends a session
        conn.execute("UPDATE session SET note = 'excluded: a practice was not passed'")
    hub = tmp_path / "hub.db"
    _pushed(capsys, site, hub)
    _session(protocol, site, "L05", "lyon", rng)
    report = _pushed(capsys, site, hub)
    assert {p["code"]: p["action"] for p in report["participants"]} == {
        "L01": "already there", "L05": "pushed"}  # fmt: skip
    rows = _stored(hub, "SELECT site, slot, code, released FROM order_slot")
    assert len(rows) == 1 and rows[0][:3] == ("lyon", 0, "L05") and "L01" in rows[0][3]
    code, out, err = asa(capsys, "db", "check", "--db", str(hub), "--no-verify")
    assert code == 0 and "clean" in out, out + err
    assert _views(hub) == _views(site)
    assert not _pushed(capsys, site, hub)["changed"]
    fresh = tmp_path / "fresh.db"  # both at once: the earlier holder's id remapped
    _pushed(capsys, site, fresh)
    (released,) = _stored(fresh, "SELECT released FROM order_slot")[0]
    (l01,) = _stored(fresh, "SELECT id FROM participant WHERE code = 'L01'")[0]
    assert json.loads(released)[0]["participant_id"] == l01
