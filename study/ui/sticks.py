"""Gamepad sticks and held directions as numbers (issue 5, "Input"; the decisions are in
:mod:`study.ui.input`'s docstring): the protocol's mapping, the deadzone, the stick's
deflection and the repeat of a held direction. Pure (no pygame): the pygame screen and the
browser participant (:mod:`study.web`) compute the stick with the same code.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass

import numpy as np

from study.engine.protocol import (
    DEFAULT_AXES,
    DEFAULT_BUTTONS,
    DEFAULT_INVERT,
    InputSettings,
)

# Known layouts as SDL2 / pygame numbers them, keyed by a lower-case fragment of the name.
LAYOUTS: dict[str, tuple[dict[str, int], dict[str, int]]] = {
    # F710 in DirectInput mode ("D" switch): X=0 A=1 B=2 Y=3 ... Start=9, right stick x = 2
    "dual action": ({"vy": 0, "vx": 1, "yaw": 2}, {"yes": 1, "no": 2, "pause": 9}),
    # Xbox / XInput pads through SDL's XInput backend on Windows: right stick x = 2
    "xinput": ({"vy": 0, "vx": 1, "yaw": 2}, {"yes": 0, "no": 1, "pause": 7}),
}
NAV_THRESHOLD = 0.6  # stick deflection that counts as one step in a form
REPEAT_DELAY_S = 0.4  # [s] a held direction repeats after this ...
REPEAT_EVERY_S = 0.07  # [s] ... once per this
NAV = ("up", "down", "left", "right")


@dataclass(frozen=True, slots=True)
class GamepadMapping:
    """Axis and button indices of one gamepad layout."""

    axes: Mapping[str, int]  # "vx", "vy", "yaw" -> axis index
    buttons: Mapping[str, int]  # "yes", "no", "pause" -> button index
    invert: tuple[str, ...] = DEFAULT_INVERT  # axes whose sign is flipped
    deadzone: float = 0.1  # [0, 1)

    @classmethod
    def from_settings(cls, settings: InputSettings) -> GamepadMapping:
        """The protocol's ``[input]`` mapping."""
        return cls(
            axes=dict(settings.axes),
            buttons=dict(settings.buttons),
            invert=tuple(settings.invert),
            deadzone=float(settings.deadzone),
        )

    def for_device(self, name: str) -> GamepadMapping:
        """This mapping, or a known layout for a pad called ``name`` if this is the default."""
        if dict(self.axes) != dict(DEFAULT_AXES) or dict(self.buttons) != dict(DEFAULT_BUTTONS):
            return self
        low = name.lower()
        for fragment, (axes, buttons) in LAYOUTS.items():
            if fragment in low:
                return GamepadMapping(axes, buttons, self.invert, self.deadzone)
        return self

    def stick_to_raw(self, stick: np.ndarray) -> dict[int, float]:
        """Inverse of :meth:`InputState.stick`: raw axis values that give ``stick`` (3,).

        Used by the event injector so an injected deflection survives the deadzone.
        """
        s = np.clip(np.asarray(stick, dtype=float), -1.0, 1.0)
        dz = self.deadzone
        out: dict[int, float] = {}
        m = math.hypot(s[0], s[1])
        if m > 1.0:
            s[:2] /= m
            m = 1.0
        scale = (dz + m * (1 - dz)) / m if m > 1e-9 else 0.0
        for i, name in enumerate(("vx", "vy", "yaw")):
            if name == "yaw":
                value = math.copysign(dz + abs(s[2]) * (1 - dz), s[2]) if abs(s[2]) > 1e-9 else 0.0
            else:
                value = s[i] * scale
            if name in self.invert:
                value = -value
            out[int(self.axes[name])] = float(np.clip(value, -1.0, 1.0))
        return out


def axes_stick(axes: Mapping[int, float], mapping: GamepadMapping) -> np.ndarray:
    """One pad's deflection ``(forwards, left, turn left)`` (3,) in [-1, 1] from its raw
    axis values (index -> value): the radial deadzone on the translation, the scalar one on
    the rotation, the rest rescaled to [0, 1]."""
    m = mapping
    raw = {}
    for name in ("vx", "vy", "yaw"):
        value = axes.get(int(m.axes[name]), 0.0)
        raw[name] = -value if name in m.invert else value
    dz = m.deadzone
    out = np.zeros(3)
    mag = math.hypot(raw["vx"], raw["vy"])
    if mag > dz:
        scale = min(1.0, (mag - dz) / (1 - dz)) / mag
        out[0], out[1] = raw["vx"] * scale, raw["vy"] * scale
    if abs(raw["yaw"]) > dz:
        out[2] = math.copysign(min(1.0, (abs(raw["yaw"]) - dz) / (1 - dz)), raw["yaw"])
    return out


def total_stick(pads: Collection[np.ndarray], held: Collection[str]) -> np.ndarray:
    """Every pad's deflection plus the keys ``held`` (the protocol's key actions:
    ``forward``, ``back``, ``left``, ``right``, ``turn_left``, ``turn_right``), the
    translation clipped to the unit disc and the turn to [-1, 1]; (3,)."""
    total = np.zeros(3)
    for stick in pads:
        total += stick
    total[0] += ("forward" in held) - ("back" in held)
    total[1] += ("left" in held) - ("right" in held)
    total[2] += ("turn_left" in held) - ("turn_right" in held)
    m = math.hypot(total[0], total[1])
    if m > 1.0:
        total[:2] /= m
    total[2] = float(np.clip(total[2], -1.0, 1.0))
    return total


def nav_of_stick(stick: np.ndarray) -> dict[str, bool]:
    """The form directions a stick's deflection (3,) holds past :data:`NAV_THRESHOLD`."""
    return {
        "up": bool(stick[0] > NAV_THRESHOLD),
        "down": bool(stick[0] < -NAV_THRESHOLD),
        "left": bool(stick[1] > NAV_THRESHOLD),
        "right": bool(stick[1] < -NAV_THRESHOLD),
    }


class NavRepeat:
    """A form direction held down repeats: after :data:`REPEAT_DELAY_S`, one step every
    :data:`REPEAT_EVERY_S` (keyboard, D-pad and stick alike; the first step is the press
    itself). Call :meth:`step` once per frame."""

    def __init__(self) -> None:
        self._since: dict[str, float] = {}  # direction -> when its next repeat is due

    def step(self, now: float, held: set[str]) -> list[str]:
        """The repeated steps due at ``now`` [s] for the directions ``held``."""
        out = []
        for name in NAV:
            if name not in held:
                self._since.pop(name, None)
                continue
            due = self._since.setdefault(name, now + REPEAT_DELAY_S)
            if now >= due:  # one step per call: a stalled frame does not burst
                out.append(name)
                self._since[name] = max(due, now - REPEAT_EVERY_S) + REPEAT_EVERY_S
        return out
