"""Lab Streaming Layer (issue 38), on loopback with real liblsl: the session's event and
state outlets read back by an inlet, a fake eye tracker (its own clock, in a time
namespace) recorded through a synthetic session and aligned onto the session's clock,
a required stream missing, a stream killed and restarted mid-trial.

Every LSL process of a test runs with that test's own configuration (machine scope, IPv6
off, a fresh session id: tests/lsl_procs.py), so parallel tests never see each other.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import sqlalchemy as sa

from analysis.data import load_study
from analysis.data.streams import align
from tests import lsl_procs
from tests.mini_protocol import mini_protocol

pytest.importorskip("pylsl")
CLOCK_OFFSET_S = 1000  # [s] the fake tracker's clock ahead of ours (time namespace)
# (backend, [lsl] mode_names): the mode's name in the markers only where the protocol says
BACKENDS = [("sqlite", False), pytest.param("postgresql", True, marks=pytest.mark.postgres)]


@pytest.fixture
def lsl_cfg(tmp_path: Path) -> Path:
    return lsl_procs.write_config(tmp_path)


def _protocol(tmp_path: Path, lsl: str, *, timeout_s: float = 2.0, seed: int = 5) -> Path:
    path = tmp_path / "p.toml"
    path.write_text(mini_protocol(timeout_s=timeout_s, seed=seed) + "\n" + lsl, encoding="utf-8")
    return path


TRACKER = '[[lsl.record]]\ntype = "Gaze"\nname = "FakeTracker"\n'


def _db(backend: str, request: pytest.FixtureRequest, tmp_path: Path) -> str:
    return request.getfixturevalue("pg_url") if backend == "postgresql" else str(tmp_path / "s.db")


def _wait_for(path: Path, what: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not (path.exists() and path.stat().st_size > 0):
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} did not start")
        time.sleep(0.05)


def _tracker(cfg: Path, log: Path, *, first: int = 0) -> tuple[subprocess.Popen, int]:
    """The fake eye tracker and its clock's offset from ours: that of its time namespace,
    0 where none can be made (no root and no user namespaces)."""
    prefix = lsl_procs.time_namespace_prefix(CLOCK_OFFSET_S)
    args = ["--log", str(log), "--first", str(first)]
    proc = lsl_procs.start("tracker", args, cfg, prefix=prefix)
    _wait_for(log, "the fake tracker")
    return proc, CLOCK_OFFSET_S if prefix else 0


def _tracker_log(log: Path) -> tuple[np.ndarray, np.ndarray]:
    rows = np.loadtxt(log, ndmin=2)
    return rows[:, 0].astype(int), rows[:, 1]


def _session(protocol: Path, db: str, cfg: Path, *extra: str) -> subprocess.Popen:
    return lsl_procs.start(
        "session",
        ["--protocol", str(protocol), "--db", db, *extra],
        cfg,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _finish(proc: subprocess.Popen, timeout: float = 90.0) -> str:
    out, err = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, err
    assert "status completed" in out, out + err
    return out


def _stop(*procs: subprocess.Popen) -> None:
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.wait(timeout=10)


@pytest.mark.parametrize(("backend", "mode_names"), BACKENDS)
def test_a_fake_eye_tracker_is_recorded_and_the_outlets_read_back(
    backend, mode_names, request, tmp_path, lsl_cfg, seed
):
    """Every tracker sample pushed while the trials ran is in the database, mapped to the
    session's clock within 1 ms of when it was pushed; an inlet reads every event, in
    order, and every tick's state with the tick's clock."""
    db = _db(backend, request, tmp_path)
    lsl = f"[lsl]\nwait_for_consumers_s = 30\nmode_names = {str(mode_names).lower()}\n"
    protocol = _protocol(tmp_path, lsl + TRACKER, seed=seed % 1000)
    log = tmp_path / "tracker.log"
    tracker, offset = _tracker(lsl_cfg, log)
    ready, read = tmp_path / "ready", tmp_path / "read.json"
    reader = lsl_procs.start("reader", ["--out", str(read), "--ready", str(ready)], lsl_cfg)
    try:
        session = _session(protocol, db, lsl_cfg, "--seed", str(seed % 1000))
        _finish(session)
        reader.wait(timeout=60)
    finally:
        _stop(tracker, reader)
    data = load_study(db)
    aligned = align(data.tables)
    # the recording: one stream, its header, offsets every 5 s (at least the first)
    streams = data.tables["lsl_stream"]
    assert list(streams["name"]) == ["FakeTracker"] and bool(streams["required"].iloc[0])
    assert streams["channels"].iloc[0] == ",".join(lsl_procs.TRACKER_CHANNELS)
    assert "<name>FakeTracker</name>" in streams["info_xml"].iloc[0]
    frame = aligned.streams[int(streams["id"].iloc[0])]
    index, pushed = _tracker_log(log)
    got = frame["gaze_x"].to_numpy().astype(int)
    assert (np.diff(got) == 1).all()  # no sample lost, none twice
    ticks = aligned.ticks
    ours = pushed - offset  # when each was pushed, on our clock
    clocks = ticks["session_clock_s"]
    during = index[(ours >= clocks.min()) & (ours <= clocks.max())]
    assert len(during) > 100 and set(during) <= set(got)
    # on the session's clock within 1 ms of when they were pushed (1 ms: the bar;
    # time_correction on loopback is good to some microseconds)
    expected = ours[np.searchsorted(index, got)]
    assert np.abs(frame["session_clock_s"].to_numpy() - expected).max() < 1e-3
    assert set(frame.loc[frame["trial_id"] >= 0, "trial_id"]) == set(ticks["trial_id"])
    # the outlets, read back
    got_read = json.loads(read.read_text())
    markers = [json.loads(m) for m, _ in got_read["markers"]]
    kinds = [m["event"] for m in markers if m["event"] not in ("sync", "label_code")]
    assert kinds[:2] == ["session_started", "phase_started"] and kinds[-1] == "session_ended"
    events = data.tables["event"]
    trial_events = [
        (int(r.trial_id), r.kind)
        for r in events.itertuples()
        if pd.notna(r.trial_id) and r.kind != "trial_started"
    ]
    read_trial = [
        (m["trial"], m["event"])
        for m in markers
        if m.get("trial") is not None and m["event"] not in ("sync", "label_code", "trial_started")
    ]
    assert read_trial == trial_events
    assert all(m["participant"] == "P01" for m in markers)
    started = [m for m in markers if m["event"] == "trial_started"]
    modes = data.tables["trial"].sort_values("id")["mode"].tolist()
    assert [m.get("mode") for m in started] == (modes if mode_names else [None, None])
    state = np.array(got_read["state"])
    assert len(state) == len(ticks)
    assert np.allclose(state[:, -1], ticks["session_clock_s"].to_numpy(), atol=1e-9)
    assert np.allclose(state[:, 0], ticks["tick"].to_numpy())
    assert "<unit>m/s</unit>" in got_read["state_xml"] and "<codes>" in got_read["state_xml"]


def test_a_required_stream_missing_is_one_line_and_nothing_starts(tmp_path, lsl_cfg):
    protocol = _protocol(
        tmp_path,
        '[lsl]\nresolve_timeout_s = 0.5\n\n[[lsl.record]]\ntype = "EEG"\nname = "Nobody"\n',
    )
    db = tmp_path / "s.db"
    cmd = [sys.executable, "-m", "study.cli", "run", "--protocol", str(protocol),
           "--participant", "P01", "--db", str(db), "--input", "synthetic"]  # fmt: skip
    done = subprocess.run(cmd, cwd=tmp_path, env=lsl_procs.env_with(lsl_cfg),
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "type 'EEG', name 'Nobody'" in lines[0], done.stderr
    assert "required" in lines[0] and not db.exists()  # nothing started


def test_a_stream_killed_and_restarted_mid_trial_is_a_gap(tmp_path, lsl_cfg):
    protocol = _protocol(tmp_path, "[lsl]\n" + TRACKER, timeout_s=3.0)
    db = str(tmp_path / "s.db")
    log = tmp_path / "tracker.log"
    tracker, _ = _tracker(lsl_cfg, log)
    again = None
    session = _session(protocol, db, lsl_cfg)
    try:
        assert session.stdout.readline().strip() == "ticking"  # the first trial runs
        time.sleep(0.3)
        tracker.kill()
        tracker.wait(timeout=10)
        time.sleep(0.5)
        again, _ = _tracker(lsl_cfg, tmp_path / "again.log", first=100_000)
        out, err = session.communicate(timeout=90)
        assert session.returncode == 0 and "status completed" in out, err
    finally:
        _stop(session, tracker, *([again] if again is not None else []))
    engine = sa.create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        gaps = conn.execute(sa.text("SELECT segment, start_clock_s, end_clock_s, trial_id "
                                    "FROM lsl_gap")).all()  # fmt: skip
        kinds = [r[0] for r in conn.execute(sa.text(
            "SELECT kind FROM event WHERE kind LIKE 'lsl_stream_%' ORDER BY id"))]  # fmt: skip
        segments = conn.execute(
            sa.text("SELECT segment, SUM(n) FROM lsl_chunk GROUP BY segment ORDER BY segment")
        ).all()
        streams = conn.execute(sa.text("SELECT COUNT(*) FROM lsl_stream")).scalar()
        trials = conn.execute(sa.text("SELECT status FROM trial")).scalars().all()
    engine.dispose()
    assert len(gaps) == 1 and gaps[0][0] == 0 and gaps[0][2] > gaps[0][1]
    assert gaps[0][3] is not None  # lost while a trial ran
    assert kinds == ["lsl_stream_lost", "lsl_stream_found"]
    assert streams == 1 and [s for s, _ in segments] == [0, 1] and all(n > 0 for _, n in segments)
    assert len(trials) == 2 and "aborted" not in trials
    aligned = align(load_study(db).tables)
    frame = next(iter(aligned.streams.values()))
    assert (frame.loc[frame["segment"] == 1, "gaze_x"] >= 100_000).all()


def test_lsl_without_pylsl_is_one_line_saying_how_to_get_it(tmp_path):
    protocol = _protocol(tmp_path, "")
    db = tmp_path / "s.db"
    code = (  # pylsl as if not installed, then `asa run --lsl`
        "import sys; sys.modules['pylsl'] = None; from study.cli import main; "
        f"main(['run', '--protocol', {str(protocol)!r}, '--participant', 'P01', "
        f"'--db', {str(db)!r}, '--lsl'])"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    err = done.stderr
    assert done.returncode == 2 and len(err.strip().splitlines()) == 1, err
    assert "pip install -e '.[lsl]'" in err and "conda-forge liblsl" in err
    assert "PYLSL_LIB" in err and not db.exists()


def test_a_bad_lsl_table_is_one_line(tmp_path, capsys):
    from tests.cli_helpers import asa

    for text, words in (
        ("[lsl]\nwait = 3\n", "field 'lsl.wait': is not a known field"),
        ("[lsl]\n[[lsl.record]]\nrequired = true\n", "give at least one of type, name"),
        ('[lsl]\n[[lsl.record]]\nname = "a\'b"\n', "must not contain quotes"),
        ("[lsl]\nresolve_timeout_s = -1\n", "lsl.resolve_timeout_s"),
    ):
        protocol = _protocol(tmp_path, text)
        code, _, err = asa(capsys, "plan", "--protocol", protocol, "--participants", 2)
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, (text, err)


def test_only_study_lsl_imports_pylsl_and_only_when_used(tmp_path):
    """pylsl and pyxdf are imported by study/lsl/runtime.py alone (lazily), and a session
    without LSL never loads them."""
    root = lsl_procs.ROOT
    for package in ("sim", "autonomy", "tasks", "questionnaires", "study", "analysis"):
        for path in (root / package).rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            if "import pylsl" in text or "import pyxdf" in text:
                assert path == root / "study" / "lsl" / "runtime.py", path
    protocol = _protocol(tmp_path, "")
    code = (
        "import sys, numpy as np; from study.engine.protocol import load_protocol; "
        "from study.engine.session import run_session; "
        "from study.participants import ScriptedParticipant; "
        f"run_session(load_protocol({str(protocol)!r}), 'P01', {str(tmp_path / 's.db')!r}, "
        "participant=ScriptedParticipant(np.random.default_rng(1)), record=False); "
        "print('pylsl' in sys.modules, 'pyxdf' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, check=True)  # fmt: skip
    assert done.stdout.split() == ["False", "False"]


@pytest.mark.slow
def test_the_lsl_bench_group_reports_its_figures(tmp_path):
    """``asa bench --only lsl --quick`` (about 25 s: marked slow), in its own process: the
    bench loads liblsl with a configuration of its own."""
    done = subprocess.run(
        [sys.executable, "-m", "study.cli", "bench", "--only", "lsl", "--quick", "--json"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    figures = json.loads(done.stdout)
    assert figures["lsl_lost_samples"] == 0 and figures["lsl_recorded_samples"] > 1000
    assert set(figures["budgets"]) == {
        "lsl_marker_latency_ms.p99", "lsl_lost_samples", "lsl_recorded_samples_per_s",
        "lsl_jitter_p99_delta_ms",
    }  # fmt: skip
    assert figures["lsl_tick_cost_us"]["p99"] > 0 and 0 < figures["lsl_recorder_cpu_share"] < 1
