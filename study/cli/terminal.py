"""The experimenter's terminal of ``asa run``: one line per phase and trial, one live
status line during a trial, and after an interruption the trial that was cut short and
the command that resumes the session.

The status line is rewritten in place (carriage return) when stdout is a terminal, and
otherwise (a log file, a pipe) printed as a short line at most every
:data:`STATUS_EVERY_S` of wall time, so a 10-minute trial leaves a few lines, not a
hundred. The participant's window never shows the mode; this terminal does.
"""

from __future__ import annotations

import math
import shlex
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, TextIO

from study.engine.clocks import DT
from study.engine.resume import SessionState

STATUS_EVERY_S = 30.0  # [s] wall time between status lines when stdout is no terminal
LIVE_EVERY_S = 1.0  # [s] wall time between rewrites of the live line


class ExperimenterTerminal:
    """Where ``asa run`` writes: :meth:`line` (phases and trials), :meth:`status` (the
    screen's status), :meth:`on_tick` (the trial loop's hook; a status line of its own
    when no screen sends one).

    Parameters
    ----------
    code : str
        The participant.
    stream : text stream, optional
        Default click's stdout.
    tty : bool, optional
        Rewrite the status in place; default whether ``stream`` is a terminal.
    screen : bool
        A screen sends :meth:`status` lines (with its frame rates); else the status is
        made here from the ticks.
    clock : callable
        Wall time [s] (``time.monotonic``).
    """

    def __init__(
        self,
        code: str,
        *,
        stream: TextIO | None = None,
        tty: bool | None = None,
        screen: bool = False,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.code = code
        self.stream = stream if stream is not None else sys.stdout
        self.tty = bool(tty if tty is not None else self.stream.isatty())
        self.screen = screen
        self.clock = clock
        self.opened = False  # a session line was written: the session row exists
        self.trial_id = -1
        self.trial = ""  # "main #1", the running trial
        self.mode = ""
        self._live = False  # a status line is on screen without its newline
        self._next_status = -math.inf  # [s] wall: the next line when not a terminal
        self._next_live = -math.inf  # [s] wall: the next status made from the ticks

    # -------------------------------------------------------------- writing

    def _write(self, text: str) -> None:
        self.stream.write(text)
        self.stream.flush()

    def _end_live(self) -> None:
        if self._live:
            self._write("\r\x1b[K")
            self._live = False

    def line(self, text: str) -> None:
        """A line that stays: the live status line (if any) gives way to it."""
        self._end_live()
        self._write(text + "\n")
        self.opened = True

    def status(self, text: str) -> None:
        """The running trial's status (``text`` from the screen, or :meth:`on_tick`)."""
        now = self.clock()
        full = f"  {self.code} [mode {self.mode or '-'}] {text}"
        if self.tty:
            width = shutil.get_terminal_size((100, 24)).columns
            self._write("\r" + full[: max(20, width - 1)] + "\x1b[K")
            self._live = True
        elif now >= self._next_status:
            self._write(full + "\n")
            self._next_status = now + STATUS_EVERY_S

    def close(self) -> None:
        """End the live line (the session is over)."""
        self._end_live()

    # -------------------------------------------------------------- the trial loop's hook

    def on_tick(self, tick: int, writer: Any) -> None:
        """A new trial: look up its phase and mode once; without a screen, the status."""
        if writer.trial_id != self.trial_id:
            self._new_trial(writer)
        if not self.screen and self.clock() >= self._next_live:
            self._next_live = self.clock() + (LIVE_EVERY_S if self.tty else 0.0)
            self.status(f"{self.trial}: t {tick * DT:6.1f} s simulated")

    def _new_trial(self, writer: Any) -> None:
        from sqlalchemy.orm import Session

        from study.data.storage import Trial

        with Session(writer.engine) as s:
            row = s.get(Trial, writer.trial_id)
            if row is not None:
                self.trial, self.mode = f"{row.phase} #{row.ordinal}", row.mode
        self.trial_id = writer.trial_id
        self._next_status = self.clock() + STATUS_EVERY_S  # the first after 30 s
        self._next_live = -math.inf


def resume_command(params: dict[str, Any], *, program: str = "asa") -> str:
    """The ``asa run`` command line of ``params`` (the command's options) with
    ``--resume``: what the experimenter types to continue the session."""
    args: list[str] = [program, "run"]
    for name, flag in (("protocol", "--protocol"), ("code", "--participant"), ("db", "--db")):
        args += [flag, str(params[name])]
    if params.get("input_kind", "scripted") != "scripted":
        args += ["--input", str(params["input_kind"])]
    if params.get("seed") is not None:
        args += ["--seed", str(params["seed"])]
    for name in ("force", "headless", "fast"):
        if params.get(name):
            args.append(f"--{name}")
    for name in ("snapshots", "site", "machine"):
        if params.get(name) is not None:
            args += [f"--{name}", str(params[name])]
    args.append("--resume")
    return shlex.join(args)


def interruption_lines(code: str, state: SessionState | None, command: str) -> Sequence[str]:
    """What the experimenter reads after an interruption: the trial cut short (or that
    none was), what is kept, and the command that resumes the session."""
    if state is None:
        return [f"{code}: interrupted before the session was stored; start it again"]
    if state.status == "completed":
        return []
    lines = []
    for t in state.again:
        at = f" at {t.duration_s:.1f} s simulated" if t.duration_s is not None else ""
        why = f": {t.reason}" if t.reason else ""
        lines.append(
            f"{code}: {t.name()} aborted{at}{why}; its data are kept, it runs again on resume"
        )
    if not state.again:
        after = state.last_finished.name() if state.last_finished else "the start"
        lines.append(f"{code}: interrupted between trials, after {after}; no trial was cut short")
    lines.append(f"{code}: session {state.session_id} {state.status}; to continue it:")
    lines.append(f"  {command}")
    return lines
