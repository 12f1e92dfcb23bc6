"""``asa synth``: a whole study with synthetic participants (:func:`study.jobs.synth.
run_synthetic_study`), in worker processes; the database is the same whatever the number
of workers. One line per finished participant (with the live count) goes to stderr, the
summary to stdout. Started again after an interruption, it skips the participants already
in the database and runs the others from scratch. One synthetic study writes a database at
a time: a second one waits for the first. A study made with another protocol, seed or
platform version is refused unless ``--force``. ``--no-recordings`` records no trial: the
same database without recording paths, for studies that need only the outcomes."""

from __future__ import annotations

import os
from pathlib import Path

import click

from study.cli import PARTICIPANTS, SEED, WORKERS, db_option, flag_errors


@click.command("synth")
@click.option("--protocol", required=True, help="Shipped protocol name or TOML file.")
@click.option(
    "--participants",
    type=PARTICIPANTS,
    default=None,
    help="How many synthetic participants (P01..PNN); default the protocol's number.",
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="The synthetic study's seed.")
@click.option(
    "--workers",
    type=WORKERS,
    default=None,
    help="Worker processes; default the number of CPUs.",
)
@db_option(
    "Study database: a SQLite file or a SQLAlchemy URL (created, or continued if interrupted)."
)
@click.option(
    "--recordings",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for the rerun recordings; default <db stem>_recordings beside the database "
    "(for a database URL: <database name>_recordings in the working folder).",
)
@click.option(
    "--no-recordings",
    "no_recordings",
    is_flag=True,
    help="Record no trial (faster; the database rows are the same, without recording paths): "
    "for studies that need only the outcomes, e.g. pilots of a power analysis.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Write into a study made with another protocol, seed or platform version "
    "(recorded in each session row).",
)
@click.option(
    "--site",
    default=None,
    help="The site of a multi-site study the participants belong to (codes <site>-P01 ...; "
    "required when the protocol has [study] sites) [default: $ASA_SITE].",
)
@click.option(
    "--population",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="A population file (TOML, a [population] table of the model's fields); default "
    "the platform's model.",
)
def synth(
    protocol: str,
    participants: int | None,
    seed: int,
    workers: int | None,
    db: Path,
    recordings: Path | None,
    no_recordings: bool,
    force: bool,
    site: str | None,
    population: Path | None,
) -> None:
    """Run every participant's session of a protocol with synthetic participants.

    \b
    Example:
      asa synth --protocol pilot --participants 6 --seed 1 --workers 2 --db pilot.db
      asa synth --protocol multisite.toml --site lyon --participants 6 --db lyon.db
    """
    from study.engine.protocol import load_protocol
    from study.engine.sites import SITE_ENV
    from study.jobs.synth import format_summary, run_synthetic_study, sanity_summary
    from study.participants.population_file import load_population

    people = load_population(population) if population is not None else None
    p = load_protocol(protocol)
    n = participants if participants is not None else p.study.participants
    w = workers if workers is not None else (os.cpu_count() or 1)
    try:
        with flag_errors("participants", "seed", "workers", "db"):
            summary = run_synthetic_study(
                p,
                db,
                participants=n,
                seed=seed,
                workers=w,
                recordings=recordings,
                record=not no_recordings,
                progress=lambda line: click.echo(line, err=True),
                force=force,
                population=people,
                site=site if site is not None else os.environ.get(SITE_ENV) or None,
            )
    except ValueError as error:  # the library names its parameter, the user types a flag
        raise ValueError(str(error).replace("force=True", "--force")) from error
    click.echo(
        f"{summary.db}: {len(summary.run)} participants run, {len(summary.skipped)} skipped, "
        f"in {summary.wall_s:.1f} s"
    )
    for line in format_summary(sanity_summary(summary.db)):
        click.echo(line)
