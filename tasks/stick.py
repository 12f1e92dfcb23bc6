"""A human hand on a gamepad stick: the filter that makes an ideal command look like a
person's (thesis Sec. 7.2.3: an average driving speed of about 0.3 m/s).

The translation is scaled by ``preferred_speed / reference_speed``; occasional over- or
undershoot episodes (Poisson onsets, a random gain held for a random duration); a
reaction delay of ``delay_ticks`` (FIFO); low-pass filtered Gaussian noise per channel
while the stick is deflected (first order, time constant ``noise_tau_s``); a
per-channel deadzone and quantisation to ``levels`` steps; and the robot's limits.
Every tick draws the same number of variates, so the output is a deterministic
function of the Generator's state and the inputs.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class HumanStickSettings:
    """A human hand on a gamepad stick (decided; see the module docstring)."""

    preferred_speed: float = 0.35  # [m/s] (thesis Sec. 7.2.3: about 0.3 m/s on average)
    reference_speed: float = 0.4  # [m/s] the skills' cruise speed it rescales
    noise_sigma: tuple[float, float, float] = (0.04, 0.04, 0.08)  # [m/s, m/s, rad/s]
    noise_tau_s: float = 0.4  # [s] time constant of the low-pass noise
    delay_ticks: int = 4  # reaction delay [ticks] (200 ms at 20 Hz)
    deadzone: float = 0.05  # fraction of full deflection read as zero, per channel
    levels: int = 127  # quantisation steps per half axis
    overshoot_rate_hz: float = 0.25  # [1/s] onsets of over/undershoot episodes
    overshoot_gain: tuple[float, float] = (0.7, 1.35)  # gain range of an episode
    overshoot_duration_s: tuple[float, float] = (0.3, 1.0)  # [s]
    max_speed: float = 1.0  # [m/s] full deflection, translation (thesis 7.6.1.1)
    max_yaw_rate: float = 1.2  # [rad/s] full deflection, rotation
    dt: float = 0.05  # [s] control tick

    def __post_init__(self) -> None:
        for name in ("preferred_speed", "reference_speed", "max_speed", "max_yaw_rate", "dt"):
            if not getattr(self, name) > 0:
                raise ValueError(f"HumanStickSettings: field '{name}': must be positive")
        if self.delay_ticks < 0 or self.levels < 1 or not 0 <= self.deadzone < 1:
            raise ValueError(
                "HumanStickSettings: fields 'delay_ticks' >= 0, 'levels' >= 1, "
                "'deadzone' in [0, 1) required"
            )


def _axis(value: float, full: float, deadzone: float, levels: int) -> float:
    """One channel of the stick: ``value / full`` clipped to [-1, 1], the ``deadzone``,
    the quantisation to ``levels`` steps; as ``numpy.clip``, ``numpy.where`` and
    ``numpy.round`` (half to even, keeping the sign of a zero) do it on an array."""
    axis = value / full
    axis = -1.0 if -1.0 > axis else axis  # min(max(axis, -1.0), 1.0), as Python does it
    axis = 1.0 if 1.0 < axis else axis
    if abs(axis) < deadzone:
        return 0.0
    scaled = axis * levels
    return math.copysign(float(round(scaled)), scaled) / levels


class HumanStick:
    """Turns ideal commands into human-like stick commands; deterministic per Generator.

    Call :meth:`reset` with a Generator, then :meth:`filter` once per tick.
    """

    def __init__(self, settings: HumanStickSettings | None = None) -> None:
        self.settings = HumanStickSettings() if settings is None else settings

    def reset(self, rng: np.random.Generator) -> None:
        """Forget the past; ``rng`` draws all of this stick's noise from now on."""
        s = self.settings
        self._rng = rng
        self._fifo: deque[tuple[float, float, float]] = deque([(0.0, 0.0, 0.0)] * s.delay_ticks)
        self._noise = (0.0, 0.0, 0.0)
        self._gain = 1.0
        self._episode_left = 0
        # per-tick constants: the noise's AR(1) factor a and b * sigma per channel
        a = math.exp(-s.dt / s.noise_tau_s)
        b = math.sqrt(1 - a * a)
        self._ab = (a, b * s.noise_sigma[0], b * s.noise_sigma[1], b * s.noise_sigma[2])

    def filter(self, u_ideal: np.ndarray) -> np.ndarray:
        """The stick command for this tick.

        Parameters
        ----------
        u_ideal : numpy.ndarray
            (3,) the ideal robot-frame command (v_x [m/s], v_y [m/s], omega [rad/s]).

        Returns
        -------
        numpy.ndarray
            (3,) what the hand actually commands, within the robot's limits.
        """
        u0, u1, u2 = (float(c) for c in u_ideal)
        return np.array(self.filter_uvw(u0, u1, u2))

    def filter_uvw(self, u0: float, u1: float, u2: float) -> tuple[float, float, float]:
        """:meth:`filter` of the ideal command ``(u0, u1, u2)`` as floats."""
        s = self.settings
        if not hasattr(self, "_rng"):
            raise RuntimeError("HumanStick.filter called before reset()")
        # scalar arithmetic (numpy on 3 numbers costs more than the numbers): the same
        # IEEE operations in the same order as the array form, so the same result
        z0, z1, z2 = self._rng.standard_normal(3).tolist()
        onset, g, dur = self._rng.random(3).tolist()  # always three, to keep the stream aligned
        k = s.preferred_speed / s.reference_speed
        u0, u1 = u0 * k, u1 * k
        if self._episode_left > 0:
            self._episode_left -= 1
        else:
            self._gain = 1.0
            if onset < s.overshoot_rate_hz * s.dt:
                lo, hi = s.overshoot_gain
                self._gain = lo + g * (hi - lo)
                d_lo, d_hi = s.overshoot_duration_s
                self._episode_left = round((d_lo + dur * (d_hi - d_lo)) / s.dt)
        gain = self._gain
        self._fifo.append((u0 * gain, u1 * gain, u2 * gain))
        u0, u1, u2 = self._fifo.popleft()
        a, b0, b1, b2 = self._ab
        n0, n1, n2 = self._noise
        self._noise = n0, n1, n2 = (a * n0 + b0 * z0, a * n1 + b1 * z1, a * n2 + b2 * z2)
        if abs(u0) > 1e-9 or abs(u1) > 1e-9 or abs(u2) > 1e-9:  # a hand off the stick
            u0, u1, u2 = u0 + n0, u1 + n1, u2 + n2  # does not tremble
        full_v, full_w, dead, levels = s.max_speed, s.max_yaw_rate, s.deadzone, s.levels
        out0 = _axis(u0, full_v, dead, levels) * full_v
        out1 = _axis(u1, full_v, dead, levels) * full_v
        out2 = _axis(u2, full_w, dead, levels) * full_w
        if out0 * out0 + out1 * out1 > s.max_speed * s.max_speed * (1.0 - 1e-9):
            speed = float(np.hypot(out0, out1))  # numpy's hypot, as before
            if speed > s.max_speed:
                scale = s.max_speed / speed
                out0, out1 = out0 * scale, out1 * scale
        return out0, out1, out2
