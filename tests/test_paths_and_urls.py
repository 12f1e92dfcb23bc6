"""Issue 20, files: ``--db`` paths and URLs as written, empty and foreign files refused
untouched, read-only studies, no race on a fresh database, no overwrites without
``--force``, names that cannot become paths, recordings named by study, the viewer on
localhost only."""

from __future__ import annotations

import hashlib
import multiprocessing
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from fixtures_db import FixtureSettings, make_study_db
from sqlalchemy import inspect, select
from sqlalchemy.orm import Session

from analysis.data.load import load_study
from study.data.dbfile import ro_uri
from study.data.storage import (
    SCHEMA_VERSION,
    Meta,
    Study,
    Trial,
    database_file,
    database_url,
    open_database,
)
from tests.cli_helpers import asa

SMALL = FixtureSettings(
    n_participants=2, samples=40, questions=4, baseline_questions=4, incomplete=False
)


def one_line_error(code: int, err: str) -> str:
    """The one error line of a refused command (progress lines before it are allowed)."""
    assert code == 2, err
    errors = [line for line in err.strip().splitlines() if line.startswith("asa: error")]
    assert len(errors) == 1 and err.strip().endswith(errors[0]), err
    assert "Traceback" not in err
    return errors[0]


def fingerprint(path: Path) -> tuple[str, int, int]:
    """(SHA-256, size, mtime in ns) of a file."""
    stat = path.stat()
    return hashlib.sha256(path.read_bytes()).hexdigest(), stat.st_size, stat.st_mtime_ns


def side_files(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir() if p.name.startswith(path.name + "-"))


@pytest.fixture
def study_db(tmp_path: Path, seed: int) -> Path:
    return make_study_db(tmp_path / "study.db", np.random.default_rng(seed), settings=SMALL)


# ---------------------------------------------------------------- --db as written


def test_urls_are_taken_as_written_and_paths_become_sqlite_urls(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert database_url("postgresql+psycopg://host/db") == "postgresql+psycopg://host/db"
    # a PostgreSQL URL without a driver gets psycopg 3 (issue 24)
    assert database_url("postgresql://u@host:5433/db") == "postgresql+psycopg://u@host:5433/db"
    assert database_url("postgres://host/db") == "postgresql+psycopg://host/db"
    assert database_url("postgresql+pg8000://host/db") == "postgresql+pg8000://host/db"
    assert database_url("x.db") == f"sqlite:///{tmp_path / 'x.db'}"
    assert database_file("sqlite:///x.db") == tmp_path / "x.db"
    assert database_file("sqlite:////abs/y.db") == Path("/abs/y.db")
    assert database_file("sqlite:///file:z.db?mode=ro&uri=true") == tmp_path / "z.db"


def test_a_sqlite_url_opens_the_file_not_a_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    engine = open_database("sqlite:///x.db")
    engine.dispose()
    assert (tmp_path / "x.db").is_file() and not (tmp_path / "sqlite:").exists()
    code, out, err = asa(capsys, "db", "check", "--db", "sqlite:///x.db", "--no-verify")
    assert code == 1 and "no study row" in out, err  # an empty study: checked, not refused
    assert not (tmp_path / "sqlite:").exists()


@pytest.mark.parametrize(
    ("url", "says"),
    [
        ("postgresql+pg8000://host/db", "driver"),
        ("mysql://user@host/db", "driver"),
        ("nosuchdb://host/db", "not a database URL"),
    ],
)
def test_a_url_whose_driver_is_missing_is_one_line(tmp_path, monkeypatch, capsys, url, says):
    monkeypatch.chdir(tmp_path)
    for args in (("db", "check", "--db", url), ("export", "--db", url, "--out", "csv")):
        line = one_line_error(*asa(capsys, *args)[::2])
        assert url in line and says in line
    assert list(tmp_path.iterdir()) == []  # not taken as a path


def test_no_command_normalises_its_db_option():
    import click

    from study.cli import COMMANDS, cli

    ctx = click.Context(cli)
    found = []
    stack = [cli.get_command(ctx, name) for name in COMMANDS]
    while stack:
        command = stack.pop()
        if isinstance(command, click.Group):
            stack += list(command.commands.values())
            continue
        for param in command.params:
            if "--db" in getattr(param, "opts", ()):
                found.append(command.name)
                assert param.type is click.STRING, command.name  # not click.Path
                assert param.type.convert("postgresql://host/db", param, ctx) == (
                    "postgresql://host/db"
                )
    assert {"check", "export", "replay", "report", "run", "synth"} <= set(found)


def test_a_server_style_url_is_made_a_study_when_empty_and_refused_read_only():
    """``sqlite://`` (in memory) goes the way of a server URL: no file checks."""
    engine = open_database("sqlite://")
    with Session(engine) as s:
        assert s.get(Meta, "schema_version").value == str(SCHEMA_VERSION)
    engine.dispose()
    with pytest.raises(ValueError, match="holds no tables"):
        open_database("sqlite://", create=False)


# ---------------------------------------------------------------- empty and foreign files


def _foreign_files(folder: Path) -> dict[str, Path]:
    empty = folder / "empty.db"
    empty.write_bytes(b"")
    text = folder / "notes.db"
    text.write_text("not a database at all\n" * 20, encoding="utf-8")
    other = folder / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE results (x REAL)")
    con.commit()
    con.close()
    bare = folder / "bare.db"  # an SQLite file without any table
    con = sqlite3.connect(bare)
    con.execute("PRAGMA user_version = 3")
    con.close()
    corrupt = folder / "corrupt.db"  # the SQLite header, then no database
    corrupt.write_bytes(b"SQLite format 3\x00" + bytes(range(256)) * 8)
    return {"empty": empty, "text": text, "other": other, "bare": bare, "corrupt": corrupt}


def test_empty_and_foreign_files_are_refused_and_left_untouched(tmp_path, capsys):
    files = _foreign_files(tmp_path)
    before = {name: fingerprint(path) for name, path in files.items()}
    for name, path in files.items():
        for create in (True, False):
            with pytest.raises(ValueError, match=str(path)):
                open_database(path, create=create)
        for args in (
            ("db", "check", "--db", str(path)),
            ("export", "--db", str(path), "--out", str(tmp_path / f"csv_{name}")),
            ("report", "--db", str(path), "--out", str(tmp_path / f"rep_{name}")),
        ):
            one_line_error(*asa(capsys, *args)[::2])
        assert fingerprint(path) == before[name], name
        assert side_files(path) == [], name


def test_a_folder_given_as_database_is_one_line(tmp_path, capsys):
    line = one_line_error(*asa(capsys, "db", "check", "--db", str(tmp_path))[::2])
    assert "folder" in line


# ---------------------------------------------------------------- fresh database race


def _open_at_once(path: str, start: multiprocessing.synchronize.Event, out: multiprocessing.Queue):
    start.wait()
    try:
        engine = open_database(path)
        with Session(engine) as s:
            version = s.get(Meta, "schema_version")
        engine.dispose()
        out.put("ok" if version is not None else "no version")
    except Exception as error:  # noqa: BLE001 - reported to the parent
        out.put(f"{type(error).__name__}: {error}")


def test_processes_opening_a_fresh_database_at_once_all_see_one_study(tmp_path):
    ctx = multiprocessing.get_context("fork")
    for round_ in range(3):
        path = tmp_path / f"fresh{round_}.db"
        start, out = ctx.Event(), ctx.Queue()
        procs = [ctx.Process(target=_open_at_once, args=(str(path), start, out)) for _ in range(6)]
        for p in procs:
            p.start()
        start.set()
        results = [out.get(timeout=60) for _ in procs]
        for p in procs:
            p.join(timeout=60)
        assert results == ["ok"] * len(procs), results
        engine = open_database(path, create=False)
        assert set(inspect(engine).get_table_names()) >= {"meta", "study", "trial"}
        engine.dispose()
        assert not [p for p in tmp_path.iterdir() if p.name.endswith(".creating")]


def test_a_new_database_is_whole_and_stamped(tmp_path):
    path = tmp_path / "new.db"
    open_database(path).dispose()
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    assert con.execute("SELECT value FROM meta").fetchone() == (str(SCHEMA_VERSION),)
    assert con.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    con.close()


# ---------------------------------------------------------------- read-only studies


def test_read_only_opening_writes_nothing(study_db):
    assert ro_uri(study_db).endswith("immutable=1")
    before = fingerprint(study_db)
    engine = open_database(study_db, create=False)
    with Session(engine) as s:
        assert s.scalars(select(Study)).one().seed == 7061
        s.add(Meta(key="x", value="y"))
        with pytest.raises(Exception, match="readonly|read-only|query_only"):
            s.commit()
    engine.dispose()
    assert fingerprint(study_db) == before
    assert side_files(study_db) == []


def test_a_read_only_study_can_be_checked_exported_and_reported(study_db, tmp_path, capsys):
    study_db.chmod(0o444)
    study_db.parent.chmod(0o555)  # root ignores both: the read-only opening is what counts
    try:
        before = fingerprint(study_db)
        code, out, err = asa(capsys, "db", "check", "--db", str(study_db), "--no-verify")
        assert code in (0, 1) and "Traceback" not in err, err
        assert "trial" in out
        out_csv = tmp_path.parent / f"{tmp_path.name}_csv"
        code, out, err = asa(capsys, "export", "--db", str(study_db), "--out", str(out_csv))
        assert code == 0, err
        assert (out_csv / "trial.csv").is_file()
        assert len(load_study(study_db).tables["trial"]) > 0  # what `asa report` reads
        assert fingerprint(study_db) == before
        assert side_files(study_db) == []
    finally:
        study_db.parent.chmod(0o755)
        study_db.chmod(0o644)


@pytest.mark.slow
def test_a_read_only_study_can_be_reported(study_db, tmp_path, capsys):
    study_db.chmod(0o444)
    try:
        before = fingerprint(study_db)
        report = tmp_path / "report"
        code, out, err = asa(capsys, "report", "--db", str(study_db), "--out", str(report))
        assert code == 0, err
        assert (report / "results.json").is_file()
        assert fingerprint(study_db) == before
        assert side_files(study_db) == []
    finally:
        study_db.chmod(0o644)


def test_a_study_in_use_is_read_through_its_wal(study_db):
    writer = open_database(study_db)
    with Session(writer) as s, s.begin():
        s.scalars(select(Study)).one().name = "renamed while open"
    try:
        assert ro_uri(study_db).endswith("mode=ro")  # the -wal file holds the commit
        reader = open_database(study_db, create=False)
        with Session(reader) as s:
            assert s.scalars(select(Study)).one().name == "renamed while open"
        reader.dispose()
    finally:
        writer.dispose()


# ---------------------------------------------------------------- names that cannot become paths

BAD_NAMES = ["../../escaped", "/tmp/abs_escaped", "a/b", "..", ".", "", "back\\slash", "nul\x00"]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_a_bad_scenario_name_cannot_make_the_map_leave_out(tmp_path, name):
    import dataclasses

    from sim.scenario import load_scenario
    from study.jobs.scenes import write_map

    scenario = dataclasses.replace(load_scenario("practice_course"), name=name)
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(ValueError, match="field 'name'"):
        write_map(scenario, out)
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []
    assert not Path("/tmp/abs_escaped.pgm").exists()


def test_a_symbolic_link_in_out_is_not_followed_outside(tmp_path):
    from sim.scenario import load_scenario
    from study.jobs.scenes import write_map

    victim = tmp_path / "victim.txt"
    victim.write_text("unrelated\n", encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / "practice_course.png").symlink_to(victim)
    with pytest.raises(ValueError, match="leads outside"):
        write_map(load_scenario("practice_course"), out)
    assert victim.read_text(encoding="utf-8") == "unrelated\n"
    assert sorted(p.name for p in out.iterdir()) == ["practice_course.png"]


def test_asa_scenario_map_with_an_escaping_name_is_one_line(tmp_path, capsys):
    from sim.scenario import SCENARIO_DIR

    text = (SCENARIO_DIR / "practice_course.toml").read_text(encoding="utf-8")
    text = text.replace('name = "practice_course"', 'name = "../../escaped"', 1)
    source = tmp_path / "s" / "evil.toml"
    source.parent.mkdir()
    source.write_text(text, encoding="utf-8")
    victim = tmp_path / "escaped.pgm"
    victim.write_text("unrelated\n", encoding="utf-8")
    out = tmp_path / "s" / "x" / "out"
    one_line_error(*asa(capsys, "scenario", "map", str(source), "--out", str(out))[::2])
    assert victim.read_text(encoding="utf-8") == "unrelated\n"
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == [
        "escaped.pgm",
        "evil.toml",
    ]


def test_a_session_never_saves_a_map_outside_its_maps_folder(tmp_path):
    from sim.scenario import SCENARIO_DIR
    from study.engine.runner import Scenes

    text = (SCENARIO_DIR / "practice_course.toml").read_text(encoding="utf-8")
    source = tmp_path / "evil.toml"
    source.write_text(text.replace('"practice_course"', '"../escaped"', 1), encoding="utf-8")
    victim = tmp_path / "escaped.yaml"
    victim.write_text("unrelated\n", encoding="utf-8")
    scenes = Scenes(tmp_path / "rec" / "maps")
    try:
        with pytest.raises(ValueError):
            scenes.get(str(source))
    finally:
        scenes.close()
    assert victim.read_text(encoding="utf-8") == "unrelated\n"
    assert not (tmp_path / "escaped.pgm").exists()


def test_save_ros_map_refuses_a_stem_with_a_folder(tmp_path):
    from sim.map_files import save_ros_map
    from sim.occupancy import build_grid
    from sim.scenario import load_scenario

    grid = build_grid(load_scenario("practice_course"), resolution=0.2)
    with pytest.raises(ValueError, match="plain file name"):
        save_ros_map(grid, tmp_path / "maps", "../up")
    assert not (tmp_path / "up.pgm").exists()


# ---------------------------------------------------------------- no overwrites without --force


def test_export_does_not_overwrite_without_force(study_db, tmp_path, capsys):
    out = tmp_path / "csv"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n", encoding="utf-8")
    code, _, err = asa(capsys, "export", "--db", str(study_db), "--out", str(out))
    assert code == 0, err  # other files in the folder are no obstacle
    before = {p.name: fingerprint(p) for p in out.iterdir()}
    line = one_line_error(*asa(capsys, "export", "--db", str(study_db), "--out", str(out))[::2])
    assert "--out" in line and ".csv" in line and "--force" in line
    assert {p.name: fingerprint(p) for p in out.iterdir()} == before
    code, out_text, err = asa(capsys, "export", "--db", str(study_db), "--out", str(out), "--force")
    assert code == 0 and "trial.csv" in out_text, err
    assert (out / "notes.txt").read_text(encoding="utf-8") == "mine\n"


def test_train_does_not_overwrite_a_model_without_force(tmp_path, capsys):
    model = tmp_path / "model.npz"
    model.write_bytes(b"an earlier model")
    line = one_line_error(
        *asa(capsys, "train", "--demonstrations", str(tmp_path / "d"), "--out", str(model))[::2]
    )
    assert str(model) in line and "--force" in line
    assert model.read_bytes() == b"an earlier model"
    # with --force the model is no obstacle: the missing demonstrations are the error now
    line = one_line_error(
        *asa(capsys, "train", "--demonstrations", str(tmp_path / "d"), "--out", str(model),
             "--force")[::2]
    )  # fmt: skip
    assert "exists already" not in line and str(tmp_path / "d") in line


# ---------------------------------------------------------------- recordings named by study

TWO_TRIALS = """
[study]
name = "shared-recordings"
participants = 1
seed = 3

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 2.0
"""


def test_two_studies_share_a_recordings_folder_without_replacing_files(tmp_path, seed, capsys):
    from study.data.dbtools import check, find_recording, remove_recordings_of
    from study.jobs.synth import run_synthetic_study

    protocol = tmp_path / "p.toml"
    protocol.write_text(TWO_TRIALS, encoding="utf-8")
    rec = tmp_path / "rec"
    files: dict[str, dict[str, str]] = {}
    for name, study_seed in (("a", seed % 1000), ("b", seed % 1000 + 1)):
        run_synthetic_study(protocol, tmp_path / f"{name}.db", participants=1, seed=study_seed,
                            recordings=rec)  # fmt: skip
        files[name] = {p.name: fingerprint(p)[0] for p in (rec / "P01").iterdir()}
    a_files = files["a"]
    assert len(a_files) == 2 and len(files["b"]) == 4  # b added its own two
    assert {p.name: fingerprint(p)[0] for p in (rec / "P01").iterdir() if p.name in a_files} == (
        a_files
    )
    prefixes = {name.split("_")[0] for name in files["b"]}
    assert len(prefixes) == 2 and all(len(p) == 8 for p in prefixes)
    for name in "ab":
        report = check(tmp_path / f"{name}.db", verify_recordings=False)
        assert report.clean, report.text()
        db = str(tmp_path / f"{name}.db")
        engine = open_database(db, create=False)
        with Session(engine) as s:
            trial_ids = list(s.scalars(select(Trial.id)))
        engine.dispose()
        for tid in trial_ids:
            assert find_recording(db, "P01", tid).is_file()
        code, out, err = asa(
            capsys, "replay", "--db", db, "--participant", "P01", "--trial", str(trial_ids[0]),
            "--print",
        )  # fmt: skip
        assert code == 0 and "recording" in out, err
    # throwing a study's recordings away (a synthetic participant run again) spares the other's
    removed = remove_recordings_of(tmp_path / "b.db")
    assert len(removed) == 2
    assert {p.name for p in (rec / "P01").iterdir()} == set(a_files)
    assert check(tmp_path / "a.db", verify_recordings=False).clean


# ---------------------------------------------------------------- the replay viewer


def _fake_viewer(folder: Path, body: str) -> tuple[Path, Path]:
    """An executable standing in for rerun: writes its arguments to a file, then ``body``."""
    args = folder / "args.txt"
    exe = folder / "fake_rerun"
    exe.write_text(f'#!/bin/sh\necho "$@" > {args}\n{body}\n', encoding="utf-8")
    exe.chmod(0o755)
    return exe, args


def test_the_viewer_is_bound_to_localhost(monkeypatch):
    from study.data import rrd

    monkeypatch.setattr(rrd, "rerun_executable", lambda: "rerun")
    command = rrd.viewer_command("x.rrd")
    assert command[command.index("--bind") + 1] == "127.0.0.1"
    assert (
        "0.0.0.0" not in command and "--serve-web" not in command and "--web-viewer" not in command
    )


def test_a_viewer_that_dies_is_one_line_and_exit_2(tmp_path, monkeypatch):
    from study.data import rrd

    exe, args = _fake_viewer(
        tmp_path, 'echo "Error: Failed to open connection to X server" >&2\nexit 1'
    )
    monkeypatch.setattr(rrd, "rerun_executable", lambda: str(exe))
    monkeypatch.setenv("DISPLAY", ":97")
    with pytest.raises(ValueError, match="did not start .*X server"):
        rrd.open_viewer(tmp_path / "t.rrd", grace_s=10.0)
    assert "--bind 127.0.0.1" in args.read_text(encoding="utf-8")


def test_a_viewer_that_runs_is_reported_open(tmp_path, monkeypatch):
    from study.data import rrd

    exe, args = _fake_viewer(tmp_path, "exec sleep 30")
    monkeypatch.setattr(rrd, "rerun_executable", lambda: str(exe))
    monkeypatch.setenv("DISPLAY", ":97")
    process = rrd.open_viewer(tmp_path / "t.rrd", grace_s=0.5)
    try:
        assert process.returncode is None
    finally:
        process.kill()
        process.wait()


def test_asa_replay_without_a_display_is_one_line(tmp_path, monkeypatch, capsys, seed):
    """The real viewer is never started without a display; the error names the recording."""
    from study.data import rrd

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_SOCKET", raising=False)
    monkeypatch.setattr(rrd, "rerun_executable", lambda: pytest.fail("no viewer without a display"))
    recording = tmp_path / "t.rrd"
    recording.write_bytes(b"")
    monkeypatch.setattr("study.data.dbtools.find_recording", lambda db, p, t, **kw: recording)
    code, out, err = asa(capsys, "replay", "--db", "x.db", "--participant", "P01", "--trial", "1")
    line = one_line_error(code, err)
    assert "no display" in line and str(recording) in line and "opened" not in out


def test_the_real_viewer_without_an_x_server_is_reported(tmp_path, monkeypatch):
    """rerun itself, given a display that does not exist, dies at once: reported."""
    from study.data import rrd

    monkeypatch.setenv("DISPLAY", ":97")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    recording = tmp_path / "t.rrd"
    recording.write_bytes(b"")
    try:
        process = rrd.open_viewer(recording, grace_s=20.0)
    except ValueError as error:
        assert "did not start" in str(error) and "\n" not in str(error)
    else:  # an X server answers on :97 after all
        process.kill()
        process.wait()
