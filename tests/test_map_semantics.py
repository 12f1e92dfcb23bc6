"""Semantic components from a map image (``[semantics] source = "map"``; thesis appendix
Alg. 4-5, sim.semantics.map_image and map_passages; issue 23): on the exact rendering of
a scene the doorways and gaps are the geometry's, under SLAM-like noise most of them,
objects keep the scene's names, a map file is read and checked, and from-map scenes read
their map."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.map_files import save_ros_map
from sim.map_noise import noisy_scene_map
from sim.occupancy import OccupancyGrid, build_grid, clearance_map
from sim.scenario import load_scenario, parse_scenario
from sim.semantics import derive_components, with_semantic_source
from sim.semantics.map_image import prepare_map
from sim.semantics.map_passages import map_passages
from sim.toml_text import dumps

ROOT = Path(__file__).resolve().parents[1]
MATCH_M = 0.3  # [m] a found passage matches a true one this close (issue 23)


def _passages(scenario, grid: OccupancyGrid) -> np.ndarray:
    found = map_passages(prepare_map(grid, scenario.tables), scenario)
    return np.array([p.centre for p in found]).reshape(-1, 2)


def _truth(scenario) -> np.ndarray:
    comps = derive_components(scenario)
    return np.array([c.centre for c in comps if c.kind in ("doorway", "gap")]).reshape(-1, 2)


def _matches(found: np.ndarray, truth: np.ndarray) -> tuple[int, int, int]:
    """(true passages found, found ones matching none, true ones missed)."""
    if len(found) == 0 or len(truth) == 0:
        return 0, len(found), len(truth)
    d = np.linalg.norm(found[:, None] - truth[None], axis=2)
    return (
        int((d.min(0) <= MATCH_M).sum()),
        int((d.min(1) > MATCH_M).sum()),
        int((d.min(0) > MATCH_M).sum()),
    )


@pytest.mark.parametrize(
    "name", ["cluttered_room", "practice_course", "demo_doorway_crossing", "demo_docking"]
)
def test_exact_rendering_gives_the_geometry_passages(name):
    """On the exact rendering: precision and recall at least 0.9 (the map resolves a
    width or depth only to a cell, so a passage within a cell of a threshold may flip)."""
    sc = load_scenario(name)
    hit, extra, missed = _matches(_passages(sc, build_grid(sc)), _truth(sc))
    assert extra <= 0.1 * (hit + extra) and missed <= 0.1 * (hit + missed), (hit, extra, missed)


def test_doorway_or_gap_as_the_geometry_says():
    sc = load_scenario("demo_doorway_crossing")
    by_geometry = {c.kind for c in derive_components(sc) if c.kind in ("doorway", "gap")}
    found = map_passages(prepare_map(build_grid(sc), sc.tables), sc)
    assert {p.kind for p in found} == by_geometry == {"doorway"}


def test_noisy_maps_keep_most_passages(seed):
    sc = load_scenario("cluttered_room")
    truth = _truth(sc)
    hit = extra = missed = 0
    for k in range(3):
        grid = noisy_scene_map(sc, np.random.default_rng([seed, k]))
        h, e, m = _matches(_passages(sc, grid), truth)
        hit, extra, missed = hit + h, extra + e, missed + m
    assert hit / (hit + extra) >= 0.75 and hit / (hit + missed) >= 0.75, (hit, extra, missed)


def test_a_blank_map_has_no_passages_and_a_speckle_is_none():
    sc = load_scenario("demo_object_bypass")
    grid = build_grid(sc)
    occupied = np.zeros_like(grid.occupied)
    assert len(_passages(sc, OccupancyGrid(occupied, grid.origin, grid.resolution))) == 0
    occupied[len(occupied) // 2, len(occupied[0]) // 2] = True  # one speckle cell
    image = prepare_map(OccupancyGrid(occupied, grid.origin, grid.resolution))
    assert not image.grid.occupied.any()


def test_map_components_keep_docks_and_name_the_scene_objects():
    sc = load_scenario("cluttered_room")
    geometry = derive_components(sc)
    mapped = derive_components(with_semantic_source(sc, "map"))
    docks = [c for c in mapped if c.kind == "dock"]
    assert [(c.id, tuple(c.centre)) for c in docks] == [
        (c.id, tuple(c.centre)) for c in geometry if c.kind == "dock"
    ]
    named = [c for c in mapped if c.kind == "object" and sc.inspection_object in c.source]
    assert len(named) == 1
    cylinder = sc.element(sc.inspection_object)
    assert np.linalg.norm(named[0].centre - np.asarray(cylinder.centre)) < 0.1
    walls = [c for c in mapped if c.kind == "wall"]
    assert walls and all(len(c.points) >= 2 for c in walls)
    # objects and walls lie on the scene's obstacles: every point within the closing's
    # reach (two cells) of an occupied cell of the exact rendering
    grid = build_grid(sc)
    clearance = clearance_map(grid)
    for c in mapped:
        if c.kind in ("object", "wall"):
            rc = np.floor((c.points - np.asarray(grid.origin)) / grid.resolution).astype(int)
            assert clearance[rc[:, 1], rc[:, 0]].max() <= 2 * grid.resolution + 1e-9, c.id


def _scene_with_map(tmp_path: Path, semantics: dict) -> Path:
    text = (ROOT / "sim" / "scenarios" / "demo_doorway_crossing.toml").read_text()
    import tomllib

    data = tomllib.loads(text)
    data["semantics"] = {**data.get("semantics", {}), **semantics}
    path = tmp_path / "scene.toml"
    path.write_text(dumps(data))
    return path


def test_scenario_reads_its_map_file(tmp_path, seed):
    sc = load_scenario("demo_doorway_crossing")
    grid = noisy_scene_map(sc, np.random.default_rng(seed))
    save_ros_map(grid, tmp_path / "maps", "noisy")
    path = _scene_with_map(tmp_path, {"source": "map", "map": "maps/noisy.yaml"})
    loaded = load_scenario(path)
    assert loaded.semantics.source == "map"
    assert np.array_equal(loaded.semantics.map_grid.occupied, grid.occupied)
    kinds = [c.kind for c in derive_components(loaded)]
    assert kinds.count("doorway") + kinds.count("gap") >= 1


@pytest.mark.parametrize(
    "semantics, needle",
    [
        ({"source": "map", "map": "missing.yaml"}, "field 'semantics.map': no such map file"),
        ({"map": "missing.yaml"}, "field 'semantics.map'"),
        ({"source": "lidar"}, "field 'semantics.source'"),
    ],
)
def test_bad_semantics_map_gives_one_line_and_exit_2(tmp_path, semantics, needle):
    path = _scene_with_map(tmp_path, semantics)
    with pytest.raises(ValueError, match=needle.replace("(", r"\(")):
        load_scenario(path)
    run = subprocess.run(
        [sys.executable, "-m", "study.cli", "scenario", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "semantics" in lines[0]


def test_switching_source_drops_the_other_sources_overrides():
    sc = load_scenario("cluttered_room")
    removed = dataclasses.replace(sc.semantics, remove=("gap_0",))
    sc = dataclasses.replace(sc, semantics=removed)
    mapped = with_semantic_source(sc, "map")
    assert mapped.semantics.remove == () and mapped.semantics.source == "map"
    assert with_semantic_source(sc, "geometry") is sc


def test_from_map_scene_reads_its_map_unless_told(tmp_path):
    maps = ROOT / "examples" / "maps"
    common = [
        "scenario",
        "from-map",
        str(maps / "cluttered_room_noisy.yaml"),
        "--additions",
        str(maps / "cluttered_room_noisy.additions.toml"),
    ]
    for flags, source in (([], "map"), (["--semantics", "geometry"], "geometry")):
        out = tmp_path / f"{source}.toml"
        run = subprocess.run(
            [sys.executable, "-m", "study.cli", *common, *flags, "--out", str(out)],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert run.returncode == 0, run.stderr
        assert load_scenario(out).semantics.source == source
    sc = load_scenario(tmp_path / "map.toml")
    comps = derive_components(sc)
    assert sum(c.kind == "doorway" for c in comps) >= 2  # the map's doorways in one wall blob
    data = parse_scenario({**_minimal(), "semantics": {"source": "map"}}, "x.toml")
    assert data.semantics.map_grid is None


def _minimal() -> dict:
    return {
        "name": "tiny",
        "bounds": [[0, 0], [4, 4]],
        "start": {"x": 1.0, "y": 1.0, "yaw_deg": 0.0},
        "walls": [{"name": "w", "from": [0, 0], "to": [4, 0], "thickness": 0.1, "height": 1}],
    }
