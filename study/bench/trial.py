"""Benchmark group ``trial``: the cost of one whole control tick of a synthetic trial.

DESIGN.md ("One control tick", "Performance budgets"): a full 18-participant synthetic
study of the thesis protocol must run in under 5 minutes on 2 cores, about 30 core-seconds
per participant for 15-18k ticks, so a whole tick must average about 2 ms. This group
measures that tick as the session engine runs it: :func:`study.trial.run_trial` on the
cluttered room's main trial (route A -> B -> A with the inspection, secondary questions in
the region) with the scripted participant
(:class:`study.participants.ScriptedParticipant`), SQLite logging and the rerun recording,
once per mode, for the first ``segment_s`` simulated seconds.

Figures per mode ``<m>`` (``manual``, ``reactive_bn``, ``contextual_task``):

- ``trial_tick_ms_<m>``: ``{p50, p95, mean}`` of the wall time [ms] between successive
  ticks (the participant, the mode, the world, the tasks, the sample buffering, the
  recording and the batched database flushes: everything the loop does);
- ``trial_tick_cpu_ms_<m>``: the mean process CPU time [ms] per tick (rerun's encoder
  threads included), which other processes on a busy machine disturb much less;
- ``trial_mode_ms_<m>``: the mean wall time [ms] of ``mode.step`` alone, so the modes'
  share of the tick is visible;
- ``trial_error_<m>`` instead, when the mode cannot be built or run (say, a shipped
  model file of another format version), so the other modes are still measured.

``trial_tick_ms_mean`` and ``trial_tick_cpu_ms_mean`` average the modes (equal weights,
as a participant drives each mode once). The first tick of each trial (planning, the
recording's static scene) is left out, as is the trial's set-up and its completing
transaction.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from autonomy.modes import make_mode
from sim.occupancy import build_grid
from sim.scenario import load_scenario
from sim.semantics import derive_components
from sim.world import World
from study.participants import ScriptedParticipant
from study.storage import Participant, SessionRow, Study, open_database
from study.trial import Scene, TrialSpec, TrialWriter, run_trial
from tasks.primary import PrimarySettings
from tasks.secondary import SecondarySettings

MODES = ("manual", "reactive_bn", "contextual_task")
_SEED = 7061


class _TimedMode:
    """A mode whose ``step`` is timed (everything else passes through)."""

    def __init__(self, mode: Any) -> None:
        self.mode = mode
        self.step_s: list[float] = []

    def reset(self, robot: Any) -> None:
        self.mode.reset(robot)

    def step(self, obs: Any, u: np.ndarray) -> Any:
        start = time.perf_counter()
        out = self.mode.step(obs, u)
        self.step_s.append(time.perf_counter() - start)
        return out


def _database(folder: Path) -> tuple[Any, int, int]:
    engine = open_database(folder / "bench.db")
    with Session(engine) as s, s.begin():
        study = Study(
            name="bench",
            protocol_text="",
            protocol_sha256="0" * 64,
            platform_version="bench",
            seed=0,
        )
        s.add(study)
        s.flush()
        person = Participant(
            study_id=study.id,
            code="B01",
            kind="scripted",
            order_index=0,
            mode_order=list(MODES),
            seed=_SEED,
        )
        s.add(person)
        s.flush()
        session = SessionRow(participant_id=person.id)
        s.add(session)
        s.flush()
        return engine, person.id, session.id


def _summary(values_ms: list[float]) -> dict[str, float]:
    a = np.asarray(values_ms)
    return {
        "p50": round(float(np.percentile(a, 50)), 4),
        "p95": round(float(np.percentile(a, 95)), 4),
        "mean": round(float(a.mean()), 4),
    }


def _ticks(
    engine: Any,
    spec: TrialSpec,
    scene: Scene,
    values: dict[str, Any],
    folder: Path,
    session_id: int,
) -> tuple[list[float], list[float], _TimedMode]:
    """Run one trial; the wall and CPU clocks [s] after every tick, and the timed mode."""
    wall: list[float] = []
    cpu: list[float] = []

    def on_tick(tick: int, writer: TrialWriter) -> None:
        wall.append(time.perf_counter())
        cpu.append(time.process_time())

    mode = _TimedMode(make_mode(spec.mode))
    run_trial(
        engine,
        spec,
        scene=scene,
        participant=ScriptedParticipant(np.random.default_rng(_SEED)),
        mode=mode,
        trial_values=values,
        recording_dir=folder,
        recording_rel=lambda tid: f"rec/{tid}.rrd",
        session_id=session_id,
        on_tick=on_tick,
    )
    return wall, cpu, mode


def run(quick: bool) -> dict:
    """Run a scripted main-trial segment per mode; ``quick`` runs 10 s instead of 60 s."""
    segment_s = 10.0 if quick else 60.0
    scenario = load_scenario("cluttered_room")
    components = derive_components(scenario)
    figures: dict = {"trial_scene": scenario.name, "trial_segment_s": segment_s}
    means, cpu_means = [], []
    with (
        tempfile.TemporaryDirectory(prefix="asa-bench-") as tmp,
        World(scenario, seed=0, components=components) as world,
    ):
        folder = Path(tmp)
        scene = Scene(scenario.name, scenario, build_grid(scenario), components, world)
        engine, person_id, session_id = _database(folder)
        for ordinal, name in enumerate(MODES):
            spec = TrialSpec(
                phase="main",
                ordinal=ordinal,
                attempt=0,
                mode=name,
                seed=_SEED + ordinal,
                instruction="",
                # the segment ends by the task's timeout: the same loop, shorter
                primary=PrimarySettings(
                    route=("dock", "start"), inspection_required=True, timeout_s=segment_s
                ),
                secondary=SecondarySettings(),
            )
            values = {
                "participant_id": person_id,
                "session_id": session_id,
                "phase": "main",
                "mode": name,
                "ordinal": ordinal,
                "attempt": 0,
                "scenario": scenario.name,
                "seed": spec.seed,
            }
            try:
                wall, cpu, mode = _ticks(engine, spec, scene, values, folder, session_id)
            except ValueError as error:  # e.g. a shipped model the mode cannot read
                figures[f"trial_error_{name}"] = str(error)
                continue
            tick_ms = list(1e3 * np.diff(wall))
            cpu_ms = 1e3 * (cpu[-1] - cpu[0]) / (len(cpu) - 1)
            figures[f"trial_tick_ms_{name}"] = _summary(tick_ms)
            figures[f"trial_tick_cpu_ms_{name}"] = round(cpu_ms, 4)
            figures[f"trial_mode_ms_{name}"] = round(1e3 * float(np.mean(mode.step_s[1:])), 4)
            means.append(float(np.mean(tick_ms)))
            cpu_means.append(cpu_ms)
        engine.dispose()
    if means:
        figures["trial_tick_ms_mean"] = round(float(np.mean(means)), 4)
        figures["trial_tick_cpu_ms_mean"] = round(float(np.mean(cpu_means)), 4)
    return figures
