"""Population files (issue 39): written and read back, every field checked, and used by
``asa synth``, ``asa pilot`` and ``asa power`` (``--population``)."""

from __future__ import annotations

import dataclasses
import json
import sqlite3

import numpy as np
import pytest
from cli_helpers import asa
from mini_protocol import mini_protocol

from study.participants.population import Population
from study.participants.population_file import (
    BOUNDS,
    load_population,
    population_toml,
)


def test_every_field_has_bounds_and_round_trips(tmp_path, rng):
    assert set(BOUNDS) == {f.name for f in dataclasses.fields(Population)}
    changed = dataclasses.replace(
        Population(),
        speed_median=0.35,
        speed_range=(0.3, 0.4),
        tlx_bias_mean=float(np.round(rng.uniform(-10, 10), 3)),
        distraction_p=(0.2, 0.3, 0.5),
        age_range=(20, 30),
    )
    path = tmp_path / "p.toml"
    path.write_text(population_toml(changed, {"method": "test", "moments": [1.0, 2.0]}))
    assert load_population(path) == changed
    # a file may give some fields only; the rest are the defaults
    path.write_text("[population]\ntlx_bias_mean = -3.0\n")
    assert load_population(path) == dataclasses.replace(Population(), tlx_bias_mean=-3.0)


BAD = [
    ("[population]\nspeed_medain = 0.3\n", "population.speed_medain", "allowed: speed_median"),
    ("[population]\nspeed_sigma = 2.0\n", "population.speed_sigma", "[0, 1]"),
    ("[population]\nspeed_range = [0.4, 0.2]\n", "population.speed_range", "low <= high"),
    ("[population]\nspeed_range = [0.2]\n", "population.speed_range", "list of 2"),
    ("[population]\ndistraction_p = [0.5, 0.5, 0.5]\n", "population.distraction_p", "sum to 1"),
    ("[population]\nage_range = [18.5, 40]\n", "population.age_range", "an integer"),
    ("[population]\ntlx_bias_sd = true\n", "population.tlx_bias_sd", "a number"),
    ("[population]\nspeed_median = 0.9\n", "population.speed_median", "speed_range"),
    ("[people]\nspeed_median = 0.3\n", "table 'people'", "allowed: population, calibration"),
    ("[population\n", "not a valid TOML", ""),
]


@pytest.mark.parametrize(("text", "field", "allowed"), BAD)
def test_bad_population_files_are_one_line_and_exit_2(tmp_path, capsys, text, field, allowed):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    for command in (
        ["synth", "--protocol", "pilot", "--participants", "1", "--db", tmp_path / "s.db"],
        ["power", "--protocol", "pilot", "--out", tmp_path / "pw"],
        ["pilot", "--participants", "1", "--out", tmp_path / "pl"],
    ):
        code, _, err = asa(capsys, *command, "--population", path)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, err
        assert str(path) in lines[0] and field in lines[0] and allowed in lines[0]
    assert not (tmp_path / "s.db").exists() and not (tmp_path / "pw").exists()


def test_a_missing_population_file_is_named(tmp_path, capsys):
    code, _, err = asa(
        capsys, "synth", "--protocol", "pilot", "--db", tmp_path / "s.db",
        "--population", tmp_path / "none.toml",
    )  # fmt: skip
    assert code == 2 and "none.toml" in err and len(err.strip().splitlines()) == 1


def test_synth_draws_its_people_from_the_population_file(tmp_path, capsys):
    """A real synthetic study (pybullet, SQLite): its people's parameters come from the
    file's ranges, not the defaults'."""
    protocol = tmp_path / "mini.toml"
    protocol.write_text(mini_protocol(participants=2, timeout_s=1.0))
    population = tmp_path / "fast.toml"
    population.write_text(
        "[population]\nspeed_median = 0.42\nspeed_range = [0.41, 0.43]\n"
        "delay_range_s = [0.5, 0.6]\n"
    )
    db = tmp_path / "s.db"
    code, _, err = asa(
        capsys, "synth", "--protocol", protocol, "--participants", "2", "--workers", "1",
        "--db", db, "--no-recordings", "--population", population,
    )  # fmt: skip
    assert code == 0, err
    with sqlite3.connect(db) as con:
        params = [json.loads(p) for (p,) in con.execute("SELECT parameters FROM participant")]
    assert len(params) == 2
    for p in params:
        assert 0.41 <= p["preferred_speed"] <= 0.43 and 0.5 <= p["reaction_delay_s"] <= 0.6
