"""The phases of a session (thesis Sec. 7.6.1.3, "Test procedure"): briefing, experience
questionnaire, training, practice, baseline, main trials with NASA-TLX, debrief; each a
method of :class:`SessionRunner`, found by the phase's type."""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

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
from study.data.paths import file_in
from study.data.recording import RecorderSettings, study_tag
from study.data.storage import (
    TRIAL_FINISHED,
    Event,
    Participant,
    Response,
    SessionRow,
    Study,
    Trial,
    database_file,
    utc_now,
)
from study.engine.events import jsonable
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
from study.engine.texts import practice_feedback
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
from study.participants.base import Participant as SessionParticipant
from tasks.primary import PrimarySettings, route_from_points

if TYPE_CHECKING:
    from study.lsl.session import SessionLsl

NO_LEARNING = "the participant does not learn (participant.learns is False)"
_PHASE_INDEX = {"training": 1, "practice": 2, "baseline": 3, "main": 4}


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


def derive_seed(*parts: int) -> int:
    """A 31-bit seed derived from integers (``numpy.random.SeedSequence``)."""
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(1)[0] >> 1)


class Scenes:
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
            if self.maps is not None:
                what = f"{scenario.source}: field 'name'"
                if not file_in(self.maps, scenario.name, ".yaml", what=what).exists():
                    file_in(self.maps, scenario.name, ".pgm", what=what)
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


def _study_tag(engine: Engine, study_id: int) -> str:
    """The study's identity in recording file names (:func:`study_tag`), from its row."""
    with Session(engine) as s:
        study = s.get(Study, study_id)
        assert study is not None  # the participant row refers to it
        return study_tag(study.protocol_sha256, study.seed, study.created_at, study.id)


class SessionRunner:
    """The phases of one session, in the protocol's order (:func:`run_session`)."""

    def __init__(
        self,
        protocol: Protocol,
        engine: Engine,
        db: str | Path,
        participant: SessionParticipant,
        person: Participant,
        session_id: int,
        *,
        progress: Callable[[str], None],
        control: ExperimenterControl,
        clock: FreeClock | WallClock,
        camera_hz: float,
        on_tick: Callable[[int, TrialWriter], None] | None,
        recordings: Path | None,
        record: bool = True,
        lsl: SessionLsl | None = None,
    ) -> None:
        self.protocol = protocol
        self.lsl = lsl  # the session's LSL markers, state and recorder (study.lsl)
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
        rec = protocol.recording
        self.recording = RecorderSettings(
            camera_width_px=rec.camera_width, jpeg_quality=rec.jpeg_quality
        )
        self.on_tick = on_tick
        db_path = database_file(db)
        self.folder = db_path.parent
        self.recordings = (
            recordings if recordings is not None else self.folder / f"{db_path.stem}_recordings"
        )
        self.record = record  # False: no trial is recorded
        self.scenes = Scenes(self.recordings / "maps")
        self.study_tag = _study_tag(engine, person.study_id)
        self.trials: list[TrialSummary] = []
        self._phase = ""  # the kind of the phase running (session events carry it)
        self._started = time.monotonic()  # [s] monotonic, when this run began

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
        self._store(responses, "phase_done", detail)
        if self.lsl is not None:
            self.lsl.session_event("phase_done", **detail)

    def _store(
        self, rows: Sequence[Response], kind: str, detail: dict, trial_id: int | None = None,
        *, t: float = 0.0,
    ) -> None:  # fmt: skip
        """``rows`` and one event of this session (at ``t``) in one transaction."""
        with Session(self.engine) as s, s.begin():
            s.add_all(rows)
            s.add(
                Event(session_id=self.session_id, trial_id=trial_id, t=t, kind=kind, detail=detail)
            )

    def session_event(self, kind: str, **detail: Any) -> None:
        """An event of the session outside any trial, stored at once: ``phase`` the
        protocol phase running, ``t`` [s] since this run of the session started (monotonic
        clock; ``created_at`` is the wall clock, UTC)."""
        t = time.monotonic() - self._started
        full = {"phase": self._phase, **detail}
        self._store((), kind, jsonable(full), t=round(t, 3))
        if self.lsl is not None:
            self.lsl.session_event(kind, **full)

    def _instruction(self, kind: str) -> str:
        return self.protocol.ui.instructions.get(kind, "")

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
            recording_rel=(
                (
                    lambda tid: recording_relpath(
                        self.folder, self.recordings, code, values, self.study_tag
                    )
                )
                if self.record
                else None
            ),
            session_id=self.session_id,
            clock=self.clock,
            control=self.control,
            on_tick=self.on_tick,
            max_collisions=max_collisions,
            lsl=self.lsl,
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
        self.progress(_trial_line(self.code, spec, result))
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
            camera_views=("front", "tail") if self.protocol.ui.layout == "laser" else ("front",),
            recording=self.recording,
            **fields,
        )

    # -------------------------------------------------------------- phases

    def briefing(self, phase: Briefing) -> bool:
        if not self._phase_done("briefing"):
            self.participant.read(phase.text)
            self._mark_done("briefing")
            self.progress(f"{self.code} briefing read")
        return True

    def experience(self, phase: ExperiencePhase) -> bool:
        if self._phase_done("experience"):
            return True
        raw = self.participant.fill(experience_q.INSTRUMENT, context={"phase": "experience"})
        answers = experience_q.validate(raw, source=f"participant {self.code}: experience")
        rows = [
            self._response(phase.instrument, item, value, None) for item, value in answers.items()
        ]
        self._mark_done("experience", rows)
        self.progress(f"{self.code} experience questionnaire: {len(rows)} answers")
        return True

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
        if not self.participant.learns:
            if not self._phase_done("training"):
                self._mark_done("training", skipped=NO_LEARNING)
                self.progress(f"{self.code} training skipped: {NO_LEARNING}")
            return True
        main = self.protocol.main
        for ordinal, mode in enumerate(phase.modes):
            if any(t.status in TRIAL_FINISHED for t in self._trials("training", ordinal)):
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
                limit_is_duration=True,
                of=len(phase.modes),
                rehearsal_questions=phase.rehearsal_questions,
            )
            if self._run(spec, phase.scenario).status not in TRIAL_FINISHED:
                return False
        return True

    def practice(self, phase: Practice) -> bool | None:
        """True: go on; False: aborted; None: excluded."""
        modes = self.order if phase.order == "assigned" else self.protocol.modes
        for ordinal, mode in enumerate(modes):
            done = [t for t in self._trials("practice", ordinal) if t.status in TRIAL_FINISHED]
            passed = any(t.outcome.get("passed") for t in done)
            attempts = len(done)
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
                    of=len(modes),
                    attempt_of=(attempts + 1, phase.max_attempts),
                )
                result = self._run(spec, phase.scenario, max_collisions=phase.max_collisions)
                if result.status not in TRIAL_FINISHED:
                    return False
                attempts += 1
                passed = bool(result.outcome.get("passed"))
                self.participant.read(
                    practice_feedback(
                        result.outcome,
                        self.protocol.ui.texts,
                        attempt=attempts,
                        attempts=phase.max_attempts,
                        time_limit_s=phase.time_limit_s,
                        max_collisions=phase.max_collisions,
                    )  # fmt: skip
                )
            if not passed and phase.on_fail == "exclude":
                return None
        return True

    def baseline(self, phase: Baseline) -> bool:
        if any(t.status in TRIAL_FINISHED for t in self._trials("baseline", 0)):
            return True
        spec = self._spec(
            "baseline",
            0,
            "",
            primary=None,
            secondary=self.protocol.secondary_settings,
            baseline=True,
        )
        return self._run(spec, self.protocol.main.scenario).status in TRIAL_FINISHED

    def main(self, phase: MainTrials) -> bool:
        last = len(self.order) - 1
        for ordinal, mode in enumerate(self.order):
            done = [t for t in self._trials("main", ordinal) if t.status in TRIAL_FINISHED]
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
                    of=len(self.order),
                )
                result = self._run(spec, phase.scenario)
                if result.status not in TRIAL_FINISHED:
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
        self._store(rows, "questionnaire_done", {"instrument": after.instrument}, trial_id)
        self.progress(f"{self.code} NASA-TLX after main #{ordinal}: {len(rows)} answers")

    def debrief(self, phase: Debrief) -> bool:
        if not self._phase_done("debrief"):
            self.participant.read(phase.text)
            self._mark_done("debrief")
        return True

    def run(self) -> str:
        """Every phase in order; returns the session's final status."""
        lsl = self.lsl
        if lsl is not None:
            lsl.session_event("session_started", session=self.session_id)
        self._started = time.monotonic()
        self.participant.attach_session(self.session_event)
        for phase in self.protocol.phases:
            handler = _PHASES.get(type(phase))
            if handler is None:
                continue
            self._phase = phase.kind
            if lsl is not None:
                lsl.session_event("phase_started", phase=phase.kind)
            outcome = handler(self, phase)
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
            assert row is not None  # created when the session was opened
            row.status = status
            row.ended_at = utc_now()
            if note:
                row.note = f"{row.note}; {note}" if row.note else note
        if self.lsl is not None:
            self.lsl.session_event("session_ended", session=self.session_id, status=status)
        self.progress(f"{self.code} session {status}" + (f" ({note})" if note else ""))


_STATUS_WORDS = {"completed": "completed", "timed_out": "timed out", "aborted": "aborted"}


def _trial_line(code: str, spec: TrialSpec, result: TrialResult) -> str:
    """The experimenter's line for a finished trial: who, which, how it ended."""
    out = result.outcome
    line = f"{code} {spec.phase} #{spec.ordinal}"
    if spec.attempt:
        line += f" attempt {spec.attempt}"
    if spec.mode:
        line += f" mode {spec.mode}"
    line += f": {_STATUS_WORDS.get(result.status, result.status)}"
    if result.status == "timed_out" and spec.primary is not None:
        line += f" at the {spec.primary.timeout_s:g} s limit"
        if spec.primary.route:
            line += f" ({out.get('legs_reached', 0)} of {len(spec.primary.route)} legs)"
    elif result.status == "aborted" and out.get("aborted_reason"):
        line += f" ({out['aborted_reason']})"
    line += f", {result.duration_s:.1f} s simulated"
    if out.get("collisions") is not None:
        line += f", {out['collisions']} collisions"
    if "passed" in out:
        line += ", passed" if out["passed"] else ", not passed"
    return line


# phase type -> its step; a step returns True (go on), False (aborted) or None (excluded)
_PHASES: dict[type, Callable[[SessionRunner, Any], bool | None]] = {
    Briefing: SessionRunner.briefing,
    ExperiencePhase: SessionRunner.experience,
    Training: SessionRunner.training,
    Practice: SessionRunner.practice,
    Baseline: SessionRunner.baseline,
    MainTrials: SessionRunner.main,
    Debrief: SessionRunner.debrief,
}
