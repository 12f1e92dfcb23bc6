"""``asa plan``: the order of the modes assigned to each participant, and a balance check
(:func:`study.jobs.plan.plan`). Warnings go to stderr with ``--json`` so that stdout holds
the one object."""

from __future__ import annotations

import json
from pathlib import Path

import click

from study.cli import PARTICIPANTS, SEED, flag_errors
from study.jobs.plan import format_ledger, format_plan, ledger, plan


@click.command()
@click.option(
    "--protocol",
    "protocol",
    default=None,
    help="A shipped protocol's name (thesis-7-6, reactive-7-5, pilot) or a protocol TOML file.",
)
@click.option(
    "--db",
    type=str,  # a path or a SQLAlchemy URL, as written (see study.cli.db_option)
    metavar="PATH|URL",
    default=None,
    help="An existing study database: show its order ledger (slot, participant, order, "
    "status) instead of a plan.",
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
def plan_command(
    protocol: str | None, db: Path | None, participants: int | None, seed: int | None,
    as_json: bool,
) -> None:  # fmt: skip
    """Print the order of the modes for each participant (P01, P02, ...) under the
    protocol's counterbalancing scheme, with tables of how often each mode comes in each
    position and follows each other mode, and warnings where the plan is unbalanced.

    With --db, print the order ledger of an existing study instead: every order slot
    issued (slot k gets the plan's row for participant k+1, whatever the participant's
    code), its participant, row, order and the status of its session."""
    if (protocol is None) == (db is None):
        raise ValueError("--protocol / --db: give one of them (a plan, or a study's ledger)")
    if db is not None:
        result = ledger(db)
        click.echo(json.dumps(result, allow_nan=False) if as_json else format_ledger(result))
        return
    with flag_errors("participants", "seed"):
        result = plan(protocol, participants=participants, seed=seed)
    if as_json:
        for warning in result["warnings"]:
            click.echo(f"asa: warning: {warning}", err=True)
        click.echo(json.dumps(result, allow_nan=False))
    else:
        click.echo(format_plan(result))
