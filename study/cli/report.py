"""``asa report``: the study report of a database or ``asa export`` folder
(:func:`analysis.report.build_report`). Progress goes to stderr, the written paths to stdout."""

from __future__ import annotations

from pathlib import Path

import click

from study.cli import db_option


@click.command("report")
@db_option(
    "Study database (a SQLite file or a SQLAlchemy URL, opened read-only), or a folder "
    "written by `asa export`.",
    name="source",
)
@click.option(
    "--out",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Report folder (created): report.html, results.json, figures/, tables/.",
)
@click.option(
    "--metric",
    "metrics",
    multiple=True,
    help="Only this metric (repeatable); default every metric with data.",
)
def report_command(source: str, out: Path, metrics: tuple[str, ...]) -> None:
    """Analyse a study: per metric a repeated-measures ANOVA with the protocol's alpha, gate
    and post-hoc form, figures (PNG, SVG), tables (CSV), results.json and one
    self-contained report.html."""
    from analysis.report import build_report

    def progress(line: str) -> None:
        click.echo(f"asa report: {line}", err=True)

    paths = build_report(source, out, metrics=metrics or None, progress=progress)
    click.echo(str(paths.html))
    click.echo(str(paths.results_json))
    click.echo(
        f"{len(paths.metrics)} metrics, {len(paths.figures)} figure files, "
        f"{len(paths.tables)} tables in {paths.seconds:.1f} s"
    )
