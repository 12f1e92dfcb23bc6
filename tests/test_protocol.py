"""Study protocols: the shipped ones load with the thesis's values, bad files are refused
naming file and field, the practice course is passable, and ``asa plan`` works."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import pickle
import subprocess
import sys
import tomllib

import numpy as np
import pytest

import protocols
from autonomy.modes import available_modes
from sim.occupancy import build_grid, shortest_path
from sim.scenario import SCENARIO_DIR, load_scenario
from sim.semantics import derive_components
from study.cli import main
from study.engine.protocol import (
    GATES,
    PHASE_KINDS,
    POSTHOC,
    POSTHOC_GATES,
    TESTS,
    TIMEOUTS,
    Baseline,
    Practice,
    Training,
    load_protocol,
    parse_protocol,
)

SHIPPED = protocols.available()
KNOWN = available_modes()


def shipped_text(name: str) -> str:
    return (protocols.PROTOCOL_DIR / f"{name}.toml").read_text(encoding="utf-8")


def test_the_three_protocols_are_shipped():
    assert {"thesis-7-6", "reactive-7-5", "pilot"} <= set(SHIPPED)


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_protocol_loads_against_the_live_registry(name):
    wanted = tomllib.loads(shipped_text(name))["modes"]["names"]
    assert set(wanted) <= set(available_modes())
    p = load_protocol(name)
    assert p.name == name
    assert set(p.modes) <= set(available_modes())


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_protocol_is_complete(name):
    path = protocols.PROTOCOL_DIR / f"{name}.toml"
    p = load_protocol(path, known_modes=KNOWN)
    assert p.name == name and p.study.title and p.study.description
    assert p.text == path.read_text(encoding="utf-8")
    assert p.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    kinds = [ph.kind for ph in p.phases]
    assert kinds == sorted(kinds, key=PHASE_KINDS.index) and "main" in kinds
    assert p.mode_hidden
    assert len(p.modes) >= 2 and len(set(p.modes)) == len(p.modes)
    # every scenario a phase names loads
    for ph in p.phases:
        if hasattr(ph, "scenario"):
            load_scenario(ph.scenario)
    # frozen
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.study = None  # type: ignore[misc]


def test_thesis_protocol_has_the_thesis_values():
    p = load_protocol("thesis-7-6", known_modes=KNOWN)
    assert p.modes == ("manual", "reactive_bn", "contextual_task")
    assert p.study.participants == 18 and p.counterbalancing == "full_permutation"
    assert [ph.kind for ph in p.phases] == list(PHASE_KINDS)
    training = p.phase("training")
    assert isinstance(training, Training)
    assert training.secondary and training.direct_view and training.modes == p.modes
    practice = p.phase("practice")
    assert isinstance(practice, Practice)
    assert practice.max_collisions == 0 and not practice.secondary and practice.time_limit_s > 0
    assert practice.scenario == "practice_course"
    baseline = p.phase("baseline")
    assert isinstance(baseline, Baseline) and baseline.questions == 40
    main_ = p.main
    assert main_.scenario == "cluttered_room" and main_.route == ("A", "B", "A")
    assert main_.inspection and main_.secondary and main_.block_size == 20
    assert not main_.end_on_collision
    assert main_.after_trial is not None and main_.after_trial.instrument == "nasa_tlx"
    assert p.scoring.collision_penalty_s == 60.0
    assert p.analysis.alpha == 0.05 and p.analysis.posthoc.startswith("lsd")
    s = p.secondary_settings
    assert (s.block_size, s.baseline_size) == (20, 40)


def test_reactive_protocol_compares_manual_and_reactive_without_secondary_task():
    p = load_protocol("reactive-7-5")
    assert p.modes == ("manual", "reactive_bn")
    assert not p.main.secondary and p.phase("baseline") is None
    assert p.main.end_on_collision and not p.main.inspection
    assert p.main.route == ("A", "B")
    assert {"completion_time_s", "collisions", "clearance_histogram"} <= set(p.analysis.metrics)
    assert not p.ui.show_map and p.ui.layout == "laser"


def test_ui_layout_defaults_to_the_map_and_is_validated():
    # the object is marked on the map, so a screen without one cannot mark it
    text = shipped_text("pilot").replace("show_object = true", "show_object = false")
    assert load_protocol("pilot", known_modes=KNOWN).ui.layout == "map"
    laser = parse_protocol(
        text.replace("show_map = true", 'layout = "laser"\nshow_map = false', 1),
        "p.toml",
        known_modes=KNOWN,
    )
    assert laser.ui.layout == "laser" and not laser.ui.show_map
    # without show_map the laser layout has no map
    no_map = text.replace("show_map = true", 'layout = "laser"', 1)
    assert not parse_protocol(no_map, "p.toml", known_modes=KNOWN).ui.show_map
    bad = text.replace("show_map = true", 'layout = "rviz"', 1)
    with pytest.raises(ValueError, match=r"'ui.layout': must be one of map, laser, got 'rviz'"):
        parse_protocol(bad, "p.toml", known_modes=KNOWN)


def test_recording_camera_defaults_and_settings():
    text = shipped_text("pilot")
    assert load_protocol("pilot", known_modes=KNOWN).recording.camera_hz == 2.0  # DESIGN.md
    custom = text + "\n[recording]\ncamera_hz = 5\ncamera_width = 320\njpeg_quality = 90\n"
    rec = parse_protocol(custom, "p.toml", known_modes=KNOWN).recording
    assert (rec.camera_hz, rec.camera_width, rec.jpeg_quality) == (5.0, 320, 90)
    off = parse_protocol(text + "\n[recording]\ncamera_hz = 0\n", "p.toml", known_modes=KNOWN)
    assert off.recording.camera_hz == 0.0


def test_pilot_protocol_is_short():
    p = load_protocol("pilot", known_modes=KNOWN)
    thesis = load_protocol("thesis-7-6", known_modes=KNOWN)
    assert len(p.modes) == 3 and p.study.participants == 6
    assert p.phase("baseline").questions == 10 and p.main.block_size == 5
    assert p.main.after_trial.weights == "raw"
    assert p.phase("practice").time_limit_s < thesis.phase("practice").time_limit_s
    assert p.phase("training").duration_s < thesis.phase("training").duration_s
    assert p.phase("practice").on_fail == "continue"


# --------------------------------------------------------------- the practice course


def test_practice_course_loads_and_its_goal_is_reachable_through_the_narrow_doorway():
    s = load_scenario("practice_course")
    assert s.dock is not None and s.dock.table == "" and not s.tables
    assert len(s.question_region) == 0
    grid = build_grid(s)
    clearance = s.robot.width / 2 + 0.02
    start, goal = (s.start.x, s.start.y), (s.dock.pose.x, s.dock.pose.y)
    path = shortest_path(grid, start, goal, clearance_m=clearance)
    assert path is not None
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    assert 5.0 < length < 15.0  # short: a practice attempt, not a study trial
    doorways = [c for c in derive_components(s) if c.kind == "doorway"]
    assert len(doorways) == 1
    door = np.asarray(doorways[0].centre)
    assert np.min(np.linalg.norm(path - door, axis=1)) < 0.2  # the way leads through it
    # closing the doorway cuts A off from the goal: the narrow passage is the only way
    closed = dataclasses.replace(grid, occupied=grid.occupied.copy())
    r, c = grid.world_to_cell(door.reshape(1, 2))[0]
    closed.occupied[max(r - 12, 0) : r + 13, max(c - 3, 0) : c + 4] = True
    assert shortest_path(closed, start, goal, clearance_m=clearance) is None


# ----------------------------------------------------------------- malformed protocols

BAD = [
    (
        'names = ["manual", "reactive_bn", "contextual_task"]',
        'names = ["manual", "teleport"]',
        "modes.names[1]",
    ),
    ('names = ["manual", "reactive_bn", "contextual_task"]', "names = []", "modes.names"),
    ('names = ["manual", "reactive_bn", "contextual_task"]', 'names = ["manual"]', "modes.names"),
    (
        'names = ["manual", "reactive_bn", "contextual_task"]',
        'names = ["manual", "manual"]',
        "modes.names",
    ),
    (
        'counterbalancing = "full_permutation"',
        'counterbalancing = "latin"',
        "modes.counterbalancing",
    ),
    ("hidden = true", "hidden = false", "modes.hidden"),
    ("participants = 6 ", "participants = 6\ncolour = 1 ", "study.colour"),
    ("participants = 6 ", "participants = 0 ", "study.participants"),
    ('kind = "debrief"', 'kind = "briefing"', "phases[6].kind"),
    ('kind = "baseline"', 'kind = "practice"', "phases[4].kind"),
    ('kind = "debrief"', 'kind = "epilogue"', "phases[6].kind"),
    ("time_limit_s = 60.0", "time_limit_s = -5.0", "phases[3].time_limit_s"),
    ("time_limit_s = 60.0", "time_limit_s = 60.0\ntime_limt_s = 5", "phases[3].time_limt_s"),
    ('scenario = "practice_course"', 'scenario = "no_such_room"', "phases[3].scenario"),
    ('scenario = "practice_course"', 'scenario = "demo_wall_following"', "phases[3].scenario"),
    (
        'scenario = "cluttered_room"\nroute',
        'scenario = "demo_docking"\nroute',
        "phases[5].inspection",
    ),
    (
        'scenario = "cluttered_room"\nduration_s',
        'scenario = "demo_docking"\nduration_s',
        "phases[2].secondary",
    ),
    ('route = ["A", "B", "A"]', 'route = ["B", "A"]', "phases[5].route"),
    ('route = ["A", "B", "A"]', 'route = ["A", "A"]', "phases[5].route"),
    ('route = ["A", "B", "A"]', 'route = ["A", "C"]', "phases[5].route[1]"),
    ("block_size = 5", "block_size = 0", "phases[5].block_size"),
    ('weights = "raw"', 'weights = "weighted"', "phases[5].after_trial.weights"),
    ("duration_s = 20.0", "duration_s = 0", "phases[2].duration_s"),
    ("direct_view = true", 'direct_view = true\nmodes = ["joystick"]', "phases[2].modes[0]"),
    ("direct_view = true", 'direct_view = "yes"', "phases[2].direct_view"),
    ("[scoring]", "[secondary]\nblock_size = 20\n\n[scoring]", "secondary.block_size"),
    ("[scoring]", "[secondary]\np_correct = 1.5\n\n[scoring]", "secondary.p_correct"),
    ("collision_penalty_s = 60.0", "collision_penalty_s = -1", "scoring.collision_penalty_s"),
    ("alpha = 0.05", "alpha = 1.5", "analysis.alpha"),
    ('gate = "auto"', 'gate = "bonferroni"', "analysis.gate"),
    ('posthoc = "lsd_paired"', 'posthoc = "tukey"', "analysis.posthoc"),
    ('posthoc = "lsd_paired"', 'posthoc_gate = "maybe"', "analysis.posthoc_gate"),
    ('timeouts = "exclude"', 'timeouts = "drop"', "analysis.timeouts"),
    ('"completion_time_s",', '"speed",', "analysis.metrics[0]"),
    ("window = [1280, 720]", "window = [1280]", "ui.window"),
    ("show_map = true", 'show_map = true\nlayout = "rviz"', "ui.layout"),
    ("show_map = true", 'show_map = true\nlayout = "laser"', "ui.show_map"),
    ("show_map = true", "show_map = true\n[ui.instructions]\nmian = 'x'", "ui.instructions.mian"),
    ("show_map = true", "show_map = true\n[input.axes]\nvx = 0", "input.axes.vy"),
    ("show_map = true", "show_map = true\n[input]\ndeadzone = 1.0", "input.deadzone"),
    ("show_map = true", "show_map = true\n[recording]\ncamera_hz = -2", "recording.camera_hz"),
    ("show_map = true", "show_map = true\n[recording]\ncamera_hz = 25", "recording.camera_hz"),
    ("show_map = true", "show_map = true\n[recording]\njpeg_quality = 0", "recording.jpeg_quality"),
    ("show_map = true", "show_map = true\n[recording]\ncamera_width = 8", "recording.camera_width"),
    ("show_map = true", "show_map = true\n[recording]\nfps = 2", "recording.fps"),
    (
        "[modes]",
        "[modes.settings.reactive_bn]\nno_such_setting = 1\n[modes]",
        "modes.settings.reactive_bn",
    ),
    # issue 19: the participant's texts and keys
    ("inspect the {object},", "inspect the {colour},", "phases[0].text"),
    ("inspect the {object},", "attempt {attempt},", "phases[0].text"),
    ("show_map = true", 'show_map = true\n[ui.texts]\ntimes_up = "{k} {foo}"', "ui.texts.times_up"),
    ("show_map = true", 'show_map = true\n[ui.texts]\ntime_up = "x"', "ui.texts.time_up"),
    (
        "show_map = true",
        "show_map = true\n[ui.instructions]\nmain = '{attempt}'",
        "ui.instructions.main",
    ),
    ("show_map = true", 'show_map = true\n[input.keys]\nforward = "1"', "input.keys.forward"),
    ("show_map = true", 'show_map = true\n[input.keys]\nleft = "Up"', "input.keys.left"),
    ("show_map = true", 'show_map = true\n[input.keys]\nyes = "w"', "input.keys.yes"),
    ("show_map = true", 'show_map = true\n[input.names]\nyes = ""', "input.names.yes"),
    ("show_map = true", 'show_map = true\n[input.names]\njump = "X"', "input.names.jump"),
    ("show_map = true", "show_map = false", "ui.show_object"),
    (
        "secondary = true\nrehearsal",
        "secondary = false\nrehearsal",
        "phases[2].rehearsal_questions",
    ),
    ("rehearsal_questions = 3", "rehearsal_questions = -1", "phases[2].rehearsal_questions"),
    ('posthoc = "lsd_paired"', 'posthoc = "tukey"', "analysis.posthoc"),
    ('posthoc = "lsd_paired"', 'posthoc = "holm"\ntest = "anova"', "analysis.test"),
    (
        "secondary_baseline_level = true",
        "secondary_baseline_level = true\ntests = 3",
        "analysis.tests",
    ),
    (
        "secondary_baseline_level = true",
        'secondary_baseline_level = true\n[analysis.tests]\ncollisions = "ranks"',
        "analysis.tests.collisions",
    ),
    (
        "secondary_baseline_level = true",
        'secondary_baseline_level = true\n[analysis.tests]\nspeed = "friedman"',
        "analysis.tests.speed",
    ),
]


@pytest.mark.parametrize(("old", "new", "field"), BAD, ids=[b[2] for b in BAD])
def test_malformed_protocol_names_file_and_field(old, new, field):
    text = shipped_text("pilot")
    assert old in text
    source = "/tmp/bad-pilot.toml"
    with pytest.raises(ValueError) as error:
        parse_protocol(text.replace(old, new, 1), source, known_modes=KNOWN)
    message = str(error.value)
    assert message.startswith(f"{source}: field '{field}'"), message
    assert len(message.splitlines()) == 1


def test_object_placeholder_needs_an_object_in_the_main_scene():
    text = shipped_text("pilot").replace("inspection = true", "inspection = false")
    text = text.replace('scenario = "cluttered_room"\nroute', 'scenario = "demo_docking"\nroute')
    text = text.replace("secondary = true\nblock_size", "secondary = false\nblock_size")
    with pytest.raises(ValueError) as error:
        parse_protocol(text, "/tmp/p.toml", known_modes=KNOWN)
    assert str(error.value).startswith("/tmp/p.toml: field 'phases[0].text': uses {object}")
    # without the placeholder the same protocol loads, its main text without an object
    plain = parse_protocol(text.replace("inspect the {object}, ", ""), "p.toml", known_modes=KNOWN)
    assert "{object}" not in plain.ui.instructions["main"]


def test_protocol_texts_fill_the_scene_words_and_keep_the_trial_ones():
    p = load_protocol("thesis-7-6", known_modes=KNOWN)
    assert "red cylinder" in p.phases[0].text and "purple dots" in p.phases[0].text
    assert "{attempts}" in p.ui.instructions["practice"]  # filled per attempt, when shown
    assert p.ui.texts["times_up"] == "Time's up: this drive is over."
    assert p.ui.show_object and p.phase("training").rehearsal_questions == 3
    assert dict(p.input.keys) == {
        "forward": "W", "back": "S", "left": "A", "right": "D", "turn_left": "Q",
        "turn_right": "E", "yes": "Y", "no": "N", "pause": "P",
    }  # fmt: skip
    assert p.input.pad_names() == {
        "move": "left stick", "turn": "right stick", "yes": "A", "no": "B", "pause": "Start",
    }  # fmt: skip


def test_bad_protocol_text_is_one_line_exit_2(tmp_path, capsys):
    from study.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text(shipped_text("pilot").replace("inspect the {object},", "see {it},"))
    with pytest.raises(SystemExit) as exit_info:
        main(["plan", "--protocol", str(bad)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{bad}: field 'phases[0].text': unknown placeholder {{it}}" in err[0]


def test_planned_tests_per_metric():
    text = shipped_text("pilot").replace(
        "secondary_baseline_level = true",
        'secondary_baseline_level = true\ntest = "auto"\n[analysis.tests]\ncollisions = "friedman"',
    )
    text = text.replace('posthoc = "lsd_paired"', 'posthoc = "bonferroni"')
    analysis = parse_protocol(text, "p.toml", known_modes=KNOWN).analysis
    assert analysis.posthoc == "bonferroni" and analysis.posthoc_gate == "auto"
    gated = text.replace('posthoc = "bonferroni"', 'posthoc = "holm"\nposthoc_gate = "omnibus"')
    assert parse_protocol(gated, "p.toml", known_modes=KNOWN).analysis.posthoc_gate == "omnibus"
    assert analysis.test_for("collisions") == "friedman" and analysis.test_for("tlx_raw") == "auto"
    plain = parse_protocol(shipped_text("pilot"), "p.toml", known_modes=KNOWN).analysis
    assert plain.test_for("collisions") == "rm_anova"  # the thesis's test unless declared


def test_analysis_choices_match_the_analysis_package():
    from analysis import stats
    from analysis.data import load as analysis_data

    assert GATES == stats.GATES
    assert TIMEOUTS == analysis_data.TIMEOUTS
    assert POSTHOC == stats.POSTHOC
    assert POSTHOC_GATES == stats.POSTHOC_GATES
    assert TESTS == stats.TESTS


def test_malformed_toml_and_missing_main_are_refused():
    with pytest.raises(ValueError, match=r"^bad\.toml: not valid TOML"):
        parse_protocol("[study\nname = 1", "bad.toml", known_modes=KNOWN)
    text = shipped_text("reactive-7-5")
    start = text.index('[[phases]]\nkind = "main"')
    end = text.index("[[phases]]", start + 1)
    with pytest.raises(ValueError, match=r"field 'phases'.*main"):
        parse_protocol(text[:start] + text[end:], "x.toml")


def test_unregistered_mode_is_refused_by_the_live_registry():
    text = shipped_text("reactive-7-5").replace('"reactive_bn"]', '"no_such_mode"]', 1)
    with pytest.raises(ValueError, match=r"field 'modes.names\[1\]'.*registered modes: "):
        parse_protocol(text, "x.toml")


def test_questionnaire_defaults_and_absence():
    text = shipped_text("pilot")
    with_defaults = text.replace('instrument = "nasa_tlx"\nweights = "raw"', "", 1)
    after = parse_protocol(with_defaults, "x.toml", known_modes=KNOWN).main.after_trial
    assert after is not None and (after.instrument, after.weights) == ("nasa_tlx", "per_trial")
    assert load_protocol("reactive-7-5").main.after_trial is None


def test_mode_settings_are_carried_and_checked():
    text = shipped_text("reactive-7-5").replace(
        "[modes]", "[modes.settings.reactive_bn]\nsector_deg = 10.0\n\n[modes]", 1
    )
    p = parse_protocol(text, "x.toml")
    assert dict(p.mode_settings["reactive_bn"]) == {"sector_deg": 10.0}


def test_protocol_pickles_for_worker_processes():
    p = load_protocol("reactive-7-5")
    q = pickle.loads(pickle.dumps(p))
    assert q == p and q.sha256 == p.sha256 and q.text == p.text


def test_sha256_must_match_the_text():
    p = load_protocol("reactive-7-5")
    with pytest.raises(ValueError, match="sha256"):
        dataclasses.replace(p, text=p.text + " ")


def test_scenario_files_are_found_beside_the_protocol(tmp_path, monkeypatch):
    course = SCENARIO_DIR / "practice_course.toml"
    (tmp_path / "my_course.toml").write_text(course.read_text(encoding="utf-8"), encoding="utf-8")
    text = shipped_text("reactive-7-5").replace(
        '[[phases]]\nkind = "main"',
        '[[phases]]\nkind = "practice"\nscenario = "my_course.toml"\ntime_limit_s = 60.0\n\n'
        '[[phases]]\nkind = "main"',
        1,
    )
    path = tmp_path / "mine.toml"
    path.write_text(text, encoding="utf-8")
    monkeypatch.chdir(SCENARIO_DIR)  # anywhere but the protocol's folder
    practice = load_protocol(path).phase("practice")
    assert practice.scenario == str(tmp_path / "my_course.toml")
    assert load_scenario(practice.scenario).name == "practice_course"


def test_missing_protocol_file_names_it(tmp_path):
    with pytest.raises(ValueError, match="no-such-protocol"):
        load_protocol("no-such-protocol")
    with pytest.raises(ValueError, match="directory"):
        load_protocol(tmp_path)
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b"[study]\nname = '\xe9'\n")
    with pytest.raises(ValueError, match="UTF-8"):
        load_protocol(bad)


def test_protocol_loaded_from_a_copy_has_the_same_hash(tmp_path):
    copy = tmp_path / "mine.toml"
    copy.write_text(shipped_text("reactive-7-5"), encoding="utf-8")
    assert load_protocol(copy).sha256 == load_protocol("reactive-7-5").sha256
    copy.write_text(shipped_text("reactive-7-5") + "\n# a comment\n", encoding="utf-8")
    assert load_protocol(copy).sha256 != load_protocol("reactive-7-5").sha256


# ------------------------------------------------------------------------- asa plan


def run_plan(capsys, *args: str) -> tuple[int, str, str]:
    try:
        main(["plan", *args])
        code = 0
    except SystemExit as exit_info:
        code = exit_info.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_plan_for_the_thesis_study_is_balanced(capsys):
    code, out, err = run_plan(capsys, "--protocol", "thesis-7-6", "--participants", "18")
    assert code == 0, err
    assert "P01" in out and "P18" in out and "P19" not in out
    assert "balanced for full_permutation: yes" in out
    assert "warning" not in out
    code, out, _ = run_plan(capsys, "--protocol", "thesis-7-6", "--participants", "18", "--json")
    result = json.loads(out)
    assert result["balanced"] and result["warnings"] == []
    assert [row["order_index"] for row in result["participants"]] == [i % 6 for i in range(18)]


def test_plan_json_for_the_reactive_study(capsys):
    code, out, err = run_plan(capsys, "--protocol", "reactive-7-5", "--json")
    assert code == 0 and err == ""
    result = json.loads(out)
    assert result["protocol"] == "reactive-7-5" and len(result["sha256"]) == 64
    assert result["scheme"] == "full_permutation" and result["balanced"]
    codes = [row["code"] for row in result["participants"]]
    assert codes == [f"P{i:02d}" for i in range(1, 7)]
    assert {tuple(row["modes"]) for row in result["participants"]} == {
        ("manual", "reactive_bn"),
        ("reactive_bn", "manual"),
    }
    assert result["balance"]["position_counts"] == {"manual": [3, 3], "reactive_bn": [3, 3]}


def test_plan_with_an_odd_number_warns_which_positions(capsys):
    code, out, err = run_plan(capsys, "--protocol", "reactive-7-5", "--participants", "5")
    assert code == 0
    assert "balanced for full_permutation: NO" in out
    assert "warning: position 1 is unbalanced" in out and "position 2" in out


def test_plan_random_scheme_is_reproducible_per_seed(tmp_path, capsys, seed):
    text = shipped_text("reactive-7-5").replace('"full_permutation"', '"random"', 1)
    path = tmp_path / "random.toml"
    path.write_text(text, encoding="utf-8")
    runs = [
        json.loads(run_plan(capsys, "--protocol", str(path), "--seed", str(s), "--json")[1])
        for s in (seed, seed, seed + 1)
    ]
    assert runs[0]["participants"] == runs[1]["participants"]
    assert runs[0]["seed"] == seed


def test_plan_bad_input_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        shipped_text("reactive-7-5").replace("participants = 6", "participants = -1", 1),
        encoding="utf-8",
    )
    # the real shell once, then in-process
    result = subprocess.run(
        [sys.executable, "-m", "study.cli", "plan", "--protocol", str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "study.participants" in lines[0]
    for args, needles in (
        (["--protocol", "reactive-7-5", "--participants", "0"], ["--participants"]),
        (["--protocol", "no-such-protocol"], ["no-such-protocol", "shipped"]),
        (["--protocol", "reactive-7-5", "--participants", "many"], ["--participants"]),
    ):
        code, out, err = run_plan(capsys, *args)
        assert code == 2 and out == ""
        lines = err.strip().splitlines()
        assert len(lines) == 1 and all(n in lines[0] for n in needles), lines
