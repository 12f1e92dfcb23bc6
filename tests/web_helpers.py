"""A real study server and real headless Chromium for the browser tests (issue 37): `asa
serve` as a subprocess on a free port of 127.0.0.1, Debian's chromium driven by Selenium
through chromedriver, a gamepad faked by an init script (navigator.getGamepads returns
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

import pytest

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
    protocol: Path, db: str, *extra: str, codes: tuple[str, ...] = ("P01",)
) -> Iterator[Served]:
    """`asa serve` on a free port with an invite per code; stopped with SIGINT after."""
    args = [sys.executable, "-m", "study.cli", "serve", "--protocol", str(protocol), "--db",
            db, "--port", "0", "--no-camera", *extra]  # fmt: skip
    for code in codes:
        args += ["--invite", code]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = [proc.stdout.readline().strip() for _ in range(2 + len(codes))]
        if not lines[0].startswith("asa serve: listening"):
            proc.kill()
            pytest.fail(f"asa serve did not start: {lines} {proc.stderr.read()}")
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
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

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

    def __init__(self, driver: Any) -> None:
        self.d = driver
        self.pairs: list[tuple[str, str]] = []  # titles of each pair shown
        self.forms: list[str] = []  # titles of the forms filled
        self.answered = 0
        self.pushes: list[tuple[int, int]] = []  # (tick drawn at push, at release)

    def js(self, script: str) -> Any:
        return self.d.execute_script(script)

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
                return st
            if st["screen"] is None:  # the check or a message
                st = self.wait_other(self.key(st))
                continue
            screen = st["screen"]
            if screen["kind"] == "drive" and stop_at and screen["title"].startswith(stop_at):
                return st
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
                time.sleep(0.4)
            else:
                strip = self.state()["strip"] or {}
                if strip.get("question") and strip["question"] != asked:
                    asked = strip["question"]
                    self.press(A)
                    self.answered += 1
                time.sleep(0.05)


class CuttableProxy:
    """A TCP proxy between the page and the server on 127.0.0.1 whose connections the test
    cuts (from the server's side as the page sees it) and whose port it can block."""

    def __init__(self, target_port: int) -> None:
        import socket
        import threading

        self.target = target_port
        self.blocked = False
        self.pairs: list[tuple[Any, Any]] = []
        self._lock = threading.Lock()
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        import socket
        import threading

        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if self.blocked:
                client.close()
                continue
            upstream = socket.create_connection(("127.0.0.1", self.target))
            with self._lock:
                self.pairs.append((client, upstream))
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    @staticmethod
    def _pipe(a: Any, b: Any) -> None:
        try:
            while data := a.recv(65536):
                b.sendall(data)
        except OSError:
            pass
        for s in (a, b):
            with contextlib.suppress(OSError):
                s.close()

    def cut(self) -> None:
        """Close every connection now."""
        import socket

        with self._lock:
            pairs, self.pairs = self.pairs, []
        for pair in pairs:
            for s in pair:
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
                    s.close()

    def close(self) -> None:
        self.cut()
        self.listener.close()
