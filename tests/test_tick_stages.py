"""The per-stage clock of the control tick (study/engine/stages.py, ``asa bench --only
trial``): every stage is timed, the shares add up, and timing changes no row."""

from __future__ import annotations

import numpy as np

from study.data.dbdiff import diff
from study.engine.stages import STAGES, StageClock
from study.engine.standalone import standalone_trial
from study.participants import ScriptedParticipant


def _trial(folder, seed, mode, stages=None):
    folder.mkdir()
    result, engine = standalone_trial(
        folder,
        ScriptedParticipant(np.random.default_rng(seed)),
        mode=mode,
        timeout_s=3.0,
        seed=seed,
        stages=stages,
    )
    engine.dispose()
    return result


def test_stage_clock_books_every_tick_and_changes_nothing(tmp_path, seed):
    stages = StageClock()
    timed = _trial(tmp_path / "timed", seed, "contextual_task", stages)
    plain = _trial(tmp_path / "plain", seed, "contextual_task")
    assert diff(tmp_path / "timed" / "trial.db", tmp_path / "plain" / "trial.db").identical
    assert len(stages.rows) == timed.ticks == plain.ticks
    summary = stages.summary()
    assert list(summary) == [*STAGES, "tick"]
    assert abs(sum(summary[s]["share"] for s in STAGES) - 1.0) < 0.01
    for name in ("participant", "mode", "physics", "sensing", "tasks", "tick"):
        assert 0 < summary[name]["p50_ms"] <= summary[name]["p95_ms"], name
    # the contextual mode reads the components: they have their own stage
    assert summary["components"]["mean_ms"] > 0


def test_stage_clock_arithmetic():
    clock = StageClock()
    for _ in range(3):
        clock.begin()
        clock.lap(0)
        clock.lap(0)  # a stage lapped twice in a tick adds up
        clock.end()
    clock.begin()
    clock.lap(1)
    clock.discard()  # a paused poll: not a tick
    assert len(clock.rows) == 3
    assert all(row[1] == 0 and row[0] >= 0 and len(row) == len(STAGES) for row in clock.rows)
    assert clock.summary(skip=3) == {}
