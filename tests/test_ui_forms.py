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
from study.ui.forms import FormState, FormView
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
    state.row = age
    state.action("right")
    for _ in range(200):  # past the oldest age: the last option is "prefer not to say"
        state.action("right")
    state.row = state.done_row
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
