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
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.data import load_study
from analysis.data.streams import align
from tests import lsl_procs
from tests.mini_protocol import mini_protocol

pytest.importorskip("pylsl")
CLOCK_OFFSET_S = 1000  # [s] the fake tracker's clock ahead of ours (time namespace)
BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]


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


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_fake_eye_tracker_is_recorded_and_the_outlets_read_back(
    backend, request, tmp_path, lsl_cfg, seed
):
    """Every tracker sample pushed while the trials ran is in the database, mapped to the
    session's clock within 1 ms of when it was pushed; an inlet reads every event, in
    order, and every tick's state with the tick's clock."""
    db = _db(backend, request, tmp_path)
    protocol = _protocol(tmp_path, "[lsl]\nwait_for_consumers_s = 30\n" + TRACKER, seed=seed % 1000)
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
    assert "mode" not in json.dumps([m for m in markers if m["event"] == "trial_started"])
    state = np.array(got_read["state"])
    assert len(state) == len(ticks)
    assert np.allclose(state[:, -1], ticks["session_clock_s"].to_numpy(), atol=1e-9)
    assert np.allclose(state[:, 0], ticks["tick"].to_numpy())
    assert "<unit>m/s</unit>" in got_read["state_xml"] and "<codes>" in got_read["state_xml"]
