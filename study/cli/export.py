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
def export_command(path: str, out: Path, force: bool) -> None:
    """Write one CSV per table (study, participant, session, trial, sample, event,
    question, response, meta) into --out; JSON columns as JSON text.

    An existing CSV of the same name in --out is not overwritten without --force (the
    command then writes nothing); other files in --out are left alone.
    """
    from study.data.dbtools import export

    with flag_errors("out"):
        written = export(path, out, force=force)
    for name, n in written.items():
        click.echo(f"{out / (name + '.csv')}: {n} rows")
