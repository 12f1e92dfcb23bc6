"""The floor-plan generator (sim.generate), its TOML writer and `asa scenario generate`:
properties over a handful of seeds derived from the seed fixture."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from sim.check import _under, check_scene
from sim.generate import DOOR_WIDTH_M, GAP_WIDTH_M, generate_scene, scene_toml
from sim.scenario import parse_scenario
from sim.semantics import derive_components
from sim.toml_text import dumps
from tests.test_cli_scenario import asa

N_SEEDS = 4


@pytest.fixture
def scenes(seed: int) -> list[tuple[int, str, dict]]:
    """(rooms, TOML text, parsed TOML) for a handful of seeds, 3 to 6 rooms."""
    out = []
    for k in range(N_SEEDS):
        rng = np.random.default_rng([seed, k])
        rooms = 3 + (seed + k) % 4
        text = scene_toml(generate_scene(rng, rooms=rooms))
        out.append((rooms, text, tomllib.loads(text)))
    return out


def test_the_same_seed_gives_the_same_bytes(seed: int):
    a = scene_toml(generate_scene(np.random.default_rng(seed)))
    b = scene_toml(generate_scene(np.random.default_rng(seed)))
    assert a == b
    assert a != scene_toml(generate_scene(np.random.default_rng(seed + 1)))


def test_generated_scenes_load_and_pass_the_checker(scenes):
    for rooms, _, data in scenes:
        s = parse_scenario(data, f"generated ({rooms} rooms)")
        comps = derive_components(s)
        assert [p.line(s.source) for p in check_scene(s, components=comps)] == []
        doorways = [c for c in comps if c.kind == "doorway"]
        assert len(doorways) == rooms - 1  # a chain: one doorway between neighbours
        lo, hi = DOOR_WIDTH_M
        assert all(lo - 1e-9 <= c.width <= hi + 1e-9 for c in doorways)
        row_gaps = [c for c in comps if c.kind == "gap" and all("_row_" in n for n in c.source)]
        assert len(row_gaps) == 1
        assert GAP_WIDTH_M[0] - 1e-9 <= row_gaps[0].width <= GAP_WIDTH_M[1] + 1e-9
        table = s.element(s.dock.table)
        assert _under(table, np.array([s.dock.pose.x, s.dock.pose.y]))
        assert s.inspection_object and len(s.question_region) == 4


def test_doorways_lie_in_walls_of_both_orientations(seed: int):
    normals = []
    for k in range(8):
        data = generate_scene(np.random.default_rng([seed, 100 + k]))
        s = parse_scenario(data, "generated")
        normals += [c.normal for c in derive_components(s) if c.kind == "doorway"]
    normals = np.abs(np.array(normals))
    assert (normals[:, 0] > 0.99).any() and (normals[:, 1] > 0.99).any()


def test_proportions_vary(scenes):
    extents = {tuple(data["bounds"][1]) for _, _, data in scenes}
    assert len(extents) == len(scenes)


@pytest.mark.parametrize("rooms", [2, 7, True, 4.0])
def test_a_bad_room_count_is_refused(rooms):
    with pytest.raises(ValueError, match="rooms: must be an integer from 3 to 6"):
        generate_scene(np.random.default_rng(0), rooms=rooms)


def test_the_toml_writer_round_trips():
    data = {
        "name": 'a "quoted" name',
        "n": 3,
        "ok": True,
        "points": [[0.0, 1.5], [2.0, -0.25]],
        "start": {"x": 1.0, "yaw_deg": 90.0},
        "walls": [{"name": "w", "from": [0.0, 0.0]}, {"name": "v", "to": [1e-05, 2.0]}],
    }
    assert tomllib.loads(dumps(data)) == data
    with pytest.raises(ValueError, match="x"):
        dumps({"x": float("nan")})


# ------------------------------------------------------------------------------ CLI


def test_cli_generate_writes_a_file_check_accepts_and_refuses_to_overwrite(capsys, tmp_path: Path):
    out = tmp_path / "g.toml"
    code, text, err = asa(
        capsys, "scenario", "generate", "--seed", "7", "--rooms", "3", "--out", out
    )
    assert code == 0 and err == "" and out.is_file()
    first = out.read_bytes()
    code, text, err = asa(capsys, "scenario", "check", out)
    assert code == 0 and text.startswith("ok")
    code, text, err = asa(capsys, "scenario", "generate", "--seed", "8", "--out", out)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--force" in err
    assert out.read_bytes() == first
    code, text, err = asa(capsys, "scenario", "generate", "--seed", "7", "--out", out, "--force")
    assert code == 0 and out.read_bytes() != first  # --rooms drawn now: another plan
