"""``asa bench``: measure the performance budgets of DESIGN.md."""

from __future__ import annotations

import json
from typing import Any

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
@click.option(
    "--generated-seeds",
    "generated_seeds",
    default=None,
    metavar="SEEDS",
    help="Group recognition: the generated floor plans' seeds, e.g. 20-29 (the held-out "
    "seeds: run them once, at the end) or 0,3,5. Default 0-9.",
)
@click.option(
    "--generated-only",
    is_flag=True,
    help="Group recognition: drive the generated floor plans only, no shipped scene.",
)
@click.option(
    "--compare-recogniser",
    "compare",
    multiple=True,
    metavar="NAME",
    help="Group recognition: measure the contextual mode with setting recogniser = NAME "
    "too, its figures beside the default's (repeatable).",
)
def bench(
    only: tuple[str, ...],
    as_json: bool,
    quick: bool,
    generated_seeds: str | None,
    generated_only: bool,
    compare: tuple[str, ...],
) -> None:
    """Measure the performance budgets and print the figures.

    Headless, one core per measurement. Every group adds its keys to one JSON
    object, e.g. `sim_ticks_per_s`; `budgets` holds each budgeted figure's value,
    budget, comparison and whether it is met. Without --json: a table of group,
    figure, value, budget and met, and (group trial) where a tick's time goes: p50 /
    p95 [ms] and share of the mean tick per stage, participant kind and mode.
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

    options = _recognition_options(generated_seeds, generated_only, compare)
    if options and "recognition" not in (only or GROUPS):
        raise ValueError(
            "asa bench: --generated-seeds, --generated-only and --compare-recogniser "
            "apply to group recognition (add --only recognition)"
        )
    per_group = measure(
        list(only),
        quick=quick,
        progress=progress,
        options={"recognition": options} if options else None,
    )
    figures = merge(per_group, quick=quick)
    if as_json:
        click.echo(json.dumps(figures, sort_keys=True))
        return
    click.echo(f"machine  {json.dumps(figures['machine'])}")
    click.echo(f"quick    {json.dumps(quick)}")
    rows = table_rows(per_group, figures["budgets"])
    _print_table([row for row in rows if not row[1].startswith(_STAGES_PREFIX)])
    _print_stages(figures)


_STAGES_PREFIX = "trial_stages_"


def parse_seeds(text: str) -> tuple[int, ...]:
    """Seeds written ``"20-29"`` (inclusive), ``"0,3,5"`` or a mix (``"0-2,7"``).

    Raises
    ------
    ValueError
        For anything else, naming the text and the allowed forms.
    """
    seeds: list[int] = []
    try:
        for part in text.split(","):
            lo, dash, hi = part.strip().partition("-")
            first, last = int(lo), int(hi) if dash else int(lo)
            if first < 0 or last < first:
                raise ValueError
            seeds += range(first, last + 1)
    except ValueError:
        raise ValueError(
            f"generated seeds {text!r}: expected a range like 20-29, a list like 0,3,5 or "
            "a mix (non-negative integers, ranges low-high)"
        ) from None
    return tuple(seeds)


def _recognition_options(
    generated_seeds: str | None, generated_only: bool, compare: tuple[str, ...]
) -> dict[str, Any]:
    """The recognition group's keyword options from the command line's."""
    options: dict[str, Any] = {}
    if generated_seeds is not None:
        try:
            options["generated"] = parse_seeds(generated_seeds)
        except ValueError as error:
            raise ValueError(f"asa bench: --generated-seeds: {error}") from None
    if generated_only:
        options["scenes"] = []
    if compare:
        options["compare"] = {name: {"recogniser": name} for name in compare}
    return options


def _print_stages(figures: dict) -> None:
    """The tick's stages: one row per stage, one column per participant kind and mode,
    each cell ``p50 / p95 ms (share of the mean tick)``."""
    order = ("manual", "reactive_bn", "contextual_task")

    def position(key: str) -> tuple:
        kind, _, mode = key[len(_STAGES_PREFIX) :].partition("_")
        return (kind, order.index(mode) if mode in order else len(order), mode)

    runs = sorted((k for k in figures if k.startswith(_STAGES_PREFIX) and figures[k]), key=position)
    if not runs:
        return
    head = ["stage [ms]", *(k[len(_STAGES_PREFIX) :].replace("_", " ", 1) for k in runs)]
    table = [head]
    for stage in figures[runs[0]]:
        cells = [stage]
        for k in runs:
            v = figures[k].get(stage, {})
            cells.append(f"{v['p50_ms']:.3f} / {v['p95_ms']:.3f} ({100 * v['share']:.0f}%)")
        table.append(cells)
    widths = [max(len(row[i]) for row in table) for i in range(len(head))]
    click.echo("\nwhere a tick's time goes (p50 / p95 [ms], share of the mean tick):")
    for row in table:
        click.echo("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())


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
