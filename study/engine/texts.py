"""The participant's texts: the protocol's templates, their placeholders and the words the
scene gives them (issue 19: the protocol's text stays in the protocol file; the object to
inspect is named as the scene colours it).

A text of the protocol (``[[phases]]`` briefing and debrief ``text``, ``[ui.instructions]``,
``[ui.texts]``) may hold placeholders in braces, ``{object}`` or ``{attempt}``. Which ones a
text may use is :func:`allowed_placeholders`; the parser refuses any other. Those fixed by the
protocol (``{object}``, ``{laser_colour}``) are filled when the protocol is loaded, the
others (a trial's number, the attempt, the time limit) when the text is shown. Pure: no
pygame, no database.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from sim.scenario import Scenario
from sim.scene import Box, Cylinder
from study.types import TrialInfo

# The laser hits' colour on the participant's map and scan (study.ui.screen.LASER) in words,
# so that a briefing can name it ({laser_colour}); tests/test_ui_legend.py checks the two.
LASER_COLOUR_NAME = "purple"

# Placeholders the protocol fixes at load time, and those of one trial.
PROTOCOL_PLACEHOLDERS: tuple[str, ...] = ("object", "laser_colour")
TRIAL_PLACEHOLDERS: tuple[str, ...] = ("k", "n", "time_limit", "route")
PRACTICE_PLACEHOLDERS: tuple[str, ...] = ("attempt", "attempts", "max_collisions")
RESULT_PLACEHOLDERS: tuple[str, ...] = ("collisions", "next")

# [ui.texts]: key -> default. Titles head the "get ready" page and the status line of a
# trial; the practice_* texts are the page after an attempt; times_up and crashed the
# page after a trial that its time limit or a collision ended; paused the box over a
# paused trial (the legend under it says which button resumes).
DEFAULT_TEXTS: dict[str, str] = {
    "title_training": "Training {k} of {n}",
    "title_practice": "Practice {k} of {n}, attempt {attempt} of {attempts}",
    "title_baseline": "Questions only",
    "title_main": "Trial {k} of {n}",
    "times_up": "Time's up.",
    "crashed": "The robot collided: this drive is over.",
    "practice_passed": "Passed: you reached the goal in time without a collision.",
    "practice_collision": "Collision: attempt {attempt} of {attempts} did not pass.",
    "practice_timeout": "Time's up: the goal was not reached within {time_limit}. "
    "Attempt {attempt} of {attempts} did not pass.",
    "practice_again": "Next: attempt {next} of {attempts}.",
    "practice_last": "That was the last attempt.",
    "paused": "Paused.",
    "break": "Take a short break if you like.",
}

# [ui.instructions] of the trial phases where a protocol gives none (the body of the "get
# ready" page): the sentences of default_instruction, by what the phase asks.
_QUESTIONS = (
    "Questions start whenever the robot enters the yellow area of the map: answer Yes if "
    "the shown result is correct, No if not, quickly and accurately."
)
_REHEARSAL = (
    "Arithmetic questions appear at the bottom of the screen: answer Yes if the shown "
    "result is correct, No if not. The first few come right away; after that, as in the "
    "trials, questions start whenever the robot enters the yellow area of the map."
)


def default_instruction(
    kind: str, *, secondary: bool, inspection: bool = False, rehearsal: bool = False
) -> str:
    """The "get ready" text of a trial phase ``kind`` that the protocol leaves out, for a
    phase that asks questions (``secondary``), an inspection, questions at the start."""
    if kind == "baseline":
        return (
            "The robot stands still. Answer each arithmetic question: Yes if the shown "
            "result is correct, No if not, quickly and accurately."
        )
    if kind == "practice":
        parts = [
            "Drive from A to the goal B and stop inside its circle, facing the way its arrow "
            "points, within {time_limit}. A collision fails the attempt; you have {attempts} "
            "attempts.",
            _QUESTIONS if secondary else "No questions here.",
        ]
    elif kind == "training":
        parts = ["Drive freely and get used to the robot."]
        parts += [_REHEARSAL if rehearsal else _QUESTIONS] if secondary else []
        parts.append("You have {time_limit}.")
    else:
        drive = (
            "Drive {route}, and inspect the {object} on the way."
            if inspection
            else ("Drive {route}.")
        )
        # no time limit named: it ends a trial that went wrong, it is no target to drive to
        parts = [drive, *([_QUESTIONS] if secondary else [])]
    return " ".join(parts)


_TEXT_PLACEHOLDERS: dict[str, tuple[str, ...]] = {
    "title_training": TRIAL_PLACEHOLDERS,
    "title_practice": TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS,
    "title_baseline": TRIAL_PLACEHOLDERS,
    "title_main": TRIAL_PLACEHOLDERS,
    "times_up": TRIAL_PLACEHOLDERS,
    "crashed": TRIAL_PLACEHOLDERS,
    "practice_passed": TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS + RESULT_PLACEHOLDERS,
    "practice_collision": TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS + RESULT_PLACEHOLDERS,
    "practice_timeout": TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS + RESULT_PLACEHOLDERS,
    "practice_again": TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS + RESULT_PLACEHOLDERS,
    "practice_last": TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS + RESULT_PLACEHOLDERS,
    "paused": (),
    "break": TRIAL_PLACEHOLDERS,
}

_PLACEHOLDER = re.compile(r"\{([^{}]*)\}")

_COLOURS: dict[str, tuple[float, float, float]] = {
    "red": (0.85, 0.1, 0.1),
    "orange": (0.95, 0.55, 0.1),
    "yellow": (0.95, 0.9, 0.15),
    "green": (0.15, 0.65, 0.2),
    "blue": (0.15, 0.3, 0.85),
    "purple": (0.55, 0.2, 0.75),
    "pink": (0.95, 0.5, 0.7),
    "brown": (0.5, 0.33, 0.18),
    "grey": (0.5, 0.5, 0.5),
    "white": (0.95, 0.95, 0.95),
    "black": (0.08, 0.08, 0.08),
}


def allowed_placeholders(field: str) -> tuple[str, ...]:
    """The placeholders a protocol text may use: ``field`` is ``"text"`` (briefing,
    debrief), ``"instructions.<phase>"`` or ``"texts.<key>"``."""
    kind, _, key = field.partition(".")
    if kind == "texts":
        return PROTOCOL_PLACEHOLDERS + _TEXT_PLACEHOLDERS[key]
    if kind == "instructions" and key == "practice":
        return PROTOCOL_PLACEHOLDERS + TRIAL_PLACEHOLDERS + PRACTICE_PLACEHOLDERS
    if kind == "instructions" and key in ("training", "baseline", "main"):
        return PROTOCOL_PLACEHOLDERS + TRIAL_PLACEHOLDERS
    return PROTOCOL_PLACEHOLDERS


def placeholders(template: str) -> list[str]:
    """The names in braces in ``template``, in order."""
    return _PLACEHOLDER.findall(template)


def unknown_placeholder(template: str, allowed: tuple[str, ...]) -> str | None:
    """The first placeholder of ``template`` not in ``allowed`` (None if all are)."""
    return next((name for name in placeholders(template) if name not in allowed), None)


def fill(template: str, values: Mapping[str, Any]) -> str:
    """``template`` with ``{name}`` replaced for every name in ``values``; other
    placeholders are left as they are (a later stage fills them)."""

    def one(match: re.Match[str]) -> str:
        name = match.group(1)
        return str(values[name]) if name in values else match.group(0)

    return _PLACEHOLDER.sub(one, template)


def colour_name(rgb: tuple[float, float, float]) -> str:
    """The nearest of a few everyday colour names to ``rgb`` (each in [0, 1])."""
    r, g, b = (float(c) for c in rgb)
    return min(
        _COLOURS,
        key=lambda n: sum((a - c) ** 2 for a, c in zip((r, g, b), _COLOURS[n], strict=True)),
    )


def object_words(scenario: Scenario) -> str:
    """The scene's inspection object in words, its colour and shape ("red cylinder");
    "" when the scene has none."""
    if not scenario.inspection_object:
        return ""
    element = scenario.element(scenario.inspection_object)
    if isinstance(element, Cylinder):
        shape = "cylinder"
    elif isinstance(element, Box):
        shape = "box"
    else:
        shape = "object"
    return f"{colour_name(element.colour)} {shape}"


def time_words(seconds: float) -> str:
    """A time limit as a participant reads it: "60 s", "3 minutes", "1.5 minutes"."""
    if seconds < 120 or seconds % 30:
        return f"{seconds:.0f} s"
    minutes = seconds / 60
    return f"{minutes:g} minutes"


def practice_feedback(
    outcome: Mapping[str, Any],
    texts: Mapping[str, str],
    *,
    attempt: int,
    attempts: int,
    time_limit_s: float,
    max_collisions: int,
) -> str:
    """The page after practice attempt ``attempt`` (1-based) of ``attempts``: passed, or
    why not (a collision first: it ends the attempt), then what comes next."""
    values = {
        "attempt": attempt,
        "attempts": attempts,
        "next": attempt + 1,
        "time_limit": time_words(time_limit_s),
        "max_collisions": max_collisions,
        "collisions": outcome.get("collisions") or 0,
    }
    if outcome.get("passed"):
        return fill(texts["practice_passed"], values)
    collided = (outcome.get("collisions") or 0) > max_collisions
    first = texts["practice_collision" if collided else "practice_timeout"]
    then = texts["practice_again" if attempt < attempts else "practice_last"]
    return fill(f"{first}\n\n{then}", values)


def trial_values(info: TrialInfo) -> dict[str, Any]:
    """The trial placeholders' values of ``info`` ({k}, {n}, {time_limit}, {attempt}, ...)."""
    values: dict[str, Any] = {"k": info.ordinal + 1, "n": info.of, "route": route_words(info)}
    values["time_limit"] = time_words(info.time_limit_s) if info.time_limit_s < 1e6 else ""
    if info.attempt_of is not None:
        values["attempt"], values["attempts"] = info.attempt_of
    if info.max_collisions is not None:
        values["max_collisions"] = info.max_collisions
    return values


def route_words(info: TrialInfo) -> str:
    """The trial's route in words: "from A to B, then back to A"."""
    names = {"dock": "B", "start": "A"}
    stops = [names.get(goal, goal) for goal in info.route]
    if not stops:
        return ""
    text = f"from A to {stops[0]}"
    for k, stop in enumerate(stops[1:]):
        text += (
            f", then back to {stop}" if stop == "A" and k == len(stops) - 2 else f", then to {stop}"
        )
    return text


def trial_title(info: TrialInfo, texts: Mapping[str, str]) -> str:
    """The trial's title ("Trial 1 of 3"), from ``texts["title_<phase>"]``."""
    template = texts.get(f"title_{info.phase}", info.phase.title())
    return fill(template, trial_values(info))


def first_sentence(text: str) -> str:
    """The first sentence of ``text`` (up to and including its first full stop)."""
    flat = " ".join(text.split())
    match = re.search(r"[.!?](\s|$)", flat)
    return flat[: match.end()].strip() if match else flat
