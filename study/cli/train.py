"""``asa train``: learn the contextual-task model from recorded demonstrations (thesis
Sec. 6.2, 7.4.1; issue 3, "Demonstrations and training").

A thin shell over :func:`train_model`: load the demonstrations
(:func:`study.jobs.demonstrations.load_demonstrations`, moving ticks only), train
(:func:`autonomy.training.train`: DP-GMM clustering, tiny clusters merged, the SOGP
classifier), save the model file (:func:`autonomy.model.save_model`) and print the cluster
summary. The true task types of the demonstrations appear only in that summary.

The same demonstrations and ``--seed`` reproduce the same model (arrays identical; only
the creation date in the metadata differs), which is how the shipped model
``autonomy/models/default.npz`` is checked (see ``autonomy/models/README.md``).
"""

from __future__ import annotations

from pathlib import Path

import click

from autonomy.model import ContextualModel, save_model
from autonomy.training import TrainSettings, format_summary, train


def train_model(
    demonstrations: str | Path,
    out: str | Path,
    *,
    seed: int = 0,
    settings: TrainSettings | None = None,
) -> ContextualModel:
    """Train on the demonstrations in ``demonstrations`` and save the model to ``out``.

    Raises
    ------
    ValueError
        For unreadable demonstrations (naming the file and field) or too few points.
    """
    from study.jobs.demonstrations import load_demonstrations

    demos = load_demonstrations(demonstrations)
    if len(demos) == 0:
        raise ValueError(f"{demonstrations}: no moving ticks in these demonstrations")
    out = Path(out)
    if out.exists() and out.is_dir():
        raise ValueError(f"{out}: --out must be a file path (e.g. model.npz), not a directory")
    model = train(
        demos.q,
        seed=seed,
        settings=settings,
        task=demos.task,
        run=demos.run,
        source=Path(demonstrations).name,
    )
    save_model(model, out)
    return model


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
    type=int,
    help="Seed of every random choice in training.",
)
def train_command(demonstrations: Path, out: Path, seed: int) -> None:
    """Train the contextual-task model (DP-GMM clusters + SOGP classifier) and save it."""
    model = train_model(demonstrations, out, seed=seed)
    click.echo(format_summary(model))
    click.echo(f"model written to {out}")
