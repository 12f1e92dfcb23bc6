"""The experience questionnaire and the generic item types (questionnaires.experience, .base)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from questionnaires import experience
from questionnaires.base import DECLINE, ITEM_KINDS, Instrument, Item

GOOD = {"age": 29, "handedness": "right", "driving": 4, "games": 2, "gamepad": 3, "robots": 1}


def _answer(item: Item) -> st.SearchStrategy:
    """Any valid answer to ``item``."""
    if item.kind == "number":
        base = st.integers(item.minimum, item.maximum)
    else:
        base = st.sampled_from(item.values)
    if item.can_decline:
        base = base | st.just(DECLINE)
    if item.optional:
        base = base | st.none()
    return base


ANSWERS = st.fixed_dictionaries({item.id: _answer(item) for item in experience.INSTRUMENT.items})


def test_instrument_is_short_and_renderable() -> None:
    items = experience.INSTRUMENT.items
    assert 6 <= len(items) <= 8
    assert {"age", "handedness", "driving", "games", "gamepad", "robots"} <= set(
        experience.INSTRUMENT.ids
    )
    for item in items:
        assert item.kind in ITEM_KINDS and item.text and item.title
        if item.kind in ("likert", "choice"):
            assert all(label for _, label in item.choices)
        if item.kind == "likert":
            assert item.values == (1, 2, 3, 4, 5)
            assert item.anchors == (item.labels[0], item.labels[-1])
    assert experience.INSTRUMENT.item("age").can_decline
    assert experience.INSTRUMENT.item("handedness").choices[-1][0] == DECLINE


@settings(max_examples=80, deadline=None)
@given(answers=ANSWERS)
def test_valid_answers_summarise(answers: dict) -> None:
    summary = experience.summarise(answers)
    for key in ("age", "handedness"):
        assert summary[key] == (None if answers[key] in (None, DECLINE) else answers[key])
    for key in experience.LIKERT_IDS:
        assert summary[key] == answers[key]
    flags = [summary[f"experienced_{d}"] for d in ("driving", "games", "robots")]
    assert flags == [answers[d] >= 3 for d in ("driving", "games", "robots")]
    assert summary["any_experience"] == any(flags)
    assert summary["experience_mean"] == pytest.approx(
        np.mean([answers[k] for k in experience.LIKERT_IDS])
    )
    assert 1.0 <= summary["experience_mean"] <= 5.0


def test_optional_items_may_be_left_out() -> None:
    answers = {k: v for k, v in GOOD.items() if k not in ("age", "handedness")}
    summary = experience.summarise(answers)
    assert summary["age"] is None and summary["handedness"] is None
    assert experience.validate(answers)["age"] is None


def test_decline_is_recorded_distinctly_from_no_answer() -> None:
    valid = experience.validate({**GOOD, "age": DECLINE, "handedness": None})
    assert valid["age"] == DECLINE and valid["handedness"] is None


@pytest.mark.parametrize(
    ("change", "item", "allowed"),
    [
        ({"age": 12}, "age", "whole number from 18 to 99"),
        ({"age": 30.5}, "age", "whole number"),
        ({"age": "thirty"}, "age", "whole number"),
        ({"handedness": "up"}, "handedness", "'right', 'left', 'ambidextrous'"),
        ({"driving": 0}, "driving", "one of 1, 2, 3, 4, 5"),
        ({"games": 6}, "games", "one of 1, 2, 3, 4, 5"),
        ({"gamepad": True}, "gamepad", "one of 1, 2, 3, 4, 5"),
        ({"robots": DECLINE}, "robots", "one of 1, 2, 3, 4, 5"),
        ({"robots": None}, "robots", "is required"),
        ({"driving_licence": 1}, "driving_licence", "allowed: age, handedness"),
    ],
)
def test_invalid_answers_name_the_item(change: dict, item: str, allowed: str) -> None:
    with pytest.raises(ValueError) as info:
        experience.summarise({**GOOD, **change}, source="answers.csv")
    message = str(info.value)
    assert message.startswith("answers.csv: ")
    assert f"'{item}'" in message and allowed in message


def test_missing_required_item_is_named() -> None:
    answers = {k: v for k, v in GOOD.items() if k != "games"}
    with pytest.raises(ValueError, match="experience: item 'games': is required"):
        experience.summarise(answers)


def test_answers_must_be_a_mapping() -> None:
    with pytest.raises(ValueError, match="mapping"):
        experience.summarise([("age", 30)])  # type: ignore[arg-type]


def test_whole_floats_are_accepted_as_ints() -> None:
    valid = experience.validate({**GOOD, "age": 29.0, "driving": np.int64(4)})
    assert valid["age"] == 29 and type(valid["age"]) is int
    assert valid["driving"] == 4 and type(valid["driving"]) is int


def test_malformed_definitions_fail_when_built() -> None:
    with pytest.raises(ValueError, match="kind"):
        Item(id="x", text="?", kind="scale", values=(1, 2))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="one label per value"):
        Item(id="x", text="?", kind="likert", values=(1, 2), labels=("a",))
    with pytest.raises(ValueError, match="minimum <= maximum"):
        Item(id="x", text="?", kind="number")
    with pytest.raises(ValueError, match="unique"):
        item = Item(id="x", text="?", kind="choice", values=("a", "b"))
        Instrument(id="i", title="I", instructions="", items=(item, item))
