"""The protocol client that ``asa bench --only web`` measures the server alone with
(:mod:`study.web.loadclient`): against a real ``asa serve`` (real pybullet, camera and
SQLite), one client through a short protocol of every screen kind ends on the end page,
and the stored session is what it did: complete, every tick with its input's age and
round trip, the forms and pairs answered, the robot driven towards its goal."""

from __future__ import annotations

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from questionnaires import experience, nasa_tlx
from study.data.storage import Response, Sample, SessionRow, Trial, open_database
from study.web.loadclient import run_clients
from tests.web_helpers import served, short_protocol


def test_a_protocol_client_completes_a_session_and_every_tick_is_timed(tmp_path, seed):
    protocol = short_protocol(tmp_path, seed % 1000, timeout_s=3.0)
    db = str(tmp_path / "web.db")
    seen: list[bool] = []
    with served(protocol, db, camera=True) as server:
        (record,) = run_clients(
            [server.links["P01"]],
            timeout_s=240,
            on_every=lambda clients: seen.append(clients[0].driving),
        )
    assert record.stopped == "" and record.end is not None
    assert record.end["status"] == "completed" and record.end["code"] == "C0DE42"
    assert {"page", "form", "pair", "drive"} <= set(record.screens)
    assert record.pongs == 5 and record.maps >= 1 and any(seen)
    assert record.drive_camera_frames > 0 and record.camera_fps > 0
    engine = open_database(db, create=False)
    with Session(engine) as s:
        assert s.scalars(select(SessionRow.status)).all() == ["completed"]
        answers = s.scalars(select(Response.instrument)).all()
        assert answers.count(experience.INSTRUMENT.id) == len(experience.INSTRUMENT.items)
        # two main trials rated, the 15 pairs chosen once
        assert answers.count(nasa_tlx.INSTRUMENT_ID) == 2 * len(nasa_tlx.SUBSCALES) + 15
        ticks = s.execute(
            select(Sample.trial_id, Sample.tick, Sample.x, Sample.u_x, Sample.input_age_ticks,
                   Sample.rtt_ms).order_by(Sample.trial_id, Sample.tick)
        ).all()  # fmt: skip
        assert len(ticks) == record.states  # a state for every tick, each one decoded
        for trial in s.scalars(select(Trial).where(Trial.phase == "main")):
            rows = [t for t in ticks if t.trial_id == trial.id]
            assert trial.status in ("completed", "timed_out")
            assert [t.tick for t in rows] == list(range(len(rows)))  # no tick lost
            ages = [t.input_age_ticks for t in rows if t.input_age_ticks is not None]
            rtts = [t.rtt_ms for t in rows if t.rtt_ms is not None]
            assert len(ages) >= 0.9 * len(rows) and min(ages) >= 0
            assert len(rtts) >= 0.9 * len(rows) and min(rtts) > 0
            ux = np.array([t.u_x for t in rows])
            assert ux.max() > 0  # the stick pushed towards B, east of A
            assert rows[-1].x > rows[0].x
    engine.dispose()
