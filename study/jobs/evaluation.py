"""The evaluation runner behind ``asa evaluate`` (thesis Sec. 7.2.2, 7.3, 7.4; issue 3,
"Offline evaluation"): the model's recipe, the demonstrations behind it (cached, or
recorded again), worker processes, and repeats with further seeds, around
:func:`autonomy.evaluation.evaluate`. Choices: docs/decisions.md."""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import shutil
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from autonomy.evaluation import EvaluationSettings, evaluate, summarise_repeats
from autonomy.model import DEFAULT_MODEL, load_model

RECIPE = {"task": "all", "runs": 12, "seed": 7}  # autonomy/models/README.md

_FROM_MODEL = ("stride",)  # the model's settings the evaluation takes over


@dataclass(frozen=True, slots=True)
class DemonstrationsMismatch:
    """The demonstrations found for a model (cached, or recorded now from its recipe) do
    not hash to its ``metadata["data_sha256"]``: recorded on a machine whose CPU rounds
    differently (docs/decisions.md, "Reproducibility across machines"), or a cache
    folder holding other data. Not an error: the evaluation runs on them and says so."""

    where: str  # the model file
    folder: Path
    recorded: bool  # recorded now (else found in the cache)
    recipe: dict[str, Any]  # task, runs, seed of ``asa demonstrations record``
    got: str
    expected: str

    def text(self, *, flags: bool = False) -> str:
        """One line naming both hashes; ``flags``: the recipe as command-line flags."""
        if not self.recorded:
            source = f"cached in {self.folder}"
        elif flags:
            r = self.recipe
            source = f"recorded with --task {r['task']} --runs {r['runs']} --seed {r['seed']}"
        else:
            source = "recorded with " + ", ".join(f"{k}={v!r}" for k, v in self.recipe.items())
        return (
            f"{self.where}: field 'metadata.data_sha256': the demonstrations {source} hash to "
            f"{self.got[:16]}..., the model's to {self.expected[:16]}... (another machine's "
            "rounding, or other data); evaluating on these"
        )


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
) -> tuple[Path, bool, DemonstrationsMismatch | None]:
    """The cached demonstrations of the model whose data hash to ``data_sha256``,
    recording them (``task``, ``runs``, ``seed`` as ``asa demonstrations record``) if
    missing.

    They are recorded into a temporary sibling folder and only then renamed into place,
    so an interrupted recording never leaves a half-filled cache; a cached folder is
    hashed on every use. Demonstrations recorded on another CPU may hash differently
    (floating-point results differ in the last bits): they are kept and used, and the
    difference is returned for the caller to report.

    Returns
    -------
    directory : pathlib.Path
        ``cache_root() / data_sha256[:16]``.
    recorded : bool
        Whether they were recorded now.
    mismatch : DemonstrationsMismatch or None
        Set when they do not hash to ``data_sha256``.

    Raises
    ------
    ValueError
        Naming ``where``, if ``data_sha256`` is missing.
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
    if recorded:
        try:
            folder.rename(final)
        except OSError:  # another process filled the cache meanwhile
            shutil.rmtree(folder, ignore_errors=True)
    mismatch = None
    if got != data_sha256:
        recipe = {"task": task, "runs": runs, "seed": seed}
        mismatch = DemonstrationsMismatch(where, final, recorded, recipe, got, data_sha256)
    return final, recorded, mismatch


def model_recipe(metadata: dict[str, Any]) -> dict[str, Any]:
    """How the model's demonstrations were recorded (``metadata["recipe"]["record"]``:
    task, runs, seed), the shipped model's :data:`RECIPE` for a model without one."""
    record = metadata.get("recipe", {}).get("record", {}) if isinstance(metadata, dict) else {}
    ok = isinstance(record, dict) and set(RECIPE) <= set(record)
    return {k: record[k] for k in RECIPE} if ok else dict(RECIPE)


def run_evaluation(
    demonstrations: str | Path | None,
    *,
    model: str | Path | None = None,
    folds: int = 5,
    seed: int = 0,
    workers: int = 1,
    repeats: int = 1,
    progress: Callable[[int, int], None] | None = None,
    warn: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Evaluate the model's recipe on the demonstrations in ``demonstrations``.

    The way-point ``stride`` comes from the ``model`` file (default: the shipped model),
    the rest of the settings are the evaluation's own; without ``demonstrations`` the
    model's own are used (:func:`cached_demonstrations`). ``workers`` > 1 runs the jobs
    in that many ``spawn`` processes, one BLAS thread each (same result); with
    ``repeats`` > 1 the evaluation is repeated with seeds ``seed + 1``, ..., the result
    being the first seed's with their summary under ``"repeats"``
    (:func:`autonomy.evaluation.summarise_repeats`). ``progress(done, total)`` is called
    as each job (fold or introspection pair) of each repeat finishes, counting over all
    repeats (``total`` = repeats x jobs per evaluation). ``warn(line)`` is told when the
    model's own demonstrations, recorded again from its recipe (:func:`model_recipe`),
    hash differently than the model says (another CPU); the result's
    ``"demonstrations"`` names both hashes. The candidates' passage normals, which the
    kind-and-time recogniser reads and the recorder does not store, come from the runs'
    scenes (:func:`study.jobs.demonstrations.candidate_normals`); ``warn`` is told of
    runs left without them, and the result's ``"passage_normals"`` counts them.

    Raises
    ------
    ValueError
        Unreadable demonstrations or model file (naming the file and field), ``folds``
        outside [2, number of runs], ``workers`` outside 1..1024 or ``repeats`` outside
        1..1000 (checked first, before any demonstrations are recorded).
    """
    from study.jobs.demonstrations import candidate_normals, load_demonstrations
    from tasks.contextual import TARGET_KIND

    if not 1 <= workers <= 1024:
        raise ValueError(f"workers: must be at least 1 and at most 1024, got {workers}")
    if not 1 <= repeats <= 1000:
        raise ValueError(f"repeats: must be at least 1 and at most 1000, got {repeats}")
    settings = EvaluationSettings(folds=folds, seed=seed)
    model_path = Path(DEFAULT_MODEL if model is None else model)
    metadata = load_model(model_path).metadata
    settings = _with_model_recipe(settings, metadata, model_path)
    if demonstrations is None:
        demonstrations, provenance = _model_demonstrations(metadata, model_path, warn)
    else:
        provenance = {"folder": str(demonstrations)}
    demos = load_demonstrations(demonstrations)
    normals, missing = candidate_normals(demos)
    if missing and warn is not None:
        warn(
            f"{demonstrations}: {len(missing)} of {len(demos.runs)} runs are in scenes that are "
            f"not shipped ({', '.join(sorted(set(missing)))}): no passage normals there, the "
            "kind-and-time recogniser's axis cue is off on them"
        )
    with contextlib.ExitStack() as stack:
        map_fn: Any = map
        if workers > 1:
            from study._blas import limit_blas_threads

            ctx = multiprocessing.get_context("spawn")
            pool = cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=limit_blas_threads)
            map_fn = _as_completed_map(stack.enter_context(pool))
        results = [
            evaluate(
                demos,
                kinds=TARGET_KIND,
                settings=replace(settings, seed=seed + i),
                model=str(model_path),
                where=str(demonstrations),
                map_fn=map_fn,
                progress=None if progress is None else _across_repeats(progress, i, repeats),
                normals=normals,
            )
            for i in range(repeats)
        ]
    result = results[0]
    result["demonstrations"] = provenance
    result["passage_normals"] = {"runs": len(demos.runs) - len(missing), "of": len(demos.runs)}
    if repeats > 1:
        result["repeats"] = summarise_repeats(results)
    return result


def _model_demonstrations(
    metadata: dict[str, Any], model_path: Path, warn: Callable[[str], None] | None
) -> tuple[Path, dict[str, Any]]:
    """The model's own demonstrations (:func:`cached_demonstrations` with its recipe) and
    where they came from, for the result's ``"demonstrations"``; ``warn`` is told when they
    hash otherwise than the model's data."""
    recipe = model_recipe(metadata)
    expected = metadata.get("data_sha256")
    folder, _, mismatch = cached_demonstrations(expected, where=str(model_path), **recipe)
    if mismatch is not None and warn is not None:
        warn(mismatch.text(flags=True))
    return folder, {
        "folder": str(folder),
        "recipe": recipe,
        "model_data_sha256": expected,
        "data_sha256": expected if mismatch is None else mismatch.got,
        "same_as_model": mismatch is None,
    }


def _as_completed_map(
    pool: cf.Executor,
) -> Callable[[Callable[[Any], Any], Iterable[Any]], Iterator[Any]]:
    """A ``map`` over ``pool`` that yields the results as the jobs finish (not in
    order), so progress is counted when a job ends; the jobs not yet started are
    cancelled if one fails or the caller stops early."""

    def map_fn(fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        futures = [pool.submit(fn, item) for item in items]
        try:
            for future in cf.as_completed(futures):
                yield future.result()
        finally:
            for future in futures:
                future.cancel()

    return map_fn


def _across_repeats(
    progress: Callable[[int, int], None], repeat: int, repeats: int
) -> Callable[[int, int], None]:
    """``progress`` of one repeat's jobs, counted over all ``repeats``."""

    def report(done: int, total: int) -> None:
        progress(repeat * total + done, repeats * total)

    return report


def _with_model_recipe(
    settings: EvaluationSettings, metadata: dict[str, Any], model_path: Path
) -> EvaluationSettings:
    """``settings`` with the model's training settings (``metadata["settings"]``) named
    in ``_FROM_MODEL``; a bad value is a ValueError naming ``model_path``."""
    recipe = metadata.get("settings", {})
    overrides = {
        name: recipe[name]
        for name in _FROM_MODEL
        if name in recipe and isinstance(recipe[name], int | float)
    }
    try:
        return replace(settings, **overrides)
    except ValueError as error:
        raise ValueError(f"{model_path}: field 'metadata.settings': {error}") from None
