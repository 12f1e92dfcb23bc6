"""``asa plan``: the order of the modes assigned to each participant, and a balance check
(:func:`study.jobs.plan.plan`). Warnings go to stderr with ``--json`` so that stdout holds
the one object."""

from __future__ import annotations

import json

import click

from study.cli import PARTICIPANTS, SEED, flag_errors
from study.jobs.plan import format_plan, plan


@click.command()
@click.option(
    "--protocol",
    "protocol",
    required=True,
    help="A shipped protocol's name (thesis-7-6, reactive-7-5, pilot) or a protocol TOML file.",
)
@click.option(
    "--participants",
    type=PARTICIPANTS,
    default=None,
    help="Number of participants [default: the protocol's study.participants].",
)
@click.option(
    "--seed",
    type=SEED,
    default=None,
    help="Seed of the random scheme [default: the protocol's study.seed].",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object and nothing else.")
def plan_command(protocol: str, participants: int | None, seed: int | None, as_json: bool) -> None:
    """Print the order of the modes for each participant (P01, P02, ...) under the
    protocol's counterbalancing scheme, with tables of how often each mode comes in each
    position and follows each other mode, and warnings where the plan is unbalanced."""
    with flag_errors("participants", "seed"):
        result = plan(protocol, participants=participants, seed=seed)
    if as_json:
        for warning in result["warnings"]:
            click.echo(f"asa: warning: {warning}", err=True)
        click.echo(json.dumps(result, allow_nan=False))
    else:
        click.echo(format_plan(result))
