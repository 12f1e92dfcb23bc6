"""``asa pilot``: the README's main job.

The full job (issue 6) runs the thesis protocol with 18 synthetic participants
into a fresh folder, recordings included, then writes the report. Until the
synthetic participants exist, the command says so plainly, shows what the
platform can already do and exits 0, so the README's first command is honest
on a fresh machine.
"""

from __future__ import annotations

import click

from study.cli import COMMANDS

_TRY = (
    "asa scenario list",
    "asa scenario show cluttered_room --png cluttered_room.png",
    "asa scenario map cluttered_room --out maps/",
    "asa stats --csv FILE --dv COL --within COL --subject COL",
    "asa bench --only sim",
)


@click.command()
def pilot() -> None:
    """Run a synthetic pilot study of the thesis protocol and write its report.

    Not built yet: synthetic participants and whole studies arrive with the
    session engine. The command lists what is there today.
    """
    click.echo(
        "asa pilot: the synthetic pilot study (the thesis protocol with 18 synthetic "
        "participants, recordings and the report) is not built yet."
    )
    click.echo("What the platform has today:")
    width = max(len(name) for name in COMMANDS)
    for name in sorted(COMMANDS):
        if name != "pilot":
            click.echo(f"  asa {name:<{width}}  {COMMANDS[name][1]}")
    click.echo("Try:")
    for line in _TRY:
        click.echo(f"  {line}")
