"""Manual mode: the command sent to the robot is the joystick command, ``v = u``
(``beta = 0`` in eq. 3.2). The baseline of the user study (thesis 7.6.1.2).

No safety layer and no assistance of any kind; collisions are possible, as in
the thesis's manual condition.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from autonomy.modes import register
from autonomy.types import EMPTY_PATH, Assist, Mode, RobotModel


class ManualMode(Mode):
    """``v = u``: no assistance."""

    name = "manual"

    def __init__(self) -> None:
        self.robot_: RobotModel | None = None

    def reset(self, robot: RobotModel) -> None:
        self.robot_ = robot

    def step(self, obs: Any, u: np.ndarray) -> Assist:
        start = time.perf_counter()
        u = np.array(u, dtype=float).reshape(3)
        return Assist(
            v=u,
            g=u.copy(),
            beta=0.0,
            label="",
            target="",
            scores={},
            predicted_path=EMPTY_PATH,
            timings_ms={"total": (time.perf_counter() - start) * 1e3},
        )


@register("manual")
def make_manual(**settings: Any) -> ManualMode:
    """Registry factory; manual mode has no settings."""
    if settings:
        raise ValueError(f"mode 'manual': takes no settings, got {', '.join(sorted(settings))}")
    return ManualMode()
