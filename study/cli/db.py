"""``asa db check``: integrity and consistency of a study database
(:func:`study.data.dbtools.check`); ``asa db diff``; ``asa db upgrade``: the schema
migrations (:func:`study.data.upgrade.upgrade`); ``asa db push``: a site's database into
the study's (:func:`study.data.push.push`)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from study.cli import db_option


@click.group("db")
def db() -> None:
    """Study database tools."""


@db.command("check")
@db_option("Study database: a SQLite file or a SQLAlchemy URL (opened read-only).", name="path")
@click.option("--json", "as_json", is_flag=True, help="One JSON object on stdout.")
@click.option("--no-verify", is_flag=True, help="Skip `rerun rrd verify` on the recordings.")
@click.option(
    "--recordings",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The folder the sessions wrote their recordings to (as `asa run --recordings`) "
    "[default: the paths stored, from the database's folder].",
)
def check_command(path: str, as_json: bool, no_verify: bool, recordings: Path | None) -> None:
    """Check a study database: every completed trial has its samples (~20 per simulated
    second), its events, its outcome, its recording (verified with rerun) and, for main
    trials, its questionnaire; no orphan rows; no trial left running outside a running
    session; no session or trial running without a live `asa run` holding it (else it was
    interrupted: resume it with `asa run ... --resume`); completed sessions have the
    questionnaires their protocol requires; every order slot issued once, to the
    participant whose order it gives.

    Exit status 0 when clean, 1 with a report of the problems, 2 on bad input.
    """
    from study.data.dbtools import check

    report = check(path, verify_recordings=not no_verify, recordings=recordings)
    if as_json:
        click.echo(json.dumps(report.as_dict(), indent=2))
    else:
        click.echo(report.text())
    if not report.clean:
        sys.exit(1)


@db.command("diff")
@click.argument("a", metavar="A")
@click.argument("b", metavar="B")
@click.option(
    "--tolerance",
    type=float,
    default=0.0,
    show_default=True,
    help="Floats within this of each other (absolute) count as equal.",
)
@click.option("--json", "as_json", is_flag=True, help="One JSON object on stdout.")
def diff_command(a: str, b: str, tolerance: float, as_json: bool) -> None:
    """Compare two study databases (SQLite files or SQLAlchemy URLs, opened read-only)
    row by row: is a rerun, or the same study on another platform version, the same
    data? Columns that record when or where rather than what (creation, start and end
    times, the tick jitter of human sessions, recording file names, the platform
    version, the model file's path) are not compared.

    Exit status 0 when identical, 1 with the first differences of each table, 2 on bad
    input.

    \b
    Example:
      asa db diff before.db after.db
    """
    from study.data.dbdiff import diff

    report = diff(a, b, tolerance=tolerance)
    click.echo(json.dumps(report.as_dict(), indent=2) if as_json else report.text())
    if not report.identical:
        sys.exit(1)


@db.command("upgrade")
@db_option("Study database: a SQLite file or a SQLAlchemy URL (written).")
@click.option(
    "--to",
    "to",
    default="head",
    show_default=True,
    metavar="REV",
    help="The schema revision to reach (0001, 0002, ...; head: the newest).",
)
def upgrade_command(db: str, to: str) -> None:
    """Bring a study database made by an earlier asa-study to this version's schema:
    run the schema migrations (Alembic) from its revision to REV, all in one
    transaction, and print both revisions. A database from before the migrations
    counts as revision 0001. Running it again changes nothing; there is no downgrade.
    Back the database up first.

    Exit status 0 when upgraded (or already there), 2 on bad input.

    \b
    Example:
      asa db upgrade --db study.db
    """
    from study.data.upgrade import upgrade

    before, after = upgrade(db, to=to)
    if before == after:
        click.echo(f"{db}: at schema revision {after} already; nothing to do")
    else:
        click.echo(f"{db}: schema revision {before} -> {after}")


@db.command("push")
@click.option(
    "--from",
    "src",
    required=True,
    metavar="PATH|URL",
    help="The site's study database to push: a SQLite file or a SQLAlchemy URL.",
)
@click.option(
    "--to",
    "dst",
    required=True,
    metavar="PATH|URL",
    help="The study database to push into (a new file or an empty server "
    "database gets the schema and the study).",
)
@click.option("--dry-run", is_flag=True, help="Write nothing; say what a push would do.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object on stdout.")
def push_command(src: str, dst: str, dry_run: bool, as_json: bool) -> None:  # fmt: skip
    """Push a site's study database into the study's shared database (an offline site's
    SQLite file into the server), in one transaction: participants not there are copied
    with their order slots, new sessions of participants already there are added, a
    session pushed aborted and since resumed is replaced by its newer state. Pushing the
    same file again changes nothing. Participants with a session still running are held
    back (one line each on stderr) for a later push. Rows are matched by participant
    code and session uid, never by row ids. Recordings are not copied.

    A participant that is there with other data (another order, seed, site, order slot,
    or a session whose trials differ) is a conflict: one line naming the participant and
    the field, exit status 2, and nothing is written.

    Exit status 0 when pushed (or nothing to do), 2 on bad input or a conflict.

    \b
    Example:
      asa db push --from lyon.db --to postgresql://asa@server/study
    """
    from study.data.push import push

    report = push(src, dst, dry_run=dry_run)
    for p in report.people:
        if p.action == "held back":
            click.echo(f"asa: {p.code} held back: {p.detail}", err=True)
    click.echo(json.dumps(report.as_dict(), indent=2) if as_json else report.text())
