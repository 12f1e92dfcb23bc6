"""The experience questionnaire filled in before the study.

Thesis Sec. 7.6.1.3: "an experience questionnaire before the user study reported that the
majority of the human subjects have experience in driving, playing computer games or
operating mobile robots", and the sample was described by age (24-32). The thesis does not
print the questionnaire, so the six items here are this platform's (:data:`INSTRUMENT`):
``age``, ``handedness``, and 5-point scales for ``driving``, ``games``, ``gamepad`` and
``robots``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from questionnaires.base import DECLINE, Instrument, Item

INSTRUMENT_ID = "experience"
EXPERIENCED_AT = 3  # on the 5-point scales: monthly / some experience or more

FREQUENCY_LABELS = (
    "Never",
    "Less than once a month",
    "About once a month",
    "About once a week",
    "Daily or almost daily",
)
FAMILIARITY_LABELS = (
    "Not at all familiar",
    "Slightly familiar",
    "Moderately familiar",
    "Very familiar",
    "Extremely familiar",
)
ROBOT_LABELS = (
    "None",
    "Tried it once or twice",
    "Some experience",
    "Regular experience",
    "Expert (for example in my work or research)",
)
_POINTS = (1, 2, 3, 4, 5)


def _likert(item_id: str, title: str, text: str, labels: tuple[str, ...]) -> Item:
    return Item(
        id=item_id,
        text=text,
        kind="likert",
        values=_POINTS,
        labels=labels,
        anchors=(labels[0], labels[-1]),
        title=title,
    )


INSTRUMENT = Instrument(
    id=INSTRUMENT_ID,
    title="About you",
    instructions=(
        "Please answer a few questions about yourself and your experience. "
        "There are no right or wrong answers."
    ),
    items=(
        Item(
            id="age",
            text="How old are you?",
            kind="number",
            minimum=18,
            maximum=99,
            unit="years",
            title="Age",
            optional=True,
            can_decline=True,
        ),
        Item(
            id="handedness",
            text="Which hand do you write with?",
            kind="choice",
            values=("right", "left", "ambidextrous"),
            labels=("Right", "Left", "Both equally"),
            title="Handedness",
            optional=True,
            can_decline=True,
        ),
        _likert(
            "driving",
            "Driving",
            "How often do you drive a car or another motor vehicle?",
            FREQUENCY_LABELS,
        ),
        _likert(
            "games",
            "Computer games",
            "How often do you play computer or video games?",
            FREQUENCY_LABELS,
        ),
        _likert(
            "gamepad",
            "Gamepad",
            "How familiar are you with using a gamepad (a game controller with two thumb sticks)?",
            FAMILIARITY_LABELS,
        ),
        _likert(
            "robots",
            "Mobile robots",
            "How much experience do you have operating mobile robots, remote-controlled "
            "vehicles or drones?",
            ROBOT_LABELS,
        ),
    ),
)
LIKERT_IDS: tuple[str, ...] = ("driving", "games", "gamepad", "robots")
EXPERIENCE_DOMAINS: tuple[str, ...] = ("driving", "games", "robots")


def validate(answers: Mapping[str, object], *, source: str | None = None) -> dict:
    """Check the answers; return them normalised (ints, choice codes, ``DECLINE``).

    Raises
    ------
    ValueError
        Naming ``source`` (default ``"experience"``), the item and what is allowed,
        on an unknown or missing item or a value not allowed.
    """
    return INSTRUMENT.validate(answers, source=source)


def summarise(answers: Mapping[str, object], *, source: str | None = None) -> dict:
    """Validate the answers and derive the sample-description figures.

    Parameters
    ----------
    answers : Mapping[str, object]
        Item id -> answer, every item of :data:`INSTRUMENT` (age and handedness
        may be missing or :data:`~questionnaires.base.DECLINE`).
    source : str, optional
        Named in error messages (e.g. a CSV file name).

    Returns
    -------
    dict
        ``age`` (int, or None if declined or unanswered), ``handedness`` (code,
        or None likewise), the four 5-point answers (1..5) under their item ids,
        ``experienced_<domain>`` (bool, rating >= 3) for driving, games and robots,
        ``any_experience`` (bool) and ``experience_mean`` (float, 1..5).

    Raises
    ------
    ValueError
        As :func:`validate`.
    """
    valid = validate(answers, source=source)
    out: dict[str, object] = {
        key: None if valid[key] == DECLINE else valid[key] for key in ("age", "handedness")
    }
    out.update({item_id: valid[item_id] for item_id in LIKERT_IDS})
    flags = {d: valid[d] >= EXPERIENCED_AT for d in EXPERIENCE_DOMAINS}
    out.update({f"experienced_{d}": flag for d, flag in flags.items()})
    out["any_experience"] = any(flags.values())
    out["experience_mean"] = float(np.mean([valid[i] for i in LIKERT_IDS]))
    return out
