"""The counterbalancing ledger (issue 20): order slots allocated whatever the form of the
participant code, every slot issued once, positions balanced after each full cycle; an
excluded participant's slot reissued first; databases made before the ledger backfilled;
``asa plan --db`` and ``asa db check`` on the ledger."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from study.data import locks
from study.data.dbtools import check
from study.data.storage import OrderSlot, Participant, Response, SessionRow, open_database
from study.engine.counterbalance import SlotOrders, balance, cycle_length
from study.engine.protocol import parse_protocol
from study.engine.session import _open, check_code, reserve_slots
from study.participants.scripted import ScriptedParticipant
from tests.mini_protocol import mini_protocol

# codes of every shape check_code allows: pseudonyms (more than 7 without digits), digits in
# the middle, leading zeros, zero, huge numbers, only digits, '-' and '_'
CODES = (
    "golf", "hotel", "india", "juliett", "kilo", "lima", "mike", "november", "oscar",
    "a1b", "P000", "P0001", "007", "0", "P999999", "9lives", "x-9_z", "Z_", "P01", "P1",
    "p01", "Q-0", "alpha-2-beta", "P10", "P2", "A" * 64, "zz99zz", "b_",
)  # fmt: skip
SCHEMES = ("full_permutation", "williams", "random")


def _text(scheme: str, seed: int) -> str:
    return mini_protocol(
        name="ledger",
        participants=6,
        seed=seed % 1000,
        modes=("manual", "reactive_bn", "contextual_task"),
        scheme=scheme,
        experience=True,
    )


def _protocol(tmp_path: Path, scheme: str, seed: int):
    path = tmp_path / f"{scheme}.toml"
    path.write_text(_text(scheme, seed))
    return parse_protocol(path.read_text(), str(path))


def _new(engine, protocol, db, code, seed, force=False):
    who = ScriptedParticipant(np.random.default_rng(seed))
    return _open(engine, protocol, code, db, who, seed=seed, resume=False, force=force).person


def _slots(engine) -> list[OrderSlot]:
    with Session(engine) as s:
        return list(s.scalars(select(OrderSlot).order_by(OrderSlot.slot)))


def _ledger_problems(db: Path) -> list[str]:
    return [p for p in check(db, verify_recordings=False).problems if "slot" in p]


@pytest.mark.parametrize("scheme", SCHEMES)
def test_codes_of_every_shape_get_every_slot_once(tmp_path, seed, scheme):
    assert all(check_code(c) == c for c in CODES)
    protocol = _protocol(tmp_path, scheme, seed)
    db = tmp_path / f"{scheme}.db"
    engine = open_database(db)
    codes = list(CODES)
    np.random.default_rng(seed).shuffle(codes)
    cycle = cycle_length(3, scheme)
    orders = SlotOrders(protocol.modes, scheme, seed % 1000)
    people = []
    for k, code in enumerate(codes):
        person = _new(engine, protocol, db, code, seed)
        people.append(person)
        assert (person.order_index, tuple(person.mode_order)) == orders(k)  # the k-th slot
        if cycle is not None and (k + 1) % cycle == 0:
            assert balance([p.mode_order for p in people], scheme=scheme)["balanced"], k
    slots = _slots(engine)
    assert [r.slot for r in slots] == list(range(len(CODES)))
    assert [r.code for r in slots] == codes
    engine.dispose()
    assert not _ledger_problems(db)


def test_an_excluded_participants_slot_is_reissued_first(tmp_path, seed):
    protocol = _protocol(tmp_path, "full_permutation", seed)
    db = tmp_path / "s.db"
    engine = open_database(db)
    for code in ("golf", "hotel", "india", "juliett"):
        _new(engine, protocol, db, code, seed)
    with Session(engine) as s, s.begin():
        rows = {r.participant.code: r for r in s.scalars(select(SessionRow))}
        rows["hotel"].status, rows["hotel"].note = "aborted", "excluded: practice not passed"
        rows["india"].status, rows["india"].note = "aborted", "aborted: Ctrl-C"  # keeps it
        rows["golf"].status = "completed"
    kilo = _new(engine, protocol, db, "kilo", seed)
    lima = _new(engine, protocol, db, "lima", seed)
    slots = {r.slot: r for r in _slots(engine)}
    assert slots[1].code == "kilo" and [h["code"] for h in slots[1].released] == ["hotel"]
    assert kilo.order_index == 1 and lima.order_index == 4  # lima: the lowest never issued
    assert sorted(slots) == [0, 1, 2, 3, 4]
    engine.dispose()
    assert not _ledger_problems(db)
    listed = subprocess.run(
        [sys.executable, "-m", "study.cli", "plan", "--db", str(db)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert listed.returncode == 0, listed.stderr
    assert "(released by hotel)" in listed.stdout and "5 order slots issued" in listed.stdout
    line = next(x for x in listed.stdout.splitlines() if x.strip().startswith("2  india"))
    assert "aborted" in line and "manual" in line


def test_a_database_without_a_ledger_is_backfilled(tmp_path, seed):
    protocol = _protocol(tmp_path, "full_permutation", seed)
    db = tmp_path / "old.db"
    engine = open_database(db)
    for code in ("P03", "golf", "hotel"):
        _new(engine, protocol, db, code, seed)
    with Session(engine) as s, s.begin():  # as the platform stored them before issue 20
        s.execute(delete(OrderSlot))
        for person in s.scalars(select(Participant)):
            person.order_index = {"P03": 2, "golf": 0, "hotel": 0}[person.code]
    new = _new(engine, protocol, db, "india", seed)
    slots = {r.code: r.slot for r in _slots(engine)}
    assert slots == {"P03": 2, "golf": 0, "hotel": 6, "india": 1}
    assert new.order_index == 1
    engine.dispose()
    assert not _ledger_problems(db)


def test_db_check_finds_interrupted_sessions_missing_questionnaires_and_stale_slots(tmp_path, seed):
    protocol = _protocol(tmp_path, "williams", seed)
    db = tmp_path / "s.db"
    engine = open_database(db)
    for code in ("golf", "hotel", "india"):
        _new(engine, protocol, db, code, seed)
    reserve_slots(engine, protocol, db, ["P05"], force=False)
    with Session(engine) as s, s.begin():
        rows = {r.participant.code: r for r in s.scalars(select(SessionRow))}
        rows["india"].status = "completed"  # without its experience questionnaire
        s.add(Response(participant_id=rows["hotel"].participant_id, instrument="experience",
                       item="age", value=30.0))  # fmt: skip
        rows["hotel"].status = "completed"
        bad = s.scalars(select(Participant).where(Participant.code == "hotel")).one()
        bad.order_index = 5  # not what its slot gives
    engine.dispose()
    with locks.held(locks.session_lock(db, "golf"), wait=False):  # golf runs, live
        report = check(db, verify_recordings=False)
    assert report.counts["live_sessions"] == 1
    problems = "\n".join(report.problems)
    assert "golf" not in problems
    assert "india" in problems and "'experience' questionnaire" in problems
    assert "order slot 1: gives row 1, but hotel has row 5" in problems
    assert "order slot 3: reserved for P05" in problems
    report = check(db, verify_recordings=False)  # nobody holds golf's session now
    line = next(p for p in report.problems if "golf" in p)
    assert "interrupted" in line and "--participant golf" in line and "--resume" in line


@pytest.mark.slow  # ~20 s on a contended machine; the CI test of concurrency is
# test_concurrent_writers.py::test_two_synths_and_four_runs_on_one_study
def test_concurrent_processes_never_share_a_slot(tmp_path, seed):
    path = tmp_path / "williams.toml"
    path.write_text(_text("williams", seed))
    db = tmp_path / "s.db"
    open_database(db).dispose()
    script = (
        "import sys, numpy as np\n"
        "from study.data.storage import open_database\n"
        "from study.engine.protocol import load_protocol\n"
        "from study.engine.session import _open\n"
        "from study.participants.scripted import ScriptedParticipant\n"
        "p = load_protocol(sys.argv[1]); e = open_database(sys.argv[2])\n"
        "for code in sys.argv[3:]:\n"
        "    _open(e, p, code, sys.argv[2], ScriptedParticipant(np.random.default_rng(0)),\n"
        "          seed=0, resume=False, force=False)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    groups = [[f"{w}{i}x" for i in range(8)] for w in "abc"]  # three processes
    procs = [
        subprocess.Popen([sys.executable, "-c", script, str(path), str(db), *g], env=env,
                         stderr=subprocess.PIPE, text=True)
        for g in groups
    ]  # fmt: skip
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    engine = open_database(db, create=False)
    assert [r.slot for r in _slots(engine)] == list(range(24))
    with Session(engine) as s:
        people = s.scalars(select(Participant)).all()
        assert balance([p.mode_order for p in people], scheme="williams")["balanced"]
    engine.dispose()
    assert not _ledger_problems(db)


def test_a_code_reserved_by_a_running_synth_is_refused_then_taken_up(tmp_path, seed):
    protocol = _protocol(tmp_path, "full_permutation", seed)
    db = tmp_path / "s.db"
    engine = open_database(db)
    slots, _ = reserve_slots(engine, protocol, db, ["P01", "P02"], force=False)
    assert slots == {"P01": 0, "P02": 1}
    with locks.held(locks.synth_lock(db), wait=False):  # the synthetic study runs
        with pytest.raises(ValueError, match="synthetic study running"):
            _new(engine, protocol, db, "P02", seed)
        assert _new(engine, protocol, db, "golf", seed).order_index == 2
    person = _new(engine, protocol, db, "P02", seed)  # it was interrupted: P02 takes slot 1
    assert person.order_index == 1
    assert [(r.slot, r.code, r.status) for r in _slots(engine)] == [
        (0, "P01", "reserved"), (1, "P02", "issued"), (2, "golf", "issued"),
    ]  # fmt: skip
    engine.dispose()
