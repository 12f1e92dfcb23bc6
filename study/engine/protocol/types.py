"""The protocol's constants and frozen dataclasses (thesis sections 7.5, 7.6.1; spec 7)."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, ClassVar

from questionnaires import experience as experience_q
from questionnaires import nasa_tlx
from study.engine.texts import DEFAULT_TEXTS
from study.lsl.settings import LslSettings
from study.web.settings import WebSettings
from tasks.secondary import SecondarySettings

PHASE_KINDS: tuple[str, ...] = (
    "briefing",
    "experience",
    "training",
    "practice",
    "baseline",
    "main",
    "debrief",
)
ROUTE_POINTS: tuple[str, ...] = ("A", "B")
# the driving screen: "map" camera + scene map (Sec. 7.6.1, Fig. 7.47); "laser" the
# robot-centred laser scan with the front and tail cameras, no map (Sec. 7.5, Fig. 7.42)
UI_LAYOUTS: tuple[str, ...] = ("map", "laser")
# analysis.stats.POSTHOC and TESTS, repeated for the same reason as GATES below
POSTHOC: tuple[str, ...] = ("lsd_paired", "lsd_pooled", "holm", "bonferroni")
TESTS: tuple[str, ...] = ("rm_anova", "friedman", "auto")
# analysis.stats.GATES, repeated so that loading a protocol does not import scipy and pandas
# (about 1.5 s); tests/test_protocol.py checks that the two agree.
GATES: tuple[str, ...] = ("auto", "uncorrected", "greenhouse_geisser")
POSTHOC_GATES: tuple[str, ...] = ("auto", "omnibus", "none")  # analysis.stats.POSTHOC_GATES
TLX_WEIGHTS: tuple[str, ...] = ("per_trial", "once", "raw")
AFTER_TRIAL_INSTRUMENTS: tuple[str, ...] = (nasa_tlx.INSTRUMENT_ID,)
EXPERIENCE_INSTRUMENTS: tuple[str, ...] = (experience_q.INSTRUMENT_ID,)
PRACTICE_ORDERS: tuple[str, ...] = ("assigned", "protocol")
ON_FAIL: tuple[str, ...] = ("exclude", "continue")
# How the analysis treats the completion time and score of a main trial that timed out
# (docs/decisions.md): missing ("exclude") or the time limit as a censored value ("censor").
TIMEOUTS: tuple[str, ...] = ("exclude", "censor")
# Per-trial metrics the analysis can compute from a study database (thesis 7.5, 7.6.1.3).
METRICS: tuple[str, ...] = (
    "completion_time_s",
    "collisions",
    "score_s",
    "path_length_m",
    "clearance_mean_m",
    "clearance_std_m",
    "clearance_min_m",
    "clearance_histogram",
    "secondary_answer_time_s",
    "secondary_errors",
    "secondary_misses",
    "tlx_raw",
    "tlx_weighted",
)
AXES: tuple[str, ...] = ("vx", "vy", "yaw")
BUTTONS: tuple[str, ...] = ("yes", "no", "pause")
# Defaults for a Logitech F710 in XInput mode as SDL2/pygame numbers it.
DEFAULT_AXES: Mapping[str, int] = MappingProxyType({"vy": 0, "vx": 1, "yaw": 3})
DEFAULT_BUTTONS: Mapping[str, int] = MappingProxyType({"yes": 0, "no": 1, "pause": 7})
# Stick forward, stick left and right stick right read negative; robot x is forwards,
# y to the left, yaw counter-clockwise: all three flip.
DEFAULT_INVERT: tuple[str, ...] = ("vx", "vy", "yaw")
# The keyboard's driving and answer keys ([input.keys]), letters only: the pages and forms
# use Enter, Space, the arrows and the digits.
KEY_ACTIONS: tuple[str, ...] = (
    "forward",
    "back",
    "left",
    "right",
    "turn_left",
    "turn_right",
    "yes",
    "no",
    "pause",
)
DEFAULT_KEYS: Mapping[str, str] = MappingProxyType(
    {
        "forward": "W",
        "back": "S",
        "left": "A",
        "right": "D",
        "turn_left": "Q",
        "turn_right": "E",
        "yes": "Y",
        "no": "N",
        "pause": "P",
    }
)
# What the on-screen legends call the gamepad's controls ([input.names]).
PAD_CONTROLS: tuple[str, ...] = ("move", "turn", "yes", "no", "pause")
# What is printed on an XInput pad (an F710 in X mode, an Xbox pad) at SDL2's indices: the
# names the legends derive from the protocol's indices unless [input.names] gives them.
XINPUT_BUTTON_NAMES: Mapping[int, str] = MappingProxyType(
    {0: "A", 1: "B", 2: "X", 3: "Y", 4: "LB", 5: "RB", 6: "Back", 7: "Start", 8: "Guide"}
)
XINPUT_AXIS_NAMES: Mapping[int, str] = MappingProxyType(
    {
        0: "left stick",
        1: "left stick",
        2: "left trigger",
        3: "right stick",
        4: "right stick",
        5: "right trigger",
    }
)


# --------------------------------------------------------------------------- types


@dataclass(frozen=True, slots=True)
class StudyInfo:
    """Who takes part and how the study is seeded."""

    name: str
    title: str
    description: str
    participants: int  # default number of participants for planning
    seed: int  # study seed, stored with the data
    sites: tuple[str, ...] = ()  # the sites of a multi-site study; () for one site


@dataclass(frozen=True, slots=True)
class Briefing:
    """What the experimenter tells the participant first (thesis 7.6.1.3)."""

    kind: ClassVar[str] = "briefing"
    text: str


@dataclass(frozen=True, slots=True)
class ExperiencePhase:
    """The experience questionnaire before the study (thesis 7.6.1.3)."""

    kind: ClassVar[str] = "experience"
    instrument: str  # questionnaire id, "experience"


@dataclass(frozen=True, slots=True)
class Training:
    """Free driving to learn the interface and the modes (thesis 7.6.1.3)."""

    kind: ClassVar[str] = "training"
    scenario: str
    duration_s: float | None  # [s] per mode; None: free run
    secondary: bool  # questions on entering the region
    direct_view: bool  # the scene may be viewed directly, not only via the interface
    modes: tuple[str, ...]  # in the order they are introduced
    rehearsal_questions: int = 0  # questions at the start of each run, wherever the robot is


@dataclass(frozen=True, slots=True)
class Practice:
    """The practice obstacle task, once per mode, with pass criteria (thesis 7.6.1.3)."""

    kind: ClassVar[str] = "practice"
    scenario: str
    time_limit_s: float  # [s] an attempt must reach the goal within it
    max_collisions: int  # collisions allowed in a passing attempt (thesis: 0)
    max_attempts: int  # attempts per mode
    secondary: bool  # thesis: no secondary task
    order: str  # PRACTICE_ORDERS
    on_fail: str  # ON_FAIL


@dataclass(frozen=True, slots=True)
class Baseline:
    """The secondary task alone, without driving (thesis 7.6.1.3: 40 questions)."""

    kind: ClassVar[str] = "baseline"
    questions: int


@dataclass(frozen=True, slots=True)
class AfterTrial:
    """The questionnaire after every main trial."""

    instrument: str  # AFTER_TRIAL_INSTRUMENTS
    weights: str  # TLX_WEIGHTS


@dataclass(frozen=True, slots=True)
class MainTrials:
    """One trial per mode in the participant's order (thesis 7.6.1.2)."""

    kind: ClassVar[str] = "main"
    scenario: str
    route: tuple[str, ...]  # of ROUTE_POINTS: "A" start pose, "B" dock pose
    inspection: bool  # the inspection object must be inspected on the way
    timeout_s: float  # [s] a trial not finished by then ends as timed out
    secondary: bool  # questions on entering the region
    block_size: int  # questions per entry into the region (thesis: 20)
    end_on_collision: bool  # a collision ends the trial (thesis 7.5: a crash)
    after_trial: AfterTrial | None


@dataclass(frozen=True, slots=True)
class Debrief:
    """The closing text, after the last trial."""

    kind: ClassVar[str] = "debrief"
    text: str


Phase = Briefing | ExperiencePhase | Training | Practice | Baseline | MainTrials | Debrief


@dataclass(frozen=True, slots=True)
class Scoring:
    """The primary-task score: completion time plus a penalty per collision (spec 7)."""

    collision_penalty_s: float  # [s] added to the completion time per collision (thesis: 60)


@dataclass(frozen=True, slots=True)
class AnalysisSettings:
    """How the study's data are tested (thesis 7.6.2, spec 7)."""

    alpha: float  # significance level
    gate: str  # analysis.stats.GATES
    posthoc: str  # POSTHOC
    metrics: tuple[str, ...]  # of METRICS
    secondary_baseline_level: bool  # the baseline as a further level for secondary metrics
    timeouts: str  # TIMEOUTS: timed-out trials' completion time and score
    test: str = "rm_anova"  # TESTS: the planned omnibus test of every metric
    tests: Mapping[str, str] = field(default_factory=dict)  # metric -> TESTS, overrides test
    # POSTHOC_GATES: which post-hoc families wait for the omnibus test (auto: LSD only)
    posthoc_gate: str = "auto"

    def test_for(self, metric: str) -> str:
        """The planned omnibus test of ``metric`` (its own entry, else ``test``)."""
        return self.tests.get(metric, self.test)


@dataclass(frozen=True, slots=True)
class UiSettings:
    """The participant's screen, read by the human interface."""

    window: tuple[int, int]  # [px] width, height
    fullscreen: bool
    show_map: bool  # the complete map of the scene (thesis 7.6: yes; 7.5: no)
    instructions: Mapping[str, str]  # phase kind -> text shown before it
    layout: str = "map"  # UI_LAYOUTS
    show_object: bool = False  # the inspection object marked on the map in its colour
    # study.engine.texts.DEFAULT_TEXTS keys -> the protocol's text (titles, time's up, ...)
    texts: Mapping[str, str] = field(default_factory=lambda: dict(DEFAULT_TEXTS))


@dataclass(frozen=True, slots=True)
class RecordingSettings:
    """Camera frames in each trial's rerun recording (DESIGN.md "Data": a lower rate)."""

    camera_hz: float = 2.0  # [Hz] front camera (and tail, with layout "laser"); 0: none
    camera_width: int = 160  # [px] frames rendered, or scaled down, to this width
    jpeg_quality: int = 75  # 1-100


@dataclass(frozen=True, slots=True)
class InputSettings:
    """The gamepad mapping, read by the human interface."""

    axes: Mapping[str, int]  # AXES -> gamepad axis index
    buttons: Mapping[str, int]  # BUTTONS -> gamepad button index
    invert: tuple[str, ...]  # axes whose sign is flipped
    deadzone: float  # stick magnitude below which input is zero, [0, 1)
    keys: Mapping[str, str] = field(default_factory=lambda: dict(DEFAULT_KEYS))  # KEY_ACTIONS
    names: Mapping[str, str] = field(default_factory=dict)  # PAD_CONTROLS -> legend name

    def pad_names(self) -> dict[str, str]:
        """What the legends call each of :data:`PAD_CONTROLS`: ``names``, else derived from
        the indices as an XInput pad prints them."""
        out = {
            "move": _stick_name(self.axes["vx"], self.axes["vy"]),
            "turn": _stick_name(self.axes["yaw"]),
            **{
                b: XINPUT_BUTTON_NAMES.get(self.buttons[b], f"button {self.buttons[b]}")
                for b in ("yes", "no", "pause")
            },
        }
        out.update(self.names)
        return out


def _stick_name(*axes: int) -> str:
    names = {XINPUT_AXIS_NAMES.get(a, "") for a in axes}
    if len(names) == 1 and "" not in names:
        return names.pop()
    return "axes " + " and ".join(str(a) for a in axes) if len(axes) > 1 else f"axis {axes[0]}"


@dataclass(frozen=True, slots=True)
class Protocol:
    """A validated study protocol. ``text`` is the file's exact text, ``sha256`` its hash."""

    source: str  # the file it was loaded from
    study: StudyInfo
    modes: tuple[str, ...]  # registered mode names, in the file's order
    counterbalancing: str  # study.engine.counterbalance.SCHEMES
    mode_hidden: bool  # always True
    mode_settings: Mapping[str, Mapping[str, Any]]  # mode -> make_mode keyword settings
    phases: tuple[Phase, ...]  # in the order they run
    secondary: SecondarySettings
    scoring: Scoring
    analysis: AnalysisSettings
    ui: UiSettings
    input: InputSettings
    text: str = field(repr=False)  # the file's exact text
    sha256: str  # hex SHA-256 of ``text`` in UTF-8
    recording: RecordingSettings = field(default_factory=RecordingSettings)
    lsl: LslSettings = field(default_factory=LslSettings)  # [lsl]: outlets, the lab's streams
    web: WebSettings = field(default_factory=WebSettings)  # [web]: a session from a browser

    def __post_init__(self) -> None:
        if hashlib.sha256(self.text.encode("utf-8")).hexdigest() != self.sha256:
            raise ValueError(f"{self.source}: sha256 does not match the protocol's text")

    def phase(self, kind: str) -> Phase | None:
        """The phase of ``kind``, or ``None`` if the protocol has none."""
        if kind not in PHASE_KINDS:
            raise ValueError(f"phase kind: must be one of {', '.join(PHASE_KINDS)}, got {kind!r}")
        return next((p for p in self.phases if p.kind == kind), None)

    @property
    def main(self) -> MainTrials:
        """The main-trials phase (every protocol has one)."""
        return next(p for p in self.phases if isinstance(p, MainTrials))

    @property
    def name(self) -> str:
        """The study's name, ``study.name``."""
        return self.study.name

    @property
    def secondary_settings(self) -> SecondarySettings:
        """The secondary task's settings with the main block size and baseline size."""
        baseline = self.phase("baseline")
        return replace(
            self.secondary,
            block_size=self.main.block_size,
            baseline_size=baseline.questions if baseline else self.secondary.baseline_size,
        )
