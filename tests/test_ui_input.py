"""Gamepad and keyboard input through pygame events: deadzone, mapping, layouts, keys,
hot-plug."""

from __future__ import annotations

import os

import numpy as np
import pygame
from hypothesis import given, settings
from hypothesis import strategies as st

from study.engine.protocol import load_protocol
from study.ui.input import GamepadMapping, InputState

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
PROTOCOL = load_protocol("pilot")


def _mapping(deadzone: float = 0.1) -> GamepadMapping:
    m = GamepadMapping.from_settings(PROTOCOL.input)
    return GamepadMapping(m.axes, m.buttons, m.invert, deadzone)


def _plug(state: InputState, instance: int = 5, name: str = "virtual pad") -> list[str]:
    return state.handle(
        pygame.event.Event(
            pygame.JOYDEVICEADDED, device_index=-1, instance_id=instance, virtual=True, name=name
        )
    )


def _axes(state: InputState, raw: dict[int, float], instance: int = 5) -> None:
    for axis, value in raw.items():
        state.handle(
            pygame.event.Event(pygame.JOYAXISMOTION, instance_id=instance, axis=axis, value=value)
        )


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-1, 1),
    st.floats(-1, 1),
    st.floats(-1, 1),
    st.floats(0.0, 0.3),
)
def test_stick_to_raw_inverts_the_deadzone_and_the_signs(vx, vy, yaw, deadzone):
    mapping = _mapping(deadzone)
    state = InputState(mapping)
    _plug(state)
    stick = np.array([vx, vy, yaw])
    norm = np.hypot(vx, vy)
    if norm > 1:
        stick[:2] /= norm
    _axes(state, mapping.stick_to_raw(stick))
    np.testing.assert_allclose(state.stick(), stick, atol=1e-9)


def test_deadzone_and_full_deflection():
    mapping = _mapping(0.2)
    state = InputState(mapping)
    _plug(state)
    vx, vy, yaw = (mapping.axes[k] for k in ("vx", "vy", "yaw"))
    _axes(state, {vx: -0.15, vy: 0.1, yaw: 0.19})  # inside the deadzone: nothing
    assert np.all(state.stick() == 0)
    _axes(state, {vx: -1.0, vy: 0.0, yaw: 1.0})  # stick forward (reads -1), turn right
    np.testing.assert_allclose(state.stick(), [1.0, 0.0, -1.0])
    cmd = state.command(1.0, 1.2)
    np.testing.assert_allclose(cmd, [1.0, 0.0, -1.2])


def test_keyboard_fallback_and_answers():
    state = InputState(_mapping())
    down = [pygame.K_w, pygame.K_a, pygame.K_e]
    for key in down:
        state.handle(pygame.event.Event(pygame.KEYDOWN, key=key))
    s = state.stick()
    np.testing.assert_allclose(s, [np.sqrt(0.5), np.sqrt(0.5), -1.0])
    state.handle(pygame.event.Event(pygame.KEYUP, key=pygame.K_a))
    np.testing.assert_allclose(state.stick(), [1.0, 0.0, -1.0])
    assert state.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_y)) == ["yes"]
    assert state.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_n)) == ["no"]


def test_buttons_hot_plug_and_layouts():
    mapping = _mapping()
    state = InputState(mapping)
    assert _plug(state, 1) == []
    press = pygame.event.Event(pygame.JOYBUTTONDOWN, instance_id=1, button=mapping.buttons["no"])
    assert state.handle(press) == ["no"]
    lost = state.handle(pygame.event.Event(pygame.JOYDEVICEREMOVED, instance_id=1))
    assert lost == ["device_lost"] and not state.has_gamepad
    assert state.handle(press) == []  # a removed pad says nothing
    assert _plug(state, 2, "Logitech Dual Action") == ["device_back"]
    # the protocol keeps the default mapping, so the pad's own layout applies
    dual = state.devices[2].mapping
    assert dual.buttons["yes"] == 1 and dual.axes["yaw"] == 2
    custom = GamepadMapping({"vx": 4, "vy": 5, "yaw": 6}, {"yes": 3, "no": 2, "pause": 1})
    assert custom.for_device("Logitech Dual Action") is custom  # the protocol's wins
