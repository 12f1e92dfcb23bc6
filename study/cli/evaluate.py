"""``asa evaluate``: offline evaluation of contextual-task recognition on held-out
demonstrations (thesis Sec. 7.2.2, 7.3, 7.4; issue 3, "Offline evaluation").

Click parsing around :func:`study.jobs.evaluation.run_evaluation`; prints tables
(:func:`autonomy.evaluation.format_report`) or ``--json`` on stdout, ``--out FILE`` also
writes the JSON; progress (jobs done, elapsed, time left) on stderr unless ``--quiet``.
Errors name the flags.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import click

from autonomy.evaluation import format_report
from study.cli import SEED
from study.jobs.evaluation import run_evaluation

_FLAGS = ("folds", "workers", "repeats")  # run_evaluation's parameters that are flags


def _in_flags(error: ValueError) -> ValueError:
    """The job's error in the command line's words: flags instead of parameters."""
    text = str(error)
    if any(text.startswith(f"{name}: ") for name in _FLAGS):
        return ValueError(f"--{text}")
    return error


def _warn(line: str) -> None:
    click.echo(f"asa: warning: {line}", err=True)


def _duration(seconds: float) -> str:
    """``45s``, ``2m10s`` or ``1h05m``."""
    s = int(round(seconds))
    if s < 60:
        return f"{s}s"
    if s < 3600:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s // 3600}h{s % 3600 // 60:02d}m"


class _Progress:
    """Prints ``[evaluate] 7/15 jobs, 2m10s elapsed, ~2m40s left`` on stderr per
    finished job; the time left assumes the remaining jobs take the mean so far."""

    def __init__(self) -> None:
        self.start = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        elapsed = time.monotonic() - self.start
        left = "done" if done >= total else f"~{_duration(elapsed / done * (total - done))} left"
        click.echo(
            f"[evaluate] {done}/{total} jobs, {_duration(elapsed)} elapsed, {left}", err=True
        )


@click.command("evaluate")
@click.option(
    "--demonstrations",
    "demonstrations",
    default=None,
    type=click.Path(path_type=Path),
    help="Directory written by `asa demonstrations record` (default: the model's own "
    "demonstrations, recorded again from the model's recipe if missing and cached; "
    "recorded on another CPU they may hash differently from the model's data, which a "
    "warning on stderr names).",
)
@click.option(
    "--model",
    "model",
    default=None,
    type=click.Path(path_type=Path),
    help="Model file whose demonstrations and way-point stride are used (default: the "
    "shipped model).",
)
@click.option("--folds", default=5, show_default=True, type=int, help="Folds, by run.")
@click.option("--seed", default=0, show_default=True, type=SEED, help="Seed of the folds etc.")
@click.option(
    "--repeats",
    default=1,
    show_default=True,
    type=int,
    help="Evaluate with this many seeds (--seed, --seed + 1, ...) and report the mean and "
    "spread of the F0.5 over them.",
)
@click.option(
    "--workers",
    default=None,
    type=int,
    help="Worker processes for the folds and introspection pairs; default the CPUs.",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option(
    "--quiet", is_flag=True, help="No progress lines on stderr (jobs done, elapsed, time left)."
)
@click.option(
    "--out",
    "out",
    default=None,
    type=click.Path(path_type=Path),
    help="Also write the JSON result to this file.",
)
def evaluate_command(
    demonstrations: Path | None,
    model: Path | None,
    folds: int,
    seed: int,
    repeats: int,
    workers: int | None,
    as_json: bool,
    quiet: bool,
    out: Path | None,
) -> None:
    """Cross-validated F0.5, ACR and MICAD, introspection (entropy histograms) and
    trajectory rates of the recognisers, the kind-and-time recogniser beside the SOGP."""
    if out is not None and out.is_dir():
        raise ValueError(f"{out}: --out must be a file path (e.g. evaluation.json)")
    workers = (os.cpu_count() or 1) if workers is None else workers
    try:
        result = run_evaluation(
            demonstrations,
            model=model,
            folds=folds,
            seed=seed,
            workers=workers,
            repeats=repeats,
            progress=None if quiet else _Progress(),
            warn=_warn,
        )
    except ValueError as error:
        raise _in_flags(error) from None
    text = json.dumps(result, indent=2, sort_keys=True)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text + "\n")
    click.echo(text if as_json else format_report(result))
