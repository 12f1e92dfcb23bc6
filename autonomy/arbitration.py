"""Linear arbitration of the user's and the robot's commands (thesis Ch. 3.1, eq. 3.2).

``v = (1 - beta) u + beta g``: ``beta = 0`` is manual control, ``beta = 1`` full
autonomy. ``beta`` is the confidence of the recognised situation or task
(eq. 3.4), so it is clipped to [0, 1] here rather than trusted; a NaN ``beta``
(an undefined confidence) is treated as 0, i.e. the user keeps control.
"""

from __future__ import annotations

import math

import numpy as np


def blend(u: np.ndarray, g: np.ndarray, beta: float) -> np.ndarray:
    """Blend the user's command ``u`` with the robot's command ``g``.

    Parameters
    ----------
    u : (3,) joystick command (v_x [m/s], v_y [m/s], omega [rad/s]), robot frame.
    g : (3,) the robot's own command, same frame and units.
    beta : arbitration factor; clipped to [0, 1], NaN counts as 0.

    Returns
    -------
    v : (3,) the command sent to the robot; componentwise between ``u`` and ``g``.

    Two (3,) commands of finite values are blended in Python floats (the same products,
    sums and clipping as the numpy expression below, a few microseconds less a tick).
    """
    b = 0.0 if math.isnan(beta) else min(max(float(beta), 0.0), 1.0)
    u = np.asarray(u, dtype=float)
    g = np.asarray(g, dtype=float)
    if u.shape == (3,) and g.shape == (3,):
        pairs = tuple(zip(u.tolist(), g.tolist(), strict=True))
        if all(math.isfinite(x) and math.isfinite(y) for x, y in pairs):
            a = 1.0 - b
            return np.array([_clip(a * x + b * y, x, y) for x, y in pairs])
    v = (1.0 - b) * u + b * g  # Eq. (3.2)
    # the exact value lies between u and g; clipping only removes rounding overshoot
    return np.clip(v, np.minimum(u, g), np.maximum(u, g))


def _clip(v: float, x: float, y: float) -> float:
    """``np.clip(v, np.minimum(x, y), np.maximum(x, y))`` of finite floats, signed zeros
    as numpy picks them (of equal values the second operand; ``clip`` is
    ``minimum(maximum(v, lo), hi)``)."""
    lo = x if x < y else y
    hi = x if x > y else y
    v = v if v > lo else lo
    return v if v < hi else hi
