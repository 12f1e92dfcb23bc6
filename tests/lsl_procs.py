"""The processes the LSL tests start, each with the test's own LSL configuration
(``LSLAPICFG``: machine scope, IPv6 off, a fresh session id, liblsl's log off), so that
tests running in parallel never see each other's streams:

- ``tracker``: a fake eye tracker, 4 channels at 120 Hz, stamping each sample with its own
  ``local_clock()`` (in a time namespace of its own, its clock is off by ``--offset``
  seconds); writes ``index timestamp`` per sample pushed to ``--log``;
- ``reader``: an inlet on the session's event and state outlets, until the
  ``session_ended`` marker (or ``--timeout``); writes what it read as JSON to ``--out``;
- ``session``: one synthetic participant's session of ``--protocol`` paced by the wall
  clock (``run_session`` with LSL on), printing ``ticking`` at the first tick of the first
  main trial and the summary's status at the end.

Run as ``python -m tests.lsl_procs KIND ...`` from the repository's root.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TRACKER_HZ = 120.0
TRACKER_CHANNELS = ("gaze_x", "gaze_y", "pupil_left", "pupil_right")


def write_config(folder: Path) -> Path:
    """A fresh LSL configuration file in ``folder``: machine scope, IPv6 off, a session id
    no other test uses, liblsl's log off, more probes per clock offset."""
    path = folder / "lsl_api.cfg"
    path.write_text(
        "[ports]\nIPv6 = disable\n[multicast]\nResolveScope = machine\n"
        f"[lab]\nSessionID = asa-test-{uuid.uuid4().hex}\n[log]\nlevel = -3\n"
        # more clock probes per offset (liblsl: 8, 64 ms apart): on two loaded cores the
        # fastest of more round trips keeps the offset's error well under 1 ms
        "[tuning]\nTimeProbeCount = 40\nTimeProbeInterval = 0.01\n",
        encoding="utf-8",
    )
    return path


def env_with(config: Path) -> dict[str, str]:
    env = dict(os.environ, LSLAPICFG=str(config), SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    return env


def time_namespace_prefix(offset_s: int) -> list[str]:
    """``unshare`` into a time namespace whose monotonic clock is ``offset_s`` ahead (a
    device with its own clock), as root or in a user namespace; [] where neither works."""
    exe = shutil.which("unshare")
    if exe is None:
        return []
    for extra in ([], ["-r"]):
        cmd = [exe, *extra, "--time", "--monotonic", str(offset_s), "true"]
        if subprocess.run(cmd, capture_output=True).returncode == 0:
            return [exe, *extra, "--time", "--monotonic", str(offset_s)]
    return []


def start(
    kind: str, args: list[str], config: Path, *, prefix: list[str] | None = None, **popen: object
) -> subprocess.Popen:
    """``kind`` in a process of its own, in the folder of its configuration (the test's:
    a server database's local folders go there, not into the repository)."""
    cmd = [*(prefix or []), sys.executable, "-m", "tests.lsl_procs", kind, *args]
    env = env_with(config)
    return subprocess.Popen(cmd, cwd=config.parent, env=env, **popen)  # type: ignore[call-overload]


# ---------------------------------------------------------------------- the processes


def _tracker(a: argparse.Namespace) -> None:
    import numpy as np
    import pylsl

    info = pylsl.StreamInfo(
        a.name, "Gaze", len(TRACKER_CHANNELS), TRACKER_HZ, "float32", a.source_id
    )
    chans = info.desc().append_child("channels")
    for label in TRACKER_CHANNELS:
        chans.append_child("channel").append_child_value("label", label)
    outlet = pylsl.StreamOutlet(info)
    log = open(a.log, "a", encoding="utf-8")  # noqa: SIM115 (closed by the process's end)
    period, index, start = 1.0 / TRACKER_HZ, a.first, pylsl.local_clock()
    while True:
        stamp = pylsl.local_clock()
        outlet.push_sample(np.array([index, 0.5, 3.0, 3.1], dtype=np.float32), stamp)
        log.write(f"{index} {stamp!r}\n")
        log.flush()
        index += 1
        time.sleep(max(0.0, start + (index - a.first) * period - pylsl.local_clock()))


def _reader(a: argparse.Namespace) -> None:
    import pylsl

    def inlet(kind: str) -> pylsl.StreamInlet:
        found = pylsl.resolve_byprop("type", kind, 1, 30.0)
        if not found:
            raise SystemExit(f"reader: no {kind} stream")
        i = pylsl.StreamInlet(found[0], max_buflen=60)
        i.open_stream(timeout=10.0)
        return i

    state, events = inlet("RobotState"), inlet("Markers")  # state first: the session
    # waits for a consumer of its events, then ticks at once
    Path(a.ready).write_text("ready", encoding="utf-8")
    markers: list[list] = []
    states: list[list] = []
    deadline = time.monotonic() + a.timeout
    while time.monotonic() < deadline:
        m, mt = events.pull_chunk(0.05)
        markers += [[s[0], t] for s, t in zip(m, mt, strict=True)]
        x, xt = state.pull_chunk(0.0)
        states += [[*s, t] for s, t in zip(x, xt, strict=True)]
        if any(json.loads(s)["event"] == "session_ended" for s, _ in markers[-5:]):
            break
    time.sleep(0.2)
    x, xt = state.pull_chunk(0.5)
    states += [[*s, t] for s, t in zip(x, xt, strict=True)]
    header = state.info(timeout=5.0).as_xml()
    Path(a.out).write_text(json.dumps({"markers": markers, "state": states, "state_xml": header}))


def _session(a: argparse.Namespace) -> None:
    import numpy as np

    from study.engine.clocks import FreeClock, WallClock
    from study.engine.protocol import load_protocol
    from study.engine.session import run_session
    from study.participants import synthetic_participant

    printed = []

    def on_tick(tick: int, writer: object) -> None:
        if not printed and tick == 1:
            print("ticking", flush=True)
            printed.append(1)

    summary = run_session(
        load_protocol(a.protocol),
        a.participant,
        a.db,
        participant=synthetic_participant(np.random.default_rng(a.seed)),
        seed=a.seed,
        clock=FreeClock() if a.fast else WallClock(),
        on_tick=on_tick,
        record=False,
        lsl=True if a.lsl else None,
    )
    print(f"status {summary.status}", flush=True)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="lsl_procs")
    sub = p.add_subparsers(dest="kind", required=True)
    t = sub.add_parser("tracker")
    t.add_argument("--name", default="FakeTracker")
    t.add_argument("--source-id", default="fake-tracker-1")
    t.add_argument("--log", required=True)
    t.add_argument("--first", type=int, default=0)
    r = sub.add_parser("reader")
    r.add_argument("--out", required=True)
    r.add_argument("--ready", required=True)
    r.add_argument("--timeout", type=float, default=60.0)
    s = sub.add_parser("session")
    s.add_argument("--protocol", required=True)
    s.add_argument("--db", required=True)
    s.add_argument("--participant", default="P01")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--fast", action="store_true")
    s.add_argument("--lsl", action="store_true")
    a = p.parse_args(argv)
    {"tracker": _tracker, "reader": _reader, "session": _session}[a.kind](a)


if __name__ == "__main__":
    main()
