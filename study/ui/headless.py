"""One driving trial in a fresh database, as the participant's screen runs it (issue 5).

Shared by the ``ui`` benchmark group and the tests of the interface (those with a free
clock).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sqlalchemy.engine import Engine


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
