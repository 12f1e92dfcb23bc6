"""Reading a protocol's TOML file into a :class:`~study.engine.protocol.types.Protocol`.

Tables and fields (every one optional unless marked; unknown keys are refused):
``[study]`` name (required), title, description, participants, seed, sites;
``[modes]`` names (required, >= 2, distinct), counterbalancing, hidden,
``[modes.settings.<mode>]``; ``[[phases]]`` kind, in the order they run ("main"
required, with its scenario; ``[phases.after_trial]`` instrument, weights);
``[secondary]`` p_correct, timeout_s, gap_s, near_miss_offsets, p_addition;
``[scoring]`` collision_penalty_s; ``[analysis]`` alpha, gate, posthoc, metrics,
secondary_baseline_level, timeouts, test, ``[analysis.tests]`` (metric -> test);
``[ui]`` window, fullscreen, show_map, layout, show_object,
``[ui.instructions]`` (phase -> the "get ready" text), ``[ui.texts]`` (titles, time's up,
practice feedback, pause: :data:`study.engine.texts.DEFAULT_TEXTS`); ``[input]`` deadzone,
``[input.axes]``, ``[input.buttons]``, invert, ``[input.keys]`` (the keyboard's letters),
``[input.names]`` (what the legends call the gamepad's controls); ``[recording]``
camera_hz, camera_width, jpeg_quality; ``[lsl]`` outlets, mode_names, resolve_timeout_s,
``[[lsl.record]]`` (the lab's streams: :mod:`study.lsl.settings`); ``[web]`` (a session from
a browser link: :mod:`study.web.settings`).
The participant's texts may hold placeholders (``{object}``, ``{attempt}``, ...; which ones
each may use: :func:`study.engine.texts.allowed_placeholders`); ``{object}`` and
``{laser_colour}`` are filled here, from the main scene. The shipped files in
``protocols/`` show every table.
"""

from __future__ import annotations

import hashlib
import itertools
import re
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from autonomy.modes import MODES, make_mode, mode_factory
from protocols import PROTOCOL_DIR, available
from questionnaires import nasa_tlx
from sim.check import check_scene
from sim.fields import FieldReader
from sim.limits import MAX_DURATION_S, MAX_PARTICIPANTS, MAX_SEED, loads_toml, short_repr
from sim.scenario import MAX_PIXELS, Scenario, load_scenario
from study.engine.counterbalance import SCHEMES
from study.engine.protocol.interface import input_settings, protocol_words, template, ui_settings
from study.engine.protocol.readers import boolean as _boolean
from study.engine.protocol.readers import raw as _raw
from study.engine.protocol.readers import string_list as _string_list
from study.engine.protocol.readers import text as _text
from study.engine.protocol.types import (
    AFTER_TRIAL_INSTRUMENTS,
    EXPERIENCE_INSTRUMENTS,
    GATES,
    METRICS,
    ON_FAIL,
    PHASE_KINDS,
    POSTHOC,
    POSTHOC_GATES,
    PRACTICE_ORDERS,
    ROUTE_POINTS,
    TESTS,
    TIMEOUTS,
    TLX_WEIGHTS,
    AfterTrial,
    AnalysisSettings,
    Baseline,
    Briefing,
    Debrief,
    ExperiencePhase,
    MainTrials,
    Phase,
    Practice,
    Protocol,
    RecordingSettings,
    Scoring,
    StudyInfo,
    Training,
)
from study.lsl.settings import lsl_settings
from study.web.settings import web_settings
from tasks.secondary import SecondarySettings

SITE_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,31}\Z")  # a site's name
MAX_QUESTIONS = 1_000  # questions of a block, a baseline or a rehearsal
MAX_ATTEMPTS = 100  # practice attempts, collisions allowed in one
MAX_OFFSET = 1_000  # size of a near-miss offset of the secondary task's shown answer


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
                scenario = load_scenario(name)
                problem = _first_problem(scenario)
            except (ValueError, FileNotFoundError, OSError) as error:
                raise r.fail(key, f"cannot load scenario {name!r}: {error}") from None
            if problem is not None:
                raise r.fail(key, f"scenario {name!r} fails the scene check: {problem}")
            self.cache[name] = scenario
        return name, self.cache[name]


_CHECKED: dict[tuple[str, str], str | None] = {}  # (file, SHA-256 of its bytes) -> problem


def _first_problem(scenario: Scenario) -> str | None:
    """The first problem :func:`sim.check.check_scene` finds, as one line, or ``None``.

    Remembered per file content for the process, since protocols are parsed often
    and a scene's check takes a few tenths of a second.
    """
    try:
        digest = hashlib.sha256(Path(scenario.source).read_bytes()).hexdigest()
    except OSError:
        digest = ""
    key = (scenario.source, digest)
    if not digest or key not in _CHECKED:
        problems = check_scene(scenario)
        _CHECKED[key] = problems[0].line(scenario.source) if problems else None
    return _CHECKED[key]


def _training(r: FieldReader, modes: tuple[str, ...], scenarios: _Scenarios) -> Training:
    name, scenario = scenarios.get(r, "scenario")
    duration = (
        r.number("duration_s", positive=True, maximum=MAX_DURATION_S)
        if "duration_s" in r.data
        else None
    )
    secondary = _boolean(r, "secondary", True)
    if secondary and len(scenario.question_region) < 3:
        raise r.fail("secondary", f"scenario {name!r} has no question region")
    phase = Training(
        scenario=name,
        duration_s=duration,
        secondary=secondary,
        direct_view=_boolean(r, "direct_view", True),
        modes=_string_list(r, "modes", list(modes), allowed=modes),
        rehearsal_questions=r.integer("rehearsal_questions", 0, minimum=0, maximum=MAX_QUESTIONS),
    )
    if not phase.modes:
        raise r.fail("modes", "must name at least one of the protocol's modes")
    if phase.rehearsal_questions and not secondary:
        raise r.fail("rehearsal_questions", "needs secondary = true (they are its questions)")
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
        time_limit_s=r.number("time_limit_s", positive=True, maximum=MAX_DURATION_S),
        max_collisions=r.integer("max_collisions", 0, minimum=0, maximum=MAX_ATTEMPTS),
        max_attempts=r.integer("max_attempts", 3, minimum=1, maximum=MAX_ATTEMPTS),
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
        timeout_s=r.number("timeout_s", 900.0, positive=True, maximum=MAX_DURATION_S),
        secondary=secondary,
        block_size=r.integer("block_size", 20, minimum=1, maximum=MAX_QUESTIONS),
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
            phase: Phase = Briefing(text=template(pr, "text", None, "text"))
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
            phase = Baseline(
                questions=pr.integer("questions", 40, minimum=1, maximum=MAX_QUESTIONS)
            )
            pr.finish()
        elif kind == "main":
            phase = _main(pr, scenarios)
        else:
            phase = Debrief(text=template(pr, "text", None, "text"))
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
    if (
        not isinstance(offsets, list)
        or len(offsets) > MAX_QUESTIONS
        or any(isinstance(o, int) and abs(o) > MAX_OFFSET for o in offsets)
    ):
        raise r.fail(
            "near_miss_offsets",
            f"must be a list of at most {MAX_QUESTIONS} integers of size at most "
            f"{MAX_OFFSET}, got {short_repr(offsets)}",
        )
    values = {
        "p_correct": r.number("p_correct", d.p_correct),
        "timeout_s": r.number("timeout_s", d.timeout_s, maximum=MAX_DURATION_S),
        "gap_s": r.number("gap_s", d.gap_s, maximum=MAX_DURATION_S),
        "p_addition": r.number("p_addition", d.p_addition),
    }
    try:
        s = SecondarySettings(near_miss_offsets=tuple(offsets), **values)
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
        posthoc_gate=r.string("posthoc_gate", "auto", allowed=POSTHOC_GATES),
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
        timeouts=r.string("timeouts", "exclude", allowed=TIMEOUTS),
        test=r.string("test", "rm_anova", allowed=TESTS),
        tests=_tests(r),
    )
    if not a.metrics:
        raise r.fail("metrics", f"must name at least one of {', '.join(METRICS)}")
    r.finish()
    return a


def _tests(r: FieldReader) -> dict[str, str]:
    """``[analysis.tests]``: metric -> planned test, overriding ``test`` for that metric."""
    value = _raw(r, "tests", {})
    if not isinstance(value, dict):
        raise r.fail("tests", f"must be a table of metric = test, got {value!r}")
    for metric, test in value.items():
        if metric not in METRICS:
            raise r.fail(f"tests.{metric}", f"is not a metric; choose from {', '.join(METRICS)}")
        if test not in TESTS:
            raise r.fail(f"tests.{metric}", f"must be one of {', '.join(TESTS)}, got {test!r}")
    return dict(value)


def _recording(r: FieldReader) -> RecordingSettings:
    d = RecordingSettings()
    camera_hz = r.number("camera_hz", d.camera_hz, non_negative=True)
    if camera_hz > 20:
        raise r.fail("camera_hz", f"must be at most 20 (the control rate), got {camera_hz!r}")
    quality = r.integer("jpeg_quality", d.jpeg_quality, minimum=1)
    if quality > 100:
        raise r.fail("jpeg_quality", f"must lie in 1..100, got {quality!r}")
    s = RecordingSettings(
        camera_hz=float(camera_hz),
        camera_width=r.integer("camera_width", d.camera_width, minimum=16, maximum=MAX_PIXELS),
        jpeg_quality=quality,
    )
    r.finish()
    return s


def _modes(
    r: FieldReader, known: Collection[str] | None
) -> tuple[tuple[str, ...], str, bool, Mapping[str, Mapping[str, Any]]]:
    names = _string_list(r, "names", None)
    for i, name in enumerate(names):
        if known is not None and name not in known:
            raise r.fail(
                f"names[{i}]",
                f"unknown mode {name!r}; registered modes: {', '.join(sorted(known)) or 'none'}",
            )
        if known is None:
            try:
                mode_factory(name)  # a mode from another package: loadable?
            except ValueError as error:
                raise r.fail(f"names[{i}]", str(error)) from None
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
    for i, name in enumerate(names):  # a mode from another package: does it build?
        if name not in MODES and name not in settings and known is None:
            try:
                make_mode(name)
            except (ValueError, TypeError) as error:
                raise r.fail(f"names[{i}]", str(error)) from None
    return names, scheme, hidden, settings


def _study(r: FieldReader) -> StudyInfo:
    study = StudyInfo(
        name=_text(r, "name"),
        title=r.string("title", ""),
        description=r.string("description", ""),
        participants=r.integer("participants", 18, minimum=1, maximum=MAX_PARTICIPANTS),
        seed=r.integer("seed", 0, minimum=0, maximum=MAX_SEED),
        sites=_sites(r),
    )
    r.finish()
    return study


def _sites(r: FieldReader) -> tuple[str, ...]:
    """``[study] sites``: the names of a multi-site study's sites (each site keeps its
    own counterbalancing ledger, docs/decisions.md), 1-32 letters, digits, ``_`` or ``-``."""
    sites = _string_list(r, "sites", [])
    for i, name in enumerate(sites):
        if not SITE_PATTERN.match(name):
            raise r.fail(
                f"sites[{i}]",
                f"must be 1-32 letters, digits, '_' or '-' starting with a letter or digit, "
                f"got {name!r}",
            )
    return sites


def _scoring(r: FieldReader) -> Scoring:
    scoring = Scoring(
        collision_penalty_s=r.number(
            "collision_penalty_s", 60.0, non_negative=True, maximum=MAX_DURATION_S
        )
    )
    r.finish()
    return scoring


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
        The mode names accepted; default any mode :func:`autonomy.modes.mode_factory`
        loads (the registry, installed packages' entry points, ``"package.module:factory"``).
    base : Path, optional
        Folder against which relative scenario files (``*.toml``) are resolved; default
        the folder of ``source`` when it names a file, else the working directory.

    Raises
    ------
    ValueError
        Malformed TOML or any bad field, naming ``source`` and the field.
    """
    data = loads_toml(text, source)
    known = known_modes  # None: the registry, installed packages and module references
    if base is None:
        base = Path(source).parent if Path(source).is_file() else Path.cwd()
    r = FieldReader(source, data)
    study = _study(r.sub("study"))
    if "modes" not in data:
        raise r.fail("modes", "is required: a [modes] table with names = [...]")
    modes, scheme, hidden, settings = _modes(r.sub("modes"), known)
    scenarios = _Scenarios(base)
    phases = _phases(r, modes, scenarios)
    secondary = _secondary(r.sub("secondary"))
    scoring = _scoring(r.sub("scoring"))
    analysis = _analysis(r.sub("analysis"))
    ui = ui_settings(r.sub("ui"))
    inp = input_settings(r.sub("input"))
    recording = _recording(r.sub("recording"))
    lsl = lsl_settings(r.sub("lsl"), "lsl" in data)
    web = web_settings(r.sub("web"))
    r.finish()
    main = next(p for p in phases if isinstance(p, MainTrials))
    phases, ui = protocol_words(r, phases, ui, scenarios.cache[main.scenario])
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
        recording=recording,
        lsl=lsl,
        web=web,
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
