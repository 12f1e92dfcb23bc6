"""The session's side of the browser link (issue 37): the page's standard-mapping gamepad
and keys become the same stick and presses as on the pygame screen; round trips and input
ages are counted per state tick; a bad message never passes the checks."""

from __future__ import annotations

import multiprocessing as mp
import time

import numpy as np
import pytest

from study.engine.protocol import load_protocol
from study.ui.sticks import GamepadMapping, axes_stick
from study.web import messages as wire
from study.web.link import STD_AXES, Link


@pytest.fixture
def link_pair():
    mapping = GamepadMapping.from_settings(load_protocol("pilot").input)
    ours, theirs = mp.Pipe()
    link = Link(ours, mapping)
    theirs.send(("open",))
    for _ in range(400):  # the page is open before anything else
        if link.opened:
            break
        time.sleep(0.005)
    yield link, theirs, mapping
    theirs.close()


def _input(theirs, link: Link, seq: int, **kw) -> None:
    msg = wire.unpack_input(
        wire.pack_input(seq, kw.pop("last_tick", 0), kw.pop("axes", (0,) * 4), **kw)
    )
    theirs.send(("in", time.monotonic(), msg))
    for _ in range(400):
        if link.input is not None and link.input.seq == seq:
            return
        time.sleep(0.005)
    raise AssertionError(f"the link never read input {seq}: {link.input}")


def test_the_standard_pad_drives_as_the_pygame_pad_does(link_pair, rng):
    link, theirs, mapping = link_pair
    for seq in range(1, 30):
        axes = tuple(float(np.float32(a)) for a in rng.uniform(-1, 1, 4))
        _input(theirs, link, seq, axes=axes, gamepad=True)
        xinput = {STD_AXES[i]: a for i, a in enumerate(axes)}
        assert link.stick() == pytest.approx(axes_stick(xinput, mapping))


def test_keys_and_buttons_give_the_presses_and_the_stick(link_pair):
    link, theirs, _ = link_pair
    keys = {name: 1 << i for i, name in enumerate(wire.KEYS)}
    _input(theirs, link, 1, keys=keys["forward"] | keys["turn_left"])
    assert link.stick() == pytest.approx([1.0, 0.0, 1.0])
    _input(theirs, link, 2, keys=keys["enter"], buttons=1 << 0 | 1 << 13, gamepad=True)
    _input(theirs, link, 3, buttons=1 << 9, gamepad=True)  # Start
    _input(theirs, link, 4, buttons=1 << 9, gamepad=True)  # held: no second press
    actions, _ = link.take()
    assert actions == ["yes", "down", "confirm", "pause"]


def test_round_trip_and_age_per_state_tick(link_pair):
    link, theirs, _ = link_pair
    for tick in range(1, 6):
        link.send_state(tick, b"")
    time.sleep(0.02)
    _input(theirs, link, 1, last_tick=3)
    age, rtt = link.timing(5)
    assert age == 2 and rtt is not None and rtt >= 15.0
    link.new_trial()
    assert link.timing(1) == (None, None)  # the last trial's ticks count no more


@pytest.mark.parametrize(
    "data",
    [b"", b"\x01" * 31, b"\x02" + b"\x00" * 31, wire.pack_input(1, 0, (2.0, 0, 0, 0)),
     wire.pack_input(1, 0, (float("inf"), 0, 0, 0)), wire.pack_input(1, 0, (0,) * 4, keys=1 << 20)],
)  # fmt: skip
def test_bad_input_messages_are_refused(data):
    with pytest.raises(ValueError):
        wire.unpack_input(data)


@pytest.mark.parametrize(
    "text",
    ['{"type": "eval"}', '{"type": "key", "key": "Escape"}', '{"type": "pong", "id": -1}',
     '{"type": "click", "target": "fraction", "row": 0, "fraction": 2}', "[1, 2]", "{",
     '{"type": "check", "width": 5, "height": 5, "mobile": "no", "gamepad": false}'],
)  # fmt: skip
def test_bad_json_messages_are_refused(text):
    with pytest.raises(ValueError):
        wire.client_json(text)
