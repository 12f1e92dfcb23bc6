"""A wall clock that keeps the participant's screen moving between control ticks.

The trial loop (:mod:`study.engine.trial`) asks the participant to ``act`` once per 20 Hz tick and
then calls ``clock.wait()``; a screen redrawn only in ``act`` would run at 20 fps. Issue 5
asks for 30 fps or more. :class:`UiClock` is a :class:`study.engine.clocks.WallClock` whose ``wait``
draws further frames (``frame()``: pump the input events, collect the camera image, redraw)
in the idle time before the next tick is due, every ``1 / fps`` seconds, but only when the
frame's measured cost (an exponential average of the last frames, times 2, plus 2 ms)
still ends before the tick's deadline, so drawing never delays a tick. The tick period and
its jitter are measured by :class:`WallClock` as before (``trial.tick_jitter_ms``).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from study.engine.clocks import DT, WallClock


class UiClock(WallClock):
    """Wall-clock pacing at ``1 / dt`` with screen frames drawn in the idle time.

    Parameters
    ----------
    frame : callable
        Draws one frame (and pumps the input events).
    dt : float
        [s] tick period.
    fps : float
        [1/s] frames wanted between ticks (``act`` draws one per tick as well).
    """

    def __init__(self, frame: Callable[[], None], *, dt: float = DT, fps: float = 40.0) -> None:
        super().__init__(dt)
        self.frame = frame
        self.fps = fps
        self.frame_cost = 0.005  # [s] running estimate
        self._next_frame = 0.0

    def start(self) -> None:
        super().start()
        self._next_frame = time.perf_counter() + 1.0 / self.fps

    def wait(self) -> None:
        """Draw frames while there is time, then sleep to the tick (see the module doc)."""
        deadline = self._next
        period = 1.0 / self.fps
        while True:
            now = time.perf_counter()
            if now >= deadline:
                break
            if now >= self._next_frame:
                if now + 2.0 * self.frame_cost + 0.002 < deadline:
                    self.frame()
                    cost = time.perf_counter() - now
                    self.frame_cost = 0.8 * self.frame_cost + 0.2 * cost
                self._next_frame = max(self._next_frame + period, now + 0.5 * period)
                continue
            time.sleep(max(0.0, min(deadline, self._next_frame) - now))
        super().wait()
