"""The key legends at the bottom of every screen (issue 19: the keys a participant needs,
for the gamepad and for the keyboard, taken from the protocol's ``[input]``, so a legend
can never disagree with what the keys do).

A legend (:mod:`study.ui.controls`, which says what each screen's legend holds) is two
lines, one per device; :func:`draw_legend` draws the controls as key caps.
"""

from __future__ import annotations

import re

import pygame

# the legends' words are pure (the browser draws them too); re-exported for the screen
from study.ui.controls import (  # noqa: F401
    ARROWS_LR,
    ARROWS_UD,
    ENTER,
    Controls,
    Entry,
    Legend,
    Line,
    drive_legend,
    form_legend,
    legend_strings,
    page_legend,
    pairs_legend,
    prompt_text,
    resume_text,
)

KEY_CAP = (70, 76, 88)
CAP_TEXT = (245, 245, 245)
LABEL = (160, 160, 160)

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
