"""What a trial is and how it ended (:class:`TrialSpec`, :class:`TrialResult`), the scene
it runs in (:class:`Scene`), where its recording goes (:func:`recording_relpath`) and its
questions (:func:`secondary_task`); the loop that runs it is :mod:`study.engine.trial`."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from sim.types import SemanticComponent
from sim.world import World
from study.data.paths import file_in
from study.data.recording import RecorderSettings
from tasks.primary import PrimarySettings
from tasks.secondary import SecondarySettings, SecondaryTask


@dataclass(frozen=True, slots=True)
class Scene:
    """A scenario with what the loop derives from it once."""

    name: str  # as stored in trial.scenario
    scenario: Scenario
    grid: OccupancyGrid
    components: tuple[SemanticComponent, ...]
    world: World


@dataclass(frozen=True, slots=True)
class TrialSpec:
    """What one trial is (the session engine fills it from the protocol)."""

    phase: str  # storage.TRIAL_PHASES
    ordinal: int  # position within its phase, from 0
    attempt: int  # repeats of (phase, ordinal), from 0
    mode: str  # registered mode name, "" for the baseline
    seed: int  # world noise and secondary questions
    instruction: str  # shown on the screen
    primary: PrimarySettings | None  # None: no driving task (baseline)
    secondary: SecondarySettings | None  # None: no questions
    baseline: bool = False  # the secondary task alone, without driving
    end_on_collision: bool = False
    camera_hz: float = 0.0  # [Hz] camera frames in the recording; 0: none
    camera_views: tuple[str, ...] = ("front",)  # recorded cameras: "front", "tail"
    recording: RecorderSettings = field(default_factory=RecorderSettings)  # rates, JPEG
    # the time limit is the trial's planned length (training), so reaching it completes
    # the trial; otherwise a trial that reaches it ends "timed_out"
    limit_is_duration: bool = False
    of: int = 1  # trials in its phase (the participant's "k of n")
    attempt_of: tuple[int, int] | None = None  # practice: (this attempt, allowed), from 1
    rehearsal_questions: int = 0  # questions at the start, wherever the robot is (training)

    def __post_init__(self) -> None:
        # a trial must be able to end: by its driving task (which times out) or, for the
        # baseline block, by its last question
        if self.baseline and self.secondary is None:
            raise ValueError("trial spec: field 'secondary': a baseline trial needs questions")
        if not self.baseline and self.primary is None:
            raise ValueError(
                "trial spec: field 'primary': a driving trial needs a primary task (it ends "
                "the trial); only the baseline block has none"
            )
        if not (math.isfinite(self.camera_hz) and self.camera_hz >= 0):
            raise ValueError(f"trial spec: field 'camera_hz': must be >= 0, got {self.camera_hz}")
        if not set(self.camera_views) <= {"front", "tail"}:
            raise ValueError(
                f"trial spec: field 'camera_views': must be of front, tail, got {self.camera_views}"
            )


@dataclass(frozen=True, slots=True)
class TrialResult:
    """How a trial ended."""

    trial_id: int
    status: str  # "completed", "timed_out" or "aborted" (storage.TRIAL_STATUSES)
    outcome: dict[str, Any]  # as stored in trial.outcome
    ticks: int
    duration_s: float  # [s] simulated


def recording_relpath(
    folder: Path, recordings: Path, code: str, values: dict[str, Any], tag: str = ""
) -> str:
    """Where a trial's recording goes, relative to the database's ``folder``.

    ``<recordings>/<code>/<tag>_s<session>_<phase>_<ordinal>_a<attempt>.rrd``, ``tag`` the
    study's identity (:func:`study.data.recording.study_tag`), so studies sharing a
    recordings folder never name a file alike; if that file exists all the same, ``_2``,
    ``_3``, ... is appended rather than overwriting it. ``code`` and ``tag`` must be plain
    file names (:func:`study.data.paths.file_in`).
    """
    name = f"s{values['session_id']}_{values['phase']}_{values['ordinal']}_a{values['attempt']}"
    name = f"{tag}_{name}" if tag else name
    base = file_in(recordings, code, what="participant code") / name
    path, n = base.with_suffix(".rrd"), 1
    while path.exists():
        n += 1
        path = base.with_name(f"{base.name}_{n}.rrd")
    return os.path.relpath(path, folder)


def secondary_task(
    spec: TrialSpec, scenario: Scenario, rng: np.random.Generator
) -> SecondaryTask | None:
    """The questions: the baseline block, or in the scenario's question region, or none."""
    if spec.secondary is None:
        return None
    if spec.baseline:
        return SecondaryTask.baseline(rng, settings=spec.secondary)
    if len(scenario.question_region):
        return SecondaryTask(rng, settings=spec.secondary, first_block=spec.rehearsal_questions)
    return None
