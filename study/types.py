"""Plain value types of the session engine: what the participant's screen shows, what the
participant does in one tick, what one tick stores, and what a participant is told about
a trial before it starts.

DESIGN.md ("One control tick"): the observation (``sim.types``), the input, the mode
output (``autonomy.types``) and the tick record are small frozen dataclasses passed by
value. Thesis sections 7.5 and 7.6: the participant is never told which control mode is
active, so no type here has a field for the mode's name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.scenario import Scenario
from sim.types import Pose2D
from tasks.primary import PrimarySettings

_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


@dataclass(frozen=True, slots=True)
class ScreenState:
    """What the participant's screen shows at one tick (never the active mode's name)."""

    phase: str  # "briefing", "training", "practice", "baseline", "main", "debrief", ...
    instruction: str = ""  # the current instruction text
    question: str | None = None  # the secondary-task question on screen, e.g. "47 + 38 = 85 ?"
    feedback: str = ""  # e.g. practice feedback ("Passed", "Collision: please try again")
    paused: bool = False  # the experimenter has paused the trial
    t: float = 0.0  # [s] simulated trial time


@dataclass(frozen=True, slots=True)
class ParticipantInput:
    """What the participant does in one tick."""

    u: np.ndarray = field(default_factory=lambda: _ZERO3)  # (3,) robot frame [m/s, m/s, rad/s]
    answer: bool | None = None  # Yes (True) / No (False) pressed this tick, None: neither
    pause: bool = False  # the pause button is pressed this tick
    # a browser participant's input (study.web): ticks since the state it answered was
    # drawn, and that state's round trip [ms]; None for others
    age_ticks: int | None = None
    rtt_ms: float | None = None


@dataclass(frozen=True, slots=True)
class TrialInfo:
    """What a participant is told about a trial before it starts (not the mode)."""

    phase: str  # "training", "practice", "baseline" or "main"
    scenario: Scenario
    route: tuple[str, ...]  # goals after the start, "dock" / "start" (tasks.primary)
    inspection: bool  # the inspection object must be inspected on the way
    secondary: bool  # questions are asked on entering the region
    time_limit_s: float  # [s] the trial ends after this
    drive: bool = True  # False for the baseline block (no driving)
    primary: PrimarySettings | None = None  # the task's criteria (inspection arc, ...)
    ordinal: int = 0  # position within its phase, from 0 (the screen's "k of n": k - 1)
    of: int = 1  # trials in its phase (n)
    attempt_of: tuple[int, int] | None = None  # practice: (this attempt, allowed), from 1
    max_collisions: int | None = None  # practice: collisions a passing attempt may have
    rehearsal_questions: int = 0  # questions asked at the start, wherever the robot is


@dataclass(frozen=True, slots=True)
class TickRecord:
    """What one control tick stores (one ``storage.Sample`` row)."""

    tick: int
    t: float  # [s] simulated trial time
    pose: Pose2D  # true pose, map frame
    u: np.ndarray  # (3,) joystick command [m/s, m/s, rad/s]
    v: np.ndarray  # (3,) command sent to the robot [m/s, m/s, rad/s]
    beta: float  # arbitration factor in [0, 1]
    label: str  # recognised situation or task ("" for manual)
    target: str  # recognised component id
    min_clearance_m: float  # [m] footprint to nearest laser hit (inf: none in range)
    in_region: bool  # true pose inside the question region
    true_task: str = ""  # ground truth from the participant's ``intention()``
    true_target: str = ""
    lsl_clock_s: float | None = None  # [s] LSL local_clock() when the tick happened
    input_age_ticks: int | None = None  # ParticipantInput.age_ticks
    rtt_ms: float | None = None  # [ms] ParticipantInput.rtt_ms

    def row(self, trial_id: int) -> dict[str, object]:
        """Column values of the ``sample`` table for this tick.

        A clearance of ``inf`` (nothing within laser range) is stored as a large finite
        number (1e9 m) because SQLite cannot hold infinities in every driver.
        """
        clearance = self.min_clearance_m
        if not math.isfinite(clearance):
            clearance = 1e9
        return {
            "trial_id": trial_id,
            "tick": self.tick,
            "t": self.t,
            "x": self.pose.x,
            "y": self.pose.y,
            "yaw": self.pose.yaw,
            "u_x": float(self.u[0]),
            "u_y": float(self.u[1]),
            "u_w": float(self.u[2]),
            "v_x": float(self.v[0]),
            "v_y": float(self.v[1]),
            "v_w": float(self.v[2]),
            "beta": self.beta,
            "label": self.label,
            "target": self.target,
            "min_clearance_m": clearance,
            "in_region": self.in_region,
            "true_task": self.true_task,
            "true_target": self.true_target,
            "lsl_clock_s": self.lsl_clock_s,
            "input_age_ticks": self.input_age_ticks,
            "rtt_ms": self.rtt_ms,
        }
