"""``asa export``: one CSV per table of a study database (:func:`study.data.dbtools.export`)."""

from __future__ import annotations

from pathlib import Path

import click

from study.cli import db_option, flag_errors


@click.command("export")
@db_option("Study database: a SQLite file or a SQLAlchemy URL (opened read-only).", name="path")
@click.option(
    "--out",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder for the CSV files (created if missing).",
)
@click.option("--force", is_flag=True, help="Overwrite CSV files of an earlier export in --out.")
@click.option(
    "--aligned",
    is_flag=True,
    help="Also write --out/aligned/: the ticks, the events and every recorded or imported "
    "LSL stream on the session's clock.",
)
def export_command(path: str, out: Path, force: bool, aligned: bool) -> None:
    """Write one CSV per table (study, participant, session, trial, sample, event,
    question, response, meta; and where the study recorded or imported the lab's streams,
    lsl_stream, lsl_chunk with its samples as base64, lsl_offset, lsl_gap) into --out;
    JSON columns as JSON text.

    With --aligned also --out/aligned/: ticks.csv, events.csv and offsets.csv, and one
    stream-<id>-<name>.csv per stream with its samples on the session's clock
    (session_clock_s: the session machine's LSL local_clock), their trial and trial time
    (trial_t_s: simulated seconds), one column per channel.

    An existing CSV of the same name in --out is not overwritten without --force (the
    command then writes nothing); other files in --out are left alone.
    """
    from study.data.dbtools import export

    with flag_errors("out"):
        written = export(path, out, force=force)
    for name, n in written.items():
        click.echo(f"{out / (name + '.csv')}: {n} rows")
    if aligned:
        from study.lsl.export import export_aligned

        with flag_errors("out"):
            files = export_aligned(path, out, force=force)
        for name, n in files.items():
            click.echo(f"{out / 'aligned' / name}: {n} rows")
