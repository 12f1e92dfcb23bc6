"""The key legends' words (issue 19): which controls a screen uses and what they do, for
the gamepad and for the keyboard, taken from the protocol's ``[input]`` so that a legend can
never disagree with what the keys do. Pure (no pygame): the pygame screen
(:mod:`study.ui.legend`) and the browser (:mod:`study.web`) draw the same legends.

A legend is two lines, one per device, each a sequence of (control, what it does) entries.
The gamepad's controls are named as printed on the pad
(:meth:`study.engine.protocol.InputSettings.pad_names`), the keyboard's are the protocol's
``[input.keys]``; pages and forms use Enter, the arrows and the digits, which the protocol
does not remap.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from study.engine.protocol import InputSettings

Entry = tuple[str, str]  # (control, what it does)
Line = tuple[str, tuple[Entry, ...]]  # (device, entries)
Legend = tuple[Line, ...]

ENTER = "Enter"
ARROWS_UD = "\u2191 \u2193"
ARROWS_LR = "\u2190 \u2192"


@dataclass(frozen=True, slots=True)
class Controls:
    """The participant's controls as the legends name them."""

    pad: Mapping[str, str]  # PAD_CONTROLS -> name printed on the pad ("A", "left stick")
    keys: Mapping[str, str]  # KEY_ACTIONS -> key letter

    @classmethod
    def from_settings(cls, settings: InputSettings) -> Controls:
        """The protocol's ``[input]``."""
        return cls(pad=settings.pad_names(), keys=dict(settings.keys))


def page_legend(c: Controls, verb: str = "continue") -> Legend:
    """A text page: one button goes on."""
    return (("Gamepad", ((c.pad["yes"], verb),)), ("Keyboard", ((ENTER, verb),)))


def drive_legend(c: Controls, *, drive: bool = True, questions: bool = True) -> Legend:
    """The driving screen: move, turn, answer (when the trial asks questions), pause."""
    k = c.keys
    pad: list[Entry] = []
    keys: list[Entry] = []
    if drive:
        pad += [(c.pad["move"], "move"), (c.pad["turn"], "turn")]
        keys += [
            (f"{k['forward']} {k['back']}", "forward / back"),
            (f"{k['left']} {k['right']}", "sideways"),
            (f"{k['turn_left']} {k['turn_right']}", "turn"),
        ]
    if questions:
        pad += [(c.pad["yes"], "Yes"), (c.pad["no"], "No")]
        keys += [(k["yes"], "Yes"), (k["no"], "No")]
    pad.append((c.pad["pause"], "pause"))
    keys.append((k["pause"], "pause"))
    return (("Gamepad", tuple(pad)), ("Keyboard", tuple(keys)))


def form_legend(c: Controls, *, numbers: bool = False) -> Legend:
    """A questionnaire page: choose a question, set its answer, go on."""
    pad = (
        ("D-pad " + ARROWS_UD, "question"),
        ("D-pad " + ARROWS_LR, "answer (hold to repeat)"),
        (c.pad["yes"], "next / Done"),
    )
    keys: tuple[Entry, ...] = (
        (ARROWS_UD, "question"),
        (ARROWS_LR, "answer (hold to repeat)"),
    )
    if numbers:
        keys += (("0-9", "type a number"),)
    keys += ((ENTER, "next / Done"),)
    return (("Gamepad", pad), ("Keyboard", keys))


def pairs_legend(c: Controls) -> Legend:
    """A pairwise comparison: highlight one side, choose it."""
    return (
        ("Gamepad", (("D-pad " + ARROWS_LR, "highlight"), (c.pad["yes"], "choose"))),
        ("Keyboard", ((ARROWS_LR, "highlight"), (ENTER, "choose"))),
    )


def prompt_text(c: Controls, verb: str = "continue") -> str:
    """How a page goes on, in words."""
    return f"Press {c.pad['yes']} on the gamepad or {ENTER} on the keyboard to {verb}."


def resume_text(c: Controls) -> str:
    """How a paused trial goes on, in words."""
    return (
        f"Press {c.pad['pause']} on the gamepad or {c.keys['pause']} on the keyboard to continue."
    )


def legend_strings(legend: Legend) -> list[str]:
    """Every control and action of ``legend`` as ``"<device>: <control> <action>"``."""
    return [
        f"{device}: {control} {action}" for device, entries in legend for control, action in entries
    ]
