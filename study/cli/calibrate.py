"""``asa calibrate``: the synthetic population fitted to a study's people
(:func:`study.jobs.calibrate.run_calibration`, issue 39). A bank of synthetic participants
drives the study's own protocol on Dask, with the fitted person-level values drawn over
wide ranges once; the population's parameters are then fitted by the method of simulated
moments on that bank and bootstrapped. A progress bar goes to stderr; the report to
stdout and beside the population file."""

from __future__ import annotations

from pathlib import Path

import click

from study.cli import COUNT, SEED, WORKERS


@click.command("calibrate")
@click.option(
    "--study",
    "source",
    required=True,
    metavar="DB",
    help="The study to fit to: a database (file or URL) whose protocol plans the metrics "
    "(at least 3 participants with every level of each planned metric).",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=Path("population.toml"),
    show_default=True,
    help="The population file to write (read by --population of asa synth, pilot, power); "
    "the reports FILE.json, FILE.txt and FILE.html (e.g. population.html) and the bank "
    "FILE_bank.sqlite go beside it.",
)
@click.option(
    "--bank",
    type=COUNT,
    default=300,
    show_default=True,
    help="Synthetic participants in the bank (each drives one main trial per mode); an "
    "existing bank of the same settings beside --out is continued.",
)
@click.option(
    "--replicates",
    type=COUNT,
    default=100,
    show_default=True,
    help="Bootstrap replicates (the study's participants and the bank's entries redrawn).",
)
@click.option(
    "--level",
    type=click.FloatRange(0.5, 1.0, max_open=True),
    default=0.95,
    show_default=True,
    help="Level of each parameter's interval.",
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of bank and bootstrap.")
@click.option(
    "--population",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="A population file whose parameters the fit starts from and keeps where the study "
    "does not identify them; default the platform's model.",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="A running Dask scheduler (tcp://host:8786); default a local cluster.",
)
@click.option(
    "--workers",
    type=WORKERS,
    default=None,
    help="Worker processes of the local cluster; default the number of CPUs.",
)
def calibrate(
    source: str,
    out: Path,
    bank: int,
    replicates: int,
    level: float,
    seed: int,
    population: Path | None,
    scheduler: str | None,
    workers: int | None,
) -> None:
    """Fit the synthetic population to a study's people: the population parameters that
    make synthetic participants driving the study's protocol reproduce its per-mode means,
    spreads and correlations across modes of the planned metrics. Fitted where a planned
    metric identifies them: preferred speed (completion_time_s, score_s), answer time and
    dual-task slowdown (secondary_answer_time_s with its baseline level), NASA-TLX bias
    (tlx_raw, tlx_weighted); the rest keep the base population's values.

    \b
    Examples:
      asa calibrate --study pilot.db --out population.toml
      asa calibrate --study pilot.db --bank 100 --replicates 50 --workers 2 --out pop.toml
      asa power --protocol thesis-7-6 --population population.toml --out pw
    """
    import os

    from study.cli.power import ProgressBar
    from study.jobs.calibrate import CalibrateSettings, run_calibration
    from study.participants.population import Population
    from study.participants.population_file import load_population

    settings = CalibrateSettings(
        bank=bank, replicates=replicates, level=float(level), seed=seed, scheduler=scheduler,
        workers=workers if workers is not None else (os.cpu_count() or 1),
        base=load_population(population) if population is not None else Population(),
    )  # fmt: skip
    summary = run_calibration(source, out, settings, progress=ProgressBar())
    for line in summary.lines:
        click.echo(line)
    click.echo(f"{summary.out} ({summary.json}, {summary.text}, {summary.html})")
