"""Benchmark group ``lsl``: the session on the lab's clock (issue 38; DESIGN.md budgets),
on loopback with this process's own LSL configuration (machine scope, IPv6 off, a fresh
session id).

- ``lsl_marker_latency_ms``: a marker's latency from ``push_sample`` (its timestamp, the
  pusher's ``local_clock()``) to an inlet's ``pull_sample`` in another process, p50 / p99
  over markers 10 ms apart (DESIGN.md: p99 < 5 ms);
- ``lsl_recorded_samples_per_s`` and ``lsl_lost_samples``: four streams of 500 Hz x 8
  channels pushed by another process (chunks of 5 samples every 10 ms) and recorded into
  the study database (SQLite) while a 20 Hz session paced by the wall clock runs with its
  outlets on: the samples stored per second of the recording, and the samples pushed while
  it recorded that are missing from the database (DESIGN.md: none lost);
- ``lsl_tick_cost_us``: what LSL adds to one control tick (the tick's clock, its state
  sample, a marker every 20 ticks: :class:`study.lsl.session.SessionLsl`), p50 / p99 over
  2,000 ticks with an inlet connected; and ``lsl_recorder_cpu_share``, the recording
  thread's CPU time per second of recording those four streams into SQLite: the cost
  behind the jitter figures, which a loaded machine's scheduling dominates;
- ``lsl_tick_jitter_p99_ms`` with LSL on (those four streams recorded, the outlets open)
  and off (the streams still pushed, nobody recording), after a warm-up session, the
  median over pairs of sessions (3, each pair's first in turn; 1 with ``quick``) of each
  session's worst trial p99 of ``|period - 50 ms|``, and their difference
  ``lsl_jitter_p99_delta_ms`` (DESIGN.md: within 1 ms).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
import uuid
from pathlib import Path

import numpy as np

STREAMS, RATE_HZ, CHANNELS = 4, 500.0, 8
_PUSHER = textwrap.dedent(
    """
    import sys, time, numpy as np, pylsl
    n, rate, ch, log = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    outs = []
    for i in range(n):
        info = pylsl.StreamInfo(f"BenchEEG{i}", "BenchEEG", ch, rate, "float32", f"bench-{i}")
        outs.append(pylsl.StreamOutlet(info, chunk_size=5))
    print("ready", flush=True)
    per, k, start = 5, 0, pylsl.local_clock()
    first = {}
    while True:
        now = pylsl.local_clock()
        due = int((now - start) * rate)
        while k < due:
            stamps = start + (k + np.arange(per)) / rate
            block = np.zeros((per, ch), dtype=np.float32)
            block[:, 0] = k + np.arange(per)
            for o in outs:
                o.push_chunk(block, stamps)
            k += per
        with open(log, "w") as f:
            f.write(f"{start!r} {k}")
        time.sleep(0.01)
    """
)
_READER = textwrap.dedent(
    """
    import sys, json, pylsl
    found = pylsl.resolve_byprop("name", sys.argv[1], 1, 20.0)
    inlet = pylsl.StreamInlet(found[0])
    inlet.open_stream(timeout=10.0)
    print("ready", flush=True)
    lat = []
    for _ in range(int(sys.argv[2])):
        sample, ts = inlet.pull_sample(timeout=10.0)
        if sample is None:
            break
        lat.append(pylsl.local_clock() - ts)
    print(json.dumps(lat), flush=True)
    """
)


def _config(folder: Path) -> dict[str, str]:
    cfg = folder / "lsl_api.cfg"
    cfg.write_text(
        "[ports]\nIPv6 = disable\n[multicast]\nResolveScope = machine\n"
        f"[lab]\nSessionID = asa-bench-{uuid.uuid4().hex}\n[log]\nlevel = -3\n",
        encoding="utf-8",
    )
    os.environ["LSLAPICFG"] = str(cfg)  # before this process loads liblsl
    return dict(os.environ)


def _marker_latency(env: dict[str, str], n: int) -> dict[str, float]:
    from study.lsl import runtime

    lsl = runtime.pylsl()
    name = f"bench-markers-{uuid.uuid4().hex[:8]}"
    outlet = lsl.StreamOutlet(
        lsl.StreamInfo(name, "Markers", 1, lsl.IRREGULAR_RATE, lsl.cf_string, name)
    )
    reader = subprocess.Popen([sys.executable, "-c", _READER, name, str(n)], env=env,
                              stdout=subprocess.PIPE, text=True)  # fmt: skip
    assert reader.stdout is not None
    reader.stdout.readline()
    outlet.wait_for_consumers(10.0)
    time.sleep(0.2)
    for i in range(n):
        outlet.push_sample([json.dumps({"event": "bench", "i": i})], lsl.local_clock())
        time.sleep(0.01)
    lat = np.asarray(json.loads(reader.stdout.readline())) * 1e3
    reader.wait(timeout=20)
    return {"p50": round(float(np.percentile(lat, 50)), 3),
            "p99": round(float(np.percentile(lat, 99)), 3), "n": len(lat)}  # fmt: skip


def _tick_cost(n: int) -> dict[str, float]:
    """[us] per tick of :meth:`SessionLsl.tick` and :meth:`SessionLsl.state`."""
    from sim.types import Pose2D
    from study.lsl import runtime
    from study.lsl.outlets import OutletNames, SessionOutlets
    from study.lsl.session import SessionLsl
    from study.types import TickRecord

    lsl = runtime.pylsl()
    outlets = SessionOutlets(lsl, OutletNames(f"bench-{uuid.uuid4().hex[:8]}"))
    found = lsl.resolve_byprop("source_id", outlets.names.state_source_id, 1, 10.0)
    inlet = lsl.StreamInlet(found[0])
    inlet.open_stream(timeout=10.0)
    link = SessionLsl(lsl, "B01", outlets=outlets, recorder=None, mode_names=False)
    link.begin_trial(1, {"phase": "main", "ordinal": 0, "attempt": 0, "scenario": "bench"})
    zero = np.zeros(3)
    costs = np.empty(n)
    for i in range(n):
        start = time.perf_counter()
        stamp = link.tick(i, i * 0.05)
        record = TickRecord(i, i * 0.05, Pose2D(0.0, 0.0, 0.0), zero, zero, 0.0, "", "", 1.0,
                            False, lsl_clock_s=stamp)  # fmt: skip
        link.state(record, zero)
        costs[i] = time.perf_counter() - start
        inlet.pull_chunk(0.0)
    link.close()
    us = costs * 1e6
    return {"p50": round(float(np.percentile(us, 50)), 1),
            "p99": round(float(np.percentile(us, 99)), 1)}  # fmt: skip


def _session(
    folder: Path, *, lsl: bool, trial_s: float, recorders: list | None = None
) -> tuple[Path, float | None]:
    """One paced session of two ``trial_s`` trials; LSL on: the four bench streams recorded
    and the outlets open (its recorder appended to ``recorders``). Its database and the
    trials' worst tick jitter p99 [ms]."""
    from study.lsl import session as lsl_session

    made = recorders if recorders is not None else []

    class Kept(lsl_session.StreamRecorder):  # the session's recorder, for its CPU time
        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            made.append(self)

    original, lsl_session.StreamRecorder = lsl_session.StreamRecorder, Kept
    try:
        return _one_session(folder, lsl=lsl, trial_s=trial_s)
    finally:
        lsl_session.StreamRecorder = original


def _one_session(folder: Path, *, lsl: bool, trial_s: float) -> tuple[Path, float | None]:
    from sqlalchemy import create_engine, text

    from study.engine.clocks import WallClock
    from study.engine.protocol import parse_protocol
    from study.engine.session import run_session
    from study.participants import ScriptedParticipant

    record = '\n[lsl]\n\n[[lsl.record]]\ntype = "BenchEEG"\n' if lsl else ""
    text_ = _protocol(trial_s) + record
    protocol = parse_protocol(text_, str(folder / "bench.toml"))
    folder.mkdir(parents=True, exist_ok=True)
    db = folder / "bench.db"
    run_session(protocol, "B01", db, participant=ScriptedParticipant(np.random.default_rng(1)),
                seed=1, clock=WallClock(), record=False, lsl=None if lsl else False)  # fmt: skip
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        jitter = conn.execute(text("SELECT MAX(tick_jitter_ms) FROM trial")).scalar()
    engine.dispose()
    return db, jitter


def _protocol(trial_s: float) -> str:
    return textwrap.dedent(
        f"""
        [study]
        name = "bench-lsl"
        [modes]
        names = ["manual", "reactive_bn"]
        [[phases]]
        kind = "main"
        scenario = "practice_course"
        route = ["A", "B"]
        inspection = false
        secondary = false
        timeout_s = {trial_s:g}
        """
    )


def _recorded(db: Path) -> tuple[int, int, float]:
    """(samples stored, samples missing inside each stream's stored span, the spans' sum
    over the streams [s])."""
    from sqlalchemy import create_engine, text

    engine = create_engine(f"sqlite:///{db}")
    stored = missing = 0
    spans = []
    with engine.connect() as conn:
        for (sid,) in conn.execute(text("SELECT id FROM lsl_stream")):
            rows = conn.execute(text("SELECT data, timestamps FROM lsl_chunk WHERE stream_id = "
                                     ":s ORDER BY id"), {"s": sid}).all()  # fmt: skip
            seq = np.concatenate([np.frombuffer(d, "<f8").reshape(-1, CHANNELS)[:, 0]
                                  for d, _ in rows])  # fmt: skip
            ts = np.concatenate([np.frombuffer(t, "<f8") for _, t in rows])
            stored += len(seq)
            missing += int(seq.max() - seq.min() + 1 - len(np.unique(seq)))
            spans.append(float(ts[-1] - ts[0]))
    engine.dispose()
    return stored, missing, float(np.sum(spans))


def run(quick: bool = False) -> dict:
    """The ``lsl`` figures (see the module docstring)."""
    trial_s, pairs = (3.0, 1) if quick else (8.0, 3)
    with tempfile.TemporaryDirectory(prefix="asa-bench-lsl-") as tmp:
        folder = Path(tmp)
        env = _config(folder)
        latency = _marker_latency(env, 100 if quick else 500)
        tick_cost = _tick_cost(500 if quick else 2000)
        log = folder / "pusher.txt"
        pusher = subprocess.Popen(
            [sys.executable, "-c", _PUSHER, str(STREAMS), str(RATE_HZ), str(CHANNELS), str(log)],
            env=env, stdout=subprocess.PIPE, text=True,
        )  # fmt: skip
        off, on, recorded, recorders = [], [], [], []
        try:
            assert pusher.stdout is not None
            pusher.stdout.readline()
            _session(folder / "warm-up", lsl=False, trial_s=1.0)  # compiled kernels, caches
            for k in range(pairs):  # interleaved, in turn first, so that load hits both
                for lsl in (k % 2 == 1, k % 2 == 0):
                    if not lsl:
                        off.append(_session(folder / f"off{k}", lsl=False, trial_s=trial_s)[1])
                        continue
                    db, jitter = _session(folder / f"on{k}", lsl=True, trial_s=trial_s,
                                          recorders=recorders)  # fmt: skip
                    on.append(jitter)
                    recorded.append(_recorded(db))
        finally:
            pusher.kill()
            pusher.wait(timeout=10)
    stored = sum(r[0] for r in recorded)
    span = sum(r[2] for r in recorded) / STREAMS
    med_on, med_off = _median(on), _median(off)
    wall = sum(r.wall_s for r in recorders)
    return {
        "lsl_marker_latency_ms": latency,
        "lsl_tick_cost_us": tick_cost,
        "lsl_recorder_cpu_share": round(sum(r.cpu_s for r in recorders) / wall, 4)
        if wall
        else None,
        "lsl_streams": f"{STREAMS} x {RATE_HZ:g} Hz x {CHANNELS} channels",
        "lsl_recorded_samples": stored,
        "lsl_recorded_samples_per_s": round(stored / span, 1) if span else None,
        "lsl_lost_samples": sum(r[1] for r in recorded),
        "lsl_tick_jitter_p99_ms": {"on": med_on, "off": med_off, "runs": pairs},
        "lsl_jitter_p99_delta_ms": (
            None if med_on is None or med_off is None else round(med_on - med_off, 3)
        ),
    }


def _median(values: list[float | None]) -> float | None:
    known = [v for v in values if v is not None]
    return round(float(np.median(known)), 3) if known else None
