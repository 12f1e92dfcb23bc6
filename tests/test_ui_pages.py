"""A short session through the participant's screens (issue 19): training asks questions
from its start, practice shows "attempt k of n" and a collision's feedback without carrying
it into the next attempt, a trial that runs out of time shows a "time's up" page, and every
screen carries the key legend."""

from __future__ import annotations

import os

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.storage import Event, Trial, open_database
from study.engine.clocks import FreeClock
from study.engine.protocol import parse_protocol
from study.engine.session import run_session
from study.participants.base import ParticipantBase
from study.participants.human import HumanParticipant
from study.types import ParticipantInput
from study.ui.camera import CameraFeed
from study.ui.inject import EventDriver
from study.ui.input import GamepadMapping

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

PROTOCOL = """
[study]
name = "screens"
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]

[[phases]]
kind = "briefing"
text = "Inspect the {{object}} on the way; laser hits are {{laser_colour}} dots."

[[phases]]
kind = "training"
scenario = "cluttered_room"
duration_s = 3.0
secondary = true
rehearsal_questions = 2
modes = ["manual"]

[[phases]]
kind = "practice"
scenario = "practice_course"
time_limit_s = 6.0
max_attempts = 2
on_fail = "continue"
order = "protocol"

[[phases]]
kind = "main"
scenario = "cluttered_room"
inspection = false
secondary = false
timeout_s = 1.5

[[phases]]
kind = "debrief"
text = "Thank you."

[ui]
window = [640, 400]
"""


class Pusher(ParticipantBase):
    """Drives straight ahead in practice (into the box ahead of A), stands still otherwise,
    answers every question Yes; remembers what it was shown."""

    kind = "scripted"
    parameters: dict = {}  # noqa: RUF012

    def __init__(self) -> None:
        self.pages: list[str] = []
        self.seen: list[tuple[str, object, str, str | None]] = []  # phase, attempt, ...
        self.info = None

    def read(self, text: str) -> None:
        self.pages.append(text)

    def begin_trial(self, info) -> None:
        self.info = info

    def act(self, obs, screen) -> ParticipantInput:
        self.seen.append((screen.phase, self.info.attempt_of, screen.feedback, screen.question))
        push = self.info.phase == "practice"
        u = np.array([0.8, 0.0, 0.0]) if push else np.zeros(3)
        return ParticipantInput(u=u, answer=True if screen.question else None)


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    seed = int(os.environ.get("ASA_TEST_SEED", "20261123"))  # conftest's seed, once
    tmp_path = tmp_path_factory.mktemp("screens")
    protocol = parse_protocol(PROTOCOL.format(seed=seed % 1000), str(tmp_path / "screens.toml"))
    inner = Pusher()
    driver = EventDriver(inner, GamepadMapping.from_settings(protocol.input))
    person = HumanParticipant(
        protocol.ui, protocol.input, driver=driver, snapshots=tmp_path / "shots",
        camera=CameraFeed(inline=True, inline_every=1000),
    )  # fmt: skip
    try:
        summary = run_session(
            protocol, "P01", tmp_path / "s.db", participant=person, clock=FreeClock(),
            camera_hz=0.0,
        )  # fmt: skip
    finally:
        person.close()
    engine = open_database(tmp_path / "s.db", create=False)
    with Session(engine) as s:
        trials = list(s.scalars(select(Trial).order_by(Trial.id)))
        events = list(s.scalars(select(Event).order_by(Event.id)))
    engine.dispose()
    shots = sorted(p.name for p in (tmp_path / "shots").glob("*.png"))
    return summary, inner, person, trials, events, shots


def test_training_asks_questions_from_its_start(session):
    summary, inner, person, trials, events, shots = session
    assert summary.status == "completed"
    training = next(t for t in trials if t.phase == "training")
    shown = [e for e in events if e.trial_id == training.id and e.kind == "question_shown"]
    entered = [e for e in events if e.trial_id == training.id and e.kind == "region_entry"]
    assert len(shown) >= 1 and not entered  # asked although the robot stood at A
    assert any(q for phase, _, _, q in inner.seen if phase == "training")
    assert any(shot.endswith("training_ready.png") for shot in shots)
    assert any(shot.endswith("training_question.png") for shot in shots)
    texts = person.screen.texts_seen
    assert "Training 1 of 1" in texts
    assert any("yellow area" in t for t in texts)  # says where the questions start


def test_practice_counts_attempts_and_a_collision_fails_one(session):
    summary, inner, person, trials, events, shots = session
    practice = [t for t in trials if t.phase == "practice"]
    assert len(practice) == 4  # two modes, two attempts each, none passed
    assert not any(t.outcome["passed"] for t in practice)
    for t in practice[:2]:  # manual: into the box
        assert t.outcome["collisions"] == 1
        assert t.outcome["duration_s"] < 6.0  # the collision ended the attempt
    texts = person.screen.texts_seen
    for k in (1, 2):
        for attempt in (1, 2):
            assert f"Practice {k} of 2, attempt {attempt} of 2" in texts
    results = [p for p in inner.pages if "did not pass" in p]
    assert len(results) == 4
    assert results[0].startswith("Collision: attempt 1 of 2 did not pass.")
    assert "Next: attempt 2 of 2." in results[0] and "last attempt" in results[1]
    for page, t in zip(results[2:], practice[2:], strict=True):  # the reactive mode
        if t.outcome["collisions"] == 0:  # kept off the box: the time ran out
            assert page.startswith("Time's up: the goal was not reached within 6 s.")
    # no attempt shows a failure on its driving screen, the second not the first's
    assert all(feedback == "" for phase, _, feedback, _ in inner.seen if phase == "practice")
    assert {a for phase, a, _, _ in inner.seen if phase == "practice"} == {(1, 2), (2, 2)}
    # the practice has no questions: no question window
    assert not any(q for phase, _, _, q in inner.seen if phase == "practice")
    assert sum(shot.endswith("practice_result.png") for shot in shots) == 4


def test_a_trial_that_runs_out_of_time_shows_times_up(session):
    summary, inner, person, trials, events, shots = session
    main = [t for t in trials if t.phase == "main"]
    assert len(main) == 2 and all(t.outcome["timed_out"] for t in main)
    assert sum(shot.endswith("main_times_up.png") for shot in shots) == 2
    assert "Time's up." in person.screen.texts_seen
    assert "Trial 2 of 2" in person.screen.texts_seen


def test_every_screen_has_the_legend_and_the_protocol_words(session):
    summary, inner, person, trials, events, shots = session
    texts = person.screen.texts_seen
    assert {"Gamepad:", "Keyboard:", "Enter", "continue", "start", "pause"} <= texts
    assert {"W S", "A D", "Q E", "P"} <= texts  # the driving keys
    assert inner.pages[0] == "Inspect the red cylinder on the way; laser hits are purple dots."
    assert shots[-1].endswith("_page.png")  # the debrief, not under the last trial's title
