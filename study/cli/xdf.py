"""``asa xdf import``: a LabRecorder XDF file into a study database, aligned with a
participant's trials through this platform's markers in it (:mod:`study.lsl.xdf`)."""

from __future__ import annotations

from pathlib import Path

import click

from study.cli import db_option


@click.group("xdf")
def xdf() -> None:
    """LabRecorder's XDF files (Lab Streaming Layer): import one into a study database."""


@xdf.command("import")
@db_option("Study database: a SQLite file or a SQLAlchemy URL (it must exist).")
@click.option(
    "--xdf",
    "xdf_file",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The XDF file LabRecorder wrote while the session ran with LSL.",
)
@click.option(
    "--participant",
    default=None,
    help="Whose session to align with (required when the file holds several).",
)
@click.option("--force", is_flag=True, help="Import a file imported before for that session.")
def import_command(db: str, xdf_file: Path, participant: str | None, force: bool) -> None:
    """Store every lab stream of --xdf with the participant's session, aligned with its
    trials by the sync markers of this platform's event stream in the file.

    The streams keep their own timestamps and clock offsets; the shift from the
    recorder's clock to the session's is stored with them, so `asa export --aligned` and
    the report put them on the session's clock. Needs the [lsl] extra (pyxdf).

    \b
    Example:
      asa xdf import --db pilot.db --xdf sub-P01_ses-1.xdf --participant P01
      asa export --db pilot.db --out csv/ --aligned
    """
    from study.lsl.xdf import import_xdf

    summary = import_xdf(db, xdf_file, participant=participant, force=force)
    click.echo(
        f"{summary.participant}: session {summary.session_id}, {summary.pairs} sync markers "
        f"matched (spread {summary.spread_ms:.3f} ms), recorder clock + "
        f"{summary.clock_shift_s:.6f} s = session clock"
    )
    for name, n in summary.streams:
        click.echo(f"  {name}: {n} samples")
