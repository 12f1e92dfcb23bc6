"""Benchmark group ``trial``: the cost of one whole control tick of a trial (DESIGN.md,
"One control tick", "Performance budgets").

:func:`study.engine.trial.run_trial` on the cluttered room's main trial (A -> B -> A with
the inspection, secondary questions) with SQLite logging and the rerun recording, once
per mode and per participant kind (the scripted driver, a synthetic participant), for
the first ``segment_s`` simulated seconds, with the per-stage clock of
:mod:`study.engine.stages`. The figures are listed in :func:`run`.
"""

from __future__ import annotations

import contextlib
import tempfile
import time
from typing import Any

import numpy as np

from autonomy.types import Mode
from study.engine.stages import StageClock
from study.engine.standalone import standalone_trial
from study.engine.trial import TrialWriter
from study.participants import ScriptedParticipant
from study.participants.base import Participant
from study.participants.synthetic import Population, SyntheticParticipant
from tasks.secondary import SecondarySettings

MODES = ("manual", "reactive_bn", "contextual_task")
_SEED = 7061


class _TimedMode(Mode):
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

    def label_tasks(self) -> dict[str, str] | None:
        return self.mode.label_tasks()


def _summary(values_ms: list[float]) -> dict[str, float]:
    a = np.asarray(values_ms)
    return {
        "p50": round(float(np.percentile(a, 50)), 4),
        "p95": round(float(np.percentile(a, 95)), 4),
        "mean": round(float(a.mean()), 4),
    }


def _participant(kind: str) -> Participant:
    """The scripted driver, or a synthetic participant drawn from the default population."""
    rng = np.random.default_rng(_SEED)
    if kind in ("scripted", "warmup"):
        return ScriptedParticipant(rng)
    return SyntheticParticipant(Population().sample(rng), rng)


def _measure(
    folder: str, name: str, seed: int, segment_s: float, kind: str = "scripted"
) -> tuple[list[float], list[float], _TimedMode, StageClock]:
    """One trial segment of mode ``name`` driven by a ``kind`` participant: wall and CPU
    clocks [s] after every tick, the timed mode and the per-stage clock."""
    wall: list[float] = []
    cpu: list[float] = []
    timed: list[_TimedMode] = []

    def on_tick(tick: int, writer: TrialWriter) -> None:
        wall.append(time.perf_counter())
        cpu.append(time.process_time())

    def wrap(mode: Any) -> _TimedMode:
        timed.append(_TimedMode(mode))
        return timed[-1]

    stages = StageClock()
    # the segment ends by the task's timeout: the same loop, shorter
    _, engine = standalone_trial(
        folder,
        _participant(kind),
        mode=name,
        inspection=True,
        timeout_s=segment_s,
        secondary=SecondarySettings(),
        seed=seed,
        on_tick=on_tick,
        wrap_mode=wrap,
        database=f"{kind}_{name}.db",
        stages=stages,
    )
    engine.dispose()
    return wall, cpu, timed[0], stages


def _scripted_figures(figures: dict, name: str, measured: tuple) -> tuple[float, float]:
    """The scripted driver's tick figures of mode ``name``; its mean wall and CPU [ms]."""
    wall, cpu, mode, _ = measured
    tick_ms = list(1e3 * np.diff(wall))
    cpu_ms = 1e3 * (cpu[-1] - cpu[0]) / (len(cpu) - 1)
    figures[f"trial_tick_ms_{name}"] = _summary(tick_ms)
    figures[f"trial_tick_cpu_ms_{name}"] = round(cpu_ms, 4)
    figures[f"trial_mode_ms_{name}"] = round(1e3 * float(np.mean(mode.step_s[1:])), 4)
    return float(np.mean(tick_ms)), cpu_ms


def run(quick: bool) -> dict:
    """Run a main-trial segment per mode and participant kind; ``quick`` runs 10 s
    instead of 60 s.

    The first tick of each trial (planning, the recording's static scene), the set-up
    and the completing transaction are left out; a 3 s segment per mode runs first and is
    discarded (the compiled kernels' first calls, paid once per process).

    Returns
    -------
    dict
        Per mode ``<m>`` (``manual``, ``reactive_bn``, ``contextual_task``), driven by
        the scripted driver: ``trial_tick_ms_<m>`` {p50, p95, mean}: wall time [ms]
        between successive ticks (participant, mode, world, tasks, sample buffering,
        recording, batched database flushes); ``trial_tick_cpu_ms_<m>``: mean process
        CPU time [ms] per tick (rerun's encoder threads included; less disturbed by
        other processes); ``trial_mode_ms_<m>``: mean wall time [ms] of ``mode.step``
        alone; or ``trial_error_<m>`` when the mode cannot be built or run.
        ``trial_tick_ms_mean`` and ``trial_tick_cpu_ms_mean`` average the modes with
        equal weights (a participant drives each mode once).
        ``trial_stages_<p>_<m>`` for ``<p>`` ``scripted`` and ``synthetic`` (a synthetic
        participant of the default population): per stage of the tick
        (:data:`study.engine.stages.STAGES`, and ``tick``) {p50_ms, p95_ms, mean_ms,
        share of the mean tick}.
    """
    segment_s = 10.0 if quick else 60.0
    figures: dict = {"trial_scene": "cluttered_room", "trial_segment_s": segment_s}
    means, cpu_means = [], []
    with tempfile.TemporaryDirectory(prefix="asa-bench-") as tmp:
        for name in MODES:  # discarded: the compiled kernels' first calls, once a process
            with contextlib.suppress(ValueError):
                _measure(tmp, name, _SEED, 3.0, "warmup")
        for kind in ("scripted", "synthetic"):
            for ordinal, name in enumerate(MODES):
                try:
                    measured = _measure(tmp, name, _SEED + ordinal, segment_s, kind)
                except ValueError as error:  # e.g. a shipped model the mode cannot read
                    figures[f"trial_error_{name}"] = str(error)
                    continue
                figures[f"trial_stages_{kind}_{name}"] = measured[3].summary()
                if kind == "scripted":
                    mean, cpu_mean = _scripted_figures(figures, name, measured)
                    means.append(mean)
                    cpu_means.append(cpu_mean)
    if means:
        figures["trial_tick_ms_mean"] = round(float(np.mean(means)), 4)
        figures["trial_tick_cpu_ms_mean"] = round(float(np.mean(cpu_means)), 4)
    return figures
