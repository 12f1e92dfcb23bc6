"""The robot's camera image for the participant's screen, rendered off the control path.

Issue 5 ("Timing"): the camera at 15 fps or more, and its rendering must never delay a
control tick. pybullet's software renderer (``World.camera_image``, ER_TINY_RENDERER) takes
about 50 ms for the default 320 x 240 image on the development machine, a whole 20 Hz tick,
and it holds Python's GIL while it renders (measured: a rendering thread left the main thread
17 % of its speed), so neither the trial loop nor a thread of its process can afford it.

Decision: :class:`CameraFeed` renders in a separate *process* (``spawn`` start method, so no
pybullet or SDL state is inherited) holding its own :class:`sim.world.World` per scenario.
The screen sends the robot's true pose (``World.true_pose()``, read through the trial's
``attach`` hook) and receives an RGB image; one request is in flight at a time, so the feed
runs as fast as the worker renders (about 20 fps on a free core) and always shows the newest
pose. The worker runs at a lower priority (``nice`` 10) so that on a busy machine the
control loop and the screen are served first. The control loop only pays a non-blocking
``poll`` and a pipe write (well under 1 ms).
With ``tail=True`` (the ``layout = "laser"`` screen, thesis Sec. 7.5) each request renders
the front and the tail camera at the same pose; other screens never render the tail camera.
``inline=True`` renders in the calling process instead, at most every ``inline_every``
calls of :meth:`CameraFeed.update` (tests); a worker that dies falls back to that.
"""

from __future__ import annotations

import multiprocessing as mp
from typing import Any

import numpy as np

from sim.scenario import Scenario
from sim.types import Pose2D


def _render(world: Any, tail: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """The front image and, with ``tail``, the tail camera's, at the world's pose."""
    return world.camera_image("front"), world.camera_image("tail") if tail else None


def _serve(conn: Any) -> None:
    """Worker process: ``("scenario", Scenario)``, ``("render", x, y, yaw, tail)``,
    ``("stop",)``; answers a render with ``(front, tail)`` as (shape, bytes) or None."""
    import os

    from sim.world import World

    if hasattr(os, "nice"):
        os.nice(10)  # the control loop and the screen come first
    worlds: dict[str, World] = {}
    world: World | None = None
    try:
        while True:
            msg = conn.recv()
            if msg[0] == "stop":
                break
            if msg[0] == "scenario":
                scenario = msg[1]
                key = scenario.source or scenario.name
                if key not in worlds:
                    worlds[key] = World(scenario, seed=0)
                world = worlds[key]
            elif msg[0] == "render" and world is not None:
                world.reset(Pose2D(msg[1], msg[2], msg[3]))
                images = _render(world, bool(msg[4]))
                conn.send(tuple(None if i is None else (i.shape, i.tobytes()) for i in images))
    except (EOFError, KeyboardInterrupt, BrokenPipeError):
        pass
    finally:
        for w in worlds.values():
            w.close()


class CameraFeed:
    """The newest camera image of the robot at its latest pose.

    Parameters
    ----------
    inline : bool
        Render in this process (blocking, ~50 ms a frame) instead of a worker process.
    inline_every : int
        With ``inline``: render on every n-th :meth:`update`.
    tail : bool
        Render the tail camera too (``tail_image``).
    """

    def __init__(self, *, inline: bool = False, inline_every: int = 10, tail: bool = False) -> None:
        self.inline = inline
        self.inline_every = max(1, int(inline_every))
        self.tail = tail
        self.image: np.ndarray | None = None  # (h, w, 3) uint8, newest
        self.tail_image: np.ndarray | None = None  # (h, w, 3) uint8, newest back view
        self.frames = 0  # images received
        self._scenario_key = ""
        self._busy = False
        self._calls = 0
        self._world: Any = None
        self._conn: Any = None
        self._proc: Any = None
        if not inline:
            ctx = mp.get_context("spawn")
            self._conn, child = ctx.Pipe()
            self._proc = ctx.Process(target=_serve, args=(child,), daemon=True, name="asa-camera")
            self._proc.start()
            child.close()

    def set_world(self, world: Any) -> None:
        """Render ``world``'s scenario from now on (a new trial)."""
        self._world = world
        scenario: Scenario = world.scenario
        key = scenario.source or scenario.name
        if key != self._scenario_key:
            self.image = self.tail_image = None
            self._scenario_key = key
            if self._conn is not None:
                self._drain(block=True)
                self._conn.send(("scenario", scenario))

    def update(self) -> None:
        """Collect a finished image (never blocks) and ask for one at the current pose."""
        if self._world is None:
            return
        if self.inline:
            if self._calls % self.inline_every == 0:
                self.image, self.tail_image = _render(self._world, self.tail)
                self.frames += 1
            self._calls += 1
            return
        self._drain(block=False)
        if not self._busy and self._conn is not None:
            pose = self._world.true_pose()
            try:
                self._conn.send(
                    ("render", float(pose.x), float(pose.y), float(pose.yaw), self.tail)
                )
                self._busy = True
            except OSError:  # the worker died: render here from now on
                self._conn, self.inline = None, True

    def _drain(self, *, block: bool) -> None:
        if self._conn is None or not self._busy:
            return
        try:
            if not (block or self._conn.poll()):
                return
            front, tail = self._conn.recv()
        except (EOFError, OSError):  # the worker died: render here from now on
            self._busy = False
            self._conn = None
            self.inline = True
            return
        self.image = np.frombuffer(front[1], dtype=np.uint8).reshape(front[0])
        if tail is not None:
            self.tail_image = np.frombuffer(tail[1], dtype=np.uint8).reshape(tail[0])
        self.frames += 1
        self._busy = False

    def close(self) -> None:
        """Stop the worker (idempotent)."""
        if self._conn is not None:
            try:
                self._drain(block=True)
                self._conn.send(("stop",))
            except (BrokenPipeError, OSError):
                pass
            self._conn.close()
            self._conn = None
        if self._proc is not None:
            self._proc.join(timeout=5)
            if self._proc.is_alive():
                self._proc.terminate()
            self._proc = None
