"""The session state machine: one participant through every phase of a protocol.

Thesis section 7.6.1.3 ("Test procedure") and issue 4: briefing, the experience
questionnaire, training (free driving with each mode), practice per mode (repeated until
passed: no more than the allowed collisions within the time limit, or the maximum number
of attempts), a baseline block of the secondary task without driving, the main trials in
the participant's counterbalanced order with NASA-TLX after each, and the debrief. The
active mode is never shown to the participant (no ``ScreenState`` field names it).

Storage (:mod:`study.data.storage`, DESIGN.md "Data"): the study row (protocol text and SHA-256),
the participant row (code, kind, parameters, order index, mode order, seed), a session
row, and per trial what :func:`study.engine.trial.run_trial` writes. A database made with a
different protocol, or a second session for a participant, is refused with a
``ValueError`` unless ``force``; a forced run is recorded in ``session.forced`` and
``session.note``. ``resume`` continues the participant's last session: a trial left
``running`` by a crash is marked ``aborted`` (kept) and run again; completed trials are
never repeated or overwritten.

Decisions where the spec is silent:

- Order index: a code ending in a number ``n >= 1`` (``P03``) gets row ``n - 1`` of the
  counterbalancing scheme, so that codes and orders match the plan ``asa plan`` prints;
  any other code gets the smallest index no participant of the study has. The order is
  ``study.engine.counterbalance.assign_indexed`` row ``order_index`` (the random scheme draws
  from a generator seeded with the study seed).
- Seeds: the participant's seed is ``seed`` if given, else :func:`default_seed` of the
  study seed and the participant code (what ``asa run`` uses too); each trial's seed is
  derived from the participant's seed, the phase, the ordinal and the attempt
  (``numpy.random.SeedSequence``), so a re-run trial gets fresh noise and questions and
  the same session is reproducible.
- Non-trial phases (briefing, experience, debrief) are marked done by a ``phase_done``
  event, written in the same transaction as their responses, so a resumed session skips
  them.
- Training is for people to learn the interface and the modes. A participant whose
  ``learns`` attribute is False (a synthetic participant: its skill is a fixed sample of
  the population model, so training would change nothing and cost about 40 % of a thesis
  session's simulation) skips it: the phase is marked done with a ``phase_done`` event
  whose detail names the reason (``skipped``), and no training trials are stored.
- Training: one trial per mode in the protocol's training order, on the main route
  without the inspection requirement, ending after ``duration_s`` or when the route is
  driven, whichever comes first. Practice goes from A to pose B only. A practice attempt
  passes when the goal is reached within the time limit with at most ``max_collisions``
  collisions; ``passed`` is stored in ``trial.outcome`` in the completing transaction.
  After each attempt the participant reads the feedback, and the next attempt shows it.
  ``on_fail = "exclude"`` ends the session (status ``aborted``, note "excluded ...").
- The baseline block runs on the main scenario with the robot standing at A.
- NASA-TLX: the six ratings, and the 15 pairwise choices when the protocol's weights are
  ``per_trial`` (after every main trial) or ``once`` (after the last), are stored with the
  trial's id: items are the subscale ids and ``pair:<a>|<b>`` in the canonical pair order
  of ``questionnaires.nasa_tlx.PAIRS`` with the chosen subscale as text. A main trial
  completed before a crash but without its questionnaire gets it on resume.
- Maps: each scenario's occupancy grid is saved once as ``<recordings>/maps/<scenario>.pgm``
  and ``.yaml`` (ROS map_server format), so the report draws the paths on the map without
  importing the simulator.
- Camera frames in recordings: 2 Hz for human participants, none otherwise (``camera_hz``
  overrides).
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from autonomy.modes import make_mode
from questionnaires import experience as experience_q
from questionnaires import nasa_tlx
from sim.map_files import save_ros_map
from sim.occupancy import build_grid
from sim.scenario import load_scenario
from sim.semantics import derive_components
from sim.world import World
from study import __version__
from study.engine.counterbalance import assign_indexed, cycle_length
from study.engine.protocol import (
    Baseline,
    Briefing,
    Debrief,
    ExperiencePhase,
    MainTrials,
    Practice,
    Protocol,
    Training,
)
from study.data.storage import (
    Event,
    Participant,
    Response,
    SessionRow,
    Study,
    Trial,
    database_file,
    get_study,
    open_database,
    utc_now,
)
from study.engine.trial import (
    ExperimenterControl,
    FreeClock,
    Scene,
    TrialResult,
    TrialSpec,
    TrialWriter,
    WallClock,
    recording_relpath,
    run_trial,
)
from tasks.primary import PrimarySettings, route_from_points

CODE_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")
NO_LEARNING = "the participant does not learn (participant.learns is False)"
MAX_RANDOM_INDEX = 100_000  # participant numbers the random scheme serves
_PHASE_INDEX = {"training": 1, "practice": 2, "baseline": 3, "main": 4}
DEFAULT_INSTRUCTIONS = {
    "training": "Training: drive freely and get used to the robot.",
    "practice": "Practice: drive to the goal without touching anything.",
    "baseline": "Answer the questions: is the shown result correct? Press Yes or No.",
    "main": "Drive from A to B and back to A; inspect the red object on the way; "
    "answer the questions when they appear.",
}


@dataclass(frozen=True, slots=True)
class TrialSummary:
    """One trial of a session, as the experimenter sees it."""

    trial_id: int
    phase: str
    ordinal: int
    attempt: int
    mode: str
    status: str
    completion_time_s: float | None
    collisions: int | None


@dataclass(frozen=True, slots=True)
class SessionSummary:
    """What :func:`run_session` did."""

    participant: str  # code
    participant_id: int
    session_id: int
    status: str  # "completed" or "aborted"
    mode_order: tuple[str, ...]
    trials: tuple[TrialSummary, ...]  # run by this call, in order
    resumed: bool
    forced: bool
    note: str


def check_code(code: str) -> str:
    """A participant code: letters, digits, ``_`` and ``-``, at most 64, starting with a
    letter or digit. Raises ``ValueError`` naming the field otherwise."""
    if not isinstance(code, str) or not CODE_PATTERN.match(code):
        raise ValueError(
            f"participant code: must be 1-64 letters, digits, '_' or '-' starting with a "
            f"letter or digit, got {code!r}"
        )
    return code


def default_seed(study_seed: int, code: str) -> int:
    """A participant's seed when none is given: a 31-bit hash of the study seed and code."""
    digest = hashlib.sha256(f"{study_seed}:{code}".encode()).digest()
    return int.from_bytes(digest[:4], "little") >> 1


def derive_seed(*parts: int) -> int:
    """A 31-bit seed derived from integers (``numpy.random.SeedSequence``)."""
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(1)[0] >> 1)


class _Scenes:
    """Scenarios, grids, components and one World per scenario, built once per session;
    each scenario's occupancy map is saved once to ``maps`` (ROS PGM + YAML) so that the
    analysis can draw paths on it without the simulator."""

    def __init__(self, maps: Path | None = None) -> None:
        self._scenes: dict[str, Scene] = {}
        self.maps = maps

    def get(self, source: str) -> Scene:
        if source not in self._scenes:
            scenario = load_scenario(source)
            components = derive_components(scenario)
            grid = build_grid(scenario)
            if self.maps is not None and not (self.maps / f"{scenario.name}.yaml").exists():
                self._save_map(grid, scenario.name)
            self._scenes[source] = Scene(
                name=scenario.name,
                scenario=scenario,
                grid=grid,
                components=components,
                world=World(scenario, seed=0, components=components),
            )
        return self._scenes[source]

    def _save_map(self, grid: Any, name: str) -> None:
        """Write the map files atomically (parallel sessions may write the same map)."""
        assert self.maps is not None
        self.maps.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=self.maps, prefix=".tmp-") as tmp:
            pgm, yaml = save_ros_map(grid, tmp, name)
            os.replace(pgm, self.maps / pgm.name)
            os.replace(yaml, self.maps / yaml.name)  # last: its presence means complete

    def close(self) -> None:
        for scene in self._scenes.values():
            scene.world.close()
        self._scenes.clear()


class _Runner:
    """The state of one :func:`run_session` call."""

    def __init__(
        self,
        protocol: Protocol,
        engine: Engine,
        db: str | Path,
        participant: Any,
        person: Participant,
        session_id: int,
        *,
        progress: Callable[[str], None],
        control: ExperimenterControl,
        clock: FreeClock | WallClock,
        camera_hz: float,
        on_tick: Callable[[int, TrialWriter], None] | None,
        recordings: Path | None,
    ) -> None:
        self.protocol = protocol
        self.engine = engine
        self.participant = participant
        self.person_id = person.id
        self.code = person.code
        self.seed = person.seed
        self.order = tuple(person.mode_order)
        self.session_id = session_id
        self.progress = progress
        self.control = control
        self.clock = clock
        self.camera_hz = camera_hz
        self.on_tick = on_tick
        db_path = database_file(db)
        self.folder = db_path.parent
        self.recordings = (
            recordings if recordings is not None else self.folder / f"{db_path.stem}_recordings"
        )
        self.scenes = _Scenes(self.recordings / "maps")
        self.trials: list[TrialSummary] = []

    # -------------------------------------------------------------- database helpers

    def _trials(self, phase: str, ordinal: int) -> list[Trial]:
        with Session(self.engine) as s:
            return list(
                s.scalars(
                    select(Trial)
                    .where(
                        Trial.session_id == self.session_id,
                        Trial.phase == phase,
                        Trial.ordinal == ordinal,
                    )
                    .order_by(Trial.id)
                )
            )

    def _phase_done(self, kind: str) -> bool:
        with Session(self.engine) as s:
            events = s.scalars(
                select(Event).where(Event.session_id == self.session_id, Event.kind == "phase_done")
            ).all()
        return any(e.detail.get("phase") == kind for e in events)

    def _mark_done(
        self, kind: str, responses: Sequence[Response] = (), *, skipped: str = ""
    ) -> None:
        detail = {"phase": kind, **({"skipped": skipped} if skipped else {})}
        with Session(self.engine) as s, s.begin():
            s.add_all(responses)
            s.add(
                Event(
                    session_id=self.session_id,
                    trial_id=None,
                    t=0.0,
                    kind="phase_done",
                    detail=detail,
                )
            )

    def _instruction(self, kind: str) -> str:
        return self.protocol.ui.instructions.get(kind, DEFAULT_INSTRUCTIONS.get(kind, ""))

    # -------------------------------------------------------------- trials

    def _run(
        self, spec: TrialSpec, scenario_source: str, *, max_collisions: int | None = None
    ) -> TrialResult:
        scene = self.scenes.get(scenario_source)
        mode = None
        if spec.mode:
            mode = make_mode(spec.mode, **dict(self.protocol.mode_settings.get(spec.mode, {})))
        values = {
            "participant_id": self.person_id,
            "session_id": self.session_id,
            "phase": spec.phase,
            "mode": spec.mode,
            "ordinal": spec.ordinal,
            "attempt": spec.attempt,
            "scenario": scene.name,
            "seed": spec.seed,
        }
        code = self.code
        result = run_trial(
            self.engine,
            spec,
            scene=scene,
            participant=self.participant,
            mode=mode,
            trial_values=values,
            recording_dir=self.folder,
            recording_rel=lambda tid: recording_relpath(self.folder, self.recordings, code, values),
            session_id=self.session_id,
            clock=self.clock,
            control=self.control,
            on_tick=self.on_tick,
            max_collisions=max_collisions,
        )
        out = result.outcome
        summary = TrialSummary(
            result.trial_id,
            spec.phase,
            spec.ordinal,
            spec.attempt,
            spec.mode,
            result.status,
            out.get("completion_time_s"),
            out.get("collisions"),
        )
        self.trials.append(summary)
        line = f"{self.code} {spec.phase} #{spec.ordinal}"
        if spec.attempt:
            line += f" attempt {spec.attempt}"
        if spec.mode:
            line += f" mode {spec.mode}"
        line += f": {result.status}, {result.duration_s:.1f} s simulated"
        if out.get("collisions") is not None:
            line += f", {out['collisions']} collisions"
        if "passed" in out:
            line += ", passed" if out["passed"] else ", not passed"
        self.progress(line)
        return result

    def _spec(self, phase: str, ordinal: int, mode: str, **fields: Any) -> TrialSpec:
        attempt = len(self._trials(phase, ordinal))
        return TrialSpec(
            phase=phase,
            ordinal=ordinal,
            attempt=attempt,
            mode=mode,
            seed=derive_seed(self.seed, _PHASE_INDEX[phase], ordinal, attempt),
            instruction=self._instruction(phase),
            camera_hz=self.camera_hz,
            **fields,
        )

    # -------------------------------------------------------------- phases

    def briefing(self, phase: Briefing) -> None:
        if self._phase_done("briefing"):
            return
        self.participant.read(phase.text)
        self._mark_done("briefing")
        self.progress(f"{self.code} briefing read")

    def experience(self, phase: ExperiencePhase) -> None:
        if self._phase_done("experience"):
            return
        raw = self.participant.fill(experience_q.INSTRUMENT, context={"phase": "experience"})
        answers = experience_q.validate(raw, source=f"participant {self.code}: experience")
        rows = [
            self._response(phase.instrument, item, value, None) for item, value in answers.items()
        ]
        self._mark_done("experience", rows)
        self.progress(f"{self.code} experience questionnaire: {len(rows)} answers")

    def _response(self, instrument: str, item: str, value: Any, trial_id: int | None) -> Response:
        number = (
            float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None
        )
        text = "" if number is not None or value is None else str(value)
        return Response(
            participant_id=self.person_id,
            trial_id=trial_id,
            instrument=instrument,
            item=item,
            value=number,
            text=text,
        )

    def training(self, phase: Training) -> bool:
        if not getattr(self.participant, "learns", True):
            if not self._phase_done("training"):
                self._mark_done("training", skipped=NO_LEARNING)
                self.progress(f"{self.code} training skipped: {NO_LEARNING}")
            return True
        main = self.protocol.main
        for ordinal, mode in enumerate(phase.modes):
            if any(t.status == "completed" for t in self._trials("training", ordinal)):
                continue
            limit = phase.duration_s if phase.duration_s is not None else main.timeout_s
            spec = self._spec(
                "training",
                ordinal,
                mode,
                primary=PrimarySettings(
                    route=route_from_points(main.route),
                    inspection_required=False,
                    timeout_s=limit,
                    collision_penalty_s=self.protocol.scoring.collision_penalty_s,
                ),
                secondary=self.protocol.secondary_settings if phase.secondary else None,
            )
            if self._run(spec, phase.scenario).status != "completed":
                return False
        return True

    def practice(self, phase: Practice) -> bool | None:
        """True: go on; False: aborted; None: excluded."""
        modes = self.order if phase.order == "assigned" else self.protocol.modes
        for ordinal, mode in enumerate(modes):
            done = [t for t in self._trials("practice", ordinal) if t.status == "completed"]
            passed = any(t.outcome.get("passed") for t in done)
            attempts = len(done)
            feedback = ""
            while not passed and attempts < phase.max_attempts:
                spec = self._spec(
                    "practice",
                    ordinal,
                    mode,
                    primary=PrimarySettings(
                        route=("dock",),
                        inspection_required=False,
                        timeout_s=phase.time_limit_s,
                        collision_penalty_s=self.protocol.scoring.collision_penalty_s,
                    ),
                    secondary=self.protocol.secondary_settings if phase.secondary else None,
                    feedback=feedback,
                )
                result = self._run(spec, phase.scenario, max_collisions=phase.max_collisions)
                if result.status != "completed":
                    return False
                attempts += 1
                passed = bool(result.outcome.get("passed"))
                feedback = _practice_feedback(result.outcome, phase)
                self.participant.read(feedback)
            if not passed and phase.on_fail == "exclude":
                return None
        return True

    def baseline(self, phase: Baseline) -> bool:
        if any(t.status == "completed" for t in self._trials("baseline", 0)):
            return True
        spec = self._spec(
            "baseline",
            0,
            "",
            primary=None,
            secondary=self.protocol.secondary_settings,
            baseline=True,
        )
        return self._run(spec, self.protocol.main.scenario).status == "completed"

    def main(self, phase: MainTrials) -> bool:
        last = len(self.order) - 1
        for ordinal, mode in enumerate(self.order):
            done = [t for t in self._trials("main", ordinal) if t.status == "completed"]
            if done:
                trial_id = done[0].id
            else:
                spec = self._spec(
                    "main",
                    ordinal,
                    mode,
                    primary=PrimarySettings(
                        route=route_from_points(phase.route),
                        inspection_required=phase.inspection,
                        timeout_s=phase.timeout_s,
                        collision_penalty_s=self.protocol.scoring.collision_penalty_s,
                    ),
                    secondary=self.protocol.secondary_settings if phase.secondary else None,
                    end_on_collision=phase.end_on_collision,
                )
                result = self._run(spec, phase.scenario)
                if result.status != "completed":
                    return False
                trial_id = result.trial_id
            if phase.after_trial is not None:
                self._questionnaire(phase, ordinal, trial_id, ordinal == last)
        return True

    def _questionnaire(self, phase: MainTrials, ordinal: int, trial_id: int, last: bool) -> None:
        after = phase.after_trial
        assert after is not None  # checked by the caller
        with Session(self.engine) as s:
            have = s.scalar(
                select(func.count())
                .select_from(Response)
                .where(Response.trial_id == trial_id, Response.instrument == nasa_tlx.INSTRUMENT_ID)
            )
        if have:
            return
        context = {"phase": "main", "ordinal": ordinal}
        raw = self.participant.fill(nasa_tlx.INSTRUMENT, context=context)
        ratings = nasa_tlx.validate_ratings(raw, source=f"participant {self.code}: NASA-TLX")
        rows = [self._response(nasa_tlx.INSTRUMENT_ID, k, v, trial_id) for k, v in ratings.items()]
        if after.weights == "per_trial" or (after.weights == "once" and last):
            rng = np.random.default_rng(derive_seed(self.seed, 9, ordinal))
            choices = self.participant.choose(nasa_tlx.presentation_order(rng))
            nasa_tlx.weights_from_choices(choices)  # validates: 15 pairs, members chosen
            chosen = {tuple(sorted(pair)): pick for pair, pick in choices.items()}
            for a, b in nasa_tlx.PAIRS:
                row = self._response(nasa_tlx.INSTRUMENT_ID, f"pair:{a}|{b}", None, trial_id)
                row.text = chosen[tuple(sorted((a, b)))]
                rows.append(row)
        with Session(self.engine) as s, s.begin():
            s.add_all(rows)
            s.add(
                Event(
                    session_id=self.session_id,
                    trial_id=trial_id,
                    t=0.0,
                    kind="questionnaire_done",
                    detail={"instrument": after.instrument},
                )
            )
        self.progress(f"{self.code} NASA-TLX after main #{ordinal}: {len(rows)} answers")

    def debrief(self, phase: Debrief) -> None:
        if self._phase_done("debrief"):
            return
        self.participant.read(phase.text)
        self._mark_done("debrief")

    def run(self) -> str:
        """Every phase in order; returns the session's final status."""
        outcome: bool | None = True
        for phase in self.protocol.phases:
            if isinstance(phase, Briefing):
                self.briefing(phase)
            elif isinstance(phase, ExperiencePhase):
                self.experience(phase)
            elif isinstance(phase, Training):
                outcome = self.training(phase)
            elif isinstance(phase, Practice):
                outcome = self.practice(phase)
            elif isinstance(phase, Baseline):
                outcome = self.baseline(phase)
            elif isinstance(phase, MainTrials):
                outcome = self.main(phase)
            elif isinstance(phase, Debrief):
                self.debrief(phase)
            if outcome is None:
                self._end("aborted", "excluded: a practice was not passed within the attempts")
                return "aborted"
            if outcome is False:
                self._end("aborted", f"aborted: {self.control.reason}")
                return "aborted"
        self._end("completed", "")
        return "completed"

    def _end(self, status: str, note: str) -> None:
        with Session(self.engine) as s, s.begin():
            row = s.get(SessionRow, self.session_id)
            assert row is not None  # created by run_session
            row.status = status
            row.ended_at = utc_now()
            if note:
                row.note = f"{row.note}; {note}" if row.note else note
        self.progress(f"{self.code} session {status}" + (f" ({note})" if note else ""))


def _practice_feedback(outcome: dict[str, Any], phase: Practice) -> str:
    if outcome.get("passed"):
        return "Practice passed."
    reasons = []
    if not outcome.get("completed"):
        reasons.append(f"the goal was not reached within {phase.time_limit_s:g} s")
    if (outcome.get("collisions") or 0) > phase.max_collisions:
        reasons.append(f"{outcome['collisions']} collision(s)")
    return "Practice not passed: " + " and ".join(reasons or ["try again"]) + "."


def _order_index(s: Session, study: Study, code: str) -> int:
    m = re.search(r"(\d+)$", code)
    if m and int(m[1]) >= 1:
        return int(m[1]) - 1
    used = set(s.scalars(select(Participant.order_index).where(Participant.study_id == study.id)))
    index = 0
    while index in used:
        index += 1
    return index


def run_session(
    protocol: Protocol,
    participant_code: str,
    db: str | Path,
    *,
    participant: Any,
    seed: int | None = None,
    resume: bool = False,
    force: bool = False,
    progress: Callable[[str], None] | None = None,
    control: ExperimenterControl | None = None,
    clock: FreeClock | WallClock | None = None,
    camera_hz: float | None = None,
    on_tick: Callable[[int, TrialWriter], None] | None = None,
    recordings: str | Path | None = None,
    durable: bool = True,
) -> SessionSummary:
    """Run (or resume) one participant's session of ``protocol`` and store everything.

    Parameters
    ----------
    protocol : Protocol
        The validated protocol (:func:`study.engine.protocol.load_protocol`).
    participant_code : str
        Pseudonymous code (:func:`check_code`).
    db : str or Path
        SQLite file or SQLAlchemy URL (created if missing).
    participant : Participant
        Who takes part (``study.participants.base.Participant``).
    seed : int, optional
        The participant's seed; default derived from the study seed and order index.
    resume : bool
        Continue the participant's last session after a crash.
    force : bool
        Run although the database was made with another protocol, or the participant
        already has a session (a new session row, ``forced``, with a note).
    progress : callable, optional
        Receives one experimenter line per phase and trial.
    control : ExperimenterControl, optional
        The experimenter's pause and abort.
    clock : FreeClock or WallClock, optional
        Default: wall-clock paced for human participants, free-running otherwise.
    camera_hz : float, optional
        Camera frames per second in the recordings; default 2 for humans, else 0.
    on_tick : callable, optional
        Passed to :func:`study.engine.trial.run_trial`.
    recordings : str or Path, optional
        Folder for the trials' rerun recordings (``<code>/...rrd`` inside it); default
        ``<db stem>_recordings`` beside the database. Paths are stored relative to the
        database's folder.
    durable : bool
        False only for a scratch database thrown away after a crash (no fsync on commit:
        :func:`study.data.storage.open_database`); a synthetic study's per-participant file.

    Returns
    -------
    SessionSummary

    Raises
    ------
    ValueError
        A bad participant code, a database that is not ours or was made with another
        protocol, a second session without ``force``, nothing to resume.
    """
    code = check_code(participant_code)
    progress = progress if progress is not None else (lambda line: None)
    control = control if control is not None else ExperimenterControl()
    kind = getattr(participant, "kind", "")
    if clock is None:
        clock = WallClock() if kind == "human" else FreeClock()
    if camera_hz is None:
        camera_hz = 2.0 if kind == "human" else 0.0
    engine = open_database(db, durable=durable)
    notes: list[str] = []
    try:
        with Session(engine) as s, s.begin():
            study = get_study(s)
            if study is None:
                study = Study(
                    name=protocol.name,
                    protocol_text=protocol.text,
                    protocol_sha256=protocol.sha256,
                    platform_version=__version__,
                    seed=protocol.study.seed,
                )
                s.add(study)
                s.flush()
            elif study.protocol_sha256 != protocol.sha256:
                message = (
                    f"{db}: field 'study.protocol_sha256': the database was made with protocol "
                    f"'{study.name}' (SHA-256 {study.protocol_sha256[:12]}...), not with "
                    f"{protocol.source} ({protocol.sha256[:12]}...)"
                )
                if not force:
                    raise ValueError(message + "; use --force to run it anyway")
                notes.append(f"forced: protocol {protocol.sha256[:12]} differs from the study's")
            person = s.scalars(
                select(Participant).where(
                    Participant.study_id == study.id, Participant.code == code
                )
            ).first()
            sessions = []
            if person is not None:
                sessions = list(
                    s.scalars(
                        select(SessionRow)
                        .where(SessionRow.participant_id == person.id)
                        .order_by(SessionRow.id)
                    )
                )
            if resume:
                if person is None or not sessions:
                    raise ValueError(
                        f"{db}: field 'participant.code': participant {code} has no session "
                        "to resume; run without --resume"
                    )
                row = sessions[-1]
                if row.status == "completed":
                    raise ValueError(
                        f"{db}: field 'session.status': the session of participant {code} "
                        "is completed; nothing to resume"
                    )
                row.resumed = True
                row.status = "running"
                row.ended_at = None
                stale = s.scalars(
                    select(Trial).where(
                        Trial.participant_id == person.id, Trial.status == "running"
                    )
                ).all()
                for trial in stale:
                    trial.status = "aborted"
                    trial.ended_at = utc_now()
                    trial.outcome = {**trial.outcome, "aborted_reason": "resumed after a crash"}
                s.add(
                    Event(
                        session_id=row.id,
                        trial_id=None,
                        t=0.0,
                        kind="session_resumed",
                        detail={"aborted_trials": [t.id for t in stale]},
                    )
                )
                if notes:
                    row.forced = True
                    row.note = "; ".join(filter(None, [row.note, *notes]))
                session_id = row.id
            else:
                if sessions:
                    if not force:
                        raise ValueError(
                            f"{db}: field 'participant.code': participant {code} already has "
                            f"a session (id {sessions[-1].id}, {sessions[-1].status}); use "
                            "--resume to continue it or --force to start a new one"
                        )
                    notes.append(
                        f"forced: a new session although participant {code} has "
                        f"{len(sessions)} (last id {sessions[-1].id}); nothing was deleted"
                    )
                if person is None:
                    index = _order_index(s, study, code)
                    cycle = cycle_length(len(protocol.modes), protocol.counterbalancing)
                    if cycle is None and index >= MAX_RANDOM_INDEX:
                        raise ValueError(
                            f"participant code: {code!r} asks for participant number "
                            f"{index + 1}; the random scheme draws orders in sequence up to "
                            f"{MAX_RANDOM_INDEX}, use a smaller number"
                        )
                    # deterministic schemes repeat with their cycle: only compute one cycle
                    rows = assign_indexed(
                        protocol.modes,
                        (index % cycle if cycle else index) + 1,
                        protocol.counterbalancing,
                        rng=np.random.default_rng(study.seed),
                    )
                    person = Participant(
                        study_id=study.id,
                        code=code,
                        kind=kind,
                        parameters=dict(getattr(participant, "parameters", {})),
                        order_index=rows[-1][0],
                        mode_order=list(rows[-1][1]),
                        seed=int(seed) if seed is not None else default_seed(study.seed, code),
                    )
                    s.add(person)
                    s.flush()
                row = SessionRow(
                    participant_id=person.id,
                    status="running",
                    forced=bool(notes),
                    note="; ".join(notes),
                )
                s.add(row)
                s.flush()
                session_id = row.id
            resumed, forced, note = row.resumed, row.forced, row.note
            s.expunge(person)
        mode_order = tuple(person.mode_order)
        unknown = [m for m in mode_order if m not in protocol.modes]
        if unknown:
            raise ValueError(
                f"{db}: field 'participant.mode_order': {unknown[0]!r} is not a mode of "
                f"{protocol.source}"
            )
        progress(
            f"{code} session {session_id}"
            + (" resumed" if resumed else "")
            + (" (forced)" if forced else "")
            + f", order index {person.order_index}"
        )
        runner = _Runner(
            protocol,
            engine,
            db,
            participant,
            person,
            session_id,
            progress=progress,
            control=control,
            clock=clock,
            camera_hz=camera_hz,
            on_tick=on_tick,
            recordings=Path(recordings).resolve() if recordings is not None else None,
        )
        try:
            status = runner.run()
        finally:
            runner.scenes.close()
        return SessionSummary(
            participant=code,
            participant_id=person.id,
            session_id=session_id,
            status=status,
            mode_order=mode_order,
            trials=tuple(runner.trials),
            resumed=resumed,
            forced=forced,
            note=note,
        )
    finally:
        engine.dispose()
