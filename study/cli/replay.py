"""``asa replay``: open a trial's rerun recording, or print what it holds
(:func:`study.data.dbtools.find_recording`, :func:`study.data.rrd.recording_summary`,
:func:`study.data.rrd.open_viewer`)."""

from __future__ import annotations

from pathlib import Path

import click

from study.cli import ROW_ID, db_option


@click.command()
@db_option("The study database: a SQLite file or a SQLAlchemy URL (opened read-only).")
@click.option("--participant", required=True, help="Participant code, e.g. P01.")
@click.option(
    "--trial",
    required=True,
    type=ROW_ID,
    help="The trial's row id in the database (trial.id, as in `asa export`); "
    "an unknown id lists the participant's trials.",
)
@click.option(
    "--print",
    "print_only",
    is_flag=True,
    help="Print what the recording holds (entities, rows, time range, camera frames) "
    "instead of opening the viewer.",
)
@click.option(
    "--recordings",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The folder the sessions wrote their recordings to [default: the stored paths].",
)
def replay(
    db: str, participant: str, trial: int, print_only: bool, recordings: Path | None
) -> None:
    """Open the rerun viewer on one trial's recording (rerun's analytics switched off;
    its server listens on localhost only). A viewer that cannot start (no display) is
    reported with one line and exit status 2.

    Example: asa replay --db study.db --participant P01 --trial 7 --print
    """
    # imported here so that `asa replay --help` does not load rerun
    from study.data.dbtools import find_recording
    from study.data.rrd import format_summary, open_viewer, recording_summary

    path = find_recording(db, participant, trial, recordings=recordings)
    if print_only:
        click.echo(format_summary(recording_summary(path)))
        return
    process = open_viewer(path)  # a viewer that fails at once: one line, exit status 2
    if process.returncode is None:
        click.echo(f"opened the rerun viewer on {path} (pid {process.pid}; localhost only)")
    else:
        click.echo(f"the rerun viewer on {path} ended (exit status 0)")
