"""``asa train``: learn the contextual-task model from recorded demonstrations (thesis
Sec. 6.2, 7.4.1; issue 3, "Demonstrations and training").

Click parsing around :func:`study.jobs.training.train_model`; prints the cluster summary
(:func:`autonomy.training.format_summary`), the only place the demonstrations' true task
types appear.
"""

from __future__ import annotations

from pathlib import Path

import click

from autonomy.model import ContextualModel
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
@click.option(
    "--compare",
    "compare",
    default=None,
    type=click.Path(path_type=Path),
    metavar="MODEL",
    help="Also recognise every tick of the demonstrations with MODEL and print how often "
    "both pick the same candidate and primitive and how far their blend weights differ "
    "(e.g. the shipped autonomy/models/default.npz after rebuilding it from its recipe).",
)
def train_command(
    demonstrations: Path, out: Path, seed: int, force: bool, compare: Path | None
) -> None:
    """Train the contextual-task model (DP-GMM clusters + SOGP classifier) and save it.

    An existing --out is not overwritten without --force. The model's metadata records
    its recipe (the `asa demonstrations record` flags that made the demonstrations, and
    the seed) when one call of that command made them.

    \b
    Rebuilding the shipped model and checking it (autonomy/models/README.md):
      asa demonstrations record --task all --runs 12 --seed 7 --out demos
      asa train --demonstrations demos --out m.npz --compare autonomy/models/default.npz
    """
    other = None
    if compare is not None:
        from autonomy.model import load_model

        with flag_errors("compare"):
            other = load_model(compare)
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
    if other is not None:
        click.echo(_agreement_line(model, other, demonstrations, compare))


def _agreement_line(
    model: ContextualModel, other: ContextualModel, demonstrations: Path, compare: Path
) -> str:
    """One line: how closely ``model`` and ``other`` recognise alike on the ticks of
    ``demonstrations`` (:func:`autonomy.evaluation.agreement.recognition_agreement`)."""
    from autonomy.evaluation.agreement import recognition_agreement
    from study.jobs.demonstrations import load_demonstrations

    demos = load_demonstrations(demonstrations)
    found = recognition_agreement(model, other, demos.cand_points, demos.cand_offsets, demos.u_norm)
    gap = found["beta_difference"]
    same = (
        " (the same data)"
        if model.metadata.get("data_sha256") == other.metadata.get("data_sha256")
        else " (other data: another machine's rounding, or other demonstrations)"
    )
    return (
        f"against {compare}{same}: the same candidate and primitive on "
        f"{found['winner_agreement']:.2%} of {found['ticks']} ticks; blend weights differ "
        f"by {gap['p50']:.2g} (median), {gap['p99']:.2g} (99th percentile), "
        f"{gap['max']:.2g} (largest)"
    )
