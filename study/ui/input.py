"""The participant's input devices: gamepads through pygame's joystick API, with a keyboard
fallback (issue 5, "Input"; thesis Sec. 7.6.1: a gamepad, left stick translation, right stick
rotation, two buttons for the secondary task's Yes and No).

Everything here works from pygame *events*, never from polling a device, so a real gamepad
and events injected by :mod:`study.ui.inject` go through exactly the same code.

Decisions where the spec is silent:

- Mapping. The protocol's ``[input]`` mapping (:class:`study.engine.protocol.InputSettings`, whose
  defaults are a Logitech F710 in XInput mode as SDL2 numbers it on Linux, identical to an
  Xbox pad there) applies to every gamepad. Only when the protocol keeps those defaults is a
  pad recognised by its name given its own known layout (:data:`LAYOUTS`: an Xbox pad under
  Windows puts the right stick's x on axis 2; an F710 switched to DirectInput mode reports as
  "Logitech Dual Action" with other indices). A mapping written in the protocol always wins.
- Deadzone. Radial on the left stick (translation), scalar on the rotation axis; the part
  outside the deadzone is rescaled to [0, 1] so there is no jump at its edge.
- Stick to command. Full deflection is the robot's ``max_speed`` (norm of the translation,
  clipped to the unit disc) and ``max_yaw_rate``.
- Keyboard. The protocol's ``[input.keys]`` (default W/S forwards/backwards, A/D left/right,
  Q/E turn left/right, full deflection while held; Y/N answer, as do the gamepad's Yes/No
  buttons; P is the pause button); in forms the arrow keys or the D-pad / left stick move
  and Enter, Space or Yes confirm, and a direction held repeats (:class:`NavRepeat`).
- Hot-plug. A pad added at any time is opened and used; one removed while it was in use is
  reported as ``device_lost`` and the next one added as ``device_back``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pygame

from study.engine.protocol import (
    DEFAULT_AXES,
    DEFAULT_BUTTONS,
    DEFAULT_INVERT,
    DEFAULT_KEYS,
    InputSettings,
)

# Known layouts as SDL2 / pygame numbers them, keyed by a lower-case fragment of the name.
LAYOUTS: dict[str, tuple[dict[str, int], dict[str, int]]] = {
    # F710 in DirectInput mode ("D" switch): X=0 A=1 B=2 Y=3 ... Start=9, right stick x = 2
    "dual action": ({"vy": 0, "vx": 1, "yaw": 2}, {"yes": 1, "no": 2, "pause": 9}),
    # Xbox / XInput pads through SDL's XInput backend on Windows: right stick x = 2
    "xinput": ({"vy": 0, "vx": 1, "yaw": 2}, {"yes": 0, "no": 1, "pause": 7}),
}
ACTIONS = ("yes", "no", "pause", "up", "down", "left", "right", "confirm", "quit")
_NAV_THRESHOLD = 0.6  # stick deflection that counts as one step in a form
REPEAT_DELAY_S = 0.4  # [s] a held direction repeats after this ...
REPEAT_EVERY_S = 0.07  # [s] ... once per this
NAV = ("up", "down", "left", "right")
_NAV_KEYS = {
    pygame.K_UP: "up",
    pygame.K_DOWN: "down",
    pygame.K_LEFT: "left",
    pygame.K_RIGHT: "right",
}
DIGIT_KEYS: dict[int, str] = {
    **{getattr(pygame, f"K_{d}"): str(d) for d in range(10)},
    **{getattr(pygame, f"K_KP{d}"): str(d) for d in range(10)},
}


def key_code(letter: str) -> int:
    """pygame's key code of a letter ``"W"`` (the protocol's ``[input.keys]``)."""
    return int(getattr(pygame, f"K_{letter.lower()}"))


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


@dataclass(slots=True)
class _Device:
    name: str
    mapping: GamepadMapping
    joystick: object | None = None  # pygame.joystick.JoystickType of a real pad
    axes: dict[int, float] = field(default_factory=dict)
    nav: dict[str, bool] = field(default_factory=dict)  # stick held past the nav threshold
    hat: tuple[int, int] = (0, 0)  # the D-pad's position


class InputState:
    """Gamepads and keyboard as seen through pygame events.

    Parameters
    ----------
    mapping : GamepadMapping
        The protocol's mapping (refined per device by :meth:`GamepadMapping.for_device`).
    keys : mapping, optional
        The protocol's ``[input.keys]`` (action -> letter); default W/S/A/D/Q/E, Y/N, P.
    """

    def __init__(self, mapping: GamepadMapping, keys: Mapping[str, str] = DEFAULT_KEYS) -> None:
        self.mapping = mapping
        self.key_codes = {action: key_code(letter) for action, letter in keys.items()}
        k = self.key_codes
        self._key_actions: dict[int, list[str]] = {
            **_KEY_ACTIONS,
            k["yes"]: ["yes"],
            k["no"]: ["no"],
            k["pause"]: ["pause"],
        }
        self.devices: dict[int, _Device] = {}
        self.keys: set[int] = set()
        self.lost: list[str] = []  # names of pads removed and not yet replaced
        self.last_device = ""  # the pad used last ("" for none)

    # -------------------------------------------------------------- events

    def handle(self, event: pygame.event.Event) -> list[str]:
        """Update the state from one event; returns the discrete actions it caused.

        Actions are :data:`ACTIONS` plus ``"device_lost"`` and ``"device_back"``.
        """
        kind = event.type
        out: list[str] = []
        if kind == pygame.QUIT:
            return ["quit"]
        if kind == pygame.JOYDEVICEADDED:
            return self._added(event)
        if kind == pygame.JOYDEVICEREMOVED:
            device = self.devices.pop(getattr(event, "instance_id", -1), None)
            if device is not None:
                self.lost.append(device.name)
                return ["device_lost"]
            return []
        if kind == pygame.KEYDOWN:
            self.keys.add(event.key)
            return self._key_actions.get(event.key, [])
        if kind == pygame.KEYUP:
            self.keys.discard(event.key)
            return []
        device = self.devices.get(getattr(event, "instance_id", -1))
        if device is None:
            return []
        self.last_device = device.name
        if kind == pygame.JOYAXISMOTION:
            device.axes[int(event.axis)] = float(event.value)
            out.extend(self._stick_nav(device))
        elif kind == pygame.JOYBUTTONDOWN:
            for name, index in device.mapping.buttons.items():
                if int(event.button) == index:
                    out.append(name)
        elif kind == pygame.JOYHATMOTION:
            hx, hy = event.value
            device.hat = (int(hx), int(hy))
            out.extend(
                a
                for a, on in (("left", hx < 0), ("right", hx > 0), ("up", hy > 0), ("down", hy < 0))
                if on
            )
        return out

    def _added(self, event: pygame.event.Event) -> list[str]:
        if getattr(event, "virtual", False):  # injected (study.ui.inject)
            instance, name, joystick = int(event.instance_id), str(event.name), None
        else:
            try:
                joystick = pygame.joystick.Joystick(event.device_index)
                joystick.init()
            except pygame.error:
                return []
            instance, name = joystick.get_instance_id(), joystick.get_name()
        if instance in self.devices:
            return []
        self.devices[instance] = _Device(name, self.mapping.for_device(name), joystick)
        self.last_device = name
        if self.lost:
            self.lost.pop()
            return ["device_back"]
        return []

    def _stick_nav(self, device: _Device) -> list[str]:
        """Left stick pushed past the threshold: one form step per push."""
        stick = _device_stick(device)
        out = []
        for name, on in (
            ("up", stick[0] > _NAV_THRESHOLD),
            ("down", stick[0] < -_NAV_THRESHOLD),
            ("left", stick[1] > _NAV_THRESHOLD),
            ("right", stick[1] < -_NAV_THRESHOLD),
        ):
            if on and not device.nav.get(name):
                out.append(name)
            device.nav[name] = on
        return out

    # -------------------------------------------------------------- state

    @property
    def has_gamepad(self) -> bool:
        return bool(self.devices)

    def held_nav(self) -> set[str]:
        """The form directions held now: arrow keys, D-pads and left sticks."""
        held = {name for key, name in _NAV_KEYS.items() if key in self.keys}
        for device in self.devices.values():
            hx, hy = device.hat
            held |= {a for a, on in (("left", hx < 0), ("right", hx > 0), ("up", hy > 0),
                                     ("down", hy < 0)) if on}  # fmt: skip
            held |= {a for a, on in device.nav.items() if on}
        return held

    def stick(self) -> np.ndarray:
        """Deflection ``(forwards, left, turn left)`` (3,) in [-1, 1], all devices and keys."""
        total = np.zeros(3)
        for device in self.devices.values():
            total += _device_stick(device)
        keys, k = self.keys, self.key_codes
        total[0] += (k["forward"] in keys) - (k["back"] in keys)
        total[1] += (k["left"] in keys) - (k["right"] in keys)
        total[2] += (k["turn_left"] in keys) - (k["turn_right"] in keys)
        m = math.hypot(total[0], total[1])
        if m > 1.0:
            total[:2] /= m
        total[2] = float(np.clip(total[2], -1.0, 1.0))
        return total

    def command(self, max_speed: float, max_yaw_rate: float) -> np.ndarray:
        """The stick as a robot-frame command (3,) [m/s, m/s, rad/s]."""
        s = self.stick()
        return np.array([s[0] * max_speed, s[1] * max_speed, s[2] * max_yaw_rate])


def _device_stick(device: _Device) -> np.ndarray:
    m = device.mapping
    raw = {}
    for name in ("vx", "vy", "yaw"):
        value = device.axes.get(int(m.axes[name]), 0.0)
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


# Keys of the pages and forms; the protocol's answer and pause keys are added per instance.
_KEY_ACTIONS: dict[int, list[str]] = {
    pygame.K_UP: ["up"],
    pygame.K_DOWN: ["down"],
    pygame.K_LEFT: ["left"],
    pygame.K_RIGHT: ["right"],
    pygame.K_RETURN: ["confirm"],
    pygame.K_KP_ENTER: ["confirm"],
    pygame.K_SPACE: ["confirm"],
}
