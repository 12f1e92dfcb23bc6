"""Scenes from ROS maps (``asa scenario from-map``, sim.map_scene; issue 23): the
rectangles cover exactly the occupied cells, a map survives grid -> files -> scene ->
grid, the example map's scene passes the checker, bad maps and placements give one line
and exit 2, and a synthetic study runs on the example map's scene."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.map_files import load_ros_map, save_ros_map
from sim.map_noise import MapNoise, noisy_occupancy
from sim.map_scene import occupied_rectangles, scene_from_map, write_scene_from_map
from sim.occupancy import OccupancyGrid, build_grid
from sim.scenario import load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
MAPS = ROOT / "examples" / "maps"
EXAMPLE = MAPS / "cluttered_room_noisy.yaml"
ADDITIONS = MAPS / "cluttered_room_noisy.additions.toml"


def _cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=cwd,
    )


def _painted(rects: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    out = np.zeros(shape, dtype=bool)
    for r0, c0, r1, c1 in rects:
        out[r0:r1, c0:c1] = True
    return out


@pytest.mark.parametrize("density", [0.02, 0.3, 0.7])
def test_rectangles_cover_exactly_the_occupied_cells(seed, density):
    rng = np.random.default_rng(seed)
    for _ in range(20):
        shape = tuple(int(v) for v in rng.integers(1, 40, size=2))
        occupied = rng.random(shape) < density
        rects = occupied_rectangles(occupied)
        assert np.array_equal(_painted(rects, shape), occupied)
        assert np.all(rects[:, 2] > rects[:, 0]) and np.all(rects[:, 3] > rects[:, 1])


def test_rectangles_merge_walls(seed):
    occupied = np.zeros((60, 80), dtype=bool)
    occupied[10:12, 5:75] = True  # a horizontal wall
    occupied[10:55, 40:42] = True  # a vertical one across it
    assert len(occupied_rectangles(occupied)) <= 3
    noisy = noisy_occupancy(occupied, np.random.default_rng(seed))
    assert np.array_equal(_painted(occupied_rectangles(noisy), noisy.shape), noisy)


def test_noise_is_seeded_and_changes_the_map(seed):
    exact = build_grid(load_scenario("cluttered_room")).occupied
    a = noisy_occupancy(exact, np.random.default_rng(seed))
    b = noisy_occupancy(exact, np.random.default_rng(seed))
    assert np.array_equal(a, b) and not np.array_equal(a, exact)
    with pytest.raises(ValueError, match="speckle_p"):
        MapNoise(speckle_p=2.0)


def test_map_round_trip_keeps_the_occupied_cells(tmp_path, seed):
    """grid -> ROS map files -> scene -> grid: the same cells (here exactly; within a
    cell is the promise), away from the start pose's cell."""
    rng = np.random.default_rng(seed)
    occupied = rng.random((50, 70)) < 0.05
    occupied[:, 0] = occupied[:, -1] = occupied[0] = occupied[-1] = True
    occupied[20:30, 30:40] = False  # room for A
    grid = OccupancyGrid(occupied, (-1.25, 2.5), 0.05)
    save_ros_map(grid, tmp_path, "m")
    data = scene_from_map(
        tmp_path / "m.yaml", {"start": {"x": 0.5, "y": 3.8, "yaw_deg": 0.0}}, source="t"
    )
    back = build_grid(parse_scenario(data, "t"), resolution=0.05)
    assert back.origin == pytest.approx(grid.origin) and back.shape == grid.shape
    assert np.array_equal(back.occupied, occupied)


def test_example_map_is_what_its_script_makes(tmp_path):
    from examples.maps.make_map import SEED  # noqa: PLC0415 (the script's own seed)
    from sim.map_noise import noisy_scene_map

    grid = noisy_scene_map(load_scenario("cluttered_room"), np.random.default_rng(SEED))
    assert load_ros_map(EXAMPLE) == grid


def test_cli_writes_a_scene_the_checker_accepts(tmp_path):
    out = tmp_path / "s.toml"
    done = _cli(
        "scenario", "from-map", str(EXAMPLE), "--additions", str(ADDITIONS), "--out", str(out)
    )
    assert done.returncode == 0, done.stderr
    assert "walls" in done.stdout
    checked = _cli("scenario", "check", str(out))
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.startswith("ok")


def test_flags_place_a_table_the_dock_and_the_object(tmp_path):
    path, counts = write_scene_from_map(
        EXAMPLE,
        tmp_path / "s.toml",
        placements={
            "start": {"x": 1.5, "y": 2.4, "yaw_deg": 0.0},
            "dock": {"x": 1.0, "y": 7.6, "yaw_deg": 180.0},
            "tables": [{"name": "table", "centre": [1.0, 7.6]}],
            "inspect": {"centre": [7.0, 8.0]},
        },
    )
    s = load_scenario(path)
    assert s.dock.table == "table" and s.tables[0].size == (1.2, 0.9)
    assert s.inspection_object == "inspect_object"
    assert counts["walls"] > 0 and len(s.walls) == counts["walls"]


def _write_map(tmp_path: Path, yaml: str, image: bytes | None = b"P5\n4 3\n255\n" + bytes(12)):
    if image is not None:
        (tmp_path / "m.pgm").write_bytes(image)
    (tmp_path / "m.yaml").write_text(yaml)
    return tmp_path / "m.yaml"


GOOD_YAML = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
BAD_MAPS = [
    ("missing-image", GOOD_YAML, None, "field 'image'"),
    ("bad-resolution", GOOD_YAML.replace("0.05", "fast"), ..., "field 'resolution'"),
    ("unsupported-mode", GOOD_YAML + "mode: blend\n", ..., "field 'mode'"),
    ("rotated", GOOD_YAML.replace("0, 0, 0", "0, 0, 0.5"), ..., "field 'origin'"),
    ("not-an-image", GOOD_YAML, b"hello", "field 'image'"),
]


@pytest.mark.parametrize(
    ("case", "yaml", "image", "needle"), BAD_MAPS, ids=[c[0] for c in BAD_MAPS]
)
def test_bad_map_gives_one_line_and_exit_2(tmp_path, case, yaml, image, needle):
    kwargs = {} if image is ... else {"image": image}
    path = _write_map(tmp_path, yaml, **kwargs)
    done = _cli("scenario", "from-map", str(path), "--start", "0.1,0.1,0", "--out", "x.toml")
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and needle in done.stderr
    assert str(path) in done.stderr


BAD_PLACEMENTS = [
    ("start-in-wall", ["--start", "0,0,0"], "field 'start'"),
    ("dock-off-map", ["--start", "1.5,2.4,0", "--dock", "30,1,0"], "field 'dock'"),
    ("start-short", ["--start", "1.5,2.4"], "--start"),
    ("no-start", ["--inspect", "7,8"], "field 'start'"),
    ("table-bad", ["--start", "1.5,2.4,0", "--table", "1,x,0"], "--table"),
]


@pytest.mark.parametrize(
    ("case", "flags", "needle"), BAD_PLACEMENTS, ids=[c[0] for c in BAD_PLACEMENTS]
)
def test_bad_placement_gives_one_line_and_exit_2(tmp_path, case, flags, needle):
    done = _cli("scenario", "from-map", str(EXAMPLE), *flags, "--out", str(tmp_path / "s.toml"))
    assert done.returncode == 2, done.stdout
    assert len(done.stderr.strip().splitlines()) == 1 and needle in done.stderr
    assert not (tmp_path / "s.toml").exists()


@pytest.mark.parametrize(
    ("text", "needle"),
    [("[map]\nwall_height = -1\n", "map.wall_height"), ("colour = 3\n", "field 'colour'")],
)
def test_bad_additions_file_names_the_field(tmp_path, text, needle):
    additions = tmp_path / "a.toml"
    additions.write_text(text + "[start]\nx = 1.5\ny = 2.4\n")
    with pytest.raises(ValueError, match=needle) as error:
        write_scene_from_map(EXAMPLE, tmp_path / "s.toml", additions_file=additions)
    assert str(additions) in str(error.value)


SYNTH = """
[study]
name = "from-map-synth"
participants = 2
seed = 5

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"

[[phases]]
kind = "main"
scenario = "SCENE"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 120.0
"""


@pytest.mark.slow
def test_synthetic_study_on_the_example_map(tmp_path):
    scene = tmp_path / "scene.toml"
    done = _cli(
        "scenario", "from-map", str(EXAMPLE), "--additions", str(ADDITIONS), "--out", str(scene)
    )
    assert done.returncode == 0, done.stderr
    protocol = tmp_path / "p.toml"
    protocol.write_text(SYNTH.replace("SCENE", str(scene)))
    done = _cli(
        "synth", "--protocol", str(protocol), "--participants", "2", "--seed", "3",
        "--workers", "1", "--db", str(tmp_path / "t.db"),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "manual" in done.stdout and "reactive_bn" in done.stdout


def test_scenes_without_groups_derive_their_passages_as_before():
    """The closest-parts rule of groups leaves ungrouped scenes alone: the thesis scene's
    doorways, gaps and dock, as derived before groups existed (a gap beside one table leg
    included)."""
    from sim.scenario import load_scenario
    from sim.semantics import derive_components

    found = [
        (c.id, [round(float(v), 4) for v in c.centre])
        for c in derive_components(load_scenario("cluttered_room"))
        if c.kind in ("doorway", "gap", "dock")
    ]
    assert found == [
        ("doorway_0", [4.0, 2.375]), ("doorway_1", [4.0, 7.575]), ("doorway_2", [9.5, 1.275]),
        ("gap_0", [1.245, 6.95]), ("gap_1", [1.7574, 8.3845]), ("gap_2", [3.0079, 4.7295]),
        ("gap_3", [3.4352, 3.8506]), ("gap_4", [5.8, 3.825]), ("gap_5", [7.75, 2.05]),
        ("gap_6", [12.5775, 7.5523]), ("gap_7", [13.9002, 6.9769]), ("dock_table", [1.0, 7.6]),
    ]  # fmt: skip
