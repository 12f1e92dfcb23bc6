"""Bad protocol and scenario TOML files, and the map writer's resolution."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from tests.bad_input import DEEP, DEEPISH, DOCKING, PILOT, PRACTICE, Env, case
from tests.bad_input import sub as _sub
from tests.bad_input import write as _write

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

# the protocol's [web] table (issue 37)
for _name, _table in [
    ("grace-negative", "grace_s = -1"),
    ("grace-huge", "grace_s = 1e12"),
    ("stale-zero", "stale_ticks = 0"),
    ("pings-string", 'pings = "20"'),
    ("gamepad-string", 'gamepad = "yes"'),
    ("window-short", "min_window = [1024]"),
    ("window-tiny", "min_window = [10, 10]"),
    ("camera-fast", "camera_hz = 1000"),
    ("url-http", 'completion_url = "http://example.org"'),
    ("unknown-key", "colour = 3"),
]:
    protocol(f"web-{_name}", PILOT + f"\n[web]\n{_table}\n")
