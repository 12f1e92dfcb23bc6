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
    ``(TrialResult, engine)`` (:func:`study.engine.standalone.standalone_trial`)."""
    from study.engine.standalone import standalone_trial
    from tasks.secondary import SecondarySettings

    return standalone_trial(
        folder,
        participant,
        mode=mode,
        scenario=scenario,
        phase=phase,
        timeout_s=seconds,
        secondary=SecondarySettings() if secondary else None,
        seed=seed,
        camera_hz=camera_hz,
        clock=clock,
        control=control,
        on_tick=on_tick,
        database="ui.db",
    )


def run(quick: bool = False) -> dict:
    """The ``ui`` figures (see the module docstring)."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    import numpy as np

    from study.participants.human import HumanParticipant
    from study.participants.scripted import ScriptedParticipant
    from study.engine.protocol import load_protocol
    from study.data.storage import Trial
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
