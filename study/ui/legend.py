"""The key legends at the bottom of every screen (issue 19: the keys a participant needs,
for the gamepad and for the keyboard, taken from the protocol's ``[input]``, so a legend
can never disagree with what the keys do).

A legend is two lines, one per device, each a sequence of (control, what it does) entries;
:func:`draw_legend` draws the controls as key caps. The gamepad's controls are named as
printed on the pad (:meth:`study.engine.protocol.InputSettings.pad_names`), the keyboard's
are the protocol's ``[input.keys]``; pages and forms use Enter, the arrows and the digits,
which the protocol does not remap.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

import pygame

from study.engine.protocol import InputSettings

Entry = tuple[str, str]  # (control, what it does)
Line = tuple[str, tuple[Entry, ...]]  # (device, entries)
Legend = tuple[Line, ...]

KEY_CAP = (70, 76, 88)
CAP_TEXT = (245, 245, 245)
LABEL = (160, 160, 160)
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


_ARROW_POINTS = {  # unit triangles pointing up, down, left, right
    "\u2191": ((0.5, 0.0), (1.0, 1.0), (0.0, 1.0)),
    "\u2193": ((0.0, 0.0), (1.0, 0.0), (0.5, 1.0)),
    "\u2190": ((0.0, 0.5), (1.0, 0.0), (1.0, 1.0)),
    "\u2192": ((0.0, 0.0), (1.0, 0.5), (0.0, 1.0)),
}


def render_label(font: pygame.font.Font, text: str, colour: tuple[int, int, int]) -> pygame.Surface:
    """``text`` rendered with ``font``, its arrows (U+2190-2193) drawn as triangles (the
    default font has no glyphs for them)."""
    if not any(ch in _ARROW_POINTS for ch in text):
        return font.render(text, True, colour)
    height = font.get_height()
    side = int(height * 0.55)
    pieces: list[pygame.Surface] = []
    for run in re.split("([\u2190-\u2193])", text):
        if run in _ARROW_POINTS:
            piece = pygame.Surface((side + 2, height), pygame.SRCALPHA)
            top = (height - side) // 2
            pts = [(1 + x * side, top + y * side) for x, y in _ARROW_POINTS[run]]
            pygame.draw.polygon(piece, colour, pts)
        elif run:
            piece = font.render(run, True, colour)
        else:
            continue
        pieces.append(piece)
    out = pygame.Surface((sum(p.get_width() for p in pieces), height), pygame.SRCALPHA)
    x = 0
    for piece in pieces:
        out.blit(piece, (x, 0))
        x += piece.get_width()
    return out


def legend_strings(legend: Legend) -> list[str]:
    """Every control and action of ``legend`` as ``"<device>: <control> <action>"``."""
    return [
        f"{device}: {control} {action}" for device, entries in legend for control, action in entries
    ]


def legend_height(font: pygame.font.Font, lines: int = 2) -> int:
    """[px] the strip a legend of ``lines`` lines needs."""
    return lines * (font.get_linesize() + 10) + 8


def draw_legend(
    surface: pygame.Surface,
    rect: pygame.Rect,
    legend: Legend,
    font: pygame.font.Font,
    remember: set[str] | None = None,
) -> None:
    """Draw ``legend`` in ``rect``, one line per device, the controls as key caps, centred;
    each string drawn is added to ``remember`` (the screen's ``texts_seen``)."""
    step = font.get_linesize() + 10
    y = rect.top + 4
    for device, entries in legend:
        parts: list[tuple[str, bool]] = [(f"{device}:", False)]
        for control, action in entries:
            parts += [(control, True), (action, False)]
        images = [
            (render_label(font, text, CAP_TEXT if cap else LABEL), cap) for text, cap in parts
        ]
        width = sum(img.get_width() + (22 if cap else 18) for img, cap in images)
        x = rect.centerx - width // 2
        for (img, cap), (text, _) in zip(images, parts, strict=True):
            if remember is not None:
                remember.add(text)
            box = img.get_rect(midleft=(x + (6 if cap else 0), y + step // 2))
            if cap:
                pygame.draw.rect(surface, KEY_CAP, box.inflate(12, 6), border_radius=5)
            surface.blit(img, box)
            x += img.get_width() + (22 if cap else 18)
        y += step
