"""Trial clocks: free-running or paced by the wall clock at 20 Hz, and the experimenter's
pause and abort (DESIGN.md, "One control tick"), Ctrl-C included (:func:`sigint_aborts`)."""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Iterator

import numpy as np

DT = 0.05  # [s] control tick (20 Hz)


class FreeClock:
    """Free-running time: ticks follow each other as fast as the machine allows."""

    paced = False

    def start(self) -> None:
        """Start timing a trial."""

    def wait(self) -> None:
        """Return at once (nothing to wait for)."""

    def jitter_p99_ms(self) -> float | None:
        """None: a free-running trial has no period to keep."""
        return None


class WallClock:
    """Wall-clock pacing at ``1 / dt``: :meth:`wait` sleeps to the next tick.

    Parameters
    ----------
    dt : float
        [s] tick period.
    """

    paced = True

    def __init__(self, dt: float = DT) -> None:
        self.dt = dt
        self._next = math.nan
        self._last = math.nan
        self._periods: list[float] = []

    def start(self) -> None:
        """Start timing a trial (forgets earlier periods)."""
        now = time.perf_counter()
        self._next, self._last, self._periods = now + self.dt, now, []

    def wait(self) -> None:
        """Sleep until the next tick is due; records the achieved period."""
        now = time.perf_counter()
        if self._next > now:
            time.sleep(self._next - now)
        else:  # late: do not try to catch up a backlog
            self._next = now
        self._next += self.dt
        now = time.perf_counter()
        self._periods.append(now - self._last)
        self._last = now

    def jitter_p99_ms(self) -> float | None:
        """99th percentile of ``|period - dt|`` [ms] over the trial, None before any tick."""
        if not self._periods:
            return None
        return float(np.percentile(np.abs(np.asarray(self._periods) - self.dt), 99) * 1e3)


INTERRUPTED = "Ctrl-C by the experimenter"


class ExperimenterControl:
    """Pause and abort requested by the experimenter (from another thread or a callback).

    ``ticking`` is True while a trial's loop runs its ticks (it looks at ``aborted`` before
    every tick), set by that loop.
    """

    def __init__(self) -> None:
        self.paused = False
        self.aborted = False
        self.reason = ""
        self.ticking = False

    def pause(self) -> None:
        self.paused = True

    def resume(self) -> None:
        self.paused = False

    def abort(self, reason: str = "aborted by the experimenter") -> None:
        self.aborted = True
        self.reason = reason


@contextlib.contextmanager
def sigint_aborts(control: ExperimenterControl) -> Iterator[ExperimenterControl]:
    """Ctrl-C (SIGINT) aborts the session cleanly while the block runs; the previous
    handler is restored afterwards.

    Installed explicitly, so Ctrl-C works even when the process started with SIGINT
    ignored (a script's ``cmd &``). While a trial ticks, the first Ctrl-C asks ``control``
    to abort: the loop finishes the current tick and stores the trial ``aborted`` with
    its outcome, and the session ends ``aborted``. Elsewhere (a page, a form, between
    trials), or at a second Ctrl-C, it raises ``KeyboardInterrupt``, whose path stores
    what a running trial buffered and marks it ``aborted``. Outside the main thread (where
    Python cannot install signal handlers) nothing is installed.
    """
    if threading.current_thread() is not threading.main_thread():
        yield control
        return

    def on_sigint(signum: int, frame: object) -> None:
        if control.ticking and not control.aborted:
            control.abort(INTERRUPTED)
            return
        raise KeyboardInterrupt(INTERRUPTED)

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield control
    finally:
        # None: a handler not installed from Python; the default is the nearest to it
        signal.signal(signal.SIGINT, previous if previous is not None else signal.SIG_DFL)
