"""``asa bench``: measure the performance budgets of DESIGN.md."""

from __future__ import annotations

import json

import click

from study.bench import GROUPS, measure, merge
from study.bench.budgets import table_rows


@click.command()
@click.option(
    "--only",
    "only",
    multiple=True,
    metavar="GROUP",
    help=f"Run only this group (repeatable). Groups: {', '.join(GROUPS)}.",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object and nothing else.")
@click.option("--quick", is_flag=True, help="Fewer repetitions: a smoke run, noisier figures.")
def bench(only: tuple[str, ...], as_json: bool, quick: bool) -> None:
    """Measure the performance budgets and print the figures.

    Headless, one core per measurement. Every group adds its keys to one JSON
    object, e.g. `sim_ticks_per_s`; `budgets` holds each budgeted figure's value,
    budget, comparison and whether it is met. Without --json: a table of group,
    figure, value, budget and met.
    """
    unknown = [n for n in only if n not in GROUPS]
    if unknown:
        raise ValueError(
            f"asa bench: --only {unknown[0]!r} is not a benchmark group; "
            f"allowed: {', '.join(GROUPS)}"
        )

    def progress(name: str) -> None:
        if not as_json:
            click.echo(f"running benchmark group {name} ...", err=True)

    per_group = measure(list(only), quick=quick, progress=progress)
    figures = merge(per_group, quick=quick)
    if as_json:
        click.echo(json.dumps(figures, sort_keys=True))
        return
    click.echo(f"machine  {json.dumps(figures['machine'])}")
    click.echo(f"quick    {json.dumps(quick)}")
    _print_table(table_rows(per_group, figures["budgets"]))


def _print_table(rows: list[tuple[str, str, object, str, str]]) -> None:
    """Aligned columns: group, figure, value (JSON), budget, met."""
    table = [("group", "figure", "value", "budget", "met")]
    for group, figure, value, budget, met in rows:
        text = "not measured" if value is None and budget else json.dumps(value)
        table.append((group, figure, text, budget, met))
    widths = [max(len(row[i]) for row in table) for i in range(4)]
    for row in table:
        cells = [cell.ljust(width) for cell, width in zip(row[:4], widths, strict=True)]
        click.echo("  ".join([*cells, row[4]]).rstrip())
