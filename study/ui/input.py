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

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pygame

from study.engine.protocol import DEFAULT_KEYS

# the stick's numbers are pure (the browser participant uses them too); re-exported here
from study.ui.sticks import (  # noqa: F401
    LAYOUTS,
    NAV,
    REPEAT_DELAY_S,
    REPEAT_EVERY_S,
    GamepadMapping,
    NavRepeat,
    axes_stick,
    nav_of_stick,
    total_stick,
)

ACTIONS = ("yes", "no", "pause", "up", "down", "left", "right", "confirm", "quit")
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
        out = []
        for name, on in nav_of_stick(_device_stick(device)).items():
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
        pads = [_device_stick(device) for device in self.devices.values()]
        held = {action for action, code in self.key_codes.items() if code in self.keys}
        return total_stick(pads, held)

    def command(self, max_speed: float, max_yaw_rate: float) -> np.ndarray:
        """The stick as a robot-frame command (3,) [m/s, m/s, rad/s]."""
        s = self.stick()
        return np.array([s[0] * max_speed, s[1] * max_speed, s[2] * max_yaw_rate])


def _device_stick(device: _Device) -> np.ndarray:
    return axes_stick(device.axes, device.mapping)


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
