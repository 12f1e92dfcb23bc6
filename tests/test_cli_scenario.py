"""`asa scenario list|show|map`: output shapes, the PNG and map files, and the bad-input
contract (one stderr line naming file and field, exit status 2, no traceback)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from sim.scenario import available_scenarios
from tests.cli_helpers import asa

ROOM = """
name = "small_room"
description = "two rooms joined by a doorway"
bounds = [[0.0, 0.0], [8.0, 5.0]]
inspection_object = "drum"

[start]
x = 1.0
y = 1.0
yaw_deg = 0.0

[dock]
x = 6.5
y = 4.0
yaw_deg = 90.0
table = "desk"

[[walls]]
name = "south"
from = [0.0, 0.0]
to = [8.0, 0.0]

[[walls]]
name = "north"
from = [0.0, 5.0]
to = [8.0, 5.0]

[[walls]]
name = "west"
from = [0.0, 0.0]
to = [0.0, 5.0]

[[walls]]
name = "east"
from = [8.0, 0.0]
to = [8.0, 5.0]

[[walls]]
name = "divider_a"
from = [4.0, 0.0]
to = [4.0, 2.0]

[[walls]]
name = "divider_b"
from = [4.0, 2.9]
to = [4.0, 5.0]

[[boxes]]
name = "crate"
centre = [2.0, 3.0]
size = [0.6, 0.4]

[[cylinders]]
name = "drum"
centre = [6.0, 1.5]
radius = 0.25

[[tables]]
name = "desk"
centre = [6.5, 4.2]
size = [1.2, 0.8]

[question_region]
polygon = [[4.5, 0.5], [7.5, 0.5], [7.5, 2.5], [4.5, 2.5]]
"""

SHOW_KEYS = {
    "name",
    "source",
    "bounds",
    "start",
    "dock",
    "inspection_object",
    "question_region",
    "components",
    "counts",
}
COMPONENT_KEYS = {"id", "kind", "centre", "ends", "width", "normal", "points_count", "source"}


@pytest.fixture
def room_file(tmp_path: Path) -> Path:
    path = tmp_path / "small_room.toml"
    path.write_text(ROOM, encoding="utf-8")
    return path


def test_show_json_has_the_summary_and_every_component(capsys, room_file):
    code, out, err = asa(capsys, "scenario", "show", room_file, "--json")
    assert code == 0, err
    data = json.loads(out)
    assert SHOW_KEYS <= set(data)
    assert data["name"] == "small_room" and data["source"] == str(room_file)
    assert data["bounds"] == [[0.0, 0.0], [8.0, 5.0]]
    assert data["start"] == {"x": 1.0, "y": 1.0, "yaw_deg": 0.0}
    assert data["dock"]["table"] == "desk" and data["dock"]["yaw_deg"] == 90.0
    assert data["inspection_object"] == "drum" and len(data["question_region"]) == 4
    comps = {c["id"]: c for c in data["components"]}
    assert all(set(c) == COMPONENT_KEYS for c in data["components"])
    assert sum(data["counts"].values()) == len(data["components"])
    door = comps["doorway_0"]
    assert door["kind"] == "doorway" and door["width"] == pytest.approx(0.9)
    assert door["centre"] == pytest.approx([4.0, 2.45]) and len(door["ends"]) == 2
    assert comps["dock_desk"]["centre"] == pytest.approx([6.5, 4.0])
    assert comps["object_drum"]["points_count"] > 0 and comps["object_drum"]["width"] is None
    assert {"wall_south", "object_crate"} <= set(comps)


def test_show_text_lists_the_summary_and_components(capsys, room_file):
    code, out, err = asa(capsys, "scenario", "show", room_file)
    assert code == 0, err
    for needle in ("small_room", "bounds", "start A", "dock B", "inspect", "drum", "question"):
        assert needle in out
    for cid in ("doorway_0", "dock_desk", "object_drum", "object_crate", "wall_divider_a"):
        assert cid in out
    assert "0.900" in out  # the doorway's width


def test_show_png_writes_a_png(capsys, room_file, tmp_path):
    png = tmp_path / "room.png"
    code, out, err = asa(capsys, "scenario", "show", room_file, "--json", "--png", png)
    assert code == 0, err
    json.loads(out)  # stdout stays pure JSON
    data = png.read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 10_000


def test_map_writes_ros_map_and_png(capsys, room_file, tmp_path):
    out_dir = tmp_path / "maps" / "new"
    code, out, err = asa(capsys, "scenario", "map", room_file, "--out", out_dir,
                         "--resolution", "0.1")  # fmt: skip
    assert code == 0, err
    paths = [Path(line.split(None, 1)[1]) for line in out.strip().splitlines()]
    assert {p.suffix for p in paths} == {".pgm", ".yaml", ".png"}
    assert all(p.is_file() and p.stat().st_size > 0 and p.parent == out_dir for p in paths)
    yaml = next(p for p in paths if p.suffix == ".yaml").read_text()
    assert "resolution: 0.1" in yaml


def test_list_shows_every_shipped_scenario(capsys):
    code, out, err = asa(capsys, "scenario", "list", "--json")
    assert code == 0, err
    rows = json.loads(out)
    assert [r["name"] for r in rows] == available_scenarios()
    assert all(set(r) == {"name", "description", "source"} for r in rows)
    code, text, _ = asa(capsys, "scenario", "list")
    assert code == 0 and all(name in text for name in available_scenarios())


@pytest.mark.parametrize("name", available_scenarios())
def test_show_every_shipped_scenario_by_name(capsys, name):
    code, out, err = asa(capsys, "scenario", "show", name, "--json")
    assert code == 0, err
    assert json.loads(out)["name"] == name


BAD_FILES = [
    ("not toml [[", "not valid TOML"),
    (ROOM.replace('name = "crate"', 'name = "crate"\nsize_typo = 1'), "boxes[0].size_typo"),
    (ROOM.replace("radius = 0.25", "radius = -0.25"), "cylinders[0].radius"),
    (ROOM.replace('table = "desk"', 'table = "nowhere"'), "dock.table"),
    (ROOM + '\n[semantics]\nremove = [{id = "gap_42"}]\n', "semantics.remove[0].id"),
    (
        ROOM + '\n[[semantics.components]]\nid = "d"\nkind = "doorway"\ncentre = [1, 1]\n'
        "ends = [[1, 1], [1, 1]]\n",
        "semantics.components[0].ends",
    ),
    (ROOM + "\n[semantics]\nsurface_spacing = 1e-7\n", "semantics.surface_spacing"),
    (ROOM.replace('name = "small_room"', "name = 3"), "'name'"),
]


@pytest.mark.parametrize(("text", "field"), BAD_FILES, ids=[f for _, f in BAD_FILES])
@pytest.mark.parametrize("command", ["show", "map"])
def test_malformed_file_is_one_line_naming_file_and_field(capsys, tmp_path, text, field, command):
    path = tmp_path / "broken_room.toml"
    path.write_text(text, encoding="utf-8")
    extra = ["--out", tmp_path / "maps"] if command == "map" else ["--json"]
    code, out, err = asa(capsys, "scenario", command, path, *extra)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "broken_room.toml" in lines[0] and field in lines[0]
    assert "Traceback" not in err and out == ""


def test_paths_that_are_not_scenario_files(capsys, tmp_path):
    folder = tmp_path / "a_folder"
    folder.mkdir()
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00 not utf-8")
    cases = [
        (folder, "a_folder"),
        (tmp_path / "missing.toml", "missing.toml"),
        ("no_such_scenario_name", "no_such_scenario_name"),
        (binary, "binary.toml"),
    ]
    for target, needle in cases:
        code, out, err = asa(capsys, "scenario", "show", target)
        assert code == 2, (target, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0], err
        assert "Traceback" not in err


def test_bad_output_paths(capsys, room_file, tmp_path):
    a_file = tmp_path / "occupied"
    a_file.write_text("x")
    code, _, err = asa(capsys, "scenario", "map", room_file, "--out", a_file)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "occupied" in err
    code, _, err = asa(capsys, "scenario", "map", room_file, "--out", tmp_path, "--resolution", "0")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "resolution" in err
    code, _, err = asa(capsys, "scenario", "show", room_file, "--png", tmp_path / "no" / "x.png")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "x.png" in err


def test_the_installed_shell_reports_a_bad_file_in_one_line(tmp_path):
    path = tmp_path / "broken_room.toml"
    path.write_text(ROOM.replace("radius = 0.25", 'radius = "big"'), encoding="utf-8")
    result = subprocess.run(
        [sys.executable, "-m", "study.cli", "scenario", "show", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "broken_room.toml" in lines[0] and "cylinders[0].radius" in lines[0]
    assert "Traceback" not in result.stderr
