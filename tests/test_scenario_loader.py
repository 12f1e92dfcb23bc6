"""The scenario loader: every field checked, every error naming file and field."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from sim.scenario import load_scenario, parse_scenario, point_in_region

BASE = {
    "name": "tiny",
    "start": {"x": 1.0, "y": 1.0, "yaw_deg": 90.0},
    "walls": [{"name": "south", "from": [0.0, 0.0], "to": [4.0, 0.0]}],
    "cylinders": [{"name": "pillar", "centre": [3.0, 3.0], "radius": 0.2}],
    "tables": [{"name": "table", "centre": [2.0, 2.0], "size": [1.0, 0.8]}],
    "dock": {"x": 2.0, "y": 2.0, "table": "table"},
    "inspection_object": "pillar",
    "question_region": {"polygon": [[0, 0], [1.5, 0], [1.5, 1.5], [0, 1.5]]},
}


def test_valid_scenario_loads_with_defaults():
    s = parse_scenario(copy.deepcopy(BASE), "tiny.toml")
    assert s.start.yaw == pytest.approx(math.pi / 2)
    assert s.robot.max_speed == 1.0 and s.robot.max_yaw_rate == 1.2
    assert [laser.name for laser in s.robot.lasers] == ["front", "rear"]
    assert s.dock is not None and s.dock.table == "table"
    # the wall is a box of the wall's length and thickness, centred between its ends
    wall = s.walls[0]
    assert wall.centre == (2.0, 0.0) and wall.size == (4.0, 0.1)
    # a table is seen by the lasers as four legs
    assert len(s.obstacle_boxes()) == 1 + 4
    assert point_in_region(s, 0.5, 0.5) and not point_in_region(s, 3.0, 3.0)


def test_box_corners_are_rotated_about_the_centre(rng):
    data = copy.deepcopy(BASE)
    yaw = float(rng.uniform(-180, 180))
    data["boxes"] = [{"name": "b", "centre": [2.0, 1.0], "size": [1.0, 0.5], "yaw_deg": yaw}]
    box = parse_scenario(data, "t").boxes[0]
    corners = box.corners()
    assert np.allclose(corners.mean(axis=0), [2.0, 1.0])
    sides = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)
    assert np.allclose(sorted(sides), [0.5, 0.5, 1.0, 1.0])


BAD = [
    (lambda d: d["cylinders"][0].update(radius=-1), "cylinders[0].radius"),
    (lambda d: d.pop("start"), "start.x"),
    (lambda d: d["walls"][0].update(colour=[2, 0, 0]), "walls[0].colour"),
    (lambda d: d["walls"][0].update(thikness=0.2), "walls[0].thikness"),
    (lambda d: d["start"].update(x="one"), "start.x"),
    (lambda d: d.update(inspection_object="ghost"), "inspection_object"),
    (lambda d: d["dock"].update(table="ghost"), "dock.table"),
    (lambda d: d.update(bounds=[[5, 5], [0, 0]]), "bounds"),
    (lambda d: d["tables"][0].update(height=0.1), "tables[0].height"),
    (
        lambda d: d.update(robot={"lasers": [{"name": "a", "position": [0, 0], "fov_deg": 400}]}),
        "robot.lasers[0].fov_deg",
    ),
    (lambda d: d.update(semantics={"passage_width": [1.0, 0.5]}), "semantics.passage_width"),
    (lambda d: d["cylinders"].append({"name": "pillar", "centre": [1, 1], "radius": 0.1}), "name"),
]


@pytest.mark.parametrize(("mutate", "field"), BAD)
def test_bad_fields_name_file_and_field(mutate, field):
    data = copy.deepcopy(BASE)
    mutate(data)
    with pytest.raises(ValueError) as error:
        parse_scenario(data, "room.toml")
    message = str(error.value)
    assert message.startswith("room.toml: field '")
    assert f"'{field}'" in message
    assert "\n" not in message


def test_file_errors(tmp_path):
    bad_toml = tmp_path / "broken.toml"
    bad_toml.write_text("name = \n")
    with pytest.raises(ValueError, match="broken.toml: not valid TOML"):
        load_scenario(bad_toml)
    with pytest.raises(ValueError, match="not a shipped scenario"):
        load_scenario("no_such_scene")
    with pytest.raises(FileNotFoundError):
        load_scenario(tmp_path / "missing.toml")
