"""``asa bench``: measure the performance budgets of DESIGN.md."""

from __future__ import annotations

import json

import click

from study.bench import GROUPS, run_benchmarks


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
    object, e.g. `sim_ticks_per_s`.
    """

    def progress(name: str) -> None:
        if not as_json:
            click.echo(f"running benchmark group {name} ...", err=True)

    figures = run_benchmarks(list(only), quick=quick, progress=progress)
    if as_json:
        click.echo(json.dumps(figures, sort_keys=True))
    else:
        width = max(len(k) for k in figures)
        for key in sorted(figures):
            click.echo(f"{key:<{width}}  {json.dumps(figures[key])}")
