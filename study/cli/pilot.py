"""``asa pilot``: a synthetic pilot study and its report (:func:`study.jobs.pilot.run_pilot`).
Progress goes to stderr, the summary to stdout; exit status 1 when the database check
finds problems (after printing them), like ``asa db check``."""

from __future__ import annotations

from pathlib import Path

import click

from study.cli import PARTICIPANTS, SEED, WORKERS, flag_errors


@click.command()
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for the pilot (must be new or empty); default pilot-<timestamp>/ here.",
)
@click.option(
    "--participants",
    type=PARTICIPANTS,
    default=18,
    show_default=True,
    help="Synthetic participants (the thesis had 18).",
)
@click.option(
    "--workers",
    type=WORKERS,
    default=None,
    help="Worker processes; default the number of CPUs.",
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="The pilot's seed.")
@click.option(
    "--protocol",
    default="thesis-7-6",
    show_default=True,
    help="Shipped protocol name or TOML file.",
)
@click.option(
    "--population",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="A population file (TOML, a [population] table of the model's fields); default "
    "the platform's model.",
)
def pilot(
    out: Path | None,
    participants: int,
    workers: int | None,
    seed: int,
    protocol: str,
    population: Path | None,
) -> None:
    """Run a synthetic pilot study of the thesis protocol and write its report.

    \b
    Example:
      asa pilot                                  # 18 participants, thesis protocol
      asa pilot --participants 6 --out quick/    # a smaller one
    """
    from study.jobs.pilot import pilot_lines, run_pilot
    from study.participants.population_file import load_population

    people = load_population(population) if population is not None else None

    def say(line: str) -> None:
        click.echo(f"asa pilot: {line}", err=True)

    with flag_errors("out", "participants", "workers", "seed"):
        result = run_pilot(
            out,
            participants=participants,
            workers=workers,
            seed=seed,
            protocol=protocol,
            progress=say,
            population=people,
        )
    if not result.check.clean:
        click.echo(result.check.text())
    for line in pilot_lines(result):
        click.echo(line)
    if not result.check.clean:
        raise SystemExit(1)
