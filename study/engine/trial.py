"""One trial: the 20 Hz control loop of DESIGN.md ("One control tick") with its storage.

Per tick, in this order::

    obs = world.sense()                  # (the previous tick's, see below)
    inp = participant.act(obs, screen)   # the screen never names the mode
    out = mode.step(obs, inp.u)          # v, beta, label, target, diagnostics
    world.apply(out.v); started = world.step()
    primary.update(...); secondary.update(...) / answer(...)
    recorder.tick(...); a Sample row buffered

The observation is sensed once per tick, right after the step, and used by the next
tick's participant and mode, which is the same sequence as sensing at the top of the loop.

Storage (DESIGN.md, "Data"; :mod:`study.data.storage` holds the models): the trial row is
written with status ``running`` before the first tick; samples, events and question rows
are buffered and written in one transaction at least once per simulated second
(``flush_every_ticks = 20``); the end of a trial (the last rows, the outcome, the status
and ``ended_at``) is one transaction. A crash therefore loses at most the last second of
a trial that a resumed session marks aborted and runs again. The per-second flushes are
plain Core ``executemany`` inserts on a connection (the ORM session's bulk path cost
about three times as much per flush, for the same rows).

Decisions where the spec is silent:

- Time. A :class:`FreeClock` runs as fast as the machine allows (scripted and synthetic
  participants); a :class:`WallClock` sleeps to the next 20 Hz tick (humans) and measures
  the period jitter, stored as its 99th percentile in ``trial.tick_jitter_ms``. The loop
  code is the same for both.
- Pause. The experimenter's :class:`ExperimenterControl` (or the participant's pause
  button, which toggles it) freezes simulated time: no tick is simulated while paused,
  the participant keeps being asked to ``act`` with ``screen.paused`` set, and ``pause``
  and ``resume`` events are stored. A free-running clock paced by nobody would spin, so
  a paused free-running trial waits 10 ms per poll.
- Abort. ``control.abort()`` ends the trial at the next tick with status ``aborted``; the
  outcome so far is stored in ``trial.outcome``. An exception inside the loop (or Ctrl-C)
  stores the buffered rows and marks the trial ``aborted`` with the reason before it
  propagates; everything that can fail on bad input (the tasks' settings) is built before
  the trial row is written.
- After the completing transaction the participant's optional ``end_trial(outcome)`` is
  called (a synthetic participant rates the trial from it).
- A mode whose labels stand for contextual task types (``label_tasks() -> {label: task
  type}``, the contextual mode's motion primitives) has that table stored in
  ``trial.outcome["label_tasks"]``, so the analysis scores recognition from the data alone.
- Before ``begin_trial`` the participant's optional ``attach(world, event)`` is called with
  the trial's World (read only: the screen renders the camera from ``true_pose()`` and
  counts ``contacts()``) and ``event(t, kind, **detail)``, which buffers an event row of
  this trial (the human interface stores ``input_lost`` / ``input_back`` with it).
- Question rows are written when the question is answered or times out (or, still
  unanswered, at the end of the trial); the ``question_shown`` event is written at once.
- Baseline trials (no driving) run the same loop with no mode: the robot stays at A with
  ``v = 0`` and the samples record that, so every trial has samples at 20 Hz.
- Recordings: ``<db stem>_recordings/<code>/s<session>_<phase>_<ordinal>_a<attempt>.rrd``
  beside the database by default (:func:`recording_relpath`; an existing file is never
  overwritten), the path stored relative to the database's folder. Camera frames are logged
  at ``camera_hz`` (the caller's choice: the session engine uses 2 Hz for human
  participants and none for scripted and synthetic ones, whose sessions would otherwise
  spend most of their time rendering). A participant that already shows a camera image
  (the human screen renders it off the control path) offers it through an optional
  ``camera_image() -> array | None``; the loop then logs that image instead of rendering
  one itself, so the recording costs no control time.
- Collision starts are events with the element and map position; collision ends too.
- Region entry and exit are events whenever the secondary task is active in the trial.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.orm import Session

from autonomy.types import RobotModel
from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario, point_in_region
from sim.types import SemanticComponent
from sim.world import World
from study.data.recording import TrialRecorder
from study.data.storage import Event, Question, Sample, Trial, utc_now
from study.types import ParticipantInput, ScreenState, TickRecord, TrialInfo
from tasks.geometry import footprint_clearance
from tasks.primary import PrimarySettings, PrimaryTask
from tasks.secondary import SecondaryEvent, SecondarySettings, SecondaryTask, summarise

DT = 0.05  # [s] control tick (20 Hz)
FLUSH_EVERY_TICKS = 20  # one transaction per simulated second at least
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)
# Core inserts of the buffered rows (plain executemany, column defaults applied)
_INSERT_SAMPLE = Sample.__table__.insert()
_INSERT_EVENT = Event.__table__.insert()
_INSERT_QUESTION = Question.__table__.insert()


# ------------------------------------------------------------------------- clocks


class FreeClock:
    """Free-running time: ticks follow each other as fast as the machine allows."""

    paced = False

    def start(self) -> None:
        """Start timing a trial."""

    def wait(self) -> None:
        """Return at once (nothing to wait for)."""

    def jitter_p99_ms(self) -> float | None:
        """None: a free-running trial has no period to keep."""
        return None


class WallClock:
    """Wall-clock pacing at ``1 / dt``: :meth:`wait` sleeps to the next tick.

    Parameters
    ----------
    dt : float
        [s] tick period.
    """

    paced = True

    def __init__(self, dt: float = DT) -> None:
        self.dt = dt
        self._next = math.nan
        self._last = math.nan
        self._periods: list[float] = []

    def start(self) -> None:
        """Start timing a trial (forgets earlier periods)."""
        now = time.perf_counter()
        self._next, self._last, self._periods = now + self.dt, now, []

    def wait(self) -> None:
        """Sleep until the next tick is due; records the achieved period."""
        now = time.perf_counter()
        if self._next > now:
            time.sleep(self._next - now)
        else:  # late: do not try to catch up a backlog
            self._next = now
        self._next += self.dt
        now = time.perf_counter()
        self._periods.append(now - self._last)
        self._last = now

    def jitter_p99_ms(self) -> float | None:
        """99th percentile of ``|period - dt|`` [ms] over the trial, None before any tick."""
        if not self._periods:
            return None
        return float(np.percentile(np.abs(np.asarray(self._periods) - self.dt), 99) * 1e3)


class ExperimenterControl:
    """Pause and abort requested by the experimenter (from another thread or a callback)."""

    def __init__(self) -> None:
        self.paused = False
        self.aborted = False
        self.reason = ""

    def pause(self) -> None:
        self.paused = True

    def resume(self) -> None:
        self.paused = False

    def abort(self, reason: str = "aborted by the experimenter") -> None:
        self.aborted = True
        self.reason = reason


# ------------------------------------------------------------------------- values


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
    feedback: str = ""  # shown on the screen from the start (practice)
    camera_hz: float = 0.0  # [Hz] camera frames in the recording; 0: none

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


@dataclass(frozen=True, slots=True)
class TrialResult:
    """How a trial ended."""

    trial_id: int
    status: str  # "completed" or "aborted"
    outcome: dict[str, Any]  # as stored in trial.outcome
    ticks: int
    duration_s: float  # [s] simulated


def _jsonable(value: Any) -> Any:
    """NaN and infinities as None, tuples as lists, recursively (for JSON columns)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return _jsonable(value.item())
    return value


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def recording_relpath(folder: Path, recordings: Path, code: str, values: dict[str, Any]) -> str:
    """Where a trial's recording goes, relative to the database's ``folder``.

    ``<recordings>/<code>/s<session>_<phase>_<ordinal>_a<attempt>.rrd``; if that file exists
    already (left by an earlier database of the same name), ``_2``, ``_3``, ... is appended
    rather than overwriting it.
    """
    name = f"s{values['session_id']}_{values['phase']}_{values['ordinal']}_a{values['attempt']}"
    base = recordings / code / name
    path, n = base.with_suffix(".rrd"), 1
    while path.exists():
        n += 1
        path = base.with_name(f"{base.name}_{n}.rrd")
    return os.path.relpath(path, folder)


# ------------------------------------------------------------------------- writer


class TrialWriter:
    """Buffers a trial's rows and writes them in few transactions.

    ``commits`` lists ``(tick, kind)`` of every transaction ("start", "flush", "end"),
    for tests and diagnostics.
    """

    def __init__(self, engine: Engine, session_id: int) -> None:
        self.engine = engine
        self.session_id = session_id
        self.trial_id = -1
        self.recording_path = ""
        self.samples: list[dict[str, Any]] = []
        self.events: list[dict[str, Any]] = []
        self.questions: list[dict[str, Any]] = []
        self.commits: list[tuple[int, str]] = []

    def start(self, values: dict[str, Any], recording: Callable[[int], str]) -> int:
        """Insert the trial row (status running) and its start event; returns its id."""
        with Session(self.engine) as s, s.begin():
            row = Trial(**values, status="running", started_at=utc_now())
            s.add(row)
            s.flush()
            row.recording_path = self.recording_path = recording(row.id)
            s.add(
                Event(
                    session_id=self.session_id,
                    trial_id=row.id,
                    t=0.0,
                    kind="trial_started",
                    detail=_jsonable(
                        {k: values[k] for k in ("phase", "ordinal", "attempt", "scenario")}
                    ),
                )
            )
            self.trial_id = row.id
        self.commits.append((0, "start"))
        return self.trial_id

    def event(self, t: float, kind: str, **detail: Any) -> None:
        self.events.append(
            {
                "session_id": self.session_id,
                "trial_id": self.trial_id,
                "t": float(t),
                "kind": kind,
                "detail": _jsonable(detail),
                "created_at": utc_now(),
            }
        )

    def _write(self, s: Session | Connection) -> None:
        if self.samples:
            s.execute(_INSERT_SAMPLE, self.samples)
        if self.events:
            s.execute(_INSERT_EVENT, self.events)
        if self.questions:
            s.execute(_INSERT_QUESTION, self.questions)

    def _clear(self) -> None:
        """Forget the buffered rows: only once their transaction has committed."""
        self.samples, self.events, self.questions = [], [], []

    def flush(self, tick: int) -> None:
        """Write what is buffered in one transaction (kept for a retry if it fails)."""
        # a Core connection: the same rows and transaction as an ORM session, about a
        # third of the cost per flush (no unit of work for plain executemany inserts)
        with self.engine.begin() as conn:
            self._write(conn)
        self._clear()
        self.commits.append((tick, "flush"))

    def abort(self, tick: int, t: float, reason: str) -> None:
        """After an exception in the loop: store what is buffered and mark the trial
        ``aborted`` with ``reason`` in one transaction (best effort: a database that
        fails here leaves the trial ``running`` for a resumed session to abort)."""
        self.event(t, "trial_ended", status="aborted", reason=reason)
        with Session(self.engine) as s, s.begin():
            self._write(s)
            row = s.get(Trial, self.trial_id)
            if row is not None:
                row.status = "aborted"
                row.outcome = {"ticks": tick, "duration_s": t, "aborted_reason": reason}
                row.ended_at = utc_now()
        self._clear()
        self.commits.append((tick, "abort"))

    def finish(self, tick: int, values: dict[str, Any]) -> None:
        """The last rows and the trial's outcome, status and end time: one transaction."""
        with Session(self.engine) as s, s.begin():
            self._write(s)
            row = s.get(Trial, self.trial_id)
            assert row is not None  # written by start()
            for key, value in values.items():
                setattr(row, key, value)
            row.ended_at = utc_now()
        self._clear()
        self.commits.append((tick, "end"))


# ------------------------------------------------------------------------- the loop


def _question_row(trial_id: int, ev: SecondaryEvent) -> dict[str, Any]:
    q = ev.question
    assert q is not None  # question events carry their question
    return {
        "trial_id": trial_id,
        "block": ev.block_index,
        "index": ev.question_index,
        "text": q.text,
        "shown_is_correct": q.shown_is_correct,
        "shown_t": float(ev.t),
        "answered_t": None,
        "response": None,
        "correct": False,
        "answer_time_s": None,
    }


def run_trial(
    engine: Engine,
    spec: TrialSpec,
    *,
    scene: Scene,
    participant: Any,
    mode: Any | None,
    trial_values: dict[str, Any],
    recording_dir: Path,
    recording_rel: Callable[[int], str],
    session_id: int,
    clock: FreeClock | WallClock | None = None,
    control: ExperimenterControl | None = None,
    on_tick: Callable[[int, TrialWriter], None] | None = None,
    max_collisions: int | None = None,
) -> TrialResult:
    """Run one trial to its end and store it.

    Parameters
    ----------
    engine : Engine
        The study database (:func:`study.data.storage.open_database`).
    spec : TrialSpec
        What the trial is.
    scene : Scene
        The scenario, its grid, components and a World on it (reset here).
    participant : Participant
        ``study.participants.base.Participant``.
    mode : Mode or None
        The control mode (``autonomy.modes.make_mode``), None for the baseline.
    trial_values : dict
        Column values of the trial row (participant_id, session_id, phase, mode, ordinal,
        attempt, scenario, seed).
    recording_dir : Path
        Folder against which ``recording_rel(trial_id)`` is resolved (the database's).
    recording_rel : callable
        Trial id -> relative path of its ``.rrd`` file.
    session_id : int
        For event rows.
    clock : FreeClock or WallClock, optional
        Default free-running.
    control : ExperimenterControl, optional
        Pause and abort.
    on_tick : callable, optional
        Called after every tick with the tick index and the writer (tests look at the
        database mid-trial through it).
    max_collisions : int, optional
        Practice: the outcome gets ``passed`` (goal reached in time with at most this many
        collisions), stored in the completing transaction.

    Returns
    -------
    TrialResult
    """
    clock = clock if clock is not None else FreeClock()
    control = control if control is not None else ExperimenterControl()
    scenario, world = scene.scenario, scene.world
    rng = np.random.default_rng(spec.seed)
    obs = world.reset(seed=int(rng.integers(2**31)))
    robot = RobotModel.from_spec(scenario.robot, dt=DT)
    if mode is not None:
        mode.reset(robot)
    primary = PrimaryTask(scenario, settings=spec.primary) if spec.primary is not None else None
    secondary: SecondaryTask | None = None
    if spec.secondary is not None:
        if spec.baseline:
            secondary = SecondaryTask.baseline(rng, settings=spec.secondary)
        elif len(scenario.question_region):
            secondary = SecondaryTask(rng, settings=spec.secondary)
    time_limit = spec.primary.timeout_s if spec.primary is not None else math.inf
    writer = TrialWriter(engine, session_id)
    trial_id = writer.start(trial_values, recording_rel)
    rec_path = recording_dir / writer.recording_path
    footprint = scenario.robot.footprint()
    camera_every = max(1, round(1.0 / (DT * spec.camera_hz))) if spec.camera_hz > 0 else 0
    intention = getattr(participant, "intention", None)
    shown_camera = getattr(participant, "camera_image", None)
    sec_events: list[SecondaryEvent] = []
    open_questions: dict[tuple[int, int], dict[str, Any]] = {}
    open_contacts: set[int] = set()
    was_in_region = False
    was_paused = False
    tick = 0
    t = 0.0
    status = "completed"
    reason = ""

    def on_secondary(ev: SecondaryEvent) -> None:
        sec_events.append(ev)
        key = (ev.block_index, ev.question_index if ev.question_index is not None else -1)
        if ev.kind == "question_shown":
            open_questions[key] = _question_row(trial_id, ev)
            text = ev.question.text if ev.question is not None else ""
            writer.event(
                ev.t, "question_shown", block=ev.block_index, index=ev.question_index, text=text
            )
            recorder.question(ev.t, text)
        elif ev.kind in ("answer_given", "question_timeout"):
            row = open_questions.pop(key, None)
            if ev.kind == "answer_given":
                if row is not None:
                    row.update(
                        answered_t=float(ev.t),
                        response=ev.response,
                        correct=bool(ev.correct),
                        answer_time_s=ev.answer_time_s,
                    )
                writer.event(
                    ev.t,
                    "answer_given",
                    block=ev.block_index,
                    index=ev.question_index,
                    response=ev.response,
                    correct=ev.correct,
                    answer_time_s=ev.answer_time_s,
                )
                recorder.question(ev.t, f"answer: {'yes' if ev.response else 'no'}")
            else:
                writer.event(
                    ev.t, "question_timeout", block=ev.block_index, index=ev.question_index
                )
                recorder.event(ev.t, "timeout", "question")
            if row is not None:
                writer.questions.append(row)
        else:
            writer.event(ev.t, ev.kind, block=ev.block_index)

    recorder: TrialRecorder | None = None
    try:
        recorder = TrialRecorder(
            rec_path,
            trial_key=f"{trial_values['phase']}/{trial_id}",
            scenario=scenario,
            components=scene.components,
            grid=scene.grid,
        )
        attach = getattr(participant, "attach", None)  # the screen's hook (study.ui)
        if attach is not None:
            attach(world, writer.event)
        participant.begin_trial(
            TrialInfo(
                phase=spec.phase,
                scenario=scenario,
                route=spec.primary.route if spec.primary is not None else (),
                inspection=bool(spec.primary and spec.primary.inspection_required),
                secondary=secondary is not None,
                time_limit_s=time_limit,
                drive=not spec.baseline,
                primary=spec.primary,
            )
        )
        clock.start()
        while True:
            question = secondary.current.text if secondary and secondary.current else None
            screen = ScreenState(
                phase=spec.phase,
                instruction=spec.instruction,
                question=question,
                feedback=spec.feedback,
                paused=control.paused,
                t=t,
            )
            inp: ParticipantInput = participant.act(obs, screen)
            if inp.pause and control.paused:
                control.resume()
            elif inp.pause:
                control.pause()
            if control.aborted:
                status, reason = "aborted", control.reason or "aborted by the experimenter"
                writer.event(t, "abort", reason=reason)
                recorder.event(t, "abort", reason)
                break
            if control.paused:
                if not was_paused:
                    writer.event(t, "pause")
                    recorder.event(t, "pause")
                    writer.flush(tick)
                    was_paused = True
                if clock.paced:
                    clock.wait()
                else:
                    time.sleep(0.01)
                continue
            if was_paused:
                writer.event(t, "resume")
                recorder.event(t, "resume")
                was_paused = False
            if inp.answer is not None and secondary is not None:
                ev = secondary.answer(t, inp.answer)
                if ev is not None:
                    on_secondary(ev)
            u = np.asarray(inp.u, dtype=float)
            if spec.baseline or mode is None:
                u = _ZERO3
                out = None
                v = _ZERO3
            else:
                out = mode.step(obs, u)
                v = out.v
            world.apply(v)
            started = world.step()
            t = world.t
            tick += 1
            pose, velocity = world.true_pose(), world.true_velocity()
            obs = world.sense()
            clearance = footprint_clearance(obs.points, footprint)
            in_region = bool(point_in_region(scenario, pose.x, pose.y))
            for c in started:
                open_contacts.add(c.index)
                writer.event(
                    c.t_start,
                    "collision",
                    element=c.obstacle,
                    x=float(c.position[0]),
                    y=float(c.position[1]),
                    index=c.index,
                )
                recorder.event(t, "collision", c.obstacle)
            if open_contacts:
                contacts = world.contacts()
                for index in sorted(open_contacts):
                    if math.isfinite(contacts[index].t_end):
                        open_contacts.discard(index)
                        writer.event(
                            contacts[index].t_end,
                            "collision_end",
                            index=index,
                            element=contacts[index].obstacle,
                        )
            done = False
            if primary is not None:
                for pe in primary.update(t, pose, velocity, clearance, started):
                    detail = {k: v_ for k, v_ in asdict(pe).items() if k not in ("kind", "t")}
                    writer.event(
                        pe.t, pe.kind, **{k: v_ for k, v_ in detail.items() if v_ is not None}
                    )
                    recorder.event(pe.t, pe.kind)
                done = primary.done
            if secondary is not None and not spec.baseline:
                if in_region != was_in_region:
                    kind = "region_entry" if in_region else "region_exit"
                    writer.event(t, kind)
                    recorder.event(t, kind)
            was_in_region = in_region
            if secondary is not None:
                for ev in secondary.update(t, in_region):
                    on_secondary(ev)
                    if spec.baseline and ev.kind == "block_finished":
                        done = True
            if spec.end_on_collision and started:
                done = True
            if t >= time_limit + 1.0:  # a safety net; PrimaryTask times out first
                done = True
            task, target = intention() if intention is not None else ("", "")
            record = TickRecord(
                tick=tick - 1,
                t=t,
                pose=pose,
                u=u,
                v=np.asarray(v, dtype=float),
                beta=float(out.beta) if out is not None else 0.0,
                label=str(out.label) if out is not None else "",
                target=str(out.target) if out is not None else "",
                min_clearance_m=clearance,
                in_region=in_region,
                true_task=task,
                true_target=target,
            )
            writer.samples.append(record.row(trial_id))
            camera = None
            if camera_every and tick % camera_every == 0:
                camera = shown_camera() if shown_camera is not None else world.camera_image()
            recorder.tick(t, pose, obs.points, u, record.v, assist=out, camera=camera)
            if tick % FLUSH_EVERY_TICKS == 0:
                writer.flush(tick)
            if on_tick is not None:
                on_tick(tick, writer)
            if done:
                break
            clock.wait()
    except BaseException as exc:
        # Keep what was buffered and do not leave a ``running`` row behind; a resumed
        # session runs the trial again.
        reason = (
            "interrupted"
            if isinstance(exc, KeyboardInterrupt)
            else f"error: {type(exc).__name__}: {exc}"
        )
        writer.questions.extend(open_questions.values())
        try:
            writer.abort(tick, t, reason)
        except Exception:  # the database itself failed; resume aborts the trial
            pass
        raise
    finally:
        if recorder is not None:
            recorder.close()
    writer.questions.extend(open_questions.values())  # shown, never resolved
    outcome: dict[str, Any] = {"ticks": tick, "duration_s": t}
    values: dict[str, Any] = {"status": status, "tick_jitter_ms": clock.jitter_p99_ms()}
    if primary is not None:
        po = primary.outcome()
        outcome.update(_jsonable(asdict(po)))
        values.update(
            completed_task=po.completed,
            completion_time_s=po.completion_time_s,
            collisions=po.collisions,
            score=po.score,
            path_length_m=po.path_length_m,
            clearance_mean_m=_finite(po.clearance_mean_m),
            clearance_min_m=_finite(po.clearance_min_m),
        )
        if max_collisions is not None:
            outcome["passed"] = bool(po.completed and po.collisions <= max_collisions)
    label_tasks = getattr(mode, "label_tasks", None)
    if callable(label_tasks):  # what the mode's labels mean, for scoring its recognition
        outcome["label_tasks"] = dict(label_tasks())
    if secondary is not None:
        outcome["secondary"] = _jsonable(summarise(sec_events))
    if status == "aborted":
        outcome["aborted_reason"] = reason
    writer.event(t, "trial_ended", status=status)
    values["outcome"] = outcome
    writer.finish(tick, values)
    end_trial = getattr(participant, "end_trial", None)
    if end_trial is not None:
        end_trial(outcome)
    return TrialResult(trial_id, status, outcome, tick, t)
