"""The training job behind ``asa train`` (thesis Sec. 6.2, 7.4.1; issue 3,
"Demonstrations and training"): recorded demonstrations in, a model file out."""

from __future__ import annotations

from pathlib import Path

from autonomy.model import ContextualModel, save_model
from autonomy.training import DemoCandidates, TrainSettings, train


def train_model(
    demonstrations: str | Path,
    out: str | Path,
    *,
    seed: int = 0,
    settings: TrainSettings | None = None,
    force: bool = False,
) -> ContextualModel:
    """Train on the moving ticks of the demonstrations in ``demonstrations``
    (:func:`autonomy.training.train`) and save the model to ``out``.

    The same demonstrations and ``seed`` reproduce the same model (arrays identical; only
    the creation date in the metadata differs), which is how the shipped model
    ``autonomy/models/default.npz`` is checked (``autonomy/models/README.md``).

    An existing ``out`` is replaced only with ``force`` (checked before training and
    again before writing).

    Raises
    ------
    ValueError
        For unreadable demonstrations (naming the file and field), too few points, an
        ``out`` that is a directory, or an existing ``out`` without ``force``.
    """
    from study.data.paths import refuse_existing
    from study.jobs.demonstrations import load_demonstrations

    out = Path(out)
    if out.exists() and out.is_dir():
        raise ValueError(f"{out}: out must be a file path (e.g. model.npz), not a directory")
    refuse_existing([out], force=force)
    demos = load_demonstrations(demonstrations)
    if len(demos) == 0:
        raise ValueError(f"{demonstrations}: no moving ticks in these demonstrations")
    model = train(
        demos.q,
        seed=seed,
        settings=settings,
        task=demos.task,
        run=demos.run,
        source=Path(demonstrations).name,
        candidates=DemoCandidates(
            points=demos.cand_points,
            offsets=demos.cand_offsets,
            ids=demos.cand_ids,
            target=demos.target,
            kinds=demos.cand_kinds,
        ),
        executing=demos.phase != "approach",
    )
    recipe = recording_recipe(demonstrations)
    if recipe is not None:
        model.metadata["recipe"] = {"record": recipe, "train": {"seed": int(seed)}}
    refuse_existing([out], force=force)  # made meanwhile by another process?
    save_model(model, out)
    return model


def recording_recipe(demonstrations: str | Path) -> dict[str, object] | None:
    """The ``asa demonstrations record`` flags that made the folder ``demonstrations``
    (``{"task", "runs", "seed"}``, read from its manifest), or None when no single call
    made it (several seeds, unequal runs per task, scenes other than the tasks' own), so
    that ``asa evaluate`` can record the model's data again on another machine."""
    import json

    from tasks.contextual import DEFAULT_SCENES, DEMONSTRATED

    try:
        manifest = json.loads((Path(demonstrations) / "manifest.json").read_text())
        runs = manifest["runs"]
        per_task: dict[str, int] = {}
        for run in runs:
            if run["scene"] != DEFAULT_SCENES[run["task"]] or run["seed"] != manifest["seed"]:
                return None
            per_task[run["task"]] = per_task.get(run["task"], 0) + 1
        seed = int(manifest["seed"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if len(set(per_task.values())) != 1:
        return None
    if set(per_task) == set(DEMONSTRATED):
        task = "all"
    elif len(per_task) == 1:
        task = next(iter(per_task))
    else:
        return None
    return {"task": task, "runs": next(iter(per_task.values())), "seed": seed}
