"""Sites of a multi-site study (issue 24): the protocol's ``[study] sites``, a session's
site and machine, one counterbalancing ledger per site (each site balanced on its own,
its own random draws), a participant kept at its site, the checks of ``asa db check``,
``asa plan --db`` showing each site's ledger and the rule, ``asa synth --site``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from analysis.data import load_study, tidy
from study.data.dbtools import check
from study.data.storage import OrderSlot, Participant, SessionRow, Study, open_database
from study.engine.counterbalance import SlotOrders, balance, cycle_length, site_seed
from study.engine.protocol import parse_protocol
from study.engine.session import _open
from study.engine.sites import Place
from study.participants.scripted import ScriptedParticipant
from tests.mini_protocol import mini_protocol

ROOT = Path(__file__).resolve().parents[1]
SITES = ("lyon", "delft", "porto")


def _text(seed: int, scheme: str = "williams", sites: tuple[str, ...] = SITES) -> str:
    return mini_protocol(
        name="multisite",
        participants=6,
        seed=seed % 1000,
        sites=sites,
        modes=("manual", "reactive_bn", "contextual_task"),
        scheme=scheme,
        camera_hz=0,
        timeout_s=1.0,
    )


def _protocol(tmp_path: Path, seed: int, scheme: str = "williams", sites=SITES):
    path = tmp_path / f"{scheme}.toml"
    path.write_text(_text(seed, scheme, sites))
    return parse_protocol(path.read_text(), str(path))


def _new(engine, protocol, db, code, seed, site, machine="rig-1"):
    who = ScriptedParticipant(np.random.default_rng(seed))
    opened = _open(
        engine,
        protocol,
        code,
        db,
        who,
        seed=seed,
        resume=False,
        force=False,
        place=Place(site, machine),
    )
    return opened.person


def _problems(db: Path) -> list[str]:
    """What ``asa db check`` finds, but the sessions that _open leaves running."""
    return [p for p in check(db, verify_recordings=False).problems if "still running" not in p]


def _asa(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    environment = {k: v for k, v in os.environ.items() if k != "ASA_SITE"}
    environment.update({"PYTHONPATH": str(ROOT), **(env or {})})
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=environment,
        timeout=300,
    )


@pytest.mark.parametrize("scheme", ["williams", "full_permutation", "random"])
def test_each_site_has_its_own_ledger_balanced_on_its_own(tmp_path, seed, scheme):
    protocol = _protocol(tmp_path, seed, scheme)
    db = tmp_path / "s.db"
    engine = open_database(db)
    rng = np.random.default_rng(seed)
    cycle = cycle_length(3, scheme) or 4
    arrivals = [site for site in SITES for _ in range(2 * cycle)]
    rng.shuffle(arrivals)  # the sites' participants arrive interleaved
    people: dict[str, list[Participant]] = {site: [] for site in SITES}
    for i, site in enumerate(arrivals):
        people[site].append(_new(engine, protocol, db, f"{site}-{i:03d}", seed + i, site))
    for site in SITES:
        orders = SlotOrders(protocol.modes, scheme, seed % 1000, site)
        got = [(p.order_index, tuple(p.mode_order)) for p in people[site]]
        assert got == [orders(k) for k in range(2 * cycle)]  # the site's slots 0, 1, ...
        assert all(p.site == site for p in people[site])
        if scheme != "random":
            assert balance([p.mode_order for p in people[site]], scheme=scheme)["balanced"]
    with Session(engine) as s:
        slots = s.scalars(select(OrderSlot)).all()
        for site in SITES:
            assert sorted(r.slot for r in slots if r.site == site) == list(range(2 * cycle))
        sessions = s.scalars(select(SessionRow)).all()
        assert {(r.site, r.machine) for r in sessions} == {(x, "rig-1") for x in SITES}
        assert len({r.uid for r in sessions}) == len(sessions)
        assert s.scalars(select(Study)).one().sites == list(SITES)
    engine.dispose()
    assert _problems(db) == []


def test_random_orders_differ_between_sites_and_repeat_within_one(seed):
    modes = ("manual", "reactive_bn", "contextual_task")
    draws = {
        site: [SlotOrders(modes, "random", seed, site)(k)[0] for k in range(40)]
        for site in (None, "", "lyon", "delft")
    }
    assert draws[None] == draws[""]  # no site: the study seed itself, as before sites
    assert site_seed(seed, None) == seed and site_seed(seed, "lyon") != seed
    assert draws["lyon"] != draws["delft"] and draws["lyon"] != draws[None]
    assert draws["lyon"] == [SlotOrders(modes, "random", seed, "lyon")(k)[0] for k in range(40)]


def test_a_participant_stays_at_its_site_and_sites_are_checked(tmp_path, seed):
    protocol = _protocol(tmp_path, seed)
    db = tmp_path / "s.db"
    engine = open_database(db)
    _new(engine, protocol, db, "L01", seed, "lyon")
    cases = {
        None: "field 'session.site': study 'multisite' runs at sites lyon, delft, porto",
        "paris": "field 'session.site': 'paris' is not a site of study 'multisite'",
        "delft": "field 'participant.site': participant L01 belongs to site lyon, not delft",
    }
    for site, words in cases.items():
        with pytest.raises(ValueError, match=words.replace("(", r"\(")) as raised:
            _new(engine, protocol, db, "L01", seed, site)
        assert "\n" not in str(raised.value)
    with Session(engine) as s:  # nothing written by the refusals
        assert len(s.scalars(select(SessionRow)).all()) == 1
    engine.dispose()
    plain = parse_protocol(_text(seed, sites=()), "plain.toml")
    other = tmp_path / "plain.db"
    engine = open_database(other)
    with pytest.raises(ValueError, match="field 'session.site': study 'multisite' has no sites"):
        _new(engine, plain, other, "P01", seed, "lyon")
    person = _new(engine, plain, other, "P01", seed, None)
    assert person.site is None
    engine.dispose()


def test_db_check_finds_a_session_at_another_site(tmp_path, seed):
    protocol = _protocol(tmp_path, seed)
    db = tmp_path / "s.db"
    engine = open_database(db)
    _new(engine, protocol, db, "L01", seed, "lyon")
    _new(engine, protocol, db, "D01", seed, "delft")
    with Session(engine) as s, s.begin():
        row = s.scalars(select(SessionRow).order_by(SessionRow.id)).first()
        row.site = "porto"
        s.scalars(select(Participant).where(Participant.code == "D01")).one().site = "paris"
    engine.dispose()
    problems = _problems(db)
    assert "participant L01: session 1 ran at site porto, the participant belongs to lyon" in (
        problems
    )
    assert any(
        p.startswith("participant D01: site paris is not one of the study's") for p in problems
    )
    assert any("order slot 0 of site delft: D01 belongs to site paris" in p for p in problems)


@pytest.mark.parametrize(
    ("sites", "words"),
    [
        ('["lyon", "lyon"]', "must not repeat names; 'lyon' appears twice"),
        ('["ly on"]', "sites[0]': must be 1-32 letters, digits, '_' or '-'"),
        ('["' + "x" * 33 + '"]', "sites[0]': must be 1-32 letters"),
        ('"lyon"', "must be a list of strings"),
    ],
)
def test_bad_sites_are_one_line(tmp_path, sites, words):
    path = tmp_path / "bad.toml"
    path.write_text(_text(1).replace(f"sites = {json.dumps(list(SITES))}", f"sites = {sites}"))
    done = _asa("plan", "--protocol", str(path), cwd=tmp_path)
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()
    assert str(path) in line and "study" in line and words in line


def test_sessions_at_two_sites_from_the_command_line(tmp_path, seed):
    path = tmp_path / "ms.toml"
    path.write_text(_text(seed, "full_permutation"))
    db = str(tmp_path / "ms.db")
    missing = _asa("run", "--protocol", str(path), "--participant", "X1", "--db", db, cwd=tmp_path)
    assert missing.returncode == 2 and "give the session's site with --site" in missing.stderr
    assert len(missing.stderr.strip().splitlines()) == 1
    runs = [("L01", ["--site", "lyon"], {}), ("D01", [], {"ASA_SITE": "delft"}),
            ("L02", ["--site", "lyon", "--machine", "rig-7"], {})]  # fmt: skip
    for code, flags, env in runs:
        done = _asa("run", "--protocol", str(path), "--participant", code, "--db", db, *flags,
                    cwd=tmp_path, env=env)  # fmt: skip
        assert done.returncode == 0, done.stderr
    engine = open_database(db, create=False)
    with Session(engine) as s:
        where = {r.participant.code: (r.site, r.machine) for r in s.scalars(select(SessionRow))}
    engine.dispose()
    assert where["L02"] == ("lyon", "rig-7") and where["D01"][0] == "delft"
    assert where["L01"][1] == where["D01"][1] != ""  # the host name by default
    listed = _asa("plan", "--db", db, "--json", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    ledger = json.loads(listed.stdout)
    assert ledger["sites"] == list(SITES) and "excluded" in ledger["rule"]
    assert [(r["site"], r["slot"], r["code"]) for r in ledger["slots"]] == [
        ("delft", 0, "D01"), ("lyon", 0, "L01"), ("lyon", 1, "L02"),
    ]  # fmt: skip
    assert set(ledger["balance_by_site"]) == {"lyon", "delft"}
    text = _asa("plan", "--db", db, cwd=tmp_path).stdout
    assert "3 order slots issued at 3 sites" in text and "site porto: no participant yet" in text
    assert text.index("site lyon: 2 slots") < text.index("site delft: 1 slot\n")
    frames = tidy(load_study(db))  # the analysis sees each participant's site
    people = frames.participants
    assert dict(zip(people["participant"], people["site"], strict=True)) == {
        "L01": "lyon", "D01": "delft", "L02": "lyon",
    }  # fmt: skip
    assert set(frames.trials["site"]) == {"lyon", "delft"}


def test_a_synthetic_study_at_a_site(tmp_path, seed):
    from study.jobs.synth import run_synthetic_study

    protocol = _protocol(tmp_path, seed, "full_permutation")
    db = tmp_path / "delft.db"
    summary = run_synthetic_study(
        protocol, db, participants=2, seed=seed % 1000, workers=1, record=False, site="delft"
    )
    assert summary.codes == ("delft-P01", "delft-P02")
    engine = open_database(db, create=False)
    with Session(engine) as s:
        people = s.scalars(select(Participant).order_by(Participant.code)).all()
        assert [(p.code, p.site) for p in people] == [
            ("delft-P01", "delft"),
            ("delft-P02", "delft"),
        ]
        assert [r.site for r in s.scalars(select(SessionRow))] == ["delft", "delft"]
        assert sorted((r.site, r.slot) for r in s.scalars(select(OrderSlot))) == [
            ("delft", 0), ("delft", 1),
        ]  # fmt: skip
    engine.dispose()
    assert check(db, verify_recordings=False).clean
    with pytest.raises(ValueError, match="field 'session.site'"):
        run_synthetic_study(protocol, tmp_path / "x.db", participants=1, seed=0, record=False)
