"""Questionnaires on the participant's screen (issue 5, "Questionnaires on screen"): any
:class:`questionnaires.base.Instrument` as one page of rows, and the NASA-TLX pairwise
comparisons one pair per page.

Decisions where the spec is silent:

- One page per instrument, one row per item; the selected row is framed. Up/down (arrow keys,
  D-pad or left stick) select a row, left/right move its mark; a mouse click on a row's track
  puts the mark there. A row starts *unmarked* (no default that a participant could leave by
  accident); the first left/right press puts the mark in the middle of the scale
  (:meth:`FormState.start_index`), each further press moves it one step (5 on the NASA-TLX's
  0-100 scale).
- Nothing can be skipped: "Done" (the last row, or the button) finishes only once every
  required item has a mark; otherwise the selection jumps to the first unmarked item and a
  reminder is shown. Confirm on an item row moves to the next row. Items a questionnaire
  marks ``optional`` may stay unmarked (stored as not answered); items that allow declining
  offer "Prefer not to say" as the last option of their scale.
- The description of the selected item (NASA-TLX: the manual's scale definition) is shown
  under the rows.
- Pairwise comparisons: the two subscales side by side as buttons with their descriptions;
  left/right highlight one, confirm chooses it (a mouse click chooses directly); nothing is
  highlighted at first, so an early press chooses nothing.
"""

from __future__ import annotations

from collections.abc import Sequence

import pygame

from questionnaires.base import DECLINE, DECLINE_LABEL, Instrument, Item
from study.ui.screen import BACKGROUND, DIM, HIGHLIGHT, PANEL, TEXT, Screen


def options(item: Item) -> list[tuple[object, str]]:
    """``(value, label)`` of every mark of ``item``'s scale, in display order."""
    if item.kind == "number":
        assert item.minimum is not None and item.maximum is not None  # checked by Item
        opts: list[tuple[object, str]] = [
            (v, f"{v} {item.unit}".strip()) for v in range(item.minimum, item.maximum + 1)
        ]
        if item.can_decline:
            opts.append((DECLINE, DECLINE_LABEL))
        return opts
    return [(v, label) for v, label in item.choices]


class FormState:
    """Where the participant is in a questionnaire page (no drawing)."""

    def __init__(self, instrument: Instrument) -> None:
        self.instrument = instrument
        self.options = [options(item) for item in instrument.items]
        self.index: list[int | None] = [None] * len(instrument.items)
        self.row = 0  # selected row; len(items) is the Done row
        self.reminder = ""
        self.done = False

    @property
    def done_row(self) -> int:
        return len(self.instrument.items)

    def start_index(self, row: int) -> int:
        """The mark's position after the first step on an unmarked row (the middle)."""
        n = len(self.options[row])
        if self.options[row][-1][0] == DECLINE:
            n -= 1
        return (n - 1) // 2

    def missing(self) -> list[int]:
        return [
            i
            for i, item in enumerate(self.instrument.items)
            if self.index[i] is None and not item.optional
        ]

    def action(self, name: str) -> None:
        """Apply one input action (``up``, ``down``, ``left``, ``right``, ``confirm``/``yes``)."""
        if name == "up":
            self.row = max(0, self.row - 1)
        elif name == "down":
            self.row = min(self.done_row, self.row + 1)
        elif name in ("left", "right") and self.row < self.done_row:
            current = self.index[self.row]
            if current is None:
                self.index[self.row] = self.start_index(self.row)
            else:
                step = 1 if name == "right" else -1
                self.index[self.row] = min(len(self.options[self.row]) - 1, max(0, current + step))
        elif name in ("confirm", "yes"):
            if self.row < self.done_row:
                self.row += 1
            else:
                self.finish()

    def finish(self) -> None:
        missing = self.missing()
        if missing:
            self.row = missing[0]
            self.reminder = "Please answer every question before you continue."
        else:
            self.done = True

    def set_fraction(self, row: int, fraction: float) -> None:
        """A click at ``fraction`` (0..1) along the row's track (its scale without the
        decline option)."""
        n = sum(1 for value, _ in self.options[row] if value != DECLINE)
        self.index[row] = min(n - 1, max(0, round(fraction * (n - 1))))
        self.row = row

    def answers(self) -> dict[str, object]:
        """Item id -> value (None for an optional item left unmarked)."""
        return {
            item.id: (None if i is None else self.options[k][i][0])
            for k, (item, i) in enumerate(zip(self.instrument.items, self.index, strict=True))
        }


class FormView:
    """Draws a :class:`FormState` and turns mouse clicks into answers."""

    def __init__(self, screen: Screen, state: FormState) -> None:
        self.screen = screen
        self.state = state
        self.tracks: list[pygame.Rect] = []
        self.done_button = pygame.Rect(0, 0, 0, 0)

    def draw(self) -> None:
        sc, st = self.screen, self.state
        s = sc.surface
        s.fill(BACKGROUND)
        w, h = sc.width, sc.height
        margin = int(w * 0.06)
        y = int(h * 0.03)
        sc.text(st.instrument.title, (margin, y), font="large")
        y += sc.fonts["large"].get_linesize()
        y = sc.paragraph(
            st.instrument.instructions,
            pygame.Rect(margin, y, w - 2 * margin, h),
            font="small",
            colour=DIM,
        )
        n = len(st.instrument.items)
        row_h = int((h * 0.70 - y) / n) if h * 0.70 > y else 40
        row_h = max(row_h, sc.fonts["small"].get_linesize() * 2 + 8)
        self.tracks = []
        for k, item in enumerate(st.instrument.items):
            top = y + k * row_h
            rect = pygame.Rect(margin - 8, top, w - 2 * margin + 16, row_h - 4)
            if k == st.row:
                pygame.draw.rect(s, PANEL, rect, border_radius=6)
                pygame.draw.rect(s, HIGHLIGHT, rect, width=2, border_radius=6)
            title = item.title or item.text
            label = f"{title}: {item.text}" if item.title else item.text
            sc.text(label, (margin, top + 2), font="small")
            self.tracks.append(self._track(k, item, top + sc.fonts["small"].get_linesize() + 4))
        y = y + n * row_h + 6
        current = st.instrument.items[st.row] if st.row < n else None
        if current is not None and current.description:
            y = sc.paragraph(
                current.description,
                pygame.Rect(margin, y, w - 2 * margin, h),
                font="small",
                colour=DIM,
            )
        self.done_button = pygame.Rect(0, 0, int(w * 0.18), int(h * 0.07))
        self.done_button.midbottom = (w // 2, h - int(h * 0.03))
        active = st.row == st.done_row
        pygame.draw.rect(s, HIGHLIGHT if active else PANEL, self.done_button, border_radius=8)
        sc.text(
            "Done", self.done_button.center, anchor="center", colour=BACKGROUND if active else TEXT
        )
        if st.reminder:
            sc.text(
                st.reminder,
                (w // 2, self.done_button.top - 8),
                font="small",
                anchor="midbottom",
                colour=HIGHLIGHT,
            )
        sc.flip()

    def _track(self, k: int, item: Item, y: int) -> pygame.Rect:
        sc, st = self.screen, self.state
        s = sc.surface
        w = sc.width
        left, right = int(w * 0.25), int(w * 0.75)
        track = pygame.Rect(left, y + 6, right - left, 14)
        opts = st.options[k]
        scale = [o for o in opts if o[0] != DECLINE]
        pygame.draw.line(s, TEXT, (left, track.centery), (right, track.centery), 2)
        if len(scale) <= 25:
            for i in range(len(scale)):
                x = left + (right - left) * i / max(1, len(scale) - 1)
                tall = 8 if item.kind == "slider" and i % 2 == 0 else 5
                pygame.draw.line(s, TEXT, (x, track.centery - tall), (x, track.centery + tall), 1)
        if item.anchors:
            sc.text(item.anchors[0], (left - 10, track.centery), font="small", anchor="midright")
            lines = sc.wrap(item.anchors[1], w - right - 20, font="small")
            step = sc.fonts["small"].get_linesize()
            top = track.centery - step * len(lines) // 2
            for n, line in enumerate(lines):
                sc.text(line, (right + 10, top + n * step), font="small")
        i = st.index[k]
        if i is not None:
            value, label = opts[i]
            if value == DECLINE:
                sc.text(
                    label,
                    (right + 10, track.centery),
                    font="small",
                    anchor="midleft",
                    colour=HIGHLIGHT,
                )
            else:
                x = left + (right - left) * i / max(1, len(scale) - 1)
                pygame.draw.circle(s, HIGHLIGHT, (int(x), track.centery), 8)
                sc.text(
                    label,
                    (int(x), track.centery + 10),
                    font="small",
                    anchor="midtop",
                    colour=HIGHLIGHT,
                )
        return track

    def click(self, pos: tuple[int, int]) -> None:
        """A mouse click at ``pos``."""
        st = self.state
        if self.done_button.collidepoint(pos):
            st.row = st.done_row
            st.finish()
            return
        for k, track in enumerate(self.tracks):
            if track.inflate(20, 20).collidepoint(pos):
                st.set_fraction(k, (pos[0] - track.left) / max(1, track.width))
                return


class PairView:
    """One NASA-TLX pairwise comparison: two subscales, choose the bigger contributor."""

    def __init__(
        self, screen: Screen, pair: Sequence[str], titles: dict[str, str], texts: dict[str, str]
    ) -> None:
        self.screen = screen
        self.pair = (pair[0], pair[1])
        self.titles = titles
        self.texts = texts
        self.highlight: int | None = None
        self.chosen: str | None = None
        self.buttons: list[pygame.Rect] = []

    def action(self, name: str) -> None:
        if name == "left":
            self.highlight = 0
        elif name == "right":
            self.highlight = 1
        elif name in ("confirm", "yes") and self.highlight is not None:
            self.chosen = self.pair[self.highlight]

    def click(self, pos: tuple[int, int]) -> None:
        for i, rect in enumerate(self.buttons):
            if rect.collidepoint(pos):
                self.highlight = i
                self.chosen = self.pair[i]

    def draw(self, question: str, progress: str) -> None:
        sc = self.screen
        s = sc.surface
        s.fill(BACKGROUND)
        w, h = sc.width, sc.height
        sc.text(question, (w // 2, int(h * 0.1)), font="large", anchor="center")
        sc.text(progress, (w // 2, int(h * 0.17)), font="small", anchor="center", colour=DIM)
        self.buttons = []
        for i, sid in enumerate(self.pair):
            rect = pygame.Rect(0, 0, int(w * 0.4), int(h * 0.5))
            rect.center = (int(w * (0.28 + 0.44 * i)), int(h * 0.52))
            on = self.highlight == i
            pygame.draw.rect(s, PANEL, rect, border_radius=10)
            pygame.draw.rect(
                s, HIGHLIGHT if on else DIM, rect, width=4 if on else 2, border_radius=10
            )
            sc.text(self.titles[sid], (rect.centerx, rect.top + 30), font="large", anchor="center")
            sc.paragraph(
                self.texts[sid], rect.inflate(-30, -90).move(0, 30), font="small", colour=DIM
            )
            self.buttons.append(rect)
        sc.text(
            "Left / right to select, A or Enter to choose (or click).",
            (w // 2, int(h * 0.9)),
            font="small",
            anchor="center",
            colour=HIGHLIGHT,
        )
        sc.flip()
