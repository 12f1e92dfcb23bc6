"""Study protocols: a TOML file validated into frozen dataclasses that carry a whole study.

A protocol says who takes part (how many, seeded how), which control modes are compared
and how their order is counterbalanced (:mod:`study.engine.counterbalance`), the phases of a
session in order, the secondary-task settings, the scoring, the analysis, and the
participant interface's window, instruction texts and gamepad mapping. The session engine
runs a :class:`Protocol`; storage keeps its ``text`` and ``sha256``.

Sources: thesis section 7.6.1.3 "Test procedure" (briefing, an experience questionnaire,
a training course with direct view of the scene and the secondary task, "a practice
obstacle task for one time with each of the three control modes ... within a specific time
limit, without collision" and without the secondary task, a 40-question baseline without
driving, main trials in six rotated orders, NASA-TLX after every trial), sections
7.6.1.1-7.6.1.2 (route A -> B -> A with the cylinder inspection, 20 questions per entry into
the region), section 7.5 (manual vs reactive, two orders unknown to the participants),
spec section 7.

File format (every table and field optional unless marked; unknown keys are refused)::

    [study]
    name = "thesis-7-6"                 # required
    title = "..."
    description = "..."
    participants = 18                   # default N for planning
    seed = 7061                         # study seed, stored with the data

    [modes]
    names = ["manual", "reactive_bn"]   # required: registered modes, >= 2, distinct
    counterbalancing = "full_permutation"   # | "williams" | "random"
    hidden = true                       # the active mode is never shown
    [modes.settings.reactive_bn]        # keyword settings for autonomy.modes.make_mode
    ...

    [[phases]]                          # in the order they run; "main" is required
    kind = "briefing"                   # briefing experience training practice
    text = "..."                        # baseline main debrief
    ...
    [[phases]]
    kind = "main"
    scenario = "cluttered_room"         # required
    route = ["A", "B", "A"]
    [phases.after_trial]                # the questionnaire after every main trial
    instrument = "nasa_tlx"
    weights = "per_trial"               # | "once" | "raw"

    [secondary]   p_correct, timeout_s, gap_s, near_miss_offsets, p_addition
    [scoring]     collision_penalty_s
    [analysis]    alpha, gate, posthoc, metrics, secondary_baseline_level
    [ui]          window, fullscreen, show_map; [ui.instructions] phase kind -> text
    [input]       deadzone; [input.axes] vx vy yaw -> index; [input.buttons] yes no pause
                  -> index; invert = ["vx"]

Decisions where the thesis and the brief are silent:

- ``modes.hidden`` is kept as a field but only ``true`` is accepted: the session engine
  never shows the active mode (thesis 7.5 and 7.6: the participant is not told), and a
  field the engine would silently ignore is worse than a refusal.
- Phases run in the fixed order briefing, experience, training, practice, baseline, main,
  debrief (issue 4's state machine; the thesis names the experience questionnaire "before
  the user study" and the baseline "in addition to the training course"). Each kind may
  appear at most once; all but ``main`` are optional; a file listing them in another order
  is refused rather than reordered.
- A phase's ``scenario`` is a shipped scenario's name or a ``*.toml`` file, relative to
  the protocol's folder; the loaded phase holds the resolved path, so the session engine
  can pass it straight to :func:`sim.scenario.load_scenario`.
- The secondary task's block size lives in the ``main`` phase (``block_size``, the
  thesis's 20 per entry) and the baseline's size in the ``baseline`` phase (``questions``,
  40); ``[secondary]`` holds the rest of :class:`tasks.secondary.SecondarySettings`, and
  :attr:`Protocol.secondary_settings` puts them together. Giving either size in
  ``[secondary]`` is refused with a pointer to its place.
- Training: ``duration_s`` is per mode; without it the run is free (ended by the
  experimenter, or by a synthetic participant on finishing the route). Its ``modes``
  default to all of the protocol's, in the protocol's order (the experimenter introduces
  them), and must be among them.
- Practice runs once per mode in the participant's assigned order (``order =
  "assigned"``; ``"protocol"`` for the file's order), from A to the scenario's dock pose;
  an attempt passes with at most ``max_collisions`` collisions (thesis: none) within
  ``time_limit_s``. After ``max_attempts`` failures, ``on_fail = "exclude"`` ends the
  session (the thesis required the practice "to proceed to the actual experiment") and
  ``"continue"`` records the failure and goes on (for pilots).
- Routes are lists of "A" (start pose) and "B" (dock pose), starting at A, with no step
  from a point to itself; "B" needs a scenario with a dock, ``inspection = true`` one with
  an inspection object, ``secondary = true`` one with a question region. Scenario names
  are checked by loading them.
- ``end_on_collision`` (main phase): in thesis 7.5 a collision crashed the quadrotor and
  ended the trial (its clearance then counts as zero, Table 7.10).
- NASA-TLX weights: ``"per_trial"`` asks the 15 pairwise comparisons after every trial
  (Hart & Staveland's procedure weights each task condition), ``"once"`` after the last
  main trial only, for all; ``"raw"`` asks none (RTLX).
- ``alpha`` is a field of ``[analysis]`` only (not also of ``[study]``), so the two cannot
  disagree. Gates are those of :mod:`analysis.stats` (``GATES``); post hoc leads are
  ``"lsd_paired"`` and ``"lsd_pooled"``; metric names are :data:`METRICS`.
- The mappings in a protocol (instruction texts, gamepad indices, mode settings) are
  plain dicts, read-only by convention: a :class:`Protocol` must pickle, so that worker
  processes of a synthetic study can receive it (``MappingProxyType`` does not pickle).
- The gamepad defaults are a Logitech F710 in XInput mode as SDL2 numbers it (spec 7:
  "Logitech F710 class"): left stick axes 0/1 for sideways/forwards, right stick axis 3
  for turning, A = Yes, B = No, Start = the experimenter's pause; all three axes are
  inverted (a stick pushed forward or left, or right for turning, reads negative).
- Mode settings are checked by building each mode once at load time
  (:func:`autonomy.modes.make_mode`), so a bad setting fails before any participant comes.
"""

from __future__ import annotations

import hashlib
import itertools
import tomllib
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar

from autonomy.modes import available_modes, make_mode
from protocols import PROTOCOL_DIR, available
from questionnaires import experience as experience_q
from questionnaires import nasa_tlx
from sim.fields import FieldReader
from sim.scenario import Scenario, load_scenario
from study.engine.counterbalance import SCHEMES
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
POSTHOC: tuple[str, ...] = ("lsd_paired", "lsd_pooled")
# analysis.stats.GATES, repeated so that loading a protocol does not import scipy and pandas
# (about 1.5 s); tests/test_protocol.py checks that the two agree.
GATES: tuple[str, ...] = ("auto", "uncorrected", "greenhouse_geisser")
TLX_WEIGHTS: tuple[str, ...] = ("per_trial", "once", "raw")
AFTER_TRIAL_INSTRUMENTS: tuple[str, ...] = (nasa_tlx.INSTRUMENT_ID,)
EXPERIENCE_INSTRUMENTS: tuple[str, ...] = (experience_q.INSTRUMENT_ID,)
PRACTICE_ORDERS: tuple[str, ...] = ("assigned", "protocol")
ON_FAIL: tuple[str, ...] = ("exclude", "continue")
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


# --------------------------------------------------------------------------- types


@dataclass(frozen=True, slots=True)
class StudyInfo:
    """Who takes part and how the study is seeded."""

    name: str
    title: str
    description: str
    participants: int  # default number of participants for planning
    seed: int  # study seed, stored with the data


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


@dataclass(frozen=True, slots=True)
class UiSettings:
    """The participant's screen, read by the human interface."""

    window: tuple[int, int]  # [px] width, height
    fullscreen: bool
    show_map: bool  # the complete map of the scene (thesis 7.6: yes; 7.5: no)
    instructions: Mapping[str, str]  # phase kind -> text shown before it


@dataclass(frozen=True, slots=True)
class InputSettings:
    """The gamepad mapping, read by the human interface."""

    axes: Mapping[str, int]  # AXES -> gamepad axis index
    buttons: Mapping[str, int]  # BUTTONS -> gamepad button index
    invert: tuple[str, ...]  # axes whose sign is flipped
    deadzone: float  # stick magnitude below which input is zero, [0, 1)


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


# -------------------------------------------------------------------------- reading


def _raw(r: FieldReader, key: str, default: Any = None) -> Any:
    """The raw value of ``key`` (marked as known), ``default`` when absent, or "is required"."""
    r.used.add(key)
    if key in r.data:
        return r.data[key]
    if default is None:
        raise r.fail(key, "is required")
    return default


def _boolean(r: FieldReader, key: str, default: bool) -> bool:
    value = _raw(r, key, default)
    if not isinstance(value, bool):
        raise r.fail(key, f"must be true or false, got {value!r}")
    return value


def _text(r: FieldReader, key: str, default: str | None = None) -> str:
    value = r.string(key, default)
    if default is None and not value.strip():
        raise r.fail(key, "must not be empty")
    return value


def _string_list(
    r: FieldReader,
    key: str,
    default: list[str] | None,
    *,
    allowed: Collection[str] = (),
    unique: bool = True,
) -> tuple[str, ...]:
    value = _raw(r, key, default)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise r.fail(key, f"must be a list of strings, got {value!r}")
    for i, v in enumerate(value):
        if allowed and v not in allowed:
            raise r.fail(f"{key}[{i}]", f"must be one of {', '.join(allowed)}, got {v!r}")
    duplicates = sorted({v for v in value if value.count(v) > 1})
    if duplicates and unique:
        raise r.fail(key, f"must not repeat names; {duplicates[0]!r} appears twice")
    return tuple(value)


class _Scenarios:
    """Loads each scenario a protocol names once, naming the protocol's field on failure.

    A shipped scenario is named as it is (``"cluttered_room"``); a file ending in
    ``.toml`` is taken relative to the protocol's folder and kept as that resolved path, so
    that :func:`sim.scenario.load_scenario` finds it from anywhere.
    """

    def __init__(self, base: Path) -> None:
        self.base = base
        self.cache: dict[str, Scenario] = {}

    def get(self, r: FieldReader, key: str) -> tuple[str, Scenario]:
        name = _text(r, key)
        if name.endswith(".toml") and not Path(name).is_absolute():
            name = str(self.base / name)
        if name not in self.cache:
            try:
                self.cache[name] = load_scenario(name)
            except (ValueError, FileNotFoundError, OSError) as error:
                raise r.fail(key, f"cannot load scenario {name!r}: {error}") from None
        return name, self.cache[name]


def _training(r: FieldReader, modes: tuple[str, ...], scenarios: _Scenarios) -> Training:
    name, scenario = scenarios.get(r, "scenario")
    duration = r.number("duration_s", positive=True) if "duration_s" in r.data else None
    secondary = _boolean(r, "secondary", True)
    if secondary and len(scenario.question_region) < 3:
        raise r.fail("secondary", f"scenario {name!r} has no question region")
    phase = Training(
        scenario=name,
        duration_s=duration,
        secondary=secondary,
        direct_view=_boolean(r, "direct_view", True),
        modes=_string_list(r, "modes", list(modes), allowed=modes),
    )
    if not phase.modes:
        raise r.fail("modes", "must name at least one of the protocol's modes")
    r.finish()
    return phase


def _practice(r: FieldReader, scenarios: _Scenarios) -> Practice:
    name, scenario = scenarios.get(r, "scenario")
    if scenario.dock is None:
        raise r.fail("scenario", f"scenario {name!r} has no [dock] goal pose to reach")
    secondary = _boolean(r, "secondary", False)
    if secondary and len(scenario.question_region) < 3:
        raise r.fail("secondary", f"scenario {name!r} has no question region")
    phase = Practice(
        scenario=name,
        time_limit_s=r.number("time_limit_s", positive=True),
        max_collisions=r.integer("max_collisions", 0, minimum=0),
        max_attempts=r.integer("max_attempts", 3, minimum=1),
        secondary=secondary,
        order=r.string("order", "assigned", allowed=PRACTICE_ORDERS),
        on_fail=r.string("on_fail", "exclude", allowed=ON_FAIL),
    )
    r.finish()
    return phase


def _after_trial(r: FieldReader) -> AfterTrial:
    a = AfterTrial(
        instrument=r.string("instrument", nasa_tlx.INSTRUMENT_ID, allowed=AFTER_TRIAL_INSTRUMENTS),
        weights=r.string("weights", "per_trial", allowed=TLX_WEIGHTS),
    )
    r.finish()
    return a


def _main(r: FieldReader, scenarios: _Scenarios) -> MainTrials:
    name, scenario = scenarios.get(r, "scenario")
    route = _string_list(r, "route", ["A", "B", "A"], allowed=ROUTE_POINTS, unique=False)
    if len(route) < 2 or route[0] != "A" or any(a == b for a, b in itertools.pairwise(route)):
        raise r.fail(
            "route",
            f"must start at 'A' and alternate between 'A' and 'B' (e.g. A, B, A), "
            f"got {list(route)}",
        )
    if "B" in route and scenario.dock is None:
        raise r.fail("route", f"goes to B, but scenario {name!r} has no [dock] pose")
    inspection = _boolean(r, "inspection", True)
    if inspection and not scenario.inspection_object:
        raise r.fail("inspection", f"scenario {name!r} has no inspection_object")
    secondary = _boolean(r, "secondary", True)
    if secondary and len(scenario.question_region) < 3:
        raise r.fail("secondary", f"scenario {name!r} has no question region")
    # an empty [phases.after_trial] table still asks the questionnaire, with the defaults
    after = _after_trial(r.sub("after_trial")) if "after_trial" in r.data else None
    phase = MainTrials(
        scenario=name,
        route=route,
        inspection=inspection,
        timeout_s=r.number("timeout_s", 900.0, positive=True),
        secondary=secondary,
        block_size=r.integer("block_size", 20, minimum=1),
        end_on_collision=_boolean(r, "end_on_collision", False),
        after_trial=after,
    )
    r.finish()
    return phase


def _phases(r: FieldReader, modes: tuple[str, ...], scenarios: _Scenarios) -> tuple[Phase, ...]:
    readers = r.tables("phases")
    if not readers:
        raise r.fail("phases", 'is required: at least a [[phases]] table with kind = "main"')
    phases: list[Phase] = []
    last = -1
    for pr in readers:
        kind = pr.string("kind", allowed=PHASE_KINDS)
        rank = PHASE_KINDS.index(kind)
        if rank <= last:
            seen = phases[-1].kind
            what = "appears twice" if kind == seen else f"comes after {seen!r}"
            raise pr.fail(
                "kind",
                f"phase {kind!r} {what}; phases run once each in the order "
                f"{', '.join(PHASE_KINDS)}",
            )
        last = rank
        if kind == "briefing":
            phase: Phase = Briefing(text=_text(pr, "text"))
            pr.finish()
        elif kind == "experience":
            phase = ExperiencePhase(
                instrument=pr.string("instrument", "experience", allowed=EXPERIENCE_INSTRUMENTS)
            )
            pr.finish()
        elif kind == "training":
            phase = _training(pr, modes, scenarios)
        elif kind == "practice":
            phase = _practice(pr, scenarios)
        elif kind == "baseline":
            phase = Baseline(questions=pr.integer("questions", 40, minimum=1))
            pr.finish()
        elif kind == "main":
            phase = _main(pr, scenarios)
        else:
            phase = Debrief(text=_text(pr, "text"))
            pr.finish()
        phases.append(phase)
    if not any(isinstance(p, MainTrials) for p in phases):
        raise r.fail("phases", 'must include a phase with kind = "main"')
    return tuple(phases)


def _secondary(r: FieldReader) -> SecondarySettings:
    for key, place in (("block_size", "main"), ("baseline_size", "baseline")):
        if key in r.data:
            where = "block_size" if key == "block_size" else "questions"
            raise r.fail(key, f"is set in the {place!r} phase, as '{where}'")
    d = SecondarySettings()
    offsets = _raw(r, "near_miss_offsets", list(d.near_miss_offsets))
    if not isinstance(offsets, list):
        raise r.fail("near_miss_offsets", f"must be a list of integers, got {offsets!r}")
    try:
        s = SecondarySettings(
            p_correct=r.number("p_correct", d.p_correct),
            timeout_s=r.number("timeout_s", d.timeout_s),
            gap_s=r.number("gap_s", d.gap_s),
            near_miss_offsets=tuple(offsets),
            p_addition=r.number("p_addition", d.p_addition),
        )
    except ValueError as error:  # "SecondarySettings.<field>: <message>"
        key, _, message = str(error).removeprefix("SecondarySettings.").partition(": ")
        raise r.fail(key, message) from None
    r.finish()
    return s


def _analysis(r: FieldReader) -> AnalysisSettings:
    alpha = r.number("alpha", 0.05, positive=True)
    if alpha >= 1:
        raise r.fail("alpha", f"must lie in (0, 1), got {alpha!r}")
    a = AnalysisSettings(
        alpha=alpha,
        gate=r.string("gate", "auto", allowed=GATES),
        posthoc=r.string("posthoc", "lsd_paired", allowed=POSTHOC),
        metrics=_string_list(
            r,
            "metrics",
            [
                "completion_time_s",
                "collisions",
                "score_s",
                "secondary_answer_time_s",
                "secondary_errors",
                "tlx_raw",
            ],
            allowed=METRICS,
        ),
        secondary_baseline_level=_boolean(r, "secondary_baseline_level", True),
    )
    if not a.metrics:
        raise r.fail("metrics", f"must name at least one of {', '.join(METRICS)}")
    r.finish()
    return a


def _ui(r: FieldReader) -> UiSettings:
    window = r.vector("window", 2, [1280, 720], positive=True)
    if not all(v == int(v) and v >= 320 for v in window):
        raise r.fail("window", f"must be two whole numbers of pixels >= 320, got {list(window)}")
    ir = r.sub("instructions")
    texts = {}
    for kind in PHASE_KINDS:
        if kind in ir.data:
            texts[kind] = _text(ir, kind)
    ir.finish()
    u = UiSettings(
        window=(int(window[0]), int(window[1])),
        fullscreen=_boolean(r, "fullscreen", False),
        show_map=_boolean(r, "show_map", True),
        instructions=texts,
    )
    r.finish()
    return u


def _indices(
    r: FieldReader, names: tuple[str, ...], defaults: Mapping[str, int]
) -> Mapping[str, int]:
    out = {name: r.integer(name, defaults[name], minimum=0) for name in names}
    r.finish()
    values = list(out.values())
    duplicates = sorted({v for v in values if values.count(v) > 1})
    if duplicates:
        clash = [n for n, v in out.items() if v == duplicates[0]]
        raise r.fail(clash[1], f"uses index {duplicates[0]} as {clash[0]!r} does")
    return out


def _input(r: FieldReader) -> InputSettings:
    deadzone = r.number("deadzone", 0.1, non_negative=True)
    if deadzone >= 1:
        raise r.fail("deadzone", f"must lie in [0, 1), got {deadzone!r}")
    s = InputSettings(
        axes=_indices(r.sub("axes"), AXES, DEFAULT_AXES),
        buttons=_indices(r.sub("buttons"), BUTTONS, DEFAULT_BUTTONS),
        invert=_string_list(r, "invert", list(DEFAULT_INVERT), allowed=AXES),
        deadzone=deadzone,
    )
    r.finish()
    return s


def _modes(
    r: FieldReader, known: Collection[str]
) -> tuple[tuple[str, ...], str, bool, Mapping[str, Mapping[str, Any]]]:
    names = _string_list(r, "names", None)
    for i, name in enumerate(names):
        if name not in known:
            raise r.fail(
                f"names[{i}]",
                f"unknown mode {name!r}; registered modes: {', '.join(sorted(known)) or 'none'}",
            )
    if len(names) < 2:
        raise r.fail("names", f"a comparison needs at least two modes, got {list(names)}")
    scheme = r.string("counterbalancing", "full_permutation", allowed=SCHEMES)
    hidden = _boolean(r, "hidden", True)
    if not hidden:
        raise r.fail(
            "hidden",
            "must be true: the participant is never told the active mode (thesis 7.5, 7.6.1.3)",
        )
    sr = r.sub("settings")
    settings: dict[str, Mapping[str, Any]] = {}
    for name in list(sr.data):
        if name not in names:
            raise sr.fail(name, f"must be one of this protocol's modes ({', '.join(names)})")
        values = sr.table(name) or {}
        try:
            make_mode(name, **values)
        except (ValueError, TypeError) as error:
            raise sr.fail(name, str(error)) from None
        settings[name] = dict(values)
    sr.finish()
    r.finish()
    return names, scheme, hidden, settings


def parse_protocol(
    text: str,
    source: str = "<protocol>",
    *,
    known_modes: Collection[str] | None = None,
    base: Path | None = None,
) -> Protocol:
    """Validate a protocol's TOML ``text`` into a :class:`Protocol`.

    Parameters
    ----------
    text : str
        The file's content; kept verbatim with its SHA-256.
    source : str
        Names the file in error messages.
    known_modes : collection of str, optional
        The mode names accepted; default the registry,
        :func:`autonomy.modes.available_modes`.
    base : Path, optional
        Folder against which relative scenario files (``*.toml``) are resolved; default
        the folder of ``source`` when it names a file, else the working directory.

    Raises
    ------
    ValueError
        Malformed TOML or any bad field, naming ``source`` and the field.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{source}: not valid TOML: {error}") from None
    known = available_modes() if known_modes is None else known_modes
    if base is None:
        base = Path(source).parent if Path(source).is_file() else Path.cwd()
    r = FieldReader(source, data)
    sr = r.sub("study")
    study = StudyInfo(
        name=_text(sr, "name"),
        title=sr.string("title", ""),
        description=sr.string("description", ""),
        participants=sr.integer("participants", 18, minimum=1),
        seed=sr.integer("seed", 0, minimum=0),
    )
    sr.finish()
    if "modes" not in data:
        raise r.fail("modes", "is required: a [modes] table with names = [...]")
    modes, scheme, hidden, settings = _modes(r.sub("modes"), known)
    scenarios = _Scenarios(base)
    phases = _phases(r, modes, scenarios)
    secondary = _secondary(r.sub("secondary"))
    sc = r.sub("scoring")
    scoring = Scoring(collision_penalty_s=sc.number("collision_penalty_s", 60.0, non_negative=True))
    sc.finish()
    analysis = _analysis(r.sub("analysis"))
    ui = _ui(r.sub("ui"))
    inp = _input(r.sub("input"))
    r.finish()
    return Protocol(
        source=source,
        study=study,
        modes=modes,
        counterbalancing=scheme,
        mode_hidden=hidden,
        mode_settings=settings,
        phases=phases,
        secondary=secondary,
        scoring=scoring,
        analysis=analysis,
        ui=ui,
        input=inp,
        text=text,
        sha256=hashlib.sha256(text.encode("utf-8")).hexdigest(),
    )


def protocol_path(path_or_name: str | Path) -> Path:
    """The file of a shipped protocol name (``"thesis-7-6"``) or of a path.

    Raises ``ValueError`` naming the argument when neither exists.
    """
    text = str(path_or_name)
    path = Path(text)
    if path.is_file():
        return path
    shipped = PROTOCOL_DIR / f"{text}.toml"
    if not path.suffix and shipped.is_file():
        return shipped
    if path.is_dir():
        raise ValueError(f"{text}: is a directory, not a protocol file")
    raise ValueError(
        f"{text}: no such protocol file and not a shipped protocol; shipped: "
        f"{', '.join(available())}"
    )


def load_protocol(
    path_or_name: str | Path, *, known_modes: Collection[str] | None = None
) -> Protocol:
    """Load a shipped protocol by name (``"thesis-7-6"``) or any protocol TOML file by path.

    Every failure is a ``ValueError`` naming the file (and the field): a missing or
    unreadable file, malformed TOML, a bad field, an unknown mode or scenario.
    ``known_modes`` as in :func:`parse_protocol`.
    """
    path = protocol_path(path_or_name)
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise ValueError(f"{path}: cannot read: {error.strerror or error}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text file") from None
    return parse_protocol(text, str(path), known_modes=known_modes)
