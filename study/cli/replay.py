"""``asa replay``: open a trial's rerun recording, or print what it holds.

A thin shell over :func:`find_recording`, :func:`study.data.recording.recording_summary`
and :func:`study.data.recording.open_viewer`.

Decision where the spec is silent: ``--trial N`` is the trial's row id in the
database (``trial.id``, the id ``asa export`` writes), because it is unique even
when a practice trial was repeated or a crashed trial was run again; the trial
must belong to ``--participant``. An unknown id is answered with the
participant's trials (id, phase, ordinal, attempt, mode) so the right one is
easy to pick. A relative ``recording_path`` is taken relative to the
database's folder.
"""

from __future__ import annotations

from pathlib import Path

import click
from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.storage import Participant, Trial, database_url, open_database


def find_recording(db: str | Path, participant: str, trial: int) -> Path:
    """The ``.rrd`` file of trial ``trial`` (row id) of participant ``participant``.

    Raises
    ------
    ValueError
        Naming the database and the field (``participant.code``, ``trial.id``,
        ``trial.recording_path``) when the participant or trial is unknown, or the
        trial has no recording or its file is missing.
    """
    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            person = s.scalars(select(Participant).where(Participant.code == participant)).first()
            if person is None:
                codes = s.scalars(select(Participant.code).order_by(Participant.code)).all()
                known = ", ".join(codes[:20]) + (" ..." if len(codes) > 20 else "")
                raise ValueError(
                    f"{db}: field 'participant.code': no participant {participant!r} "
                    f"(known: {known or 'none'})"
                )
            row = s.get(Trial, trial)
            if row is None or row.participant_id != person.id:
                trials = s.scalars(
                    select(Trial).where(Trial.participant_id == person.id).order_by(Trial.id)
                ).all()
                listed = "; ".join(
                    f"{t.id} ({t.phase} {t.ordinal}"
                    + (f" attempt {t.attempt}" if t.attempt else "")
                    + (f", {t.mode}" if t.mode else "")
                    + ")"
                    for t in trials
                )
                raise ValueError(
                    f"{db}: field 'trial.id': participant {participant} has no trial {trial} "
                    f"(trial ids: {listed or 'none'})"
                )
            stored = row.recording_path
    finally:
        engine.dispose()
    if not stored:
        raise ValueError(
            f"{db}: field 'trial.recording_path': trial {trial} of {participant} has no recording"
        )
    path = Path(stored)
    if not path.is_absolute():
        url = database_url(db)
        base = Path(url[len("sqlite:///") :]).parent if url.startswith("sqlite:///") else Path()
        path = base / path
    if not path.is_file():
        raise ValueError(
            f"{db}: field 'trial.recording_path': the recording of trial {trial} of "
            f"{participant} is missing ({path})"
        )
    return path


@click.command()
@click.option(
    "--db",
    required=True,
    type=click.Path(path_type=Path),
    help="The study database (SQLite file).",
)
@click.option("--participant", required=True, help="Participant code, e.g. P01.")
@click.option(
    "--trial",
    required=True,
    type=int,
    help="The trial's row id in the database (trial.id, as in `asa export`); "
    "an unknown id lists the participant's trials.",
)
@click.option(
    "--print",
    "print_only",
    is_flag=True,
    help="Print what the recording holds (entities, rows, time range) instead of "
    "opening the viewer.",
)
def replay(db: Path, participant: str, trial: int, print_only: bool) -> None:
    """Open the rerun viewer on one trial's recording (rerun's analytics switched off).

    Example: asa replay --db study.db --participant P01 --trial 7 --print
    """
    # imported here so that `asa replay --help` does not load rerun
    from study.data.recording import format_summary, open_viewer, recording_summary

    path = find_recording(db, participant, trial)
    if print_only:
        click.echo(format_summary(recording_summary(path)))
        return
    process = open_viewer(path)
    click.echo(f"opened the rerun viewer on {path} (pid {process.pid})")
