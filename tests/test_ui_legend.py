"""Key legends on the participant's screens (issue 19): they list the protocol's keys and
buttons, a key named in a legend does what the legend says, and the colours the texts name
are the colours the screen draws."""

from __future__ import annotations

import os

import numpy as np
import pygame
import pytest

from sim.scenario import load_scenario
from study.engine import texts
from study.engine.protocol import KEY_ACTIONS, load_protocol, parse_protocol
from study.ui import laser_view, legend
from study.ui.input import GamepadMapping, InputState, key_code
from study.ui.screen import LASER

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

DRIVE_KEYS = ("forward", "back", "left", "right", "turn_left", "turn_right")
# stick component and sign each driving key gives: (forwards, left, turn left)
STICK = {
    "forward": (0, 1),
    "back": (0, -1),
    "left": (1, 1),
    "right": (1, -1),
    "turn_left": (2, 1),
    "turn_right": (2, -1),
}


def _with_keys(rng: np.random.Generator):
    """The pilot protocol with random distinct letters for every key and random buttons."""
    letters = rng.permutation([chr(c) for c in range(ord("A"), ord("Z") + 1)])[: len(KEY_ACTIONS)]
    keys = dict(zip(KEY_ACTIONS, letters, strict=True))
    buttons = rng.permutation(np.arange(8))[:3]
    pressed = zip(("yes", "no", "pause"), buttons, strict=True)
    text = (load_protocol("pilot").text.rstrip() + "\n\n[input.keys]\n"
            + "".join(f'{a} = "{k.lower()}"\n' for a, k in keys.items())
            + "\n[input.buttons]\n" + "".join(f"{b} = {i}\n" for b, i in pressed))  # fmt: skip
    return parse_protocol(text, "keys.toml"), keys, buttons


def test_legends_list_the_protocols_keys_and_buttons(rng):
    protocol, keys, buttons = _with_keys(rng)
    controls = legend.Controls.from_settings(protocol.input)
    drive = " | ".join(legend.legend_strings(legend.drive_legend(controls)))
    for action in ("yes", "no", "pause"):
        assert f"Keyboard: {keys[action]} " in drive
    for a, b in (("forward", "back"), ("left", "right"), ("turn_left", "turn_right")):
        assert f"Keyboard: {keys[a]} {keys[b]} " in drive
    names = {0: "A", 1: "B", 2: "X", 3: "Y", 4: "LB", 5: "RB", 6: "Back", 7: "Start"}
    for index in buttons:
        assert f"Gamepad: {names[int(index)]} " in drive
    assert "Gamepad: left stick move" in drive and "Gamepad: right stick turn" in drive
    # pages go on with Enter on the keyboard, never with a driving letter
    page = legend.legend_strings(legend.page_legend(controls))
    assert page == [f"Gamepad: {names[int(buttons[0])]} continue", "Keyboard: Enter continue"]
    prompt = legend.prompt_text(controls)
    assert "Enter on the keyboard" in prompt and f" {keys['left']} " not in prompt


def test_the_keys_a_legend_names_drive_the_robot_as_it_says(rng):
    protocol, keys, _ = _with_keys(rng)
    state = InputState(GamepadMapping.from_settings(protocol.input), protocol.input.keys)
    for action in DRIVE_KEYS:
        code = key_code(keys[action])
        state.handle(pygame.event.Event(pygame.KEYDOWN, key=code, mod=0, unicode=""))
        axis, sign = STICK[action]
        stick = state.stick()
        assert stick[axis] == sign and np.count_nonzero(stick) == 1, action
        state.handle(pygame.event.Event(pygame.KEYUP, key=code, mod=0, unicode=""))
    for action in ("yes", "no", "pause"):
        event = pygame.event.Event(pygame.KEYDOWN, key=key_code(keys[action]), mod=0, unicode="")
        assert state.handle(event) == [action]
    # the default W no longer drives unless the protocol says so
    if keys["forward"] != "W":
        state.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_w, mod=0, unicode=""))
        assert state.stick()[0] == 0


def test_pause_box_says_which_buttons_resume():
    controls = legend.Controls.from_settings(load_protocol("pilot").input)
    assert legend.resume_text(controls) == (
        "Press Start on the gamepad or P on the keyboard to continue."
    )


@pytest.mark.parametrize("name", ["pilot", "thesis-7-6", "reactive-7-5"])
def test_texts_name_colours_as_the_screen_draws_them(name):
    protocol = load_protocol(name)
    scene = load_scenario(protocol.main.scenario)
    thing = texts.object_words(scene)
    colour = thing.split()[0]
    assert texts.colour_name(tuple(c / 255 for c in LASER)) == texts.LASER_COLOUR_NAME
    assert texts.colour_name(tuple(c / 255 for c in laser_view.LASER)) == texts.LASER_COLOUR_NAME
    assert colour != texts.LASER_COLOUR_NAME  # two different things, two different colours
    shown = [p.text for p in protocol.phases if hasattr(p, "text")]
    shown += [*protocol.ui.instructions.values(), *protocol.ui.texts.values()]
    everything = " ".join(shown).lower()
    assert "{object}" not in everything and "{laser_colour}" not in everything
    if protocol.main.inspection:
        assert thing in everything
    for other in ("red", "purple", "orange", "green", "blue"):
        if other not in (colour, texts.LASER_COLOUR_NAME):
            assert f"{other} " not in everything, other
