"""Benchmark group ``ui``: the participant's screen in a headless session.

One training trial per mode in the cluttered room (20 s of wall time each; 8 s with
``quick``) run exactly
as for a person: :class:`study.participants.human.HumanParticipant` on SDL's dummy video
driver, its :class:`study.ui.clock.UiClock` pacing the 20 Hz ticks, the camera rendered by
its worker process, the scripted participant's decisions injected as gamepad events
(:mod:`study.ui.inject`). Figures:

- ``ui_fps``: screen frames per second of wall time during the trial, the lowest of the
  modes (issue 5: >= 30);
- ``ui_camera_fps``: camera images shown per second, the lowest of the modes (>= 15);
- ``tick_jitter_ms``: the trial's stored ``trial.tick_jitter_ms``, the 99th percentile of
  ``|period - 50 ms|``, the highest of the modes (DESIGN.md: the tick must keep its period);
- ``ui_per_mode``: the three figures of each mode (issue 19: in every mode).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session

from study.ui.headless import headless_trial

MODES = ("manual", "reactive_bn", "contextual_task")


def run(quick: bool = False) -> dict:
    """The ``ui`` figures (see the module docstring)."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    from study.engine.protocol import load_protocol

    protocol = load_protocol("pilot")
    per_mode = {mode: _one_mode(protocol, mode, 8.0 if quick else 20.0) for mode in MODES}
    rows = per_mode.values()
    jitters = [r["tick_jitter_ms"] for r in rows if r["tick_jitter_ms"] is not None]
    return {
        "ui_fps": min(r["ui_fps"] for r in rows),
        "ui_camera_fps": min(r["ui_camera_fps"] for r in rows),
        "tick_jitter_ms": max(jitters) if jitters else None,
        "ui_frames": sum(r["ui_frames"] for r in rows),
        "ui_trial_s": round(sum(r["ui_trial_s"] for r in rows), 2),
        "ui_per_mode": per_mode,
    }


def _one_mode(protocol: Any, mode: str, seconds: float) -> dict:
    """One headless training trial of ``seconds`` in ``mode`` with ``protocol``'s screen and
    input settings: its screen and camera rates, tick jitter, frames drawn and simulated
    duration."""
    import numpy as np

    from study.data.storage import Trial
    from study.participants.human import HumanParticipant
    from study.participants.scripted import ScriptedParticipant
    from study.ui.inject import EventDriver
    from study.ui.input import GamepadMapping

    driver = EventDriver(
        ScriptedParticipant(np.random.default_rng(1)), GamepadMapping.from_settings(protocol.input)
    )
    person = HumanParticipant(protocol.ui, protocol.input, driver=driver)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            frames0 = person.screen.frames
            result, engine = headless_trial(
                Path(tmp), person, seconds=seconds, clock=person.clock(), mode=mode
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
