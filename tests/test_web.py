"""Participants in a browser, end to end (issue 37): a real `asa serve`, real headless
Chromium with a faked gamepad, real pybullet and SQLite. The stored session must be what
the browser did: the forms' answers, the pairwise choices, the answers to the questions,
the stick's pushes, every tick with its input's age and round trip."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from questionnaires import experience, nasa_tlx
from study.data.storage import Invite, Question, Response, Sample, SessionRow, Trial, open_database
from study.ui.forms import FormState
from tests.web_helpers import Person, browser, served, short_protocol

pytestmark = pytest.mark.skipif(
    shutil.which("chromium") is None or shutil.which("chromedriver") is None,
    reason="needs Debian's chromium and chromium-driver (.ci/run installs them)",
)


def _same_format_in_the_page(driver, rng: np.random.Generator) -> None:
    """messages.js reads what messages.py packs, and packs what it reads (the page's own
    module, loaded from the server)."""
    import base64

    from study.web import messages as wire

    points = rng.uniform(-20, 20, (37, 2))
    state = wire.pack_state(4321, 12.5, (1.25, -2.5, 0.75), np.array([0.5, -0.25, 1.0]), points,
                            paused=True)  # fmt: skip
    axes = tuple(float(np.float32(a)) for a in rng.uniform(-1, 1, 4))
    got = driver.execute_async_script(
        """const [b64, axes, done] = arguments;
        import("/static/messages.js").then((M) => {
          const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
          const s = M.unpackState(bytes.buffer);
          const input = new Uint8Array(M.packInput(77, 4321, axes, 0x8001, 0x2a, true));
          done({tick: s.tick, t: s.t, pose: s.pose, stick: s.stick, paused: s.paused,
                points: Array.from(s.points), input: btoa(String.fromCharCode(...input))});
        });""",
        base64.b64encode(state).decode(), list(axes),
    )  # fmt: skip
    want = wire.unpack_state(state)
    assert got["tick"] == 4321 and got["paused"] and got["t"] == pytest.approx(12.5)
    assert got["pose"] == pytest.approx(want["pose"]) and got["stick"] == pytest.approx(
        want["stick"]
    )
    assert np.array_equal(np.reshape(got["points"], (-1, 2)) / 100.0, want["points"])
    page = base64.b64decode(got["input"])
    assert page == wire.pack_input(77, 4321, axes, buttons=0x8001, keys=0x2A, gamepad=True)
    msg = wire.unpack_input(page)
    assert msg.held() == {"back", "right", "turn_right"} and msg.axes == pytest.approx(axes)


def _replayed(instrument) -> dict:
    """The answers a form gets from 'right, then A' on every row and A on Done."""
    state = FormState(instrument)
    for _ in instrument.items:
        state.action("right")
        state.action("confirm")
    state.action("confirm")
    assert state.done
    return state.answers()


def _stored(s: Session, instrument: str) -> dict:
    rows = s.scalars(select(Response).where(Response.instrument == instrument)).all()
    return {r.item: (r.value if r.value is not None else r.text) for r in rows}


def test_a_browser_drives_a_whole_session_and_the_store_is_what_it_did(tmp_path, seed):
    protocol = short_protocol(tmp_path, seed % 1000)
    db = str(tmp_path / "web.db")
    with served(protocol, db) as server:
        driver = browser()
        try:
            driver.get(server.links["P01"])
            person = Person(driver)
            end = person.run()
            _same_format_in_the_page(driver, np.random.default_rng(seed))
        finally:
            driver.quit()
    assert end["phase"] == "ended" and end["end"]["code"] == "C0DE42"
    engine = open_database(db, create=False)
    with Session(engine) as s:
        assert s.scalars(select(SessionRow.status)).all() == ["completed"]
        assert s.scalars(select(Invite.status)).all() == ["completed"]
        check = s.scalars(select(Invite.checks)).one()[0]
        assert check["passed"] and len(check["rtts_ms"]) == 5
        got = _stored(s, experience.INSTRUMENT.id)
        want = {
            k: "" if v is None else v if isinstance(v, str) else float(v)
            for k, v in _replayed(experience.INSTRUMENT).items()
        }
        assert {k: got.get(k) for k in want} == want
        tlx = s.scalars(select(Response).where(Response.instrument == nasa_tlx.INSTRUMENT_ID)).all()
        ratings = sorted((r.trial_id, r.item, r.value) for r in tlx if ":" not in r.item)
        replay = _replayed(nasa_tlx.INSTRUMENT)
        trials = sorted({r.trial_id for r in tlx})
        assert len(trials) == 2  # two main trials, rated after each
        assert ratings == sorted((t, k, float(v)) for t in trials for k, v in replay.items())
        ids = {sub.title: sub.id for sub in nasa_tlx.SUBSCALES}
        chosen = {r.item: r.text for r in tlx if r.item.startswith("pair:")}
        assert len(person.pairs) == 15 == len(chosen)
        for left, right in person.pairs:
            a, b = sorted((ids[left], ids[right]))
            key = f"pair:{a}|{b}" if f"pair:{a}|{b}" in chosen else f"pair:{b}|{a}"
            assert chosen[key] == ids[right]  # the page pressed right, then A
        answers = s.scalars(select(Question.response).where(Question.response.is_not(None))).all()
        assert answers and all(answers) and len(answers) <= person.answered
        for trial in s.scalars(select(Trial).where(Trial.phase == "main")):
            ticks = s.execute(
                select(Sample.tick, Sample.u_x, Sample.input_age_ticks, Sample.rtt_ms)
                .where(Sample.trial_id == trial.id)
                .order_by(Sample.tick)
            ).all()
            assert [t.tick for t in ticks] == list(range(len(ticks)))  # no tick lost
            ages = [t.input_age_ticks for t in ticks if t.input_age_ticks is not None]
            assert len(ages) >= 0.9 * len(ticks) and min(ages) >= 0
            assert sum(t.rtt_ms is not None for t in ticks) >= 0.9 * len(ticks)
            ux = np.array([t.u_x for t in ticks])
            assert (ux > 0.9 * ux.max()).any() and ux.max() > 0 and (ux == 0).any()
    engine.dispose()
    done = subprocess.run([sys.executable, "-m", "study.cli", "db", "check", "--db", db],
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    from analysis import data_quality
    from analysis.data.load import load_study

    (row,) = data_quality.describe(load_study(db).tables).to_dict("records")
    assert row["participant"] == "P01" and row["ticks"] >= 40 and row["connections_lost"] == 0
    assert 0 <= row["age_median"] <= row["age_p95"] <= row["age_worst"]
    assert 0 < row["rtt_median_ms"] <= row["rtt_p95_ms"] <= row["rtt_worst_ms"]


def _events(s: Session, trial_id: int) -> list[str]:
    from study.data.storage import Event

    return s.scalars(select(Event.kind).where(Event.trial_id == trial_id).order_by(Event.id)).all()


def test_a_cut_connection_pauses_and_resumes_and_one_past_grace_aborts_resumably(tmp_path, seed):
    """Cut mid-trial from the server's side: the trial pauses (gap marked), the page comes
    back, no tick is lost; cut for longer than the grace period: trial and session aborted,
    and opening the link again resumes the session to its end."""
    import time

    from tests.web_helpers import CuttableProxy

    protocol = short_protocol(tmp_path, seed % 1000, timeout_s=4.0, grace_s=8.0)
    db = str(tmp_path / "web.db")
    with served(protocol, db) as server:
        port = int(server.base.rsplit(":", 1)[1])
        proxy = CuttableProxy(port)
        driver = browser()
        try:
            driver.get(server.links["P01"].replace(f":{port}/", f":{proxy.port}/"))
            person = Person(driver)
            person.run(stop_at="Trial 1")
            time.sleep(0.5)
            proxy.blocked = True
            proxy.cut()
            time.sleep(2.0)  # within the grace period
            proxy.blocked = False
            person.run(stop_at="Trial 2")
            time.sleep(0.5)
            proxy.blocked = True
            proxy.cut()
            engine = open_database(db, create=False)
            for _ in range(300):  # past the grace period (8 s): aborted
                with Session(engine) as s:
                    statuses = s.scalars(select(SessionRow.status)).all()
                if statuses == ["aborted"]:
                    break
                time.sleep(0.1)
            engine.dispose()
            assert statuses == ["aborted"]
            proxy.blocked = False
            end = person.run()
        finally:
            driver.quit()
            proxy.close()
    assert end["phase"] == "ended"
    engine = open_database(db, create=False)
    with Session(engine) as s:
        rows = s.scalars(select(SessionRow)).all()
        assert [r.status for r in rows] == ["completed"] and rows[0].resumed
        mains = s.scalars(select(Trial).where(Trial.phase == "main").order_by(Trial.id)).all()
        assert [t.status for t in mains][1] == "aborted" and len(mains) == 3
        kinds = _events(s, mains[0].id)
        for kind in ("connection_lost", "pause", "connection_back", "resume"):
            assert kind in kinds
        ticks = s.scalars(select(Sample.tick).where(Sample.trial_id == mains[0].id)).all()
        assert sorted(ticks) == list(range(len(ticks)))  # the pause lost no tick
        assert "connection_lost" in _events(s, mains[1].id)
    engine.dispose()


def test_hostile_input_is_counted_and_dropped_and_a_second_page_takes_over(tmp_path, seed):
    """Wrong and replayed-looking tokens get 404; malformed, oversized, out-of-order and
    flooding messages are dropped and counted, and the session lives on; a second page on
    one token takes over and the first is told and closed (never two drive)."""
    import asyncio
    import json

    import aiohttp

    from study.web import messages as wire

    protocol = short_protocol(tmp_path, seed % 1000)
    db = str(tmp_path / "web.db")
    rng = np.random.default_rng(seed)

    async def attack(server) -> dict:
        base, token = server.base, server.links["P01"].rsplit("/", 1)[1]
        async with aiohttp.ClientSession() as http:
            for bad in ("x" * 22, token[:-1] + ("A" if token[-1] != "A" else "B"), "../etc"):
                async with http.get(f"{base}/s/{bad}") as r:
                    assert r.status == 404
                async with http.get(f"{base}/ws/{bad}") as r:
                    assert r.status == 404
            async with http.get(f"{base}/experimenter?token=wrong") as r:
                assert r.status == 404
            ws1 = await http.ws_connect(f"{base}/ws/{token}")
            await ws1.send_bytes(bytes(rng.integers(0, 256, 32, dtype=np.uint8)))  # malformed
            await ws1.send_bytes(b"\x01" * 60)  # malformed length
            await ws1.send_bytes(b"\x01" * 4000)  # oversized
            await ws1.send_str("{not json")
            await ws1.send_str(json.dumps({"type": "click", "target": "option", "row": -1}))
            await ws1.send_str(json.dumps({"type": "x" * 5000}))  # oversized
            await ws1.send_bytes(wire.pack_input(10, 0, (0, 0, 0, 0)))
            await ws1.send_bytes(wire.pack_input(9, 0, (0, 0, 0, 0)))  # out of order
            await ws1.send_bytes(wire.pack_input(11, 0, (float("nan"), 0, 0, 0)))
            for i in range(600):  # a flood
                await ws1.send_bytes(wire.pack_input(100 + i, 0, (0, 0, 0, 0)))
            await asyncio.sleep(1.5)
            ws2 = await http.ws_connect(f"{base}/ws/{token}")
            told = await ws1.receive(timeout=10)
            while told.type == aiohttp.WSMsgType.TEXT and "taken_over" not in told.data:
                told = await ws1.receive(timeout=10)
            closed = await ws1.receive(timeout=10)
            async with http.ws_connect(
                server.experimenter.replace("/experimenter?", "/ws-experimenter?")
            ) as ex:
                overview = json.loads((await ex.receive(timeout=10)).data)
            await ws2.close()
            return {"told": told, "closed": closed, "overview": overview, "ws1": ws1}

    with served(protocol, db) as server:
        got = asyncio.run(attack(server))
    assert "taken_over" in got["told"].data
    assert got["closed"].type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
    (session,) = got["overview"]["sessions"]
    assert session["running"] and session["takeovers"] == 1
    drops = session["drops"]
    assert drops["malformed"] >= 5 and drops["oversized"] == 2 and drops["out_of_order"] == 1
    assert drops["flood"] >= 600 + 9 - 240
    assert got["overview"]["refused"]["bad_token"] >= 5  # "../etc" never reaches a token route


def test_the_experimenter_sees_the_mode_and_the_robot_and_an_abort_is_recorded(tmp_path, seed):
    """The live view lists the running session with its trial's mode (never shown to the
    participant) and the robot on its map; its abort button stores the trial aborted."""
    import time

    from study.data.storage import Event

    protocol = short_protocol(tmp_path, seed % 1000, timeout_s=30.0)
    db = str(tmp_path / "web.db")
    with served(protocol, db) as server:
        participant, experimenter = browser(), browser()
        try:
            participant.get(server.links["P01"])
            person = Person(participant)
            person.run(stop_at="Trial 1")
            experimenter.get(server.experimenter)
            view: dict = {}
            for _ in range(100):
                view = experimenter.execute_script("return window.__asa_experimenter")
                ready = view.get("sessions") and view["sessions"][0].get("rtt_ms") is not None
                if ready and view["sessions"][0].get("trial"):
                    if experimenter.execute_script(
                        "return document.querySelectorAll('#maps canvas').length"
                    ):
                        break
                time.sleep(0.1)
            (session,) = view["sessions"]
            assert session["code"] == "P01" and session["trial"]["phase"] == "main"
            assert session["trial"]["mode"] in ("manual", "reactive_bn")
            assert session["rtt_ms"] is not None and session["connected"]
            mode = session["trial"]["mode"]
            assert mode not in json.dumps(person.state())  # never on the participant's page
            experimenter.execute_script("window.confirm = () => true")
            experimenter.find_element("css selector", "#rows button").click()
            for _ in range(100):
                if person.state()["phase"] == "aborted":
                    break
                time.sleep(0.1)
            assert person.state()["phase"] == "aborted"
        finally:
            participant.quit()
            experimenter.quit()
    engine = open_database(db, create=False)
    with Session(engine) as s:
        (trial,) = s.scalars(select(Trial).where(Trial.phase == "main")).all()
        assert trial.status == "aborted"
        assert "aborted by the experimenter" in trial.outcome["aborted_reason"]
        kinds = s.scalars(select(Event.kind).where(Event.trial_id == trial.id)).all()
        assert "abort" in kinds
        assert s.scalars(select(SessionRow.status)).all() == ["aborted"]
    engine.dispose()


def _four_at_once(tmp_path, db: str, seed: int) -> None:
    """Four participants' browsers on one server at the same time, each to its end."""
    from concurrent.futures import ThreadPoolExecutor

    protocol = short_protocol(tmp_path, seed % 1000)
    codes = ("P01", "P02", "P03", "P04")
    with served(protocol, db, "--recordings", str(tmp_path / "rec"), codes=codes) as server:

        def one(code: str) -> str:
            driver = browser()
            try:
                driver.get(server.links[code])
                return Person(driver).run(timeout=480)["phase"]
            finally:
                driver.quit()

        with ThreadPoolExecutor(4) as pool:
            phases = list(pool.map(one, codes))
    assert phases == ["ended"] * 4
    engine = open_database(db, create=False)
    with Session(engine) as s:
        assert s.scalars(select(SessionRow.status)).all() == ["completed"] * 4
    engine.dispose()
    done = subprocess.run([sys.executable, "-m", "study.cli", "db", "check", "--db", db],
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.slow
def test_four_browsers_at_once_on_sqlite(tmp_path, seed):
    _four_at_once(tmp_path, str(tmp_path / "web.db"), seed)


@pytest.mark.slow
@pytest.mark.postgres
def test_four_browsers_at_once_on_postgresql(tmp_path, seed, pg_url):
    _four_at_once(tmp_path, pg_url, seed)
