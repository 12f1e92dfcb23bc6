"""Rerun recordings of trials and ``asa replay``: what goes in comes back out, every file
passes ``rerun rrd verify``, trials stay apart, rerun's analytics stay off, bad ids exit 2."""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from sqlalchemy.orm import Session

from autonomy.types import Assist
from sim.occupancy import build_grid
from sim.scenario import available_scenarios, load_scenario
from sim.semantics import derive_components
from sim.types import Pose2D
from study.cli import main
from study.data.recording import (
    ENTITY,
    TIMELINE,
    RecorderSettings,
    TrialRecorder,
    recording_id,
)
from study.data.rrd import (
    ANALYTICS_OFF_ENV,
    recording_summary,
    rerun_environment,
    rerun_executable,
    verify,
    verify_many,
)
from study.data.storage import Participant, SessionRow, Study, Trial, open_database

DT = 0.05  # [s] control tick


@pytest.fixture(scope="module")
def scene():
    scenario = load_scenario("demo_docking")
    return scenario, derive_components(scenario), build_grid(scenario)


def _record(path, key, scene, rng, *, n=200, t0=0.0, settings=None):
    """Feed ``n`` synthetic ticks (and a few events and questions); return what went in."""
    scenario, components, grid = scene
    ids = [c.id for c in components] + ["", "not_in_scene"]
    expected = {"targets": 0, "camera": 0, "events": 0, "questions": 0, "times": []}
    state = None
    with TrialRecorder(
        path,
        trial_key=key,
        scenario=scenario,
        components=components,
        grid=grid,
        settings=settings,
    ) as rec:
        x, y, yaw = scenario.start.x, scenario.start.y, scenario.start.yaw
        target, label = "", ""
        for i in range(n):
            t = t0 + i * DT
            x, y, yaw = x + rng.normal(0, 0.01), y + rng.normal(0, 0.01), yaw + rng.normal(0, 0.02)
            if i % 25 == 0:  # the recognised target changes now and then
                target, label = str(rng.choice(ids)), str(rng.choice(["FT", "OA", "GOA", ""]))
            assist = Assist(
                v=rng.normal(size=3),
                g=rng.normal(size=3),
                beta=float(rng.uniform()),
                label=label,
                target=target,
                scores={"FT": 0.5, "OA": 0.3, "GOA": 0.2},
                predicted_path=rng.normal(size=(int(rng.choice([0, 15, 15, 30])), 3)),
                timings_ms={"total": 1.0},
            )
            if (target, label) != state:
                state = (target, label)
                expected["targets"] += 1
            camera = None
            if i % 10 == 0:
                camera = rng.integers(0, 255, size=(24, 32, 3), dtype=np.uint8)
                expected["camera"] += 1
            rec.tick(
                t,
                Pose2D(x, y, yaw),
                rng.uniform(-8, 8, size=(540, 2)),
                rng.normal(size=3),
                rng.normal(size=3),
                assist,
                camera,
            )
            expected["times"].append(t)
            if i % 70 == 5:
                rec.event(t, "collision", "crate")
                expected["events"] += 1
            if i % 60 == 3:
                rec.question(t, f"{i} + 12 = {i + 12}?")
                expected["questions"] += 1
    return expected


def _rows_at(span_s: float, hz: float) -> int:
    """Rows of a stream kept at ``hz`` over ``span_s`` at 20 Hz ticks, the first at t = 0."""
    return math.floor(span_s * min(hz, 1 / DT) + 1e-9) + 1


def _motion_rows(n: int) -> int:
    """Rows of pose, u, v and beta over ``n`` ticks: every second (10 Hz) and the last."""
    assert RecorderSettings().motion_hz == 10.0
    return len(set(range(0, n, 2)) | {n - 1})


def test_recording_verifies_and_its_summary_matches_what_went_in(tmp_path, scene, rng):
    path = tmp_path / "trial.rrd"
    n = 200
    # every pose counts as a move, so the laser keeps its rate
    settings = RecorderSettings(still_m=0.0, still_rad=0.0)
    expected = _record(path, "P01/main/0", scene, rng, n=n, settings=settings)
    verify(path)
    summary = recording_summary(path)
    rows = {name: counts["rows"] for name, counts in summary["entities"].items()}
    span_s = (n - 1) * DT
    # rate-limited streams: one row per period, the first at t = 0
    for entity in (ENTITY.robot, ENTITY.u, ENTITY.v, ENTITY.beta):
        assert rows[entity] == _motion_rows(n), entity
    assert rows[ENTITY.score("FT")] == _rows_at(span_s, settings.scores_hz)
    assert rows[ENTITY.laser] == _rows_at(span_s, settings.laser_hz)
    assert rows[ENTITY.predicted_path] == _rows_at(span_s, settings.path_hz)
    assert rows[ENTITY.camera] == expected["camera"]
    assert rows[ENTITY.target] == expected["targets"]
    assert rows[ENTITY.events] == expected["events"]
    assert rows[ENTITY.questions] == expected["questions"]
    statics = {name for name, counts in summary["entities"].items() if counts["static"]}
    assert {ENTITY.map, ENTITY.obstacles, ENTITY.footprint} <= statics
    assert (ENTITY.question_region in statics) == bool(len(scene[0].question_region))
    for kind in {c.kind for c in scene[1]}:
        assert ENTITY.component(kind) in statics
    assert summary["time_range_s"] == pytest.approx([0.0, span_s], abs=1e-6)
    assert summary["timeline"] == "sim_time"
    assert summary["recording_id"] == str(recording_id("P01/main/0"))


def _temporal_column(path, entity: str, column: str) -> tuple[list[float], list]:
    """(times [s], values) of one column of ``entity``'s temporal rows, in time order."""
    from rerun.chunk import RrdReader

    rows = []
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.entity_path.lstrip("/") != entity or chunk.is_static or chunk.is_empty:
            continue
        batch = chunk.to_record_batch()
        if column in batch.schema.names:
            times = batch.column(TIMELINE).cast("int64").to_pylist()
            rows += zip(times, batch.column(column).to_pylist(), strict=True)
    rows.sort(key=lambda r: r[0])
    return [t / 1e9 for t, _ in rows], [v for _, v in rows]


def test_batched_targets_and_paths_hold_what_went_in(tmp_path, scene, rng):
    scenario, components, grid = scene
    ids = [c.id for c in components] + ["", "not_in_scene"]
    path = tmp_path / "batched.rrd"
    settings = dataclasses.replace(RecorderSettings(), flush_every_s=0.35, path_hz=20.0)
    want_targets, want_paths = [], []
    with TrialRecorder(
        path, trial_key="b", scenario=scenario, components=components, grid=grid, settings=settings
    ) as rec:
        target = None
        for i in range(60):
            t = i * DT
            if i == 0 or rng.random() < 0.3:
                target = str(rng.choice(ids))
            k = int(rng.choice([0, 3, 8, 8]))  # ragged paths, empty ones too
            predicted = rng.normal(size=(k, 3))
            assist = Assist(
                v=np.zeros(3),
                g=np.zeros(3),
                beta=0.5,
                label="FT",
                target=target,
                scores={},
                predicted_path=predicted,
                timings_ms={},
            )
            pose = Pose2D(*rng.normal(size=3))
            if not want_targets or want_targets[-1][1] != target:
                want_targets.append((t, target))
            want_paths.append((t, TrialRecorder._path_in_map(pose, predicted)))
            rec.tick(t, pose, None, np.zeros(3), np.zeros(3), assist=assist)
    verify(path)
    by_id = {c.id: c for c in components}
    times, positions = _temporal_column(path, ENTITY.target, "Points2D:positions")
    _, labels = _temporal_column(path, ENTITY.target, "Points2D:labels")
    assert times == pytest.approx([t for t, _ in want_targets], abs=1e-9)
    for (_, target), got, text in zip(want_targets, positions, labels, strict=True):
        if target in by_id:  # highlighted: the component's points, labelled once
            want = by_id[target].points if len(by_id[target].points) else [by_id[target].centre]
            np.testing.assert_allclose(np.asarray(got), np.asarray(want)[: len(got)], atol=1e-6)
            assert text[0] == f"{target} (FT)" and not any(text[1:])
        else:  # nothing highlighted
            assert got == [] and text == []
    times, strips = _temporal_column(path, ENTITY.predicted_path, "LineStrips2D:strips")
    assert times == pytest.approx([t for t, _ in want_paths], abs=1e-9)
    for (_, want), got in zip(want_paths, strips, strict=True):
        (strip,) = got
        np.testing.assert_allclose(np.asarray(strip).reshape(-1, 2), want, atol=1e-5)


def test_two_trials_in_one_process_stay_separate(tmp_path, scene, rng):
    scenario, components, grid = scene
    paths = [tmp_path / "a.rrd", tmp_path / "b.rrd"]
    counts, offsets = [60, 35], [0.0, 100.0]
    recorders = [
        TrialRecorder(p, trial_key=k, scenario=scenario, components=components, grid=grid)
        for p, k in zip(paths, ["P01/main/0", "P01/main/1"], strict=True)
    ]
    # interleaved ticks, as two sessions in one process would produce
    for i in range(max(counts)):
        for rec, n, t0 in zip(recorders, counts, offsets, strict=True):
            if i < n:
                pose = Pose2D(float(rng.uniform(1, 3)), float(rng.uniform(1, 3)), 0.0)
                rec.tick(t0 + i * DT, pose, None, np.ones(3), np.ones(3))
    recorders[0].event(1.0, "dock", "docked at B")
    for rec in recorders:
        rec.close()
    summaries = [recording_summary(p) for p in paths]
    for summary, n, t0, key in zip(
        summaries, counts, offsets, ["P01/main/0", "P01/main/1"], strict=True
    ):
        verify(summary["path"])
        assert summary["entities"][ENTITY.robot]["rows"] == _motion_rows(n)
        assert summary["time_range_s"] == pytest.approx([t0, t0 + (n - 1) * DT], abs=1e-6)
        assert summary["recording_id"] == str(recording_id(key))
    assert ENTITY.events in summaries[0]["entities"]
    assert ENTITY.events not in summaries[1]["entities"]
    assert ENTITY.beta not in summaries[0]["entities"]  # no assist given: no plot


@pytest.mark.parametrize("name", available_scenarios())
def test_every_scenario_records_its_static_scene(tmp_path, name):
    scenario = load_scenario(name)
    components = derive_components(scenario)
    path = tmp_path / f"{name}.rrd"
    with TrialRecorder(
        path, trial_key=name, scenario=scenario, components=components, grid=build_grid(scenario)
    ) as rec:
        rec.tick(0.0, scenario.start, None, np.zeros(3), np.zeros(3))
    entities = recording_summary(path)["entities"]
    assert entities[ENTITY.robot]["rows"] == 1
    assert {ENTITY.component(c.kind) for c in components} <= set(entities)
    assert (ENTITY.question_region in entities) == bool(len(scenario.question_region))
    assert entities[ENTITY.map]["static"] == 1


def test_recording_id_is_deterministic_and_unique_per_trial():
    assert recording_id("P01/main/0") == recording_id("P01/main/0")
    assert recording_id("P01/main/0") != recording_id("P01/main/1")


def test_closed_recorder_refuses_ticks_and_settings_are_checked(tmp_path, scene):
    scenario, components, grid = scene
    rec = TrialRecorder(
        tmp_path / "c.rrd", trial_key="k", scenario=scenario, components=components, grid=grid
    )
    rec.close()
    rec.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        rec.tick(0.0, Pose2D(0, 0, 0), None, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="flush_every_s"):
        dataclasses.replace(RecorderSettings(), flush_every_s=0.0)
    with pytest.raises(ValueError, match="jpeg_quality"):
        RecorderSettings(jpeg_quality=101)


def test_verify_rejects_garbage_and_truncated_recordings(tmp_path, scene, rng):
    good = tmp_path / "good.rrd"
    _record(good, "k", scene, rng, n=20)
    truncated = tmp_path / "truncated.rrd"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    garbage = tmp_path / "garbage.rrd"
    garbage.write_text("not a recording")
    for bad in (truncated, garbage):
        with pytest.raises(ValueError, match=bad.name):
            verify(bad)
    with pytest.raises(ValueError, match="garbage.rrd"):
        recording_summary(garbage)
    # many at once: one rerun process, and only the bad ones named
    other = tmp_path / "other.rrd"
    _record(other, "k2", scene, rng, n=10)
    assert verify_many([good, other]) == {}
    failures = verify_many([good, truncated, other, garbage, tmp_path / "missing.rrd"])
    assert set(failures) == {truncated, garbage, tmp_path / "missing.rrd"}
    assert "garbage.rrd" in failures[garbage]


def _fresh_rerun_home(tmp_path, name):
    home = tmp_path / name
    dirs = {"HOME": home, "XDG_CONFIG_HOME": home / "config", "XDG_DATA_HOME": home / "data"}
    for d in dirs.values():
        d.mkdir(parents=True, exist_ok=True)
    return home, {k: str(v) for k, v in dirs.items()}


def _files_under(root):
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())


def test_analytics_stay_off_in_the_environment_the_module_sets(tmp_path):
    assert all(rerun_environment()[k] == v for k, v in ANALYTICS_OFF_ENV.items())
    # a whole trial recorded and verified through the module, in a fresh rerun home
    # whose environment does NOT disable analytics itself
    home, dirs = _fresh_rerun_home(tmp_path, "module")
    env = {k: v for k, v in os.environ.items() if k not in ANALYTICS_OFF_ENV}
    script = textwrap.dedent(
        f"""
        import numpy as np
        from sim.occupancy import build_grid
        from sim.scenario import available_scenarios, load_scenario
        from sim.semantics import derive_components
        from sim.types import Pose2D
        from study.data.recording import TrialRecorder
        from study.data.rrd import verify
        s = load_scenario("demo_docking")
        path = {str(home / "t.rrd")!r}
        with TrialRecorder(path, trial_key="k", scenario=s, components=derive_components(s),
                           grid=build_grid(s)) as rec:
            for i in range(40):
                rec.tick(i * 0.05, Pose2D(1.0, 1.0, 0.0), None, np.zeros(3), np.zeros(3))
        verify(path)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        env={**env, **dirs},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert _files_under(home) == ["t.rrd"]  # no rerun analytics config or data anywhere
    # control: the bare rerun CLI in the same kind of fresh home does start analytics,
    # so the check above can fail
    control, control_dirs = _fresh_rerun_home(tmp_path, "control")
    (control / "t.rrd").write_bytes((home / "t.rrd").read_bytes())
    subprocess.run(
        [rerun_executable(), "rrd", "verify", str(control / "t.rrd")],
        env={**env, **control_dirs},
        capture_output=True,
        timeout=120,
        check=True,
    )
    assert any("analytics" in f for f in _files_under(control))


# ------------------------------------------------------------------------ asa replay


@pytest.fixture
def study_db(tmp_path, scene, rng):
    """A hand-made database: P01 with a recorded trial (relative path), a trial without a
    recording and one whose file is gone; P02 with a trial of its own."""
    db = tmp_path / "study.db"
    (tmp_path / "recordings").mkdir()
    _record(tmp_path / "recordings" / "p01_main_0.rrd", "P01/main/0", scene, rng, n=40)
    with Session(open_database(db)) as s, s.begin():
        study = Study(
            name="t", protocol_text="x", protocol_sha256="0" * 64, platform_version="t", seed=1
        )
        s.add(study)
        s.flush()
        ids = {}
        for code in ("P01", "P02"):
            person = Participant(
                study_id=study.id, code=code, kind="scripted", order_index=0, seed=1
            )
            s.add(person)
            s.flush()
            session = SessionRow(participant_id=person.id)
            s.add(session)
            s.flush()
            for name, recording in {
                f"{code}_rec": "recordings/p01_main_0.rrd" if code == "P01" else "",
                f"{code}_none": "",
                f"{code}_gone": "recordings/gone.rrd",
            }.items():
                trial = Trial(
                    participant_id=person.id,
                    session_id=session.id,
                    phase="main",
                    mode="manual",
                    ordinal=len(ids),
                    scenario="demo_docking",
                    seed=1,
                    recording_path=recording,
                )
                s.add(trial)
                s.flush()
                ids[name] = trial.id
    return db, ids


def test_replay_print_shows_the_summary(study_db, capsys):
    db, ids = study_db
    main(
        [
            "replay",
            "--db",
            str(db),
            "--participant",
            "P01",
            "--trial",
            str(ids["P01_rec"]),
            "--print",
        ]
    )
    out = capsys.readouterr().out
    assert "p01_main_0.rrd" in out
    for entity in (ENTITY.robot, ENTITY.map, ENTITY.beta):
        assert entity in out
    assert "0.000 s .. 1.950 s" in out


@pytest.mark.parametrize(
    ("participant", "trial", "field"),
    [
        ("P99", "P01_rec", "participant.code"),
        ("P01", "P02_rec", "trial.id"),  # another participant's trial
        ("P01", 10_000, "trial.id"),
        ("P01", "P01_none", "trial.recording_path"),
        ("P01", "P01_gone", "trial.recording_path"),
    ],
)
def test_replay_bad_ids_are_one_line_exit_2(study_db, capsys, participant, trial, field):
    db, ids = study_db
    trial_id = ids.get(trial, trial)
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", "--db", str(db), "--participant", participant, "--trial", str(trial_id)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert str(db) in err[0] and field in err[0]


def test_replay_missing_database_is_one_line_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", "--db", str(tmp_path / "none.db"), "--participant", "P01", "--trial", "1"])
    assert exit_info.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_camera_frames_are_small_jpegs_and_a_standstill_logs_no_scans_or_frames(
    tmp_path, scene, rng
):
    import io

    from PIL import Image

    scenario, components, grid = scene
    settings = RecorderSettings(camera_hz=2.0)
    path = tmp_path / "camera.rrd"
    pose, sent = scenario.start, []
    with TrialRecorder(
        path, trial_key="c", scenario=scenario, components=components, grid=grid, settings=settings
    ) as rec:
        for i in range(120):  # 6 s: driving for the first 3 s, then standing still
            t = i * DT
            if i < 60:
                pose = Pose2D(pose.x + 0.02, pose.y, pose.yaw + 0.001)
            front = tail = None
            if rec.camera_due(t, pose):
                front = rng.integers(0, 255, size=(240, 320, 3), dtype=np.uint8)
                tail = front[::-1].copy()
                sent.append(t)
            points = rng.uniform(-5, 5, size=(540, 2))
            rec.tick(t, pose, points, np.zeros(3), np.zeros(3), camera=front, tail_camera=tail)
    verify(path)
    # 2 Hz while driving (0, 0.5, ..., 3.0: the pose at 3 s is the one it stopped in)
    assert sent == pytest.approx([0.5 * k for k in range(7)])
    rows = {name: counts["rows"] for name, counts in recording_summary(path)["entities"].items()}
    assert rows[ENTITY.camera] == rows[ENTITY.tail_camera] == len(sent)
    assert rows[ENTITY.laser] == len(sent)  # also 2 Hz, none while standing still
    _, blobs = _temporal_column(path, ENTITY.camera, "EncodedImage:blob")
    _, points = _temporal_column(path, ENTITY.laser, "Points2D:positions")
    image = Image.open(io.BytesIO(bytes(blobs[0][0])))
    assert image.format == "JPEG" and image.size == (settings.camera_width_px, 120)
    assert len(points[0]) == len(range(0, 540, settings.laser_stride))


def test_replay_print_lists_the_camera_frames_of_a_short_trial(tmp_path, capsys, seed):
    from study.engine.standalone import standalone_trial
    from study.participants import ScriptedParticipant

    result, engine = standalone_trial(
        tmp_path,
        ScriptedParticipant(np.random.default_rng(seed)),
        scenario="practice_course",
        route=("dock",),
        timeout_s=3.0,
        seed=seed,
        camera_hz=2.0,
        camera_views=("front", "tail"),
    )
    engine.dispose()
    args = ["replay", "--db", str(tmp_path / "trial.db"), "--participant", "T01"]
    main([*args, "--trial", str(result.trial_id), "--print"])
    out = capsys.readouterr().out
    rows = {
        line.split()[0]: int(line.split()[1])
        for line in out.splitlines()
        if line.strip().startswith("camera/")
    }
    # 2 Hz while the robot drives (it starts at once): about 6 frames in 3 s, each camera
    assert 4 <= rows[ENTITY.camera] <= 7 and rows[ENTITY.tail_camera] == rows[ENTITY.camera]
    n = rows[ENTITY.camera]
    assert f"camera frames: {ENTITY.camera} {n}, {ENTITY.tail_camera} {n}" in out
