"""Benchmark group ``map_semantics``: semantic components from a map image against those
of the exact geometry (issue 23; thesis appendix Alg. 4-5).

Agreement: the doorways and gaps found in SLAM-like noisy renderings
(:func:`sim.map_noise.noisy_scene_map`) of every shipped scene, and in the exact and one
noisy rendering of generated floor plans, against the geometry-derived ones (a match
within ``MATCH_M``): true passages found, found ones matching none, true ones missed,
and how many matched ones have the geometry's kind. Recognition: one synthetic
participant drives the contextual mode's main trial twice in each scene, once with the
geometry's components and once with those of a noisy map of the scene; the person's own
task labels come from the geometry both times, so the two task matches differ only by
the components the assistance reads. The figures are listed in :func:`run`.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import tempfile
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from sim.generate import generate_scene
from sim.map_files import save_ros_map
from sim.map_noise import noisy_scene_map
from sim.occupancy import build_grid
from sim.scenario import available_scenarios, load_scenario, parse_scenario
from sim.semantics import derive_components
from sim.semantics.map_image import prepare_map
from sim.semantics.map_passages import map_passages
from sim.toml_text import dumps
from study._blas import limit_blas_threads
from study.bench.recognition import write_generated
from study.engine.recognition import RecognitionTally
from study.engine.standalone import standalone_trial
from study.participants.synthetic import synthetic_participant

MATCH_M = 0.3  # [m] a found passage matches a true one this close (issue 23)
NOISE_SEEDS = tuple(range(60, 80))  # noisy renderings of each shipped scene; quick: 3
GENERATED_SEEDS = tuple(range(300, 360))  # generated floor plans; quick: the first 10
RECOGNITION_SEEDS = tuple(range(100, 110))  # generated scenes driven twice; quick: first 2
TIMEOUT_S = 600.0  # [s] simulated, as the scenes group
_SEED = 2311


def agreement(scenario: Any, grid: Any) -> dict[str, int]:
    """Doorways and gaps of ``grid`` (a map of ``scenario``) against the geometry's:
    ``found`` (true passages with a match), ``extra`` (found ones matching none),
    ``missed``, ``same_kind`` (matched found ones of the geometry's kind)."""
    truth = [c for c in derive_components(scenario) if c.kind in ("doorway", "gap")]
    found = map_passages(prepare_map(grid, scenario.tables), scenario)
    if not truth or not found:
        return {"found": 0, "extra": len(found), "missed": len(truth), "same_kind": 0}
    d = np.linalg.norm(
        np.array([p.centre for p in found])[:, None] - np.array([c.centre for c in truth])[None],
        axis=2,
    )
    nearest = d.argmin(axis=1)
    matched = d.min(axis=1) <= MATCH_M
    kinds = [p.kind == truth[j].kind for p, j in zip(found, nearest, strict=True)]
    return {
        "found": int((d.min(axis=0) <= MATCH_M).sum()),
        "extra": int((~matched).sum()),
        "missed": int((d.min(axis=0) > MATCH_M).sum()),
        "same_kind": int((np.array(kinds) & matched).sum()),
    }


def _rates(counts: dict[str, int]) -> dict[str, Any]:
    hit, extra, missed = counts["found"], counts["extra"], counts["missed"]
    return {
        **counts,
        "precision": round(hit / (hit + extra), 4) if hit + extra else 1.0,
        "recall": round(hit / (hit + missed), 4) if hit + missed else 1.0,
    }


def _add(total: dict[str, int], more: dict[str, int]) -> dict[str, int]:
    return {k: total.get(k, 0) + v for k, v in more.items()}


def shipped_agreement(quick: bool) -> dict[str, dict[str, Any]]:
    """Per shipped scene, the counts of :func:`agreement` summed over its noisy
    renderings (:data:`NOISE_SEEDS`) with precision and recall."""
    out = {}
    for name in available_scenarios():
        sc = load_scenario(name)
        total: dict[str, int] = {}
        for seed in NOISE_SEEDS[: 3 if quick else None]:
            total = _add(total, agreement(sc, noisy_scene_map(sc, np.random.default_rng(seed))))
        out[name] = _rates(total)
    return out


def generated_agreement(quick: bool) -> dict[str, Any]:
    """The counts of :func:`agreement` over the exact and one noisy rendering of each
    generated floor plan of :data:`GENERATED_SEEDS`, with precision and recall."""
    total: dict[str, int] = {}
    for seed in GENERATED_SEEDS[: 10 if quick else None]:
        sc = parse_scenario(generate_scene(np.random.default_rng(seed)), f"generated_{seed}")
        total = _add(total, agreement(sc, build_grid(sc)))
        noisy = noisy_scene_map(sc, np.random.default_rng([_SEED, seed]))
        total = _add(total, agreement(sc, noisy))
    return _rates(total)


def _with_noisy_map(path: Path, seed: int) -> Path:
    """A copy of the scenario file ``path`` whose semantics read a noisy map of it."""
    sc = load_scenario(path)
    save_ros_map(noisy_scene_map(sc, np.random.default_rng([_SEED, seed])), path.parent, "map")
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    data["semantics"] = {**data.get("semantics", {}), "source": "map", "map": "map.yaml"}
    out = path.with_name(f"{path.stem}_map.toml")
    out.write_text(dumps(data), encoding="utf-8")
    return out


def drive_both(seed: int) -> dict[str, Any]:
    """One synthetic participant's contextual main trial in generated scene ``seed``,
    with geometry and with noisy-map semantics: per source ``completed`` and the trial's
    ``recognition`` counts."""
    with tempfile.TemporaryDirectory(prefix="asa-bench-mapsem-") as tmp:
        folder = Path(tmp)
        (path,) = write_generated(folder, (seed,))
        scenes = {"geometry": Path(path), "map": _with_noisy_map(Path(path), seed)}
        row: dict[str, Any] = {"seed": seed}
        for source, scene in scenes.items():
            person = synthetic_participant(np.random.default_rng([_SEED, seed]))
            person.label_semantics = "geometry"
            result, engine = standalone_trial(
                folder,
                person,
                mode="contextual_task",
                scenario=str(scene),
                inspection=bool(load_scenario(scene).inspection_object),
                timeout_s=TIMEOUT_S,
                seed=seed,
                database=f"{source}.db",
                record=False,
            )
            engine.dispose()
            row[source] = {
                "completed": bool(result.outcome.get("completed")),
                "recognition": result.outcome.get("recognition"),
            }
    return row


def _tally(rows: list[dict[str, Any]], source: str) -> dict[str, Any]:
    """The pooled recognition summary of ``source``'s trials in ``rows``."""
    tally = RecognitionTally({})
    for r in rows:
        if r[source]["recognition"] is not None:
            tally.merge(RecognitionTally.from_summary(r[source]["recognition"]))
    return tally.summary()


def recognition(quick: bool, workers: int = 2) -> dict[str, Any]:
    """The task match of the contextual mode with geometry and with map semantics over
    the scenes of :data:`RECOGNITION_SEEDS` (:func:`drive_both`)."""
    seeds = RECOGNITION_SEEDS[: 2 if quick else None]
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=limit_blas_threads
    ) as pool:
        rows = list(pool.map(drive_both, seeds))
    summaries = {s: _tally(rows, s) for s in ("geometry", "map")}
    geometry = summaries["geometry"].get("loop_task_match")
    mapped = summaries["map"].get("loop_task_match")
    return {
        "map_recognition_seeds": list(seeds),
        "geometry_task_match": geometry,
        "map_task_match": mapped,
        "map_task_match_gap": (
            round(abs(mapped - geometry), 4) if None not in (geometry, mapped) else None
        ),
        "map_completion": {
            s: round(float(np.mean([r[s]["completed"] for r in rows])), 4)
            for s in ("geometry", "map")
        },
        "map_recognition_per_task": {
            s: {task: v.get("loop_task_match") for task, v in summary["per_task"].items()}
            for s, summary in summaries.items()
        },
    }


def run(quick: bool) -> dict[str, Any]:
    """``map_passages_per_scene`` (per shipped scene: found, extra, missed, same_kind,
    precision, recall over its noisy renderings), ``map_passage_precision_min`` and
    ``map_passage_recall_min`` (over the shipped scenes with passages),
    ``map_generated_passages`` (pooled over generated floor plans), and the recognition
    figures of :func:`recognition`: ``geometry_task_match``, ``map_task_match``,
    ``map_task_match_gap`` (their absolute difference), ``map_completion`` and
    ``map_recognition_per_task`` (per source, the task match of each true task)."""
    per_scene = shipped_agreement(quick)
    with_passages = [v for v in per_scene.values() if v["found"] + v["missed"] > 0]
    return {
        "map_noise_seeds": list(NOISE_SEEDS[: 3 if quick else None]),
        "map_passages_per_scene": per_scene,
        "map_passage_precision_min": min(v["precision"] for v in with_passages),
        "map_passage_recall_min": min(v["recall"] for v in with_passages),
        "map_generated_passages": generated_agreement(quick),
        **recognition(quick),
    }
