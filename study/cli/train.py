"""``asa train``: learn the contextual-task model from recorded demonstrations (thesis
Sec. 6.2, 7.4.1; issue 3, "Demonstrations and training").

Click parsing around :func:`study.jobs.training.train_model`; prints the cluster summary
(:func:`autonomy.training.format_summary`), the only place the demonstrations' true task
types appear.
"""

from __future__ import annotations

from pathlib import Path

import click

from autonomy.training import format_summary
from study.cli import SEED, flag_errors
from study.jobs.training import train_model


@click.command("train")
@click.option(
    "--demonstrations",
    "demonstrations",
    required=True,
    type=click.Path(path_type=Path),
    help="Directory written by `asa demonstrations record`.",
)
@click.option(
    "--out",
    "out",
    required=True,
    type=click.Path(path_type=Path),
    help="Model file to write (.npz).",
)
@click.option(
    "--seed",
    default=0,
    show_default=True,
    type=SEED,
    help="Seed of every random choice in training.",
)
@click.option("--force", is_flag=True, help="Overwrite --out if it exists.")
def train_command(demonstrations: Path, out: Path, seed: int, force: bool) -> None:
    """Train the contextual-task model (DP-GMM clusters + SOGP classifier) and save it.

    An existing --out is not overwritten without --force.
    """
    try:
        with flag_errors("out"):
            model = train_model(demonstrations, out, seed=seed, force=force)
    except ValueError as error:
        prefix = f"{out}: out "
        if str(error).startswith(prefix):  # the job names its parameter, the CLI its flag
            raise ValueError(f"{out}: --out {str(error)[len(prefix) :]}") from None
        raise
    click.echo(format_summary(model))
    click.echo(f"model written to {out}")
