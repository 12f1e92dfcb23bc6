"""Benchmark group ``web``: browser participants on this machine (issue 37; DESIGN.md
budgets: round trip p99 under 50 ms on loopback, at least 4 concurrent 20 Hz sessions with
the camera at 10 Hz, the browser drawing at 30 fps or more).

``asa serve`` on 127.0.0.1 with the camera on, and 1, 2 and 4 headless Chromium pages at
once (1 with ``quick``), each a scripted person with a faked gamepad
(:mod:`study.web.testing`) through a protocol of two main trials of 20 s (8 s quick).
Figures, per number of sessions and overall:

- ``web_rtt_ms``: p50 and p99 of the stored round trips of every tick (``sample.rtt_ms``);
- ``web_input_age_ticks``: p50 and p99 of the stored input ages;
- ``web_server_cpu_per_session``: CPU of the server and its session and camera processes
  while the trials run, in cores per session (the browsers' own CPU not counted);
- ``web_sessions_sustained``: the most sessions at once for which every trial kept its
  20 Hz (stored tick jitter p99 at most 10 ms) and every page got at least 9 camera frames
  a second;
- ``web_browser_fps``: the lowest frame rate of a page while driving.
"""

from __future__ import annotations

import statistics
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

PROTOCOL = """
[study]
name = "web-bench"
seed = 1

[modes]
names = ["manual", "reactive_bn"]

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = {timeout_s}

[web]
latency_gate_ms = 1000
pings = 5
camera_hz = 10
"""
_PAGE = "const a = window.__asa; return [a.phase, a.fps, a.cameraFrames || 0]"
JITTER_OK_MS = 10.0  # [ms] a trial's tick jitter p99 within which it kept its 20 Hz
CAMERA_OK_FPS = 9.0  # [1/s] camera frames a page must get (10 Hz asked)


def run(quick: bool = False) -> dict:
    """The ``web`` figures (see the module docstring)."""
    counts = (1,) if quick else (1, 2, 4)
    per: dict[str, Any] = {}
    for n in counts:
        per[str(n)] = _sessions(n, 8.0 if quick else 20.0)
    sustained = max((n for n in counts if per[str(n)]["sustained"]), default=0)
    rtts = [r for v in per.values() for r in v.pop("rtts")]
    ages = [a for v in per.values() for a in v.pop("ages")]
    return {
        "web_rtt_ms": _quantiles(rtts),
        "web_input_age_ticks": _quantiles(ages),
        "web_server_cpu_per_session": max(v["cpu_per_session"] for v in per.values()),
        "web_sessions_sustained": sustained,
        "web_browser_fps": min(v["browser_fps"] for v in per.values()),
        "web_per_sessions": per,
    }


def _quantiles(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"p50": None, "p99": None}
    a = np.asarray(values, dtype=float)
    return {
        "p50": round(float(np.percentile(a, 50)), 2),
        "p99": round(float(np.percentile(a, 99)), 2),
    }


def _sessions(n: int, timeout_s: float) -> dict[str, Any]:
    """``n`` pages at once through the protocol; their figures."""
    import psutil

    from study.web.testing import Person, browser, served

    with tempfile.TemporaryDirectory(prefix="asa-bench-web-") as tmp:
        protocol = Path(tmp) / "bench.toml"
        protocol.write_text(PROTOCOL.format(timeout_s=timeout_s))
        db = str(Path(tmp) / "web.db")
        codes = tuple(f"B{k:02d}" for k in range(n))
        with served(protocol, db, codes=codes, camera=True) as server:
            drivers = [browser() for _ in codes]
            try:
                people = [Person(d) for d in drivers]
                threads = [
                    threading.Thread(target=_drive, args=(p, d, server.links[c]), daemon=True)
                    for p, d, c in zip(people, drivers, codes, strict=True)
                ]
                for t in threads:
                    t.start()
                cpu, fps, cams = _watch(psutil.Process(server.proc.pid), people, threads)
            finally:
                for d in drivers:
                    d.quit()
        return {**_stored(db), "cpu_per_session": round(cpu / n, 3), "browser_fps": fps,
                "camera_fps": cams, "sustained": False} | _judge(db, cams)  # fmt: skip


def _drive(person: Any, driver: Any, link: str) -> None:
    driver.get(link)
    person.run(timeout=600)


def _watch(server: Any, people: list, threads: list) -> tuple[float, float, float]:
    """While the pages drive: the server tree's CPU [cores], the pages' lowest frame rate
    and camera frames a second."""
    cpu_s, wall_s, fps, cams = 0.0, 0.0, [], []
    last: tuple[float, float, list] | None = None
    while any(t.is_alive() for t in threads):
        time.sleep(1.0)
        states = [p.js(_PAGE) for p in people]
        now, cpu = time.monotonic(), _tree_cpu(server)
        driving = all(s[0] == "drive" for s in states)
        if driving and last is not None:
            cpu_s, wall_s = cpu_s + cpu - last[1], wall_s + now - last[0]
            fps.append(min(s[1] for s in states))
            cams.append(
                min(s[2] - c for s, c in zip(states, last[2], strict=True)) / (now - last[0])
            )
        last = (now, cpu, [s[2] for s in states])
    return (cpu_s / wall_s if wall_s else float("nan"), round(min(fps), 1) if fps else 0.0,
            round(statistics.median(cams), 1) if cams else 0.0)  # fmt: skip


def _tree_cpu(proc: Any) -> float:
    """[s] user + system CPU of ``proc`` and its children."""
    total = 0.0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except Exception:  # a process that ended between listing and reading
            continue
    return total


def _stored(db: str) -> dict[str, Any]:
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from study.data.storage import Sample, open_database

    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            rows = s.execute(select(Sample.rtt_ms, Sample.input_age_ticks)).all()
    finally:
        engine.dispose()
    rtts = [r[0] for r in rows if r[0] is not None]
    ages = [r[1] for r in rows if r[1] is not None]
    return {"rtts": rtts, "ages": ages, "rtt_ms": _quantiles(rtts), "ticks": len(rows)}


def _judge(db: str, camera_fps: float) -> dict[str, Any]:
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from study.data.storage import Trial, open_database

    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            jitters = [j for j in s.scalars(select(Trial.tick_jitter_ms)) if j is not None]
    finally:
        engine.dispose()
    worst = max(jitters) if jitters else float("inf")
    ok = worst <= JITTER_OK_MS and camera_fps >= CAMERA_OK_FPS
    return {"tick_jitter_p99_worst_ms": round(worst, 2), "sustained": ok}
