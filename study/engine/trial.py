"""One trial: the 20 Hz control loop of DESIGN.md ("One control tick") and its storage.

Thesis Sec. 7.6.1.3 (the trials of a session). Per tick, in this order: the participant
acts on the last observation and the screen (never the mode), the mode steps, the world
steps and is sensed, the tasks update, and the tick's sample, events and recording are
written (:class:`TrialLoop`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from sqlalchemy.engine import Engine

from autonomy.types import Assist, Mode, RobotModel
from sim.scenario import point_in_region
from sim.types import Contact, Pose2D
from study.data.recording import NoRecording, TrialRecorder
from study.engine.clocks import DT, ExperimenterControl, FreeClock, WallClock
from study.engine.events import EventSink, TrialWriter, jsonable
from study.engine.model_file import model_identity
from study.engine.recognition import RecognitionTally
from study.engine.stages import (
    COMPONENTS,
    DATABASE,
    MODE,
    PARTICIPANT,
    PHYSICS,
    RECORDING,
    SENSING,
    TASKS,
    StageClock,
)
from study.engine.trial_spec import (
    Scene,
    TrialResult,
    TrialSpec,
    recording_relpath,
    secondary_task,
)
from study.participants.base import Participant
from study.types import ParticipantInput, ScreenState, TickRecord, TrialInfo
from tasks.clearance import RangeStats, lrf_range
from tasks.geometry import footprint_clearance
from tasks.primary import PrimaryTask
from tasks.secondary import summarise

if TYPE_CHECKING:
    from study.lsl.session import SessionLsl

__all__ = [
    "DT",
    "FLUSH_EVERY_TICKS",
    "ExperimenterControl",
    "FreeClock",
    "Scene",
    "TrialLoop",
    "TrialResult",
    "TrialSpec",
    "TrialWriter",
    "WallClock",
    "recording_relpath",
    "run_trial",
]

FLUSH_EVERY_TICKS = 20  # one transaction per simulated second at least
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


class TrialLoop:
    """The state of one trial between its start and its stored end (see :func:`run_trial`).

    Everything that can fail on bad input (the tasks' settings) is built before the trial
    row is written with status ``running``; :meth:`run` then runs the ticks, and an
    exception inside them (or ``KeyboardInterrupt``) stores what is buffered and marks the
    trial ``aborted`` with the reason before it propagates. An abort asked of the
    ``control`` (Ctrl-C under :func:`study.engine.clocks.sigint_aborts`, which sees
    ``control.ticking``) ends the trial after the current tick, stored ``aborted`` with
    its outcome.
    """

    def __init__(
        self,
        engine: Engine,
        spec: TrialSpec,
        *,
        scene: Scene,
        participant: Participant,
        mode: Mode | None,
        trial_values: dict[str, Any],
        recording_dir: Path,
        recording_rel: Callable[[int], str] | None,
        session_id: int,
        clock: FreeClock | WallClock | None = None,
        control: ExperimenterControl | None = None,
        on_tick: Callable[[int, TrialWriter], None] | None = None,
        max_collisions: int | None = None,
        stages: StageClock | None = None,
        lsl: SessionLsl | None = None,
    ) -> None:
        self.spec, self.scene, self.participant, self.mode = spec, scene, participant, mode
        self.stages = stages
        self.lsl = lsl  # the session's LSL outlets and recorder (study.lsl), if any
        self.clock = clock if clock is not None else FreeClock()
        self.control = control if control is not None else ExperimenterControl()
        self.on_tick, self.max_collisions = on_tick, max_collisions
        scenario, world = scene.scenario, scene.world
        rng = np.random.default_rng(spec.seed)
        self.obs = world.reset(seed=int(rng.integers(2**31)))
        robot = RobotModel.from_spec(scenario.robot, dt=DT)
        if mode is not None:
            mode.reset(robot)
        self.primary = (
            PrimaryTask(scenario, settings=spec.primary) if spec.primary is not None else None
        )
        self.secondary = secondary_task(spec, scenario, rng)
        self.time_limit = spec.primary.timeout_s if spec.primary is not None else math.inf
        self.writer = TrialWriter(engine, session_id)
        self.trial_id = self.writer.start(
            trial_values, recording_rel if recording_rel is not None else (lambda tid: "")
        )
        if lsl is not None:
            lsl.begin_trial(self.trial_id, trial_values)
            self.writer.listener = lsl.trial_event
        self.rec_path = recording_dir / self.writer.recording_path if recording_rel else None
        self.trial_key = f"{trial_values['phase']}/{self.trial_id}"
        self.footprint = scenario.robot.footprint()
        self.lrf = RangeStats()  # Sec. 7.5's clearance, the laser's range from the centre
        self.crashed = False  # a collision ended the trial (end_on_collision)
        self.sec_events: list[Any] = []  # SecondaryEvent, for the outcome's summary
        self.open_contacts: set[int] = set()
        self.was_in_region = False
        self.was_paused = False
        self.tick = 0
        self.t = 0.0
        self.status = "completed"
        self.reason = ""
        self.sink: EventSink | None = None
        table = mode.label_tasks() if mode is not None else None
        # what the mode's labels mean, to score its recognition (None: situations, unscored)
        self.label_tasks = dict(table) if table is not None else None
        # scored per tick of simulated time (the world's tick), blend weights included
        dt_s = float(world.settings.dt)
        self.tally = RecognitionTally(table, dt_s=dt_s) if table is not None else None
        # the mode's effective settings, stored with the outcome (e.g. reactive arbitration)
        self.mode_settings = jsonable(mode.settings_dict()) if mode is not None else None
        self.model = model_identity(self.mode_settings)  # the model file's name and SHA-256
        # an oracle mode (an ablation) is told the synthetic participant's true intention
        self.oracle = mode is not None and mode.needs_intention()
        if self.oracle and participant.kind != "synthetic":
            raise ValueError(
                f"mode {mode.name!r}: its settings drive it by the participant's true "
                f"intention, which only synthetic participants have (this participant is "
                f"{participant.kind!r}); use another recogniser for people"
            )
        self._components_read = False  # the mode reads the components (stage clock only)

    # -------------------------------------------------------------- run

    def run(self) -> TrialResult:
        """Every tick to the trial's end; the outcome stored in one transaction."""
        recorder: TrialRecorder | NoRecording | None = None
        try:
            recorder = self._recorder()
            self.sink = EventSink(self.writer, recorder)
            self._begin()
            self.control.ticking = True
            try:
                self._loop()
            finally:
                self.control.ticking = False
        except BaseException as exc:
            # keep what was buffered and leave no ``running`` row behind; a resumed
            # session runs the trial again
            self._abort(exc)
            raise
        finally:
            if recorder is not None:
                recorder.close()
        try:
            return self._finish()
        finally:
            if self.lsl is not None:
                self.lsl.end_trial()

    def _recorder(self) -> TrialRecorder | NoRecording:
        """The trial's rerun recording, or none without a recording path."""
        if self.rec_path is None:
            return NoRecording()
        scene = self.scene
        return TrialRecorder(
            self.rec_path,
            trial_key=self.trial_key,
            scenario=scene.scenario,
            components=scene.components,
            grid=scene.grid,
            settings=replace(self.spec.recording, camera_hz=self.spec.camera_hz),
        )

    def _begin(self) -> None:
        """Attach the participant to the trial's world and tell them what the trial is."""
        spec, participant = self.spec, self.participant
        participant.attach(self.scene.world, self.writer.event)  # the screen's hook (study.ui)
        participant.begin_trial(
            TrialInfo(
                phase=spec.phase,
                scenario=self.scene.scenario,
                route=spec.primary.route if spec.primary is not None else (),
                inspection=bool(spec.primary and spec.primary.inspection_required),
                secondary=self.secondary is not None,
                time_limit_s=self.time_limit,
                drive=not spec.baseline,
                primary=spec.primary,
                ordinal=spec.ordinal,
                of=spec.of,
                attempt_of=spec.attempt_of,
                max_collisions=self.max_collisions,
                rehearsal_questions=(spec.rehearsal_questions if self.secondary is not None else 0),
            )
        )

    def _loop(self) -> None:
        """Ask the participant once per tick; pause, abort or simulate the tick."""
        spec, participant, control, clock = self.spec, self.participant, self.control, self.clock
        secondary, sink, on_tick = self.secondary, self.sink, self.on_tick
        stages = self.stages
        assert sink is not None  # made by run()
        clock.start()
        while True:
            if stages is not None:
                stages.begin()
            question = secondary.current.text if secondary and secondary.current else None
            screen = ScreenState(
                phase=spec.phase,
                instruction=spec.instruction,
                question=question,
                paused=control.paused,
                t=self.t,
            )
            inp: ParticipantInput = participant.act(self.obs, screen)
            if stages is not None:
                stages.lap(PARTICIPANT)
            if inp.pause and control.paused:
                control.resume()
            elif inp.pause:
                control.pause()
            if control.aborted:
                self.status = "aborted"
                self.reason = control.reason or "aborted by the experimenter"
                sink(self.t, "abort", self.reason, reason=self.reason)
                return
            if control.paused:
                self._paused()
                if stages is not None:
                    stages.discard()
                continue
            if self.was_paused:
                sink(self.t, "resume")
                self.was_paused = False
            if inp.answer is not None and secondary is not None:
                ev = secondary.answer(self.t, inp.answer)
                if ev is not None:
                    self.sec_events.append(ev)
                    sink.secondary(ev)
            done = self._tick(inp)
            if on_tick is not None:
                on_tick(self.tick, self.writer)
            if stages is not None:
                stages.end()
            if done:
                return
            clock.wait()

    def _paused(self) -> None:
        """One poll while paused: no tick is simulated (simulated time is frozen)."""
        if not self.was_paused:
            assert self.sink is not None  # made by run()
            self.sink(self.t, "pause")
            self.writer.flush(self.tick)
            self.was_paused = True
        if self.clock.paced:
            self.clock.wait()
        else:  # a free-running clock paced by nobody would spin
            time.sleep(0.01)

    # -------------------------------------------------------------- one tick

    def _tick(self, inp: ParticipantInput) -> bool:
        """Simulate one tick and store it; True when the trial is done."""
        spec, mode, world, stages = self.spec, self.mode, self.scene.world, self.stages
        if stages is not None:
            stages.lap(TASKS)  # the answer to the question, if any
        u = np.asarray(inp.u, dtype=float)
        out: Assist | None
        if spec.baseline or mode is None:
            u = _ZERO3
            out = None
            v = _ZERO3
        else:
            if self.oracle:
                mode.observe_intention(*self.participant.intention())
            out = mode.step(self.obs, u)
            v = out.v
        if stages is not None:
            stages.lap(MODE)
            self._components_read = self._components_read or _prepared(self.obs)
        world.apply(v)
        started = world.step()
        t = self.t = world.t
        self.tick += 1
        tick = self.tick
        lsl = self.lsl
        stamp = lsl.tick(tick - 1, t) if lsl is not None else None  # the tick's LSL clock
        if stages is not None:
            stages.lap(PHYSICS)
        pose, velocity = world.true_pose(), world.true_velocity()
        obs = self.obs = world.sense()
        if stages is not None:
            stages.lap(SENSING)
            if self._components_read:  # what the mode would compute first in its step
                obs.components.prepare()
            stages.lap(COMPONENTS)
        clearance = footprint_clearance(obs.points, self.footprint)
        self.lrf.add(lrf_range(obs.points))
        in_region = bool(point_in_region(self.scene.scenario, pose.x, pose.y))
        done = self._task_events(started, pose, velocity, clearance, in_region)
        task, target = self.participant.intention()
        if stages is not None:
            stages.lap(TASKS)
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
            lsl_clock_s=stamp,
            input_age_ticks=inp.age_ticks,
            rtt_ms=inp.rtt_ms,
        )
        self.writer.samples.append(record.row(self.trial_id))
        if lsl is not None:
            lsl.state(record, velocity)
        if self.tally is not None:
            self.tally.add(record.label, record.target, task, target, record.beta)
        if stages is not None:
            stages.lap(DATABASE)
        assert self.sink is not None  # made by run()
        recorder = self.sink.recorder
        front, tail = self._camera_frames() if recorder.camera_due(t, pose) else (None, None)
        recorder.tick(t, pose, obs.points, u, record.v, assist=out, camera=front, tail_camera=tail)
        if stages is not None:
            stages.lap(RECORDING)
        if tick % FLUSH_EVERY_TICKS == 0:
            self.writer.flush(tick)
            if stages is not None:
                stages.lap(DATABASE)
        return done

    def _camera_frames(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The front and tail camera frames the recording asks for: the images on the
        participant's screen, else rendered here at the recording's width."""
        views, participant, world = self.spec.camera_views, self.participant, self.scene.world
        width = self.spec.recording.camera_width_px
        frames: list[np.ndarray | None] = []
        for which in ("front", "tail"):
            if which not in views:
                frames.append(None)
            elif participant.shows_camera:
                frames.append(participant.camera_image(which))
            else:
                frames.append(world.camera_image(which, width_px=width))
        return frames[0], frames[1]

    def _task_events(
        self,
        started: list[Contact],
        pose: Pose2D,
        velocity: Any,
        clearance: float,
        in_region: bool,
    ) -> bool:
        """Collisions, the tasks' updates and their events; True when the trial is done."""
        spec, sink, t = self.spec, self.sink, self.t
        assert sink is not None  # made by run()
        for c in started:
            self.open_contacts.add(c.index)
            sink.collision(c, t)
        if self.open_contacts:
            self._contacts_ended()
        done = False
        primary, secondary = self.primary, self.secondary
        if primary is not None:
            for pe in primary.update(t, pose, velocity, clearance, started):
                detail = {k: v_ for k, v_ in asdict(pe).items() if k not in ("kind", "t")}
                sink(pe.t, pe.kind, **{k: v_ for k, v_ in detail.items() if v_ is not None})
            done = primary.done
        if secondary is not None and not spec.baseline and in_region != self.was_in_region:
            sink(t, "region_entry" if in_region else "region_exit")
        self.was_in_region = in_region
        if secondary is not None:
            for ev in secondary.update(t, in_region):
                self.sec_events.append(ev)
                sink.secondary(ev)
                if spec.baseline and ev.kind == "block_finished":
                    done = True
        if spec.end_on_collision and started and not done:
            done = self.crashed = True  # Sec. 7.5: "the crash of the quadrotor"
        limit = self.max_collisions
        if limit is not None and primary is not None and primary.collisions > limit:
            done = True  # a practice attempt that can no longer pass ends at once
        if t >= self.time_limit + 1.0:  # a safety net; PrimaryTask times out first
            done = True
        return done

    def _contacts_ended(self) -> None:
        """A ``collision_end`` event (database only) for every open contact that ended."""
        contacts = self.scene.world.contacts()
        for index in sorted(self.open_contacts):
            if math.isfinite(contacts[index].t_end):
                self.open_contacts.discard(index)
                self.writer.event(
                    contacts[index].t_end,
                    "collision_end",
                    index=index,
                    element=contacts[index].obstacle,
                )

    # -------------------------------------------------------------- the end

    def _abort(self, exc: BaseException) -> None:
        """After an exception: store the buffered rows, the trial ``aborted`` (best effort)."""
        if isinstance(exc, KeyboardInterrupt):  # Ctrl-C, the window closed: say which
            reason = f"interrupted: {exc}" if str(exc) else "interrupted"
        else:
            reason = f"error: {type(exc).__name__}: {exc}"
        if self.sink is not None:
            self.sink.close_questions()
        try:
            self.writer.abort(self.tick, self.t, reason)
        except Exception:  # the database itself failed; resume aborts the trial
            pass

    def _end_status(self) -> str:
        """``aborted``, ``timed_out`` (the driving task reached its time limit, unless the
        limit is the trial's planned length) or ``completed``."""
        primary = self.primary
        if self.status == "completed" and primary is not None and primary.timed_out:
            return "completed" if self.spec.limit_is_duration else "timed_out"
        return self.status

    def _finish(self) -> TrialResult:
        """The outcome, status and last rows in one transaction; then ``end_trial``."""
        assert self.sink is not None  # made by run()
        self.sink.close_questions()  # shown, never resolved
        tick, t, status = self.tick, self.t, self._end_status()
        outcome: dict[str, Any] = {"ticks": tick, "duration_s": t}
        values: dict[str, Any] = {"status": status, "tick_jitter_ms": self.clock.jitter_p99_ms()}
        if self.primary is not None:
            po = self.primary.outcome()
            outcome.update(jsonable(asdict(po)))
            values.update(
                completed_task=po.completed,
                completion_time_s=po.completion_time_s,
                collisions=po.collisions,
                score=po.score,
                path_length_m=po.path_length_m,
                clearance_mean_m=_finite(po.clearance_mean_m),
                clearance_min_m=_finite(po.clearance_min_m),
            )
            # Sec. 7.5's clearance (Fig. 7.44b, Table 7.10) and whether a collision ended it
            outcome["lrf_clearance"] = self.lrf.summary()
            outcome["crashed"] = self.crashed
            if self.max_collisions is not None:
                outcome["passed"] = bool(po.completed and po.collisions <= self.max_collisions)
        if self.mode_settings is not None:
            outcome["mode_settings"] = self.mode_settings
        if self.model is not None:
            outcome["model"] = self.model
        if self.label_tasks is not None:
            outcome["label_tasks"] = self.label_tasks
        if self.tally is not None and self.tally.counts:  # the driver said what they did
            outcome["recognition"] = self.tally.summary()
        if self.secondary is not None:
            outcome["secondary"] = jsonable(summarise(self.sec_events))
        if status == "aborted":
            outcome["aborted_reason"] = self.reason
        self.writer.event(t, "trial_ended", status=status)
        values["outcome"] = outcome
        self.writer.finish(tick, values)
        self.participant.end_trial(outcome)
        return TrialResult(self.trial_id, status, outcome, tick, t)


def _prepared(obs: Any) -> bool:
    """Whether ``obs``'s semantic components were put into the robot frame (read)."""
    return bool(getattr(obs.components, "prepared", False))


def run_trial(
    engine: Engine,
    spec: TrialSpec,
    *,
    scene: Scene,
    participant: Participant,
    mode: Mode | None,
    trial_values: dict[str, Any],
    recording_dir: Path,
    recording_rel: Callable[[int], str],
    session_id: int,
    clock: FreeClock | WallClock | None = None,
    control: ExperimenterControl | None = None,
    on_tick: Callable[[int, TrialWriter], None] | None = None,
    max_collisions: int | None = None,
    stages: StageClock | None = None,
    lsl: SessionLsl | None = None,
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
    recording_rel : callable or None
        Trial id -> relative path of its ``.rrd`` file; None: no recording (the trial's
        ``recording_path`` is empty, every other row as with one).
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
    stages : StageClock, optional
        Reads the time of every stage of every tick (``asa bench --only trial``).
    lsl : SessionLsl, optional
        The session's LSL (:mod:`study.lsl.session`): every event as a marker, every tick
        a state sample, both stamped with the tick's ``local_clock()``, which its sample
        row stores.

    Returns
    -------
    TrialResult
    """
    loop = TrialLoop(
        engine,
        spec,
        scene=scene,
        participant=participant,
        mode=mode,
        trial_values=trial_values,
        recording_dir=recording_dir,
        recording_rel=recording_rel,
        session_id=session_id,
        clock=clock,
        control=control,
        on_tick=on_tick,
        max_collisions=max_collisions,
        stages=stages,
        lsl=lsl,
    )
    return loop.run()
