"""Benchmark group ``web``: browser participants on this machine (issue 37; DESIGN.md
budgets: round trip p99 under 50 ms on loopback, at least 4 concurrent 20 Hz sessions with
the camera at 10 Hz, the browser drawing at 30 fps or more).

``asa serve`` on 127.0.0.1 with the camera on, through a protocol of two main trials of
20 s (8 s quick), measured twice:

- **the server alone**: 1, 2, 4 and 6 sessions at once (1 with ``quick``), each joined by
  a protocol client of :mod:`study.web.loadclient` (the page's wire protocol without a
  browser, all clients in one event loop of this process), as in a real study where the
  browsers run on the participants' machines;
- **with the pages**: 1, 2 and 4 headless Chromium pages at once on the same machine (1
  with ``quick``), each a scripted person with a faked gamepad (:mod:`study.web.testing`).

The figures are listed in :func:`run`.
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
    """The ``web`` figures.

    Returns
    -------
    dict
        - ``web_sessions_sustained`` (the budget's): the most sessions of the server alone at once
          for which every session completed, every trial kept its 20 Hz (stored tick jitter p99 at
          most 10 ms) and every client got at least 9 camera frames a second while driving;
          ``web_sessions_sustained_with_pages``: the same judged with the pages;
        - ``web_server_cpu_per_session``: CPU of the server and its session and camera processes
          while every client drives, in cores per session, the server alone (the highest over the
          numbers of sessions); ``web_server_cpu_per_session_with_pages``: the same beside the pages
          (their own CPU not counted);
        - ``web_rtt_ms`` and ``web_input_age_ticks``: p50 and p99 of the stored round trips
          (``sample.rtt_ms``) and input ages of every tick with the pages (a page answers on its
          next animation frame, as a participant's does); ``web_server_alone_rtt_ms``: the round
          trips with the clients;
        - ``web_browser_fps``: the lowest frame rate of a page while driving;
        - ``web_per_sessions`` and ``web_server_alone_per_sessions``: the figures per number of
          sessions.
    """
    trial_s = 8.0 if quick else 20.0
    alone = {str(n): _server_alone(n, trial_s) for n in ((1,) if quick else (1, 2, 4, 6))}
    pages = {str(n): _sessions(n, trial_s) for n in ((1,) if quick else (1, 2, 4))}
    alone_rtts = [r for v in alone.values() for r in v.pop("rtts")]
    for v in alone.values():
        v.pop("ages")
    rtts = [r for v in pages.values() for r in v.pop("rtts")]
    ages = [a for v in pages.values() for a in v.pop("ages")]
    return {
        "web_sessions_sustained": _most(alone),
        "web_sessions_sustained_with_pages": _most(pages),
        "web_server_cpu_per_session": max(v["cpu_per_session"] for v in alone.values()),
        "web_server_cpu_per_session_with_pages": max(v["cpu_per_session"] for v in pages.values()),
        "web_rtt_ms": _quantiles(rtts),
        "web_input_age_ticks": _quantiles(ages),
        "web_server_alone_rtt_ms": _quantiles(alone_rtts),
        "web_browser_fps": min(v["browser_fps"] for v in pages.values()),
        "web_per_sessions": pages,
        "web_server_alone_per_sessions": alone,
    }


def _most(per: dict[str, dict[str, Any]]) -> int:
    """The most sessions at once that were sustained (0: not even one)."""
    return max((int(n) for n, v in per.items() if v["sustained"]), default=0)


def _files(tmp: str, timeout_s: float) -> tuple[Path, str]:
    """The bench's protocol file and database path in ``tmp``."""
    protocol = Path(tmp) / "bench.toml"
    protocol.write_text(PROTOCOL.format(timeout_s=timeout_s))
    return protocol, str(Path(tmp) / "web.db")


class _CpuWatch:
    """The server tree's CPU [s] and wall time [s] over the seconds when every session
    drives (sampled by :meth:`sample`)."""

    def __init__(self, server: Any) -> None:
        self.server = server
        self.cpu_s, self.wall_s = 0.0, 0.0
        self._last: tuple[float, float] | None = None

    def sample(self, driving: bool) -> None:
        now, cpu = time.monotonic(), _tree_cpu(self.server)
        if driving and self._last is not None:
            self.cpu_s += cpu - self._last[1]
            self.wall_s += now - self._last[0]
        self._last = (now, cpu)

    @property
    def cores(self) -> float:
        return self.cpu_s / self.wall_s if self.wall_s else float("nan")


def _server_alone(n: int, timeout_s: float) -> dict[str, Any]:
    """``n`` protocol clients at once through the protocol; their figures."""
    import psutil

    from study.web.loadclient import run_clients
    from study.web.testing import served

    with tempfile.TemporaryDirectory(prefix="asa-bench-web-") as tmp:
        protocol, db = _files(tmp, timeout_s)
        codes = tuple(f"B{k:02d}" for k in range(n))
        with served(protocol, db, codes=codes, camera=True) as server:
            watch = _CpuWatch(psutil.Process(server.proc.pid))
            records = run_clients(
                [server.links[c] for c in codes],
                on_every=lambda clients: watch.sample(all(c.driving for c in clients)),
            )
        cams = round(min(r.camera_fps for r in records), 1)
        stopped = [r.stopped for r in records if r.stopped]  # why a client did not end
        return {**_stored(db), "cpu_per_session": round(watch.cores / n, 3), "camera_fps": cams,
                "clients_stopped": stopped, "sustained": False} | _judge(db, cams, n)  # fmt: skip


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
        protocol, db = _files(tmp, timeout_s)
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
                "camera_fps": cams, "sustained": False} | _judge(db, cams, n)  # fmt: skip


def _drive(person: Any, driver: Any, link: str) -> None:
    driver.get(link)
    person.run(timeout=600)


def _watch(server: Any, people: list, threads: list) -> tuple[float, float, float]:
    """While the pages drive: the server tree's CPU [cores], the pages' lowest frame rate
    and camera frames a second."""
    watch, fps, cams = _CpuWatch(server), [], []
    last: tuple[float, list] | None = None
    while any(t.is_alive() for t in threads):
        time.sleep(1.0)
        states = [p.js(_PAGE) for p in people]
        now = time.monotonic()
        driving = all(s[0] == "drive" for s in states)
        watch.sample(driving)
        if driving and last is not None:
            fps.append(min(s[1] for s in states))
            cams.append(
                min(s[2] - c for s, c in zip(states, last[1], strict=True)) / (now - last[0])
            )
        last = (now, [s[2] for s in states])
    return (watch.cores, round(min(fps), 1) if fps else 0.0,
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


def _judge(db: str, camera_fps: float, n: int) -> dict[str, Any]:
    """Whether ``n`` sessions were sustained: every one completed, every trial's tick jitter
    p99 within :data:`JITTER_OK_MS`, the camera at least :data:`CAMERA_OK_FPS`."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from study.data.storage import SessionRow, Trial, open_database

    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            jitters = [j for j in s.scalars(select(Trial.tick_jitter_ms)) if j is not None]
            completed = list(s.scalars(select(SessionRow.status))).count("completed")
    finally:
        engine.dispose()
    worst = max(jitters) if jitters else float("inf")
    ok = completed == n and worst <= JITTER_OK_MS and camera_fps >= CAMERA_OK_FPS
    return {"tick_jitter_p99_worst_ms": round(worst, 2), "completed": completed, "sustained": ok}
