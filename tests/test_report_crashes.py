"""The Sec. 7.5 report section on a tiny reactive-7-5 study (2 participants, 2 modes, one
crash): Table 7.10 with 0/0* for the crashed trial and its footnote, and the clearance
distribution without the crashed trial; absent for a protocol without end_on_collision."""

from __future__ import annotations

import hashlib
import importlib.resources

import pandas as pd
from sqlalchemy.orm import Session

from analysis.report import build_report
from study.data.storage import Participant, Sample, SessionRow, Study, Trial, open_database
from tasks.clearance import RangeStats

MODES = ("manual", "reactive_bn")


def _study(path, rng, *, text: str) -> None:
    engine = open_database(path)
    with Session(engine) as s, s.begin():
        study = Study(name="reactive-7-5", protocol_text=text, platform_version="t", seed=1,
                      protocol_sha256=hashlib.sha256(text.encode()).hexdigest())  # fmt: skip
        s.add(study)
        s.flush()
        for k in range(2):
            order = list(MODES) if k == 0 else list(reversed(MODES))
            person = Participant(study_id=study.id, code=f"P0{k + 1}", kind="scripted",
                                 order_index=k, mode_order=order, seed=k)  # fmt: skip
            s.add(person)
            s.flush()
            session = SessionRow(participant_id=person.id, status="completed")
            s.add(session)
            s.flush()
            for ordinal, mode in enumerate(order):
                crash = k == 1 and mode == "manual"
                ranges = rng.uniform(0.4, 1.2, 50) + (0.1 if mode == "reactive_bn" else 0.0)
                stats = RangeStats()
                for r in ranges:
                    stats.add(float(r))
                trial = Trial(participant_id=person.id, session_id=session.id, phase="main",
                              mode=mode, ordinal=ordinal, scenario="cluttered_room", seed=k,
                              status="completed", completed_task=not crash,
                              completion_time_s=40.0 + 10 * ordinal, collisions=int(crash),
                              score=40.0, path_length_m=20.0, clearance_mean_m=0.3,
                              clearance_min_m=0.1,
                              outcome={"ticks": 50, "crashed": crash,
                                       "lrf_clearance": stats.summary()})  # fmt: skip
                s.add(trial)
                s.flush()
                s.add_all(
                    Sample(
                        trial_id=trial.id,
                        tick=i,
                        t=0.05 * i,
                        x=float(i),
                        y=0.0,
                        yaw=0.0,
                        u_x=0.0,
                        u_y=0.0,
                        u_w=0.0,
                        v_x=0.0,
                        v_y=0.0,
                        v_w=0.0,
                        beta=0.0,
                        min_clearance_m=0.3,
                        in_region=False,
                    )  # fmt: skip
                    for i in range(5)
                )
    engine.dispose()


def test_table_7_10_and_distribution_for_the_sec_7_5_protocol(tmp_path, rng):
    text = (importlib.resources.files("protocols") / "reactive-7-5.toml").read_text("utf-8")
    _study(tmp_path / "s.db", rng, text=text)
    paths = build_report(tmp_path / "s.db", tmp_path / "out")
    html = paths.html.read_text("utf-8")
    assert "Clearance and crashes (thesis Sec. 7.5)" in html
    assert "0/0*" in html and "clearance is assumed to be zero" in html
    table = pd.read_csv(tmp_path / "out" / "tables" / "clearance_table_7_10.csv")
    assert len(table) == 4 and table["crashed"].sum() == 1
    crashed = table[table["crashed"]].iloc[0]
    assert crashed["participant"] == "P02" and crashed["mode"] == "manual"
    assert crashed["mean_m"] == 0 and crashed["std_m"] == 0
    assert (table.loc[~table["crashed"], "mean_m"] > 0.4).all()
    counts = pd.read_csv(tmp_path / "out" / "tables" / "lrf_clearance_distribution.csv")
    # manual: only P01's 50 ticks (P02's crashed trial left out); reactive: both, 100
    assert counts["manual"].sum() == 50 and counts["reactive_bn"].sum() == 100
    assert "lrf_clearance_distribution.svg" in html


def test_no_sec_7_5_section_without_end_on_collision(tmp_path, rng):
    text = (importlib.resources.files("protocols") / "reactive-7-5.toml").read_text("utf-8")
    text = text.replace("end_on_collision = true", "end_on_collision = false")
    _study(tmp_path / "s.db", rng, text=text)
    html = build_report(tmp_path / "s.db", tmp_path / "out").html.read_text("utf-8")
    assert "Clearance and crashes" not in html and "0/0*" not in html
