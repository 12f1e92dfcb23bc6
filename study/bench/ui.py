"""Benchmark group ``ui``: the participant's screen in a headless session.

One training trial in the cluttered room (20 s of wall time; 8 s with ``quick``) run exactly
as for a person: :class:`study.participants.human.HumanParticipant` on SDL's dummy video
driver, its :class:`study.ui.clock.UiClock` pacing the 20 Hz ticks, the camera rendered by
its worker process, the scripted participant's decisions injected as gamepad events
(:mod:`study.ui.inject`). Figures:

- ``ui_fps``: screen frames per second of wall time during the trial (issue 5: >= 30);
- ``ui_camera_fps``: camera images shown per second (>= 15);
- ``tick_jitter_ms``: the trial's stored ``trial.tick_jitter_ms``, the 99th percentile of
  ``|period - 50 ms|`` (DESIGN.md: the tick must keep its period);

:func:`headless_trial` is also what the tests of the interface use (with a free clock).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session


def headless_trial(
    folder: Path,
    participant: Any,
    *,
    seconds: float,
    clock: Any = None,
    scenario: str = "cluttered_room",
    phase: str = "training",
    mode: str = "manual",
    secondary: bool = True,
    seed: int = 0,
    control: Any = None,
    on_tick: Any = None,
    camera_hz: float = 0.0,
) -> tuple[Any, Engine]:
    """One driving trial of ``seconds`` simulated seconds (A -> B -> A, no inspection) in a
    fresh database in ``folder``, camera frames in its recording at ``camera_hz``; returns
    ``(TrialResult, engine)``."""
    from autonomy.modes import make_mode
    from sim.occupancy import build_grid
    from sim.scenario import load_scenario
    from sim.semantics import derive_components
    from sim.world import World
    from study.storage import Participant, SessionRow, Study, open_database
    from study.trial import Scene, TrialSpec, run_trial
    from tasks.primary import PrimarySettings
    from tasks.secondary import SecondarySettings

    sc = load_scenario(scenario)
    components = derive_components(sc)
    world = World(sc, seed=0, components=components)
    engine = open_database(folder / "ui.db")
    with Session(engine) as s, s.begin():
        study = Study(
            name="ui", protocol_text="", protocol_sha256="0" * 64, platform_version="bench", seed=0
        )
        s.add(study)
        s.flush()
        person = Participant(
            study_id=study.id,
            code="P01",
            kind=getattr(participant, "kind", "human"),
            order_index=0,
            mode_order=[mode],
            seed=seed,
        )
        s.add(person)
        s.flush()
        row = SessionRow(participant_id=person.id)
        s.add(row)
        s.flush()
        ids = (person.id, row.id)
    spec = TrialSpec(
        phase=phase,
        ordinal=0,
        attempt=0,
        mode=mode,
        seed=seed,
        instruction="Drive from A to B and back to A; answer the questions when they appear.",
        primary=PrimarySettings(
            route=("dock", "start"), inspection_required=False, timeout_s=seconds
        ),
        secondary=SecondarySettings() if secondary else None,
        camera_hz=camera_hz,
    )
    values = dict(
        participant_id=ids[0],
        session_id=ids[1],
        phase=phase,
        mode=mode,
        ordinal=0,
        attempt=0,
        scenario=sc.name,
        seed=seed,
    )
    try:
        result = run_trial(
            engine,
            spec,
            scene=Scene(sc.name, sc, build_grid(sc), components, world),
            participant=participant,
            mode=make_mode(mode),
            trial_values=values,
            recording_dir=folder,
            recording_rel=lambda tid: f"rec/trial_{tid}.rrd",
            session_id=ids[1],
            clock=clock,
            control=control,
            on_tick=on_tick,
        )
    finally:
        world.close()
    return result, engine


def run(quick: bool = False) -> dict:
    """The ``ui`` figures (see the module docstring)."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    import numpy as np

    from study.participants.human import HumanParticipant
    from study.participants.scripted import ScriptedParticipant
    from study.protocol import load_protocol
    from study.storage import Trial
    from study.ui.inject import EventDriver
    from study.ui.input import GamepadMapping

    protocol = load_protocol("pilot")
    seconds = 8.0 if quick else 20.0
    driver = EventDriver(
        ScriptedParticipant(np.random.default_rng(1)), GamepadMapping.from_settings(protocol.input)
    )
    person = HumanParticipant(protocol.ui, protocol.input, driver=driver)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            frames0 = person.screen.frames
            result, engine = headless_trial(
                Path(tmp), person, seconds=seconds, clock=person.clock()
            )
            ui_fps, camera_fps = person.trial_rates()
            with Session(engine) as s:
                trial = s.get(Trial, result.trial_id)
                jitter = trial.tick_jitter_ms if trial is not None else None
            engine.dispose()
    finally:
        person.close()
    return {
        "ui_fps": round(ui_fps, 1),
        "ui_camera_fps": round(camera_fps, 1),
        "tick_jitter_ms": round(jitter, 3) if jitter is not None else None,
        "ui_frames": person.screen.frames - frames0,
        "ui_trial_s": round(result.duration_s, 2),
    }
