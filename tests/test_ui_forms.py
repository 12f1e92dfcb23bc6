"""Questionnaires on the participant's screen: answers entered by injected events are the
answers returned (and, through a session, stored); nothing can be skipped; mouse clicks."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pygame
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from questionnaires import experience, nasa_tlx
from questionnaires.base import DECLINE
from study.data.storage import Response, open_database
from study.engine.protocol import load_protocol
from study.participants import ScriptedParticipant
from study.participants.human import HumanParticipant
from study.ui.camera import CameraFeed
from study.ui.form_view import FormView
from study.ui.forms import FormState
from study.ui.inject import EventDriver, form_keys
from study.ui.input import GamepadMapping

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")


@pytest.fixture
def person(seed):
    protocol = load_protocol("pilot")
    inner = ScriptedParticipant(np.random.default_rng(seed))
    driver = EventDriver(inner, GamepadMapping.from_settings(protocol.input))
    person = HumanParticipant(
        protocol.ui, protocol.input, driver=driver, camera=CameraFeed(inline=True)
    )
    yield person
    person.close()


def test_injected_events_fill_both_questionnaires_and_the_pairs(person, seed):
    twin = ScriptedParticipant(np.random.default_rng(seed))  # decides the same
    for instrument in (experience.INSTRUMENT, nasa_tlx.INSTRUMENT):
        got = person.fill(instrument, context={"phase": "test"})
        want = instrument.validate(twin.fill(instrument, context={"phase": "test"}))
        assert got == want
    pairs = nasa_tlx.presentation_order(np.random.default_rng(seed))
    got = person.choose(pairs)
    assert got == twin.choose(pairs)
    nasa_tlx.weights_from_choices(got)  # 15 pairs, each a member of its pair


def test_form_cannot_be_finished_with_a_required_item_unanswered(rng):
    state = FormState(nasa_tlx.INSTRUMENT)
    answers = {item.id: int(rng.choice(item.values)) for item in nasa_tlx.INSTRUMENT.items}
    skipped = int(rng.integers(len(answers)))
    keys = form_keys(state, {k: v for i, (k, v) in enumerate(answers.items()) if i != skipped})
    action = {
        pygame.K_RIGHT: "right",
        pygame.K_LEFT: "left",
        pygame.K_DOWN: "down",
        pygame.K_RETURN: "confirm",
    }
    for key in keys:
        state.action(action[key])
    assert not state.done and state.row == skipped and state.reminder
    state.action("right")  # the mark appears in the middle: 50
    for _ in range(state.done_row - skipped):
        state.action("down")
    state.action("confirm")
    assert state.done
    got = state.answers()
    assert got[nasa_tlx.SUBSCALE_IDS[skipped]] == 50
    assert all(got[k] == v for i, (k, v) in enumerate(answers.items()) if i != skipped)


def test_optional_items_may_stay_empty_or_be_declined():
    state = FormState(experience.INSTRUMENT)
    for row, item in enumerate(experience.INSTRUMENT.items):
        if not item.optional:
            state.row = row
            state.action("right")
    age = experience.INSTRUMENT.ids.index("age")
    state.select(age)
    state.action("left")  # one step below the (empty) entry: "prefer not to say"
    state.select(state.done_row)
    state.action("confirm")
    assert state.done
    answers = state.answers()
    assert answers["age"] == DECLINE and answers["handedness"] is None
    experience.validate(answers)


def test_mouse_clicks_set_sliders_and_finish(person):
    state = FormState(nasa_tlx.INSTRUMENT)
    view = FormView(person.screen, state)
    view.draw()
    view.click(view.done_button.center)
    assert not state.done  # nothing answered yet
    for k, track in enumerate(view.tracks):
        fraction = k / (len(view.tracks) - 1)
        view.click((int(track.left + fraction * track.width), track.centery))
    view.click(view.done_button.center)
    assert state.done
    got = state.answers()
    values = [got[i] for i in nasa_tlx.SUBSCALE_IDS]
    assert values[0] == 0 and values[-1] == 100
    assert all(v % 5 == 0 for v in values) and values == sorted(values)


@pytest.mark.slow
def test_headless_cli_session_stores_the_injected_answers(tmp_path, seed):
    """``asa run --headless --fast`` through the pilot protocol: the stored questionnaire
    answers are the scripted participant's, and snapshots are written."""
    db, shots = tmp_path / "p.db", tmp_path / "shots"
    pseed = seed % 10_000
    done = subprocess.run(
        [sys.executable, "-m", "study.cli", "run", "--protocol", "pilot", "--participant",
         "P01", "--db", str(db), "--input", "scripted", "--headless", "--fast",
         "--snapshots", str(shots), "--seed", str(pseed)],
        capture_output=True, text=True, timeout=1200,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    twin = ScriptedParticipant(np.random.default_rng(pseed))
    want = experience.INSTRUMENT.validate(twin.fill(experience.INSTRUMENT, context={}))
    engine = open_database(db, create=False)
    with Session(engine) as s:
        rows = s.scalars(select(Response).where(Response.instrument == "experience")).all()
    engine.dispose()
    stored = {r.item: (r.value if r.value is not None else r.text) for r in rows}
    for key, value in want.items():
        if value is not None and value != DECLINE:
            assert stored[key] == value
    names = sorted(p.name for p in shots.glob("*.png"))
    assert any("main_t" in n for n in names) and any("form_nasa_tlx" in n for n in names)


# ---------------------------------------------------------------- issue 19: quick forms


def _type(state: FormState, number: str) -> None:
    for digit in number:
        state.type_digit(digit)


def test_age_entry_accepts_typed_digits_and_refuses_out_of_range(rng):
    item = experience.INSTRUMENT.items[experience.INSTRUMENT.ids.index("age")]
    row = experience.INSTRUMENT.ids.index("age")
    inside = [int(a) for a in rng.integers(item.minimum, item.maximum + 1, size=5)]
    # too young, or a typing slip that stops at one digit
    outside = [int(rng.integers(0, item.minimum))]
    for age in inside:
        state = FormState(experience.INSTRUMENT)
        state.select(row)
        _type(state, str(age))
        assert state.value(row) == age and not state.problem(row)
    for age in outside:
        state = FormState(experience.INSTRUMENT)
        state.select(row)
        _type(state, str(age))
        assert state.value(row) is None and "from 18 to 99" in state.problem(row)
        _answer_the_rest(state)
        state.select(state.done_row)
        state.action("confirm")
        assert not state.done and state.row == row  # refused, back at the age
        assert "from 18 to 99" in state.reminder
        state.backspace()
        state.backspace()  # cleared: the optional age is left unanswered
        assert state.reminder == ""
        state.select(state.done_row)
        state.action("confirm")
        assert state.done and state.answers()["age"] is None
    # no more digits than the oldest age has; arrows step from the typed number
    state = FormState(experience.INSTRUMENT)
    _type(state, "305")
    assert state.typed[row] == "30"
    state.action("right")
    state.action("right")
    assert state.value(row) == 32
    state.type_digit("4")  # after stepping, typing starts a new number
    assert state.typed[row] == "4"


def _answer_the_rest(state: FormState) -> None:
    for k, item in enumerate(state.items):
        if item.kind != "number":
            state.select(k)
            state.action("right")


def test_reminder_disappears_once_every_question_is_answered(rng):
    state = FormState(nasa_tlx.INSTRUMENT)
    first = int(rng.integers(len(state.items)))
    state.select(first)
    state.action("right")
    state.select(state.done_row)
    state.action("confirm")
    assert not state.done and state.reminder.startswith("Please answer every question")
    rows = [k for k in range(len(state.items)) if k != first]
    for k in rows[:-1]:
        state.select(k)
        state.action("right")
        assert state.reminder  # still something missing
    state.select(rows[-1])
    state.action("left")
    assert state.reminder == ""
    state.select(state.done_row)
    state.action("confirm")
    assert state.done


def test_choices_are_labelled_and_tlx_sliders_show_no_numbers(person):
    state = FormState(experience.INSTRUMENT)
    view = FormView(person.screen, state)
    view.draw()
    seen = person.screen.texts_seen
    for label in ("Right", "Left", "Both equally", "Prefer not to say", "Never"):
        assert label in seen
    person.screen.texts_seen.clear()
    tlx = FormState(nasa_tlx.INSTRUMENT)
    for k in range(len(tlx.items)):
        tlx.select(k)
        for _ in range(k + 1):
            tlx.action("right")
    FormView(person.screen, tlx).draw()
    drawn = person.screen.texts_seen
    assert "Very Low" in drawn and "Very High" in drawn
    assert not [t for t in drawn if t.strip().isdigit()]  # no rating value anywhere


def test_form_rows_and_frames_do_not_overlap(person):
    for instrument in (experience.INSTRUMENT, nasa_tlx.INSTRUMENT):
        state = FormState(instrument)
        view = FormView(person.screen, state)
        view.draw()
        rows = view.rows
        for a, b in zip(rows, rows[1:], strict=False):
            assert a.bottom <= b.top
        for k, boxes in enumerate(view.options):
            for box in boxes:
                assert rows[k].contains(box)  # every answer inside its row's frame
        assert rows[-1].bottom <= view.done_button.top
        assert view.done_button.bottom <= person.screen.legend_rect.top


def test_a_held_direction_repeats(seed):
    from study.ui.input import REPEAT_DELAY_S, REPEAT_EVERY_S, NavRepeat

    repeat = NavRepeat()
    t0 = float(seed % 1000)
    steps = 0
    t = t0
    while t < t0 + 1.0:
        steps += len(repeat.step(t, {"right"}))
        t += 0.01
    assert steps == pytest.approx((1.0 - REPEAT_DELAY_S) / REPEAT_EVERY_S, abs=1.5)
    assert repeat.step(t, set()) == [] and repeat.step(t + 0.01, {"right"}) == []  # let go


def test_a_held_arrow_key_counts_as_held():
    from study.ui.input import InputState

    protocol = load_protocol("pilot")
    state = InputState(GamepadMapping.from_settings(protocol.input), protocol.input.keys)
    state.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_RIGHT, mod=0, unicode=""))
    assert state.held_nav() == {"right"}
    state.handle(pygame.event.Event(pygame.KEYUP, key=pygame.K_RIGHT, mod=0, unicode=""))
    assert state.held_nav() == set()
