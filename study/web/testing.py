"""A real study server and real headless Chromium, which the browser tests and ``asa bench
--only web`` share (issue 37): ``asa serve`` as a subprocess on a free port of 127.0.0.1,
Debian's chromium driven by Selenium through chromedriver (the test extra; .ci/run installs
both), a gamepad faked by an init script (``navigator.getGamepads`` returns
``window.__pad``), and a scripted person who presses its buttons screen by screen."""

from __future__ import annotations

import contextlib
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

PAD_JS = """
window.__pad = { axes: [0, 0, 0, 0], buttons: new Array(17).fill(false) };
navigator.getGamepads = () => [{ id: "test pad", index: 0, connected: true,
  mapping: "standard", timestamp: performance.now(), axes: window.__pad.axes.slice(),
  buttons: window.__pad.buttons.map((p) => ({ pressed: p, touched: p, value: p ? 1 : 0 })) }];
"""
A, B, RIGHT, DOWN = 0, 1, 15, 13  # standard-mapping buttons
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"

SHORT = """
[study]
name = "web-short"
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]

[[phases]]
kind = "briefing"
text = "Drive the robot; the laser hits are {{laser_colour}} dots."

[[phases]]
kind = "experience"
instrument = "experience"

[[phases]]
kind = "baseline"
questions = 2

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = {timeout_s}

[phases.after_trial]
instrument = "nasa_tlx"
weights = "once"

[[phases]]
kind = "debrief"
text = "Thank you."

[web]
grace_s = {grace_s}
latency_gate_ms = 500
pings = 5
completion_code = "C0DE42"
"""


def short_protocol(
    folder: Path, seed: int, *, timeout_s: float = 2.0, grace_s: float = 20.0
) -> Path:
    path = folder / "short.toml"
    path.write_text(SHORT.format(seed=seed, timeout_s=timeout_s, grace_s=grace_s))
    return path


@dataclass
class Served:
    proc: subprocess.Popen
    base: str
    experimenter: str
    links: dict[str, str] = field(default_factory=dict)


@contextlib.contextmanager
def served(
    protocol: Path, db: str, *extra: str, codes: tuple[str, ...] = ("P01",), camera: bool = False
) -> Iterator[Served]:
    """`asa serve` on a free port with an invite per code; stopped with SIGINT after."""
    args = [sys.executable, "-m", "study.cli", "serve", "--protocol", str(protocol), "--db",
            db, "--port", "0", *(() if camera else ("--no-camera",)), *extra]  # fmt: skip
    for code in codes:
        args += ["--invite", code]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = [proc.stdout.readline().strip() for _ in range(2 + len(codes))]
        if not lines[0].startswith("asa serve: listening"):
            proc.kill()
            raise RuntimeError(f"asa serve did not start: {lines} {proc.stderr.read()}")
        base = lines[1].split(": ", 1)[1].split("/experimenter")[0]
        links = dict(line.split("\t") for line in lines[2:])
        yield Served(proc, base, lines[1].split(": ", 1)[1], links)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=40)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def browser() -> Any:
    """Headless Chromium with the fake gamepad."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.options import Options
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        raise ValueError("needs selenium: pip install -e '.[test]'") from None
    if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
        raise ValueError(
            "needs chromium and chromedriver: apt-get install chromium chromium-driver"
        )

    opts = Options()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--window-size=1280,800", "--disable-gpu",
              "--disable-dev-shm-usage", "--disable-background-timer-throttling",
              "--disable-renderer-backgrounding"):  # fmt: skip
        opts.add_argument(a)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": PAD_JS})
    return driver


class Person:
    """Presses the fake gamepad's buttons as the screens ask; remembers what it did."""

    def __init__(self, driver: Any, *, shots: Path | None = None) -> None:
        self.d = driver
        self.shots = shots  # a PNG of every screen goes here (None: none)
        self._shot = 0
        self.pairs: list[tuple[str, str]] = []  # titles of each pair shown
        self.forms: list[str] = []  # titles of the forms filled
        self.answered = 0
        self.pushes: list[tuple[int, int]] = []  # (tick drawn at push, at release)

    def js(self, script: str) -> Any:
        return self.d.execute_script(script)

    def snapshot(self, what: str) -> None:
        """A PNG of the page now, ``NNNN_<what>.png`` in :attr:`shots` (if any)."""
        if self.shots is None:
            return
        self._shot += 1
        name = "".join(c if c.isalnum() else "_" for c in what)[:60]
        self.shots.mkdir(parents=True, exist_ok=True)
        self.d.save_screenshot(str(self.shots / f"{self._shot:04d}_{name}.png"))

    def state(self) -> dict[str, Any]:
        return self.js(
            "const a = window.__asa; return {phase: a.phase, screen: a.screen || null, "
            "n: a.screens.length, strip: a.strip || null, tick: a.lastTick, end: a.end || null}"
        )

    def press(self, button: int, hold: float = 0.12) -> None:
        self.js(f"window.__pad.buttons[{button}] = true")
        time.sleep(hold)
        self.js(f"window.__pad.buttons[{button}] = false")
        time.sleep(0.12)

    @staticmethod
    def key(st: dict[str, Any]) -> tuple:
        """What makes a screen another one (a form's or a pair's updates do not)."""
        screen = st["screen"] or {}
        return (st["phase"], screen.get("kind"), screen.get("title"), screen.get("body"),
                screen.get("progress"), screen.get("tag"))  # fmt: skip

    def wait_other(self, key: tuple, timeout: float = 60.0) -> dict[str, Any]:
        """The state once the screen is another than ``key`` (or the session ended)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            st = self.state()
            if self.key(st) != key or st["phase"] in ("ended", "refused", "aborted"):
                return st
            time.sleep(0.05)
        raise AssertionError(f"no other screen within {timeout} s: {self.state()}")

    def run(self, timeout: float = 240.0, stop_at: str | None = None) -> dict[str, Any]:
        """Every screen until the end page (or a drive screen titled ``stop_at``...)."""
        end = time.monotonic() + timeout
        st = self.wait_other(self.key(self.state()))
        while time.monotonic() < end:
            if st["phase"] in ("ended", "refused", "aborted"):
                self.snapshot(st["phase"])
                return st
            if st["screen"] is None:  # the check or a message
                st = self.wait_other(self.key(st))
                continue
            screen = st["screen"]
            if screen["kind"] == "drive" and stop_at and screen["title"].startswith(stop_at):
                return st
            time.sleep(0.1 if self.shots else 0.0)  # drawn on the next frame
            self.snapshot(f"{screen['kind']}_{screen.get('tag') or screen.get('title') or ''}")
            getattr(self, f"_{screen['kind']}")(screen)
            st = self.wait_other(self.key(st))
        raise AssertionError("the session did not end in time")

    def _page(self, screen: dict[str, Any]) -> None:
        self.press(A)

    def _form(self, screen: dict[str, Any]) -> None:
        self.forms.append(screen["title"])
        for _ in screen["rows"]:
            self.press(RIGHT)
            self.press(A)
        self.press(A)

    def _pair(self, screen: dict[str, Any]) -> None:
        self.pairs.append(tuple(screen["titles"]))
        self.press(RIGHT)
        self.press(A)

    def _drive(self, screen: dict[str, Any]) -> None:
        key = self.key(self.state())
        asked = None
        while self.key(self.state()) == key:
            if screen["drive"]:
                start = self.state()["tick"]
                self.js("window.__pad.axes[1] = -1")  # left stick forwards
                time.sleep(0.6)
                self.js("window.__pad.axes[1] = 0")
                self.pushes.append((start, self.state()["tick"]))
                if len(self.pushes) % 4 == 1:
                    self.snapshot(f"drive_{screen['title']}")
                time.sleep(0.4)
            else:
                strip = self.state()["strip"] or {}
                if strip.get("question") and strip["question"] != asked:
                    asked = strip["question"]
                    self.snapshot(f"question_{screen['title']}")
                    self.press(A)
                    self.answered += 1
                time.sleep(0.05)


def shortened(text: str, trial_s: float) -> str:
    """A protocol's text with every trial's ``timeout_s``, ``duration_s`` and
    ``time_limit_s`` cut to at most ``trial_s`` seconds (a look at the screens)."""
    import re

    def cut(m: re.Match) -> str:
        return f"{m.group(1)}{min(float(m.group(2)), trial_s):g}"

    return re.sub(r"(?m)^(\s*(?:timeout_s|duration_s|time_limit_s)\s*=\s*)([0-9.]+)", cut, text)


def snapshot_session(
    protocol: str, out: Path, *, camera: bool = True, trial_s: float = 10.0
) -> list[Path]:
    """Every screen of ``protocol`` as the browser shows it: a throwaway study served on
    127.0.0.1 with every trial cut to ``trial_s`` seconds (:func:`shortened`), one
    headless Chromium page driven by the scripted person, a PNG of each screen (and of the
    driving screen now and then) into ``out``; the PNGs written."""
    import tempfile

    from study.engine.protocol import protocol_path

    with tempfile.TemporaryDirectory(prefix="asa-snapshots-") as tmp:
        short = Path(tmp) / "protocol.toml"
        text = protocol_path(protocol).read_text(encoding="utf-8")
        short.write_text(shortened(text, trial_s), encoding="utf-8")
        protocol = str(short)
        db = str(Path(tmp) / "s.db")
        with served(protocol, db, camera=camera) as server:  # type: ignore[arg-type]
            driver = browser()
            try:
                driver.get(server.links["P01"])
                Person(driver, shots=out).run(timeout=3600)
            finally:
                driver.quit()
    return sorted(out.glob("*.png"))
