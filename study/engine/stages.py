"""Where the time of a control tick goes: the per-stage clock of ``asa bench --only trial``
(issue 25).

:class:`StageClock` is given to :func:`study.engine.trial.run_trial`, which reads it at
the seams of every tick (:data:`STAGES`, in the order the tick runs them); without one
the loop reads no clock. ``other`` is what lies between the seams (the loop itself, the
experimenter's controls, the tick callback).
"""

from __future__ import annotations

import time

import numpy as np

# the stages of one tick, in the order the loop runs them
STAGES = (
    "participant",  # the participant's act on the last observation and the screen
    "mode",  # the mode's step (for the contextual mode: not the components' transform)
    "physics",  # the command applied and the physics substeps, contacts included
    "sensing",  # both lasers, their noise, the pose, velocity and IMU estimates
    "components",  # the semantic components put into the robot frame (when a mode reads them)
    "tasks",  # clearances, the primary and secondary tasks' updates and their events
    "database",  # the tick's sample row, the batched transactions
    "recording",  # the rerun recording (and camera frames, when due)
    "other",
)
PARTICIPANT, MODE, PHYSICS, SENSING, COMPONENTS, TASKS, DATABASE, RECORDING, OTHER = range(
    len(STAGES)
)


class StageClock:
    """Per-tick wall time [ns] of every stage of :data:`STAGES`.

    A tick is :meth:`begin`, then :meth:`lap` at the end of each stage (a stage may be
    lapped more than once a tick: its times add up), then :meth:`end`, which books the
    time not lapped as ``other``. :meth:`summary` gives the percentiles.
    """

    __slots__ = ("_current", "_last", "_start", "rows")

    def __init__(self) -> None:
        self.rows: list[list[int]] = []  # one row per tick, ns per stage
        self._current = [0] * len(STAGES)
        self._start = self._last = 0

    def begin(self) -> None:
        """A tick starts now."""
        self._start = self._last = time.perf_counter_ns()

    def lap(self, stage: int) -> None:
        """Stage ``stage`` (an index into :data:`STAGES`) ends now."""
        now = time.perf_counter_ns()
        self._current[stage] += now - self._last
        self._last = now

    def discard(self) -> None:
        """The tick was not simulated (the trial is paused): forget its laps."""
        self._current = [0] * len(STAGES)

    def end(self) -> None:
        """The tick ends now: its row is kept, ``other`` the time not lapped."""
        row = self._current
        row[OTHER] += time.perf_counter_ns() - self._last
        self.rows.append(row)
        self._current = [0] * len(STAGES)

    def summary(self, skip: int = 1) -> dict[str, dict[str, float]]:
        """Per stage (and ``tick``, their sum): ``p50_ms``, ``p95_ms``, ``mean_ms`` and
        ``share`` (of the mean tick) over the ticks after the first ``skip`` (the first
        tick plans the route and logs the recording's static scene)."""
        ns = np.asarray(self.rows[skip:], dtype=float).reshape(-1, len(STAGES))
        if not len(ns):
            return {}
        ms = ns / 1e6
        total = ms.sum(axis=1)
        out = {}
        for i, name in enumerate((*STAGES, "tick")):
            column = ms[:, i] if i < len(STAGES) else total
            out[name] = {
                "p50_ms": round(float(np.percentile(column, 50)), 4),
                "p95_ms": round(float(np.percentile(column, 95)), 4),
                "mean_ms": round(float(column.mean()), 4),
                "share": round(float(column.mean() / total.mean()), 4),
            }
        return out
