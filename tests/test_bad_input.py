"""The bad-input corpus (issue 20): every input the platform reads, made wrong.

Protocol TOML, scenario TOML, the long CSV of ``asa stats``, the CSV folder of ``asa
export`` (questionnaire answers among it), study database files, model files,
demonstration folders, and the options of every command. Each case runs ``asa`` in
process and asserts what the CLI promises for bad input: exit status 2, exactly one
line on stderr, no traceback, no printed warning. A few run as real subprocesses to
prove the console path. All cases are counted here (``len(CASES)`` >= 150).
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import shutil
import subprocess
import sys
import warnings
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from autonomy.model import DEFAULT_MODEL
from protocols import PROTOCOL_DIR
from sim.scenario import SCENARIO_DIR
from study.cli import main

PILOT = (PROTOCOL_DIR / "pilot.toml").read_text(encoding="utf-8")
PRACTICE = (SCENARIO_DIR / "practice_course.toml").read_text(encoding="utf-8")
DOCKING = (SCENARIO_DIR / "demo_docking.toml").read_text(encoding="utf-8")
DEEP = "x = " + "[" * 5000 + "]" * 5000 + "\n"  # tomllib recurses once per level
DEEPISH = "x = " + "[" * 100 + "]" * 100 + "\n"  # parses, but nests beyond the limit


@dataclass(frozen=True)
class Env:
    """Valid inputs to break: a study database, its export folder, a demonstrations
    folder and the shipped model."""

    db: Path
    export: Path
    demos: Path
    model: Path


@pytest.fixture(scope="module")
def env(tmp_path_factory: pytest.TempPathFactory) -> Env:
    from tests.fixtures_db import FixtureSettings, make_study_db

    root = tmp_path_factory.mktemp("corpus")
    db = make_study_db(
        root / "study.db",
        np.random.default_rng(0),
        settings=FixtureSettings(n_participants=3, samples=10),
    )
    export = root / "export"
    demos = root / "demos"
    for argv in (
        ["export", "--db", str(db), "--out", str(export)],
        ["demonstrations", "record", "--task", "doorway_crossing", "--runs", "1"]
        + ["--out", str(demos)],
    ):
        try:
            main([*argv])
        except SystemExit as done:
            assert done.code in (0, None), argv
    return Env(db=db, export=export, demos=demos, model=Path(DEFAULT_MODEL))


Setup = Callable[[Path, Env], list[str]]
CASES: list[tuple[str, Setup]] = []


def case(name: str, setup: Setup) -> None:
    CASES.append((re.sub(r"[^A-Za-z0-9_.+-]+", "_", name), setup))


def _write(path: Path, content: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _sub(text: str, pattern: str, new: str) -> str:
    """``text`` with the first line matching ``pattern`` (a regex of a whole line) replaced."""
    out, n = re.subn(f"(?m)^{pattern}$", new, text, count=1)
    assert n == 1, pattern
    return out


# ------------------------------------------------------------------ protocol TOML


def protocol(name: str, text: str | bytes | Callable[[Path], str]) -> None:
    """A protocol file, loaded by ``asa plan`` (the same loader every command uses)."""

    def setup(tmp: Path, env: Env) -> list[str]:
        content = text(tmp) if callable(text) else text
        return ["plan", "--protocol", str(_write(tmp / "protocol.toml", content))]

    case(f"protocol-{name}", setup)


def protocol_field(name: str, pattern: str, new: str) -> None:
    protocol(name, _sub(PILOT, pattern, new))


for _name, _value in [
    ("huge", str(2**63 - 1)),
    ("trillion", str(10**12)),
    ("zero", "0"),
    ("negative", "-3"),
    ("string", '"six"'),
    ("float", "6.5"),
    ("bool", "true"),
    ("above-max", "10001"),
    ("array", "[6]"),
]:
    protocol_field(f"participants-{_name}", r"participants = .*", f"participants = {_value}")
for _name, _value in [
    ("10e23", str(10**23)),
    ("2e63", str(2**63)),
    ("negative", "-1"),
    ("string", '"1"'),
    ("float", "1.0"),
    ("inf", "inf"),
]:
    protocol_field(f"seed-{_name}", r"seed = .*", f"seed = {_value}")
for _name, _value in [
    ("1e308", "1e308"),
    ("inf", "inf"),
    ("nan", "nan"),
    ("negative", "-1.0"),
    ("zero", "0"),
    ("over-24h", "86401.0"),
    ("string", '"600"'),
]:
    protocol_field(f"timeout_s-{_name}", r"timeout_s = .*", f"timeout_s = {_value}")
for _name, _value in [("huge", str(2**63 - 1)), ("zero", "0"), ("large", "1001"), ("float", "5.0")]:
    protocol_field(f"block_size-{_name}", r"block_size = .*", f"block_size = {_value}")
protocol_field("duration_s-1e9", r"duration_s = .*", "duration_s = 1e9")
protocol_field("duration_s-negative", r"duration_s = .*", "duration_s = -20.0")
protocol_field("time_limit_s-1e308", r"time_limit_s = .*", "time_limit_s = 1e308")
protocol_field("max_attempts-million", r"max_attempts = .*", "max_attempts = 1000000")
protocol_field("max_attempts-zero", r"max_attempts = .*", "max_attempts = 0")
protocol_field("max_collisions-negative", r"max_collisions = .*", "max_collisions = -1")
protocol_field("baseline-questions-1e9", r"questions = 10 .*", "questions = 1000000000")
protocol_field(
    "rehearsal-questions-huge", r"rehearsal_questions = .*", "rehearsal_questions = 10000000"
)
protocol_field(
    "collision_penalty-1e300", r"collision_penalty_s = .*", "collision_penalty_s = 1e300"
)
protocol_field(
    "collision_penalty-negative", r"collision_penalty_s = .*", "collision_penalty_s = -1.0"
)
protocol_field("alpha-above-1", r"alpha = .*", "alpha = 1.5")
protocol_field("alpha-zero", r"alpha = .*", "alpha = 0")
protocol_field("alpha-string", r"alpha = .*", 'alpha = "0.05"')
protocol_field("gate-unknown", r"gate = .*", 'gate = "sometimes"')
protocol_field("metrics-unknown", r'    "tlx_raw",', '    "happiness",')
protocol_field("window-huge", r"window = .*", "window = [1e9, 720]")
protocol_field("window-small", r"window = .*", "window = [100, 100]")
protocol_field("modes-one", r"names = .*", 'names = ["manual"]')
protocol_field("modes-repeated", r"names = .*", 'names = ["manual", "manual"]')
protocol_field("modes-unknown", r"names = .*", 'names = ["manual", "teleport"]')
protocol_field("modes-not-a-list", r"names = .*", 'names = "manual"')
protocol_field("hidden-false", r"hidden = .*", "hidden = false")
protocol_field("counterbalancing-unknown", r"counterbalancing = .*", 'counterbalancing = "alpha"')
protocol_field("phase-kind-unknown", r'kind = "debrief"', 'kind = "party"')
protocol_field("phase-order", r'kind = "briefing"', 'kind = "debrief"')
protocol_field("route-starts-at-B", r"route = .*", 'route = ["B", "A"]')
protocol_field("route-unknown-point", r"route = .*", 'route = ["A", "C", "A"]')
protocol_field("scenario-unknown", r'scenario = "practice_course"', 'scenario = "moon_base"')
protocol_field("scenario-escape", r'scenario = "practice_course"', 'scenario = "../../../x.toml"')
protocol_field("typo-key", r"participants = .*", "participant = 6")
protocol_field("instrument-unknown", r'instrument = "nasa_tlx"', 'instrument = "sus"')
protocol_field("on_fail-unknown", r"on_fail = .*", 'on_fail = "retry_forever"')
protocol_field("briefing-placeholder", r'text = "Pilot run: .*', 'text = "drive to {nowhere}"')
protocol_field("name-empty", r'name = "pilot"', 'name = ""')
protocol("secondary-p_correct", PILOT + "\n[secondary]\np_correct = 2.0\n")
protocol("secondary-gap-1e308", PILOT + "\n[secondary]\ngap_s = 1e308\n")
protocol("secondary-timeout-inf", PILOT + "\n[secondary]\ntimeout_s = inf\n")
protocol("secondary-offsets-zero", PILOT + "\n[secondary]\nnear_miss_offsets = [0]\n")
protocol("secondary-offsets-huge", PILOT + f"\n[secondary]\nnear_miss_offsets = [{10**30}]\n")
protocol("secondary-offsets-string", PILOT + '\n[secondary]\nnear_miss_offsets = "1"\n')
protocol("recording-camera_hz", PILOT + "\n[recording]\ncamera_hz = 100.0\n")
protocol("recording-jpeg_quality", PILOT + "\n[recording]\njpeg_quality = 101\n")
protocol("recording-camera_width", PILOT + "\n[recording]\ncamera_width = 1000000\n")
protocol("input-deadzone", PILOT + "\n[input]\ndeadzone = 5.0\n")
protocol("input-axis-huge", PILOT + f"\n[input.axes]\nvx = {2**62}\n")
protocol("mode-settings-unknown", PILOT + "\n[modes.settings.manual]\nturbo = 1\n")
protocol("deep-array", DEEP)
protocol("deepish-array", PILOT + DEEPISH)
protocol("not-toml", "[study\nname = ")
protocol("duplicate-key", _sub(PILOT, r"seed = .*", "seed = 1\nseed = 2"))
protocol("empty", "")
protocol("binary", bytes(range(256)) * 4)
protocol("latin-1", '[study]\nname = "caf\xe9"\n'.encode("latin-1"))
protocol("no-modes", PILOT.split("[modes]")[0])
protocol("no-main", re.sub(r"(?s)\[\[phases\]\]\nkind = \"main\".*?(?=\[\[phases\]\])", "", PILOT))
case("protocol-missing-file", lambda tmp, env: ["plan", "--protocol", str(tmp / "nope.toml")])
case("protocol-a-directory", lambda tmp, env: ["plan", "--protocol", str(tmp)])


def _protocol_with_scene(scene: str) -> Callable[[Path], str]:
    def make(tmp: Path) -> str:
        _write(tmp / "scene.toml", scene)
        return _sub(PILOT, 'scenario = "practice_course"', 'scenario = "scene.toml"')

    return make


protocol("scene-start-in-box", _protocol_with_scene(_sub(PRACTICE, r"x = 1\.0", "x = 2.6")))
protocol(
    "scene-bad-name",
    _protocol_with_scene(_sub(PRACTICE, r'name = "practice_course"', 'name = "../x"')),
)


# ------------------------------------------------------------------ scenario TOML


def scenario(name: str, text: str | bytes, command: str = "show") -> None:
    """A scenario file, loaded by ``asa scenario show`` (or ``map``/``check``)."""

    def setup(tmp: Path, env: Env) -> list[str]:
        path = str(_write(tmp / "scene.toml", text))
        if command == "map":
            return ["scenario", "map", path, "--out", str(tmp / "maps")]
        return ["scenario", command, path]

    case(f"scenario-{name}", setup)


def scenario_field(name: str, pattern: str, new: str, base: str = PRACTICE) -> None:
    scenario(name, _sub(base, pattern, new))


for _name, _value in [
    ("1e7", "[[0, 0], [1e7, 1e7]]"),
    ("201m", "[[0, 0], [201, 10]]"),
    ("reversed", "[[8, 5], [0, 0]]"),
    ("nan", "[[nan, 0], [8, 5]]"),
    ("inf", "[[0, 0], [inf, 5]]"),
    ("string", '"big"'),
    ("one-point", "[[0, 0]]"),
    ("1e300", "[[-1e300, -1e300], [1e300, 1e300]]"),
    ("9999m", "[[0, 0], [9999, 9999]]"),
]:
    scenario_field(f"bounds-{_name}", r"bounds = .*", f"bounds = {_value}")
scenario("bounds-1e7-map", _sub(PRACTICE, r"bounds = .*", "bounds = [[0, 0], [1e7, 1e7]]"), "map")
for _name, _value in [
    ("../../escaped", '"../../escaped"'),
    ("absolute", '"/tmp/escaped"'),
    ("empty", '""'),
    ("space", '"practice course"'),
    ("too-long", '"' + "x" * 65 + '"'),
    ("number", "5"),
    ("dot-dot", '".."'),
    ("backslash", '"a\\\\b"'),
]:
    scenario_field(f"name-{_name}", r'name = "practice_course"', f"name = {_value}")
scenario_field("start-in-box", r"x = 1\.0", "x = 2.6")  # box_west's centre
scenario_field("start-in-wall", r"y = 2\.5", "y = 0.0")
scenario_field("start-outside", r"x = 1\.0", "x = -50.0")
scenario_field("start-nan", r"x = 1\.0", "x = nan")
scenario_field("start-yaw-1e300", r"yaw_deg = 0\.0", "yaw_deg = 1e300")
scenario("dock-in-box", _sub(_sub(PRACTICE, r"x = 7\.0", "x = 5.3"), r"y = 2\.3", "y = 3.1"))
scenario_field("dock-table-unknown", r'table = "table"', 'table = "desk"', DOCKING)
_REGION = "\n[question_region]\npolygon = {}\n"
scenario("region-a-line", PRACTICE + _REGION.format("[[1, 1], [2, 2], [3, 3]]"))
scenario("region-outside", PRACTICE + _REGION.format("[[1, 1], [50, 1], [50, 4], [1, 4]]"))
scenario("region-two-points", PRACTICE + _REGION.format("[[1, 1], [2, 2]]"))
scenario("region-string", PRACTICE + _REGION.format('"everywhere"'))
scenario("region-point", PRACTICE + _REGION.format("[[1, 1], [1, 1], [1, 1]]"))
scenario_field(
    "wall-thickness-negative", r"to = \[8\.05, 0\.0\]", "to = [8.05, 0.0]\nthickness = -0.1"
)
scenario_field(
    "wall-thickness-1e300", r"to = \[8\.05, 0\.0\]", "to = [8.05, 0.0]\nthickness = 1e300"
)
scenario_field("wall-zero-length", r"to = \[8\.05, 0\.0\]", "to = [-0.05, 0.0]")
scenario_field("wall-from-1e300", r"from = \[-0\.05, 0\.0\]", "from = [1e300, 0.0]")
scenario("robot-length-zero", PRACTICE + "\n[robot]\nlength = 0.0\n")
scenario("robot-mass-1e308", PRACTICE + "\n[robot]\nmass = 1e308\n")
scenario(
    "laser-resolution-tiny",
    PRACTICE + '\n[[robot.lasers]]\nname = "f"\nposition = [0.3, 0.0]\nresolution_deg = 1e-9\n',
)
scenario(
    "laser-fov-400",
    PRACTICE + '\n[[robot.lasers]]\nname = "f"\nposition = [0.3, 0.0]\nfov_deg = 400.0\n',
)
scenario(
    "laser-min-above-max",
    PRACTICE + '\n[[robot.lasers]]\nname = "f"\nposition = [0.3, 0.0]\nmin_range = 9.0\n',
)
scenario("camera-width-million", PRACTICE + "\n[robot.camera]\nwidth = 1000000\n")
scenario("camera-height-huge", PRACTICE + f"\n[robot.camera]\nheight_px = {2**63 - 1}\n")
scenario_field("table-too-low", r"height = 0\.75", "height = 0.3", DOCKING)
scenario_field("table-leg-too-thick", r"leg = 0\.06", "leg = 0.6", DOCKING)
scenario("semantics-width-reversed", PRACTICE + "\n[semantics]\npassage_width = [1.5, 0.5]\n")
scenario("semantics-spacing-tiny", PRACTICE + "\n[semantics]\nsurface_spacing = 1e-9\n")
scenario_field(
    "inspection-unknown",
    r'name = "practice_course"',
    'name = "practice_course"\ninspection_object = "unicorn"',
)
scenario_field("duplicate-names", r'name = "outer_north"', 'name = "outer_south"')
scenario_field(
    "unknown-key", r'name = "practice_course"', 'name = "practice_course"\nfloor = "wood"'
)
scenario_field("cylinder-radius-zero", r"radius = 0\.2", "radius = 0.0")
scenario("no-elements", 'name = "empty"\n[start]\nx = 0\ny = 0\n')
scenario("no-name", PRACTICE.replace('name = "practice_course"', "", 1))
scenario("deep-array", DEEP)
scenario("deepish-array", PRACTICE + DEEPISH)
scenario("not-toml", "name = \n[[walls")
scenario("binary", bytes(range(256)) * 4)
scenario("empty", "")
case(
    "scenario-map-resolution-tiny",
    lambda t, e: [
        "scenario",
        "map",
        "practice_course",
        "--out",
        str(t / "m"),
        "--resolution",
        "1e-9",
    ],
)
case(
    "scenario-map-resolution-nan",
    lambda t, e: [
        "scenario",
        "map",
        "practice_course",
        "--out",
        str(t / "m"),
        "--resolution",
        "nan",
    ],
)
case(
    "scenario-map-resolution-zero",
    lambda t, e: ["scenario", "map", "practice_course", "--out", str(t / "m"), "--resolution", "0"],
)
case("scenario-show-unknown-name", lambda t, e: ["scenario", "show", "moon_base"])
case("scenario-show-directory", lambda t, e: ["scenario", "show", str(t)])
case(
    "scenario-generate-negative-seed",
    lambda t, e: ["scenario", "generate", "--seed", "-1", "--out", str(t / "g.toml")],
)
case(
    "scenario-generate-seed-10e23",
    lambda t, e: ["scenario", "generate", "--seed", str(10**23), "--out", str(t / "g.toml")],
)
case(
    "scenario-generate-rooms",
    lambda t, e: [
        "scenario",
        "generate",
        "--seed",
        "1",
        "--rooms",
        "9",
        "--out",
        str(t / "g.toml"),
    ],
)


# --------------------------------------------------------------- asa stats: long CSV

GOOD_CSV = "s,m,y\n1,a,1.0\n1,b,2.0\n2,a,1.5\n2,b,2.5\n3,a,0.5\n3,b,3.0\n"
STATS = ["--dv", "y", "--within", "m", "--subject", "s"]


def stats_csv(name: str, content: str | bytes, *extra: str) -> None:
    def setup(tmp: Path, env: Env) -> list[str]:
        return ["stats", "--csv", str(_write(tmp / "data.csv", content)), *STATS, *extra]

    case(f"stats-{name}", setup)


def stats_value(name: str, value: str) -> None:
    stats_csv(name, GOOD_CSV.replace("1,a,1.0", f"1,a,{value}"))


for _name, _value in [
    ("1e307", "1e307"),
    ("minus-1e300", "-1e300"),
    ("1e16", "1e16"),
    ("inf", "inf"),
    ("minus-inf", "-inf"),
    ("text", "fast"),
    ("1e400", "1e400"),
    ("comma-decimal", '"1,5"'),
    ("hex", "0x10"),
]:
    stats_value(f"value-{_name}", _value)
stats_csv("all-1e307", "s,m,y\n" + "".join(f"{i},{m},1e307\n" for i in range(4) for m in "ab"))
stats_csv("empty-file", "")
stats_csv("header-only", "s,m,y\n")
stats_csv("missing-column", GOOD_CSV.replace("s,m,y", "s,m,z"))
stats_csv("one-level", "s,m,y\n1,a,1\n2,a,2\n3,a,3\n")
stats_csv("empty-subject", GOOD_CSV.replace("2,a,1.5", ",a,1.5"))
stats_csv("extra-field", GOOD_CSV + "4,a,1,oops\n")
stats_csv("latin-1", "s,m,y\n1,caf\xe9,1\n".encode("latin-1"))
stats_csv("binary", bytes(range(256)) * 8)
stats_csv("alpha-zero", GOOD_CSV, "--alpha", "0")
stats_csv("alpha-nan", GOOD_CSV, "--alpha", "nan")
stats_csv("alpha-text", GOOD_CSV, "--alpha", "five")
stats_csv("gate-unknown", GOOD_CSV, "--gate", "never")
case("stats-missing-file", lambda t, e: ["stats", "--csv", str(t / "none.csv"), *STATS])
case("stats-a-directory", lambda t, e: ["stats", "--csv", str(t), *STATS])
case(
    "stats-same-column",
    lambda t, e: (
        ["stats", "--csv", str(_write(t / "d.csv", GOOD_CSV)), "--dv", "y"]
        + ["--within", "y", "--subject", "s"]
    ),
)


# --------------------------------------------- asa report: an export folder (CSV files)


def export_folder(name: str, change: Callable[[Path], None]) -> None:
    """A copy of the fixture study's ``asa export`` folder with ``change`` applied, read
    by ``asa report`` (which stops at the bad file, before any figure)."""

    def setup(tmp: Path, env: Env) -> list[str]:
        folder = tmp / "export"
        shutil.copytree(env.export, folder)
        change(folder)
        return ["report", "--db", str(folder), "--out", str(tmp / "report")]

    case(f"export-{name}", setup)


def _cell(table: str, column: str, value: str, row: int = 0) -> Callable[[Path], None]:
    """Set one cell of ``table``.csv (row ``row`` of the data) to the raw CSV ``value``."""

    def change(folder: Path) -> None:
        import pandas as pd

        path = folder / f"{table}.csv"
        frame = pd.read_csv(path, dtype=str, keep_default_na=False)
        frame.loc[row, column] = value
        frame.to_csv(path, index=False)

    return change


for _table, _column, _value, _row in [
    ("response", "value", "abc", 0),
    ("response", "value", "1e308", 0),
    ("response", "value", "inf", 0),
    ("response", "value", "-1e300", 7),
    ("trial", "completion_time_s", "1e400", 1),
    ("trial", "collisions", "many", 1),
    ("trial", "seed", str(10**30), 0),
    ("participant", "order_index", "first", 0),
    ("participant", "seed", "-inf", 0),
    ("sample", "x", "nan-ish", 0),
    ("sample", "t", "1e309", 0),
    ("question", "answer_time_s", "quick", 0),
    ("study", "seed", "1e99", 0),
    ("participant", "parameters", "{not json", 0),
    ("trial", "outcome", "[unclosed", 1),
    ("study", "protocol_text", "[analysis]\nalpha = 'high'\n", 0),
    ("study", "protocol_text", DEEP, 0),
    ("study", "protocol_text", "[analysis\n", 0),
]:
    export_folder(f"{_table}-{_column}-{_value[:12]}", _cell(_table, _column, _value, _row))
export_folder("response-missing", lambda f: (f / "response.csv").unlink())
export_folder("response-empty", lambda f: (f / "response.csv").write_text(""))
export_folder("trial-binary", lambda f: (f / "trial.csv").write_bytes(bytes(range(256)) * 8))
export_folder("study-no-rows", lambda f: (f / "study.csv").write_text("id,name,seed\n"))
export_folder("sample-no-id", lambda f: (f / "sample.csv").write_text("t,x\n1,2\n"))


# ---------------------------------------------------------------- database files

DB_COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "db-check": lambda db, t: ["db", "check", "--db", str(db), "--no-verify"],
    "export": lambda db, t: ["export", "--db", str(db), "--out", str(t / "out")],
    "report": lambda db, t: ["report", "--db", str(db), "--out", str(t / "report")],
    "replay": lambda db, t: (
        ["replay", "--db", str(db), "--participant", "P01", "--trial", "1"] + ["--print"]
    ),
}


def _foreign_sqlite(path: Path) -> Path:
    import sqlite3

    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TABLE recipes (id INTEGER PRIMARY KEY, name TEXT)")
    return path


def _truncated(env: Env, path: Path) -> Path:
    path.write_bytes(env.db.read_bytes()[:5000])
    return path


DB_FILES: dict[str, Callable[[Path, Env], Path]] = {
    "empty-file": lambda t, e: _write(t / "x.db", b""),
    "text-file": lambda t, e: _write(t / "x.db", "participant,mode\nP01,manual\n"),
    "random-bytes": lambda t, e: _write(t / "x.db", np.random.default_rng(1).bytes(8192)),
    "foreign-sqlite": lambda t, e: _foreign_sqlite(t / "x.db"),
    "truncated": lambda t, e: _truncated(e, t / "x.db"),
    "a-directory": lambda t, e: t,
    "missing": lambda t, e: t / "none.db",
}

for _file, _make in DB_FILES.items():
    for _command, _argv in DB_COMMANDS.items():
        if _file == "a-directory" and _command == "report":
            continue  # a folder is an export folder to `asa report`: covered above
        case(
            f"database-{_command}-{_file}",
            lambda t, e, make=_make, argv=_argv: argv(make(t, e), t),
        )
for _name, _trial in [("zero", "0"), ("10e30", str(10**30)), ("negative", "-1"), ("text", "one")]:
    case(
        f"replay-trial-{_name}",
        lambda t, e, trial=_trial: (
            ["replay", "--db", str(e.db), "--participant", "P01"] + ["--trial", trial, "--print"]
        ),
    )
case(
    "replay-participant-unknown",
    lambda t, e: ["replay", "--db", str(e.db), "--participant", "Q99", "--trial", "1", "--print"],
)


# --------------------------------------------------------------------- model files


def _npz(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return _write(path, buffer.getvalue())


def _model_arrays() -> dict[str, np.ndarray]:
    with np.load(DEFAULT_MODEL, allow_pickle=False) as data:
        return {name: data[name] for name in data.files}


def _model_changed(change: Callable[[dict[str, np.ndarray]], None]) -> Callable[[Path], Path]:
    def make(path: Path) -> Path:
        arrays = _model_arrays()
        change(arrays)
        return _npz(path, arrays)

    return make


def _first_float(arrays: dict[str, np.ndarray]) -> str:
    return next(k for k, v in arrays.items() if v.dtype.kind == "f" and v.size)


def _set_nan(arrays: dict[str, np.ndarray]) -> None:
    name = _first_float(arrays)
    arrays[name] = np.full_like(arrays[name], np.nan)


def _reshape(arrays: dict[str, np.ndarray]) -> None:
    name = _first_float(arrays)
    arrays[name] = arrays[name].ravel()[:-1]


def _meta(value: object) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        arrays["metadata"] = np.array(value if isinstance(value, str) else json.dumps(value))

    return change


MODEL_FILES: dict[str, Callable[[Path], Path]] = {
    "empty-file": lambda p: _write(p, b""),
    "text-file": lambda p: _write(p, "not a model\n"),
    "random-bytes": lambda p: _write(p, np.random.default_rng(2).bytes(4096)),
    "empty-zip": lambda p: _write(p, _empty_zip()),
    "no-metadata": _model_changed(lambda a: a.pop("metadata")),
    "metadata-not-json": _model_changed(_meta("{oops")),
    "metadata-a-list": _model_changed(_meta([1, 2])),
    "format-version-999": _model_changed(_meta({"format_version": 999})),
    "nan-array": _model_changed(_set_nan),
    "wrong-shape": _model_changed(_reshape),
    "truncated": lambda p: _write(p, Path(DEFAULT_MODEL).read_bytes()[:2000]),
    "pickled-object": lambda p: _npz(p, {"metadata": np.array([object()], dtype=object)}),
}


def _empty_zip() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w"):
        pass
    return buffer.getvalue()


for _name, _make_model in MODEL_FILES.items():
    case(
        f"model-{_name}",
        lambda t, e, make=_make_model: (
            ["evaluate", "--model", str(make(t / "model.npz"))]
            + ["--demonstrations", str(e.demos), "--quiet"]
        ),
    )
case("model-missing", lambda t, e: ["evaluate", "--model", str(t / "no.npz"), "--quiet"])
case("model-a-directory", lambda t, e: ["evaluate", "--model", str(t), "--quiet"])


# --------------------------------------------------------------- demonstration folders


def demos(name: str, change: Callable[[Path], None], command: str = "show") -> None:
    """A copy of the fixture's demonstrations folder with ``change`` applied, read by
    ``asa demonstrations show`` (or ``asa train``)."""

    def setup(tmp: Path, env: Env) -> list[str]:
        folder = tmp / "demos"
        shutil.copytree(env.demos, folder)
        change(folder)
        if command == "train":
            return ["train", "--demonstrations", str(folder), "--out", str(tmp / "m.npz")]
        return ["demonstrations", "show", str(folder)]

    case(f"demonstrations-{command}-{name}", setup)


def _manifest(change: Callable[[dict], object], *, replace: bool = False) -> Callable[[Path], None]:
    """Change the manifest in place, or with ``replace`` write what ``change`` returns."""

    def apply(folder: Path) -> None:
        path = folder / "manifest.json"
        data = json.loads(path.read_text())
        result = change(data)
        path.write_text(json.dumps(result if replace else data))

    return apply


def _run_file(folder: Path) -> Path:
    return next(folder.rglob("*.npz"))


def _rewrite_run(change: Callable[[dict[str, np.ndarray]], None]) -> Callable[[Path], None]:
    """Change the run's arrays and fix the manifest's hash, so the arrays are what is wrong."""

    def apply(folder: Path) -> None:
        path = _run_file(folder)
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        change(arrays)
        _npz(path, arrays)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        _manifest(lambda m: m["runs"][0].update(sha256=digest))(folder)

    return apply


def _nan_q(a: dict[str, np.ndarray]) -> None:
    a["q"] = np.full_like(a["q"], np.nan)


for _command in ("show", "train"):
    demos("no-manifest", lambda f: (f / "manifest.json").unlink(), _command)
    demos("manifest-not-json", lambda f: (f / "manifest.json").write_text("{oops"), _command)
demos("manifest-a-list", _manifest(lambda m: [m], replace=True))
demos("manifest-binary", lambda f: (f / "manifest.json").write_bytes(bytes(range(256))))
demos("version-99", _manifest(lambda m: m.update(version=99)))
demos("runs-not-a-list", _manifest(lambda m: m.update(runs="all")))
demos("run-not-an-object", _manifest(lambda m: m.update(runs=[5])))
demos("run-missing-field", _manifest(lambda m: m["runs"][0].pop("sha256")))
demos("run-unknown-task", _manifest(lambda m: m["runs"][0].update(task="juggling")))
demos("run-file-escapes", _manifest(lambda m: m["runs"][0].update(file="../../etc/passwd")))
demos("run-file-absolute", _manifest(lambda m: m["runs"][0].update(file="/etc/passwd")))
demos("run-ticks-huge", _manifest(lambda m: m["runs"][0].update(ticks=10**30)), "train")
demos("run-file-missing", lambda f: _run_file(f).unlink(), "train")
demos("run-hash-mismatch", lambda f: _run_file(f).write_bytes(b"PK\x05\x06" + b"\0" * 18), "train")
demos("run-nan-array", _rewrite_run(_nan_q), "train")
demos("run-missing-array", _rewrite_run(lambda a: a.pop("u")), "train")
demos("run-truncated-array", _rewrite_run(lambda a: a.update(t=a["t"][:-1])), "train")
case("demonstrations-show-missing", lambda t, e: ["demonstrations", "show", str(t / "none")])
case(
    "demonstrations-show-a-file", lambda t, e: ["demonstrations", "show", str(_write(t / "f", "x"))]
)


# ------------------------------------------------------------- options of every command


def options(name: str, *argv: str) -> None:
    """``asa`` with these arguments; ``{tmp}`` is replaced by the case's folder."""
    case(f"options-{name}", lambda t, e: [a.replace("{tmp}", str(t)) for a in argv])


options("no-command-unknown", "teleport")
options("top-unknown-option", "--colour")
options("plan-participants-trillion", "plan", "--protocol", "pilot", "--participants", str(10**12))
options("plan-participants-2e63", "plan", "--protocol", "pilot", "--participants", str(2**63 - 1))
options("plan-participants-zero", "plan", "--protocol", "pilot", "--participants", "0")
options("plan-participants-text", "plan", "--protocol", "pilot", "--participants", "ten")
options("plan-seed-10e23", "plan", "--protocol", "pilot", "--seed", str(10**23))
options("plan-seed-negative", "plan", "--protocol", "pilot", "--seed", "-1")
options("plan-seed-2e63", "plan", "--protocol", "pilot", "--seed", str(2**63))
options("plan-protocol-unknown", "plan", "--protocol", "moon")
options(
    "synth-participants-trillion",
    "synth",
    "--protocol",
    "pilot",
    "--db",
    "{tmp}/s.db",
    "--participants",
    str(10**12),
)
options(
    "synth-seed-10e23", "synth", "--protocol", "pilot", "--db", "{tmp}/s.db", "--seed", str(10**23)
)
options(
    "synth-workers-zero", "synth", "--protocol", "pilot", "--db", "{tmp}/s.db", "--workers", "0"
)
options(
    "synth-workers-billion",
    "synth",
    "--protocol",
    "pilot",
    "--db",
    "{tmp}/s.db",
    "--workers",
    str(10**9),
)
options("synth-protocol-missing", "synth", "--db", "{tmp}/s.db")
options("synth-protocol-unknown", "synth", "--protocol", "moon", "--db", "{tmp}/s.db")
options("pilot-participants-zero", "pilot", "--out", "{tmp}/p", "--participants", "0")
options("pilot-participants-big", "pilot", "--out", "{tmp}/p", "--participants", "10001")
options("pilot-seed-negative", "pilot", "--out", "{tmp}/p", "--seed", "-5")
options("pilot-workers-zero", "pilot", "--out", "{tmp}/p", "--workers", "0")
options(
    "run-seed-10e23",
    "run",
    "--protocol",
    "pilot",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
    "--seed",
    str(10**23),
)
options(
    "run-seed-negative",
    "run",
    "--protocol",
    "pilot",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
    "--seed",
    "-1",
)
options(
    "run-code-path", "run", "--protocol", "pilot", "--participant", "../P01", "--db", "{tmp}/r.db"
)
options("run-code-empty", "run", "--protocol", "pilot", "--participant", "", "--db", "{tmp}/r.db")
options(
    "run-code-long", "run", "--protocol", "pilot", "--participant", "P" * 65, "--db", "{tmp}/r.db"
)
options(
    "run-input-unknown",
    "run",
    "--protocol",
    "pilot",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
    "--input",
    "telepathy",
)
options(
    "run-protocol-bad-file",
    "run",
    "--protocol",
    "{tmp}",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
)
options(
    "demonstrations-runs-zero",
    "demonstrations",
    "record",
    "--task",
    "all",
    "--runs",
    "0",
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-runs-billion",
    "demonstrations",
    "record",
    "--task",
    "all",
    "--runs",
    str(10**9),
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-task-unknown",
    "demonstrations",
    "record",
    "--task",
    "juggling",
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-seed-negative",
    "demonstrations",
    "record",
    "--task",
    "all",
    "--seed",
    "-1",
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-scene-unknown",
    "demonstrations",
    "record",
    "--task",
    "doorway_crossing",
    "--scene",
    "moon",
    "--out",
    "{tmp}/d",
)
options("train-seed-negative", "train", "--out", "{tmp}/m.npz", "--seed", "-1")
options("train-out-missing", "train")
options("evaluate-folds-one", "evaluate", "--folds", "1", "--quiet")
options("evaluate-repeats-zero", "evaluate", "--repeats", "0", "--quiet")
options("evaluate-workers-zero", "evaluate", "--workers", "0", "--quiet")
options("evaluate-seed-10e23", "evaluate", "--seed", str(10**23), "--quiet")
options("bench-only-unknown", "bench", "--only", "everything")
options("export-out-missing", "export", "--db", "{tmp}/x.db")
options("db-unknown-subcommand", "db", "repair")
options("db-check-db-missing", "db", "check")
options("scenario-unknown-subcommand", "scenario", "paint")
options("stats-dv-missing", "stats", "--csv", "{tmp}/x.csv", "--within", "m", "--subject", "s")


# ------------------------------------------------------------------------------ tests


def test_the_corpus_holds_at_least_150_cases() -> None:
    names = [name for name, _ in CASES]
    assert len(names) >= 150, len(names)
    assert len(set(names)) == len(names), "case names must be unique"


def _run_in_process(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Run ``asa argv`` in this process; its exit status and stderr. Warnings that Python
    would print count as lines of stderr."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            main(argv)
        except SystemExit as done:
            code = done.code if isinstance(done.code, int) else (0 if done.code is None else 1)
        else:
            code = 0
    err = capsys.readouterr().err
    shown = [
        f"{w.category.__name__}: {w.message}"
        for w in caught
        if not issubclass(w.category, DeprecationWarning | PendingDeprecationWarning)
    ]
    return code, err + "".join(line + "\n" for line in shown)


# Cases another part of issue 20 makes pass (the storage's checks of a database file).
PENDING = {
    f"database-{command}-empty-file": "a 0-byte file is a valid empty SQLite file; refusing it "
    "as 'not an asa-study database' is the storage's part of issue 20 (open_database)"
    for command in DB_COMMANDS
}


def _params() -> list:
    return [
        pytest.param(
            name,
            setup,
            id=name,
            marks=[pytest.mark.xfail(reason=PENDING[name], strict=False)]
            if name in PENDING
            else [],
        )
        for name, setup in CASES
    ]


@pytest.mark.parametrize(("name", "setup"), _params())
def test_bad_input_is_one_line_and_exit_2(
    name: str, setup: Setup, env: Env, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = setup(tmp_path, env)
    code, err = _run_in_process(argv, capsys)
    lines = err.strip().splitlines()
    assert "Traceback" not in err, err
    assert code == 2, (code, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("asa"), err


@pytest.mark.parametrize(
    "argv",
    [
        ["plan", "--protocol", "pilot", "--seed", str(10**23)],
        ["stats", "--csv", "{tmp}/big.csv", *STATS],
        ["scenario", "show", "{tmp}/deep.toml"],
        ["plan", "--protocol", "{tmp}/deep.toml"],
    ],
    ids=["seed-10e23", "csv-1e307", "scenario-deep", "protocol-deep"],
)
def test_the_console_path_prints_one_line(argv: list[str], tmp_path: Path) -> None:
    """The same promise through a real process: python -m study.cli, with warnings on."""
    _write(
        tmp_path / "big.csv",
        "s,m,y\n" + "".join(f"{i},{m},1e307\n" for i in range(4) for m in "ab"),
    )
    _write(tmp_path / "deep.toml", DEEP)
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    done = subprocess.run(
        [sys.executable, "-W", "default", "-m", "study.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr


# ------------------------------------------------- a full disk, a read-only file system


def _fail_with(monkeypatch: pytest.MonkeyPatch, raise_it: Callable[[], None]) -> None:
    import study.cli

    monkeypatch.setattr(study.cli.cli, "main", lambda *a, **k: raise_it())


def _enospc_naming_the_file(path: Path) -> None:
    import errno
    import os

    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


def _enospc_from_a_write(path: Path) -> None:
    """As ``f.write`` reports a full disk: an OSError that names no file."""
    import errno
    import os

    with open(path, "w") as handle:  # noqa: F841 - the open file names the path
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _sqlite_full(path: Path) -> None:
    """As SQLAlchemy reports SQLite's SQLITE_FULL, raised while handling a rollback."""
    import sqlite3

    from sqlalchemy import create_engine
    from sqlalchemy.exc import OperationalError

    engine = create_engine(f"sqlite:///{path}")  # noqa: F841 - names the database
    try:
        raise OperationalError(
            "INSERT INTO sample ...", {}, sqlite3.OperationalError("database or disk is full")
        )
    except OperationalError as error:
        raise RuntimeError("rollback failed too") from error


@pytest.mark.parametrize(
    ("raise_it", "expected"),
    [
        (_enospc_naming_the_file, "{path}: no space left on device"),
        (_enospc_from_a_write, "{path}: no space left on device"),
        (_sqlite_full, "{path}: database or disk is full"),
    ],
    ids=["oserror-with-filename", "oserror-from-write", "sqlite-full-chained"],
)
def test_a_full_disk_is_one_line_naming_the_file(
    raise_it: Callable[[Path], None],
    expected: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    path = tmp_path / "study.db"
    _fail_with(monkeypatch, lambda: raise_it(path))
    code, err = _run_in_process(["db", "check", "--db", str(path)], capsys)
    assert code == 2
    assert err == f"asa: error: {expected.format(path=path)}\n"


@pytest.mark.parametrize("name", ["EACCES", "EROFS", "EIO", "EFBIG", "EDQUOT"])
def test_other_file_system_errors_are_one_line(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import errno
    import os

    number = getattr(errno, name)

    def fail() -> None:
        raise OSError(number, os.strerror(number), str(tmp_path / "x.csv"))

    _fail_with(monkeypatch, fail)
    code, err = _run_in_process(["export", "--db", "x.db", "--out", str(tmp_path)], capsys)
    assert code == 2
    assert err == f"asa: error: {tmp_path / 'x.csv'}: {os.strerror(number).lower()}\n"


def test_a_bug_keeps_its_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only a failing disk or file system is reported as one line; a bug still raises."""

    def fail() -> None:
        raise KeyError("a bug")

    _fail_with(monkeypatch, fail)
    with pytest.raises(KeyError):
        main(["db", "check", "--db", "x.db"])


def _with_file_size_limit(limit: int) -> Callable[[], None]:
    def apply() -> None:
        import resource
        import signal

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write fails with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


@pytest.mark.slow  # 15-25 s: a real session's start-up; the in-process cases above run in CI
def test_a_disk_filling_up_during_a_session_leaves_a_consistent_database(tmp_path: Path) -> None:
    """A real process whose files cannot grow past 300 kB (RLIMIT_FSIZE, as a full disk
    but without root): `asa run` stops with one line naming the database, and `asa db
    check` finds it consistent (the unfinished session is kept, as after a crash)."""
    db = tmp_path / "study.db"
    argv = ["run", "--protocol", "pilot", "--participant", "P01", "--db", str(db)]
    done = subprocess.run(
        [sys.executable, "-m", "study.cli", *argv, "--input", "scripted", "--headless", "--fast"],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=_with_file_size_limit(300_000),
        cwd=Path(__file__).resolve().parents[1],
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("asa: error: "), done.stderr
    assert str(tmp_path) in lines[0], lines[0]
    check = subprocess.run(
        [sys.executable, "-m", "study.cli", "db", "check", "--db", str(db), "--no-verify"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert check.returncode == 0, check.stdout + check.stderr
    assert "clean" in check.stdout


def test_scene_names_follow_the_participant_code_rule() -> None:
    """sim.limits.SAFE_NAME (scenario names) is study.engine.session.CODE_PATTERN."""
    from sim.limits import SAFE_NAME
    from study.engine.session import CODE_PATTERN

    assert SAFE_NAME.pattern == CODE_PATTERN.pattern
