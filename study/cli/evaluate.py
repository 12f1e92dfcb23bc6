"""``asa evaluate``: offline evaluation of contextual-task recognition on held-out
demonstrations (thesis Sec. 7.2.2, 7.3, 7.4; issue 3, "Offline evaluation").

A thin shell over :func:`autonomy.evaluation.evaluate`: load the demonstrations
(:func:`study.jobs.demonstrations.load_demonstrations`, moving ticks), read the model file
named by ``--model`` (default: the shipped model) for its training recipe, evaluate, and
print tables (or ``--json``; ``--out FILE`` also writes the JSON).

Decisions where the brief is silent:

- ``--model`` names the model whose demonstrations and recipe are evaluated: the
  cross-validation trains a fresh SOGP per fold (a model trained on all runs would be
  tested on its own training data), on the model's way-point ``stride``. Its capacity,
  evidence subsample, length-scale cap and claim thresholds are the evaluation's own
  (:class:`autonomy.evaluation.EvaluationSettings`: capacity 1200 with the posterior
  refined on the chosen basis, 1000 points, the cap and a claim threshold per task type
  by inner cross-validation): the shipped model's capacity (250) is a
  run-time budget (a model file under 5 MB, a cheap tick), while the evaluation measures
  what the classifier can do, which rises with the capacity towards the full GP (see
  the module docstring of :mod:`autonomy.evaluation`). One evidence restart per GP. The
  file is validated like any model file (a bad one is a ValueError naming it).
- ``--repeats R`` evaluates with the seeds ``--seed`` to ``--seed + R - 1`` (each its own
  folds and draws) and adds the F0.5's mean and standard deviation over them, and the
  share of seeds in which the SOGP is at least every baseline (JSON ``repeats``; the
  other keys are the first seed's). One seed's comparison moves by a few hundredths with
  the draws alone; R times the run time.
- ``--workers`` (default: the number of CPUs) runs the folds and the introspection pairs
  in that many ``spawn`` worker processes, one BLAS thread each; the result is the same
  for any number of workers (every job has its own seed).
- The task types' target kinds come from :data:`tasks.contextual.TARGET_KIND`.
- Without ``--demonstrations`` the demonstrations behind the model are used: the cache
  folder (``$ASA_CACHE``, else ``$XDG_CACHE_HOME/asa-study``, else
  ``~/.cache/asa-study``) holds them in a subfolder named by the first 16 hex digits of
  the model's ``metadata["data_sha256"]``. When that folder is missing they are recorded
  with the shipped model's recipe (``autonomy/models/README.md``: ``asa demonstrations
  record --task all --runs 12 --seed 7``, :data:`RECIPE`; about 15 s) into a temporary
  sibling folder, their hash is checked against the model's (a mismatch is a
  ValueError: the recorder changed, or the model was not trained on that recipe; pass
  ``--demonstrations``) and the folder is then renamed into place, so an interrupted
  recording never leaves a half-filled cache. A cached folder is re-checked on every use.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import multiprocessing
import os
import shutil
from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from autonomy.evaluation import EvaluationSettings, evaluate, format_report, summarise_repeats
from autonomy.model import DEFAULT_MODEL, load_model
from study._blas import limit_blas_threads

RECIPE = {"task": "all", "runs": 12, "seed": 7}  # autonomy/models/README.md

_FROM_MODEL = ("stride",)  # the model's settings the evaluation takes over


def cache_root() -> Path:
    """``$ASA_CACHE``, else ``$XDG_CACHE_HOME/asa-study``, else ``~/.cache/asa-study``."""
    if os.environ.get("ASA_CACHE"):
        return Path(os.environ["ASA_CACHE"])
    if os.environ.get("XDG_CACHE_HOME"):
        return Path(os.environ["XDG_CACHE_HOME"]) / "asa-study"
    return Path.home() / ".cache" / "asa-study"


def cached_demonstrations(
    data_sha256: str,
    *,
    task: str = RECIPE["task"],
    runs: int = RECIPE["runs"],
    seed: int = RECIPE["seed"],
    where: str = "model",
) -> tuple[Path, bool]:
    """The cached demonstrations whose moving ticks hash to ``data_sha256``, recording
    them (``task``, ``runs``, ``seed`` as ``asa demonstrations record``) if missing.

    Returns
    -------
    directory : pathlib.Path
        ``cache_root() / data_sha256[:16]``.
    recorded : bool
        Whether they were recorded now.

    Raises
    ------
    ValueError
        Naming ``where`` and the folder, if the demonstrations (cached or recorded) do
        not hash to ``data_sha256``.
    """
    from autonomy.training import data_sha256 as hash_of
    from study.jobs.demonstrations import load_demonstrations, plan_recording, record_demonstrations

    if not (isinstance(data_sha256, str) and len(data_sha256) >= 16):
        raise ValueError(f"{where}: field 'metadata.data_sha256': missing, cannot find its data")
    final = cache_root() / data_sha256[:16]
    recorded = not (final / "manifest.json").is_file()
    folder = final
    if recorded:
        folder = final.parent / f".{final.name}.recording-{os.getpid()}"
        shutil.rmtree(folder, ignore_errors=True)
        record_demonstrations(folder, plan_recording(task, None), runs, seed=seed)
    got = hash_of(load_demonstrations(folder).q)
    if got != data_sha256:
        if recorded:
            shutil.rmtree(folder, ignore_errors=True)
        raise ValueError(
            f"{where}: field 'metadata.data_sha256': the demonstrations "
            f"{'recorded with --task ' + task if recorded else 'cached in ' + str(final)}"
            f"{f' --runs {runs} --seed {seed}' if recorded else ''} hash to {got[:16]}..., "
            f"the model to {data_sha256[:16]}...; pass --demonstrations DIR"
        )
    if recorded:
        try:
            folder.rename(final)
        except OSError:  # another process filled the cache meanwhile
            shutil.rmtree(folder, ignore_errors=True)
    return final, recorded


def run_evaluation(
    demonstrations: str | Path | None,
    *,
    model: str | Path | None = None,
    folds: int = 5,
    seed: int = 0,
    workers: int = 1,
    repeats: int = 1,
) -> dict[str, Any]:
    """Evaluate on the demonstrations in ``demonstrations`` (see the module docstring),
    with ``workers`` processes; with ``repeats`` > 1 again with seeds ``seed + 1``, ...,
    the result being the first seed's with their summary under ``"repeats"``
    (:func:`autonomy.evaluation.summarise_repeats`).

    Raises
    ------
    ValueError
        Unreadable demonstrations or model file (naming the file and field), ``folds``
        outside [2, number of runs], ``workers`` or ``repeats`` below 1 (checked first,
        before any demonstrations are recorded).
    """
    from study.jobs.demonstrations import load_demonstrations
    from tasks.contextual import TARGET_KIND

    if workers < 1:
        raise ValueError(f"--workers: must be at least 1, got {workers}")
    if repeats < 1:
        raise ValueError(f"--repeats: must be at least 1, got {repeats}")
    settings = EvaluationSettings(folds=folds, seed=seed)
    model_path = Path(DEFAULT_MODEL if model is None else model)
    metadata = load_model(model_path).metadata
    recipe = metadata.get("settings", {})
    overrides = {
        name: recipe[name]
        for name in _FROM_MODEL
        if name in recipe and isinstance(recipe[name], int | float)
    }
    try:
        settings = replace(settings, **overrides)
    except ValueError as error:
        raise ValueError(f"{model_path}: field 'metadata.settings': {error}") from None
    if demonstrations is None:
        demonstrations, _ = cached_demonstrations(
            metadata.get("data_sha256"), where=str(model_path)
        )
    demos = load_demonstrations(demonstrations)
    with contextlib.ExitStack() as stack:
        map_fn = map
        if workers > 1:
            ctx = multiprocessing.get_context("spawn")
            pool = cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=limit_blas_threads)
            map_fn = stack.enter_context(pool).map
        results = [
            evaluate(
                demos,
                kinds=TARGET_KIND,
                settings=replace(settings, seed=seed + i),
                model=str(model_path),
                where=str(demonstrations),
                map_fn=map_fn,
            )
            for i in range(repeats)
        ]
    result = results[0]
    if repeats > 1:
        result["repeats"] = summarise_repeats(results)
    return result


@click.command("evaluate")
@click.option(
    "--demonstrations",
    "demonstrations",
    default=None,
    type=click.Path(path_type=Path),
    help="Directory written by `asa demonstrations record` (default: the model's own "
    "demonstrations, cached; recorded again if missing).",
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
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the folds etc.")
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
    out: Path | None,
) -> None:
    """Cross-validated F0.5, introspection and trajectory rates of the recognisers."""
    if out is not None and out.is_dir():
        raise ValueError(f"{out}: --out must be a file path (e.g. evaluation.json)")
    workers = (os.cpu_count() or 1) if workers is None else workers
    result = run_evaluation(
        demonstrations, model=model, folds=folds, seed=seed, workers=workers, repeats=repeats
    )
    text = json.dumps(result, indent=2, sort_keys=True)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text + "\n")
    click.echo(text if as_json else format_report(result))
