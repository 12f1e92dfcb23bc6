"""The 20 Hz trial loop: batched flushes at least once per simulated second, completion in
one transaction, pause and abort, clocks."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import event, func, select
from sqlalchemy.orm import Session

from autonomy.modes import make_mode
from sim.occupancy import build_grid
from sim.scenario import load_scenario
from sim.semantics import derive_components
from sim.world import World
from study.data.storage import Event, Participant, Sample, SessionRow, Study, Trial, open_database
from study.engine.trial import (
    FLUSH_EVERY_TICKS,
    ExperimenterControl,
    Scene,
    TrialSpec,
    WallClock,
    run_trial,
)
from study.participants import ScriptedParticipant
from study.participants.base import ParticipantBase
from study.types import ParticipantInput
from tasks.primary import PrimarySettings


@pytest.fixture(scope="module")
def scene():
    scenario = load_scenario("practice_course")
    components = derive_components(scenario)
    world = World(scenario, seed=0, components=components)
    yield Scene("practice_course", scenario, build_grid(scenario), components, world)
    world.close()


def _database(tmp_path: Path):
    engine = open_database(tmp_path / "t.db")
    with Session(engine) as s, s.begin():
        study = Study(
            name="t", protocol_text="", protocol_sha256="0" * 64, platform_version="test", seed=0
        )
        s.add(study)
        s.flush()
        person = Participant(
            study_id=study.id,
            code="P01",
            kind="scripted",
            order_index=0,
            mode_order=["manual"],
            seed=0,
        )
        s.add(person)
        s.flush()
        session = SessionRow(participant_id=person.id)
        s.add(session)
        s.flush()
        ids = (person.id, session.id)
    return engine, ids


def _trial(engine, ids, scene, tmp_path, participant, seed, *, timeout_s=60.0, **kw):
    spec = TrialSpec(
        phase="practice",
        ordinal=0,
        attempt=0,
        mode="reactive_bn",
        seed=seed,
        instruction="drive",
        primary=PrimarySettings(route=("dock",), inspection_required=False, timeout_s=timeout_s),
        secondary=None,
    )
    values = dict(
        participant_id=ids[0],
        session_id=ids[1],
        phase="practice",
        mode="reactive_bn",
        ordinal=0,
        attempt=0,
        scenario="practice_course",
        seed=seed,
    )
    return run_trial(
        engine,
        spec,
        scene=scene,
        participant=participant,
        mode=make_mode("reactive_bn"),
        trial_values=values,
        recording_dir=tmp_path,
        recording_rel=lambda tid: f"rec/trial_{tid}.rrd",
        session_id=ids[1],
        **kw,
    )


def test_flush_every_simulated_second_and_one_completing_transaction(tmp_path, scene, seed):
    engine, ids = _database(tmp_path)
    commits: list[int] = []
    event.listen(engine, "commit", lambda conn: commits.append(1))
    seen: list[tuple[int, int, str]] = []

    def on_tick(tick, writer):
        with Session(engine) as s:
            n = s.scalar(select(func.count()).select_from(Sample))
            status = s.scalar(select(Trial.status).where(Trial.id == writer.trial_id))
        seen.append((tick, n, status))
        seen_commits.append(len(commits))

    seen_commits: list[int] = []
    scripted = ScriptedParticipant(np.random.default_rng(seed))
    screens = []

    class Watching(ParticipantBase):
        kind, parameters = "scripted", {}
        begin_trial = scripted.begin_trial

        def act(self, obs, screen):
            screens.append(screen)
            return scripted.act(obs, screen)

    result = _trial(engine, ids, scene, tmp_path, Watching(), seed, on_tick=on_tick)
    # the active mode (reactive_bn) is never on the participant's screen
    assert len(screens) == result.ticks
    assert not any("reactive" in repr(screen) for screen in screens)
    assert result.status == "completed" and result.outcome["completed"]
    # mid-trial: the trial row is running, and no more than a simulated second is unwritten
    assert all(status == "running" for _, _, status in seen)
    assert all(tick - n < FLUSH_EVERY_TICKS for tick, n, _ in seen)
    # after the last tick exactly one more transaction: the completion
    assert len(commits) - seen_commits[-1] == 1
    with Session(engine) as s:
        trial = s.get(Trial, result.trial_id)
        assert trial.status == "completed" and trial.ended_at is not None
        assert trial.completion_time_s == pytest.approx(result.outcome["completion_time_s"])
        n = s.scalar(select(func.count()).select_from(Sample))
        assert n == result.ticks
        ticks = s.scalars(select(Sample.tick).order_by(Sample.tick)).all()
        assert ticks == list(range(result.ticks))
    assert (tmp_path / "rec" / f"trial_{result.trial_id}.rrd").is_file()
    engine.dispose()


class PausingParticipant(ParticipantBase):
    """Presses pause at tick 5, and again after being shown 7 paused screens."""

    kind = "scripted"
    parameters: dict = {}

    def __init__(self) -> None:
        self.calls = 0
        self.paused_screens = 0

    def begin_trial(self, info) -> None:
        pass

    def act(self, obs, screen):
        self.calls += 1
        if screen.paused:
            self.paused_screens += 1
            return ParticipantInput(pause=self.paused_screens == 7)
        return ParticipantInput(u=np.array([0.2, 0.0, 0.0]), pause=self.calls == 5)


def test_pause_freezes_simulated_time_and_is_recorded(tmp_path, scene, seed):
    engine, ids = _database(tmp_path)
    who = PausingParticipant()
    result = _trial(engine, ids, scene, tmp_path, who, seed, timeout_s=1.0)
    assert result.ticks == 20  # 1 s of simulated time, the pause not counted
    assert who.paused_screens == 7
    with Session(engine) as s:
        kinds = [e.kind for e in s.scalars(select(Event).order_by(Event.id))]
        assert kinds.index("pause") < kinds.index("resume")
        assert kinds.count("pause") == 1
    engine.dispose()


def test_abort_mid_trial(tmp_path, scene, seed):
    engine, ids = _database(tmp_path)
    control = ExperimenterControl()
    stop_at = int(np.random.default_rng(seed).integers(3, 40))

    def on_tick(tick, writer):
        if tick == stop_at:
            control.abort("stop")

    result = _trial(
        engine,
        ids,
        scene,
        tmp_path,
        ScriptedParticipant(np.random.default_rng(1)),
        seed,
        control=control,
        on_tick=on_tick,
    )
    assert result.status == "aborted" and result.ticks == stop_at
    with Session(engine) as s:
        trial = s.get(Trial, result.trial_id)
        assert trial.status == "aborted" and trial.outcome["aborted_reason"] == "stop"
        assert s.scalar(select(func.count()).select_from(Sample)) == stop_at
    engine.dispose()


def test_wall_clock_paces_and_measures_jitter():
    clock = WallClock(0.01)
    start = time.perf_counter()
    clock.start()
    for _ in range(10):
        clock.wait()
    assert time.perf_counter() - start >= 0.095
    jitter = clock.jitter_p99_ms()
    assert jitter is not None and math.isfinite(jitter) and jitter >= 0.0


def test_the_outcome_stores_the_modes_effective_settings(tmp_path, seed):
    """A standalone reactive trial stores its settings, the arbitration among them, as JSON."""
    import json

    from study.engine.standalone import standalone_trial

    result, engine = standalone_trial(
        tmp_path,
        ScriptedParticipant(np.random.default_rng(seed)),
        mode="reactive_bn",
        scenario="practice_course",
        route=("dock",),
        timeout_s=1.0,
        seed=seed,
        mode_settings={"arbitration": "blend", "dwa": {"horizon_s": 1.0}},
    )
    with Session(engine) as s:
        stored = s.scalars(select(Trial.outcome).where(Trial.id == result.trial_id)).one()
    engine.dispose()
    settings = result.outcome["mode_settings"]
    assert settings["arbitration"] == "blend" and settings["dwa"]["horizon_s"] == 1.0
    assert settings["d_safe"] == 0.15  # defaults too: the effective settings
    stored = json.loads(stored) if isinstance(stored, str) else stored
    assert stored["mode_settings"] == settings


class Forward(ParticipantBase):
    """Pushes straight ahead at full speed (into whatever is there)."""

    kind = "scripted"
    parameters: dict = {}

    def begin_trial(self, info) -> None:
        pass

    def act(self, obs, screen) -> ParticipantInput:
        return ParticipantInput(u=np.array([1.0, 0.0, 0.0]))


def test_a_collision_ends_the_trial_as_a_crash_with_the_lrf_clearance(tmp_path, scene, seed):
    """Sec. 7.5: end_on_collision ends the trial at the first contact (``crashed``); the
    outcome carries the laser clearance of Fig. 7.44b and Table 7.10."""
    from dataclasses import replace

    engine, ids = _database(tmp_path)
    spec = TrialSpec(
        phase="main",
        ordinal=0,
        attempt=0,
        mode="manual",
        seed=seed,
        instruction="drive",
        primary=PrimarySettings(route=("dock",), inspection_required=False, timeout_s=60.0),
        secondary=None,
        end_on_collision=True,
    )
    values = dict(
        participant_id=ids[0], session_id=ids[1], phase="main", mode="manual", ordinal=0,
        attempt=0, scenario="practice_course", seed=seed,
    )  # fmt: skip
    common = dict(
        scene=scene, participant=Forward(), trial_values=values, recording_dir=tmp_path,
        recording_rel=lambda tid: f"rec/trial_{tid}.rrd", session_id=ids[1],
    )  # fmt: skip
    crash = run_trial(engine, spec, mode=make_mode("manual"), **common)
    out = crash.outcome
    assert out["crashed"] and out["collisions"] == 1 and not out["completed"]
    lrf = out["lrf_clearance"]
    assert lrf["samples"] == crash.ticks and lrf["mean_m"] > 0 and lrf["min_m"] <= lrf["mean_m"]
    values["ordinal"] = 1
    short = replace(spec.primary, timeout_s=2.0)
    still = replace(spec, ordinal=1, end_on_collision=False, primary=short)
    on = run_trial(engine, still, mode=None, **common)
    assert on.outcome["crashed"] is False
