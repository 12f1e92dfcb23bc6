"""One trial outside a session, for benchmarks, tests and a quick look at one mode: a fresh
study database with its parent rows, the scene, :func:`study.engine.trial.run_trial` as a
session runs it; the recording goes to ``<folder>/rec/trial_<id>.rrd``."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from autonomy.modes import make_mode, with_defaults
from sim.occupancy import build_grid
from sim.scenario import load_scenario
from sim.semantics import derive_components
from sim.world import World
from study.data.storage import Participant as ParticipantRow
from study.data.storage import SessionRow, Study, open_database
from study.engine.stages import StageClock
from study.engine.trial import Scene, TrialResult, TrialSpec, TrialWriter, run_trial
from study.participants.base import Participant
from tasks.primary import PrimarySettings
from tasks.secondary import SecondarySettings


def standalone_trial(
    folder: str | Path,
    participant: Participant,
    *,
    mode: str = "manual",
    scenario: str = "cluttered_room",
    phase: str = "main",
    route: tuple[str, ...] = ("dock", "start"),
    inspection: bool = False,
    timeout_s: float = 60.0,
    secondary: SecondarySettings | None = None,
    seed: int = 0,
    camera_hz: float = 0.0,
    camera_views: tuple[str, ...] = ("front",),
    clock: Any = None,
    control: Any = None,
    on_tick: Callable[[int, TrialWriter], None] | None = None,
    mode_settings: Mapping[str, Any] | None = None,
    wrap_mode: Callable[[Any], Any] | None = None,
    database: str = "trial.db",
    record: bool = True,
    stages: StageClock | None = None,
    durable: bool = True,
) -> tuple[TrialResult, Engine]:
    """Run one driving trial in a fresh database ``folder / database``.

    Parameters
    ----------
    folder : folder for the database and the recording (must exist).
    participant : any participant (``study.participants.base.Participant``).
    mode : registered mode name; ``mode_settings`` its keyword settings, ``wrap_mode`` a
        function applied to the built mode (e.g. to time its ``step``).
    scenario : shipped scenario name or TOML file.
    phase, route, inspection, timeout_s : the trial (``tasks.primary.PrimarySettings``);
        the trial ends when the route is driven or at ``timeout_s`` [s] of simulated time.
    secondary : questions in the scenario's question region, or None.
    seed : the trial's seed (world noise, questions) and the participant row's.
    camera_hz, camera_views : camera frames per second in the recording, and which cameras
        (:class:`study.engine.trial.TrialSpec`).
    clock, control, on_tick, stages : as :func:`study.engine.trial.run_trial`.
    record : write the rerun recording (else the trial has none, its rows unchanged).
    durable : False skips SQLite's fsync on commit, as a synthetic study's scratch
        database does (:func:`study.data.storage.open_database`).

    Returns
    -------
    (TrialResult, Engine)
        The engine stays open for the caller to read the rows (``engine.dispose()`` after).
    """
    folder = Path(folder)
    sc = load_scenario(scenario)
    components = derive_components(sc)
    built = make_mode(mode, **dict(mode_settings or {}))
    if wrap_mode is not None:
        built = with_defaults(wrap_mode(built))
    engine = open_database(folder / database, durable=durable)
    person_id, session_id = _parent_rows(engine, participant, mode, seed)
    spec = TrialSpec(
        phase=phase,
        ordinal=0,
        attempt=0,
        mode=mode,
        seed=seed,
        instruction="",
        primary=PrimarySettings(route=route, inspection_required=inspection, timeout_s=timeout_s),
        secondary=secondary,
        camera_hz=camera_hz,
        camera_views=camera_views,
    )
    values = _trial_values(person_id, session_id, spec, sc.name)
    with World(sc, seed=0, components=components) as world:
        result = run_trial(
            engine,
            spec,
            scene=Scene(sc.name, sc, build_grid(sc), components, world),
            participant=participant,
            mode=built,
            trial_values=values,
            recording_dir=folder,
            recording_rel=(lambda tid: f"rec/trial_{tid}.rrd") if record else None,
            session_id=session_id,
            clock=clock,
            control=control,
            on_tick=on_tick,
            stages=stages,
        )
    return result, engine


def _parent_rows(engine: Engine, participant: Participant, mode: str, seed: int) -> tuple[int, int]:
    """A study, participant and session row for the trial's rows: their ids."""
    with Session(engine) as s, s.begin():
        study = Study(
            name="standalone",
            protocol_text="",
            protocol_sha256="0" * 64,
            platform_version="standalone",
            seed=seed,
        )
        s.add(study)
        s.flush()
        person = ParticipantRow(
            study_id=study.id,
            code="T01",
            kind=participant.kind,
            parameters=dict(participant.parameters),
            order_index=0,
            mode_order=[mode],
            seed=seed,
        )
        s.add(person)
        s.flush()
        row = SessionRow(participant_id=person.id)
        s.add(row)
        s.flush()
        return person.id, row.id


def _trial_values(
    person_id: int, session_id: int, spec: TrialSpec, scenario: str
) -> dict[str, Any]:
    """Column values of the trial row."""
    return {
        "participant_id": person_id,
        "session_id": session_id,
        "phase": spec.phase,
        "mode": spec.mode,
        "ordinal": 0,
        "attempt": 0,
        "scenario": scenario,
        "seed": spec.seed,
    }
