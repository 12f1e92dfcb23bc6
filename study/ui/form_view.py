"""Drawing the questionnaires (:mod:`study.ui.forms`) and the NASA-TLX pairwise comparisons.

A form page: the instrument's title and instructions, one row per item (its question, then
its answer: a typed number box, a row of labelled options, or a slider with its two end
labels and no numbers), the selected row framed with everything it draws inside the frame,
the selected item's description, the reminder, "Done", and the key legend. Every row is
measured before it is drawn, so nothing overlaps whatever the texts.
"""

from __future__ import annotations

from collections.abc import Sequence

import pygame

from questionnaires.base import DECLINE, Item
from study.ui.forms import FormState
from study.ui.legend import Legend
from study.ui.screen import BACKGROUND, DIM, HIGHLIGHT, PANEL, TEXT, Screen

PAD = 8  # [px] inside a row's frame
GAP = 8  # [px] between options


class FormView:
    """Draws a :class:`FormState` and turns mouse clicks into answers."""

    def __init__(self, screen: Screen, state: FormState, legend: Legend = ()) -> None:
        self.screen = screen
        self.state = state
        self.legend = legend
        self.tracks: list[pygame.Rect | None] = []  # per row: a slider's track
        self.options: list[list[pygame.Rect]] = []  # per row: its option boxes
        self.rows: list[pygame.Rect] = []  # per row: its frame
        self.done_button = pygame.Rect(0, 0, 0, 0)

    # -------------------------------------------------------------- layout

    @property
    def _line(self) -> int:
        return self.screen.fonts["small"].get_linesize()

    @property
    def _opt_line(self) -> int:
        return self.screen.fonts["legend"].get_linesize()

    def _label(self, item: Item) -> str:
        return f"{item.title}: {item.text}" if item.title else item.text

    def _option_lines(self, k: int, width: int) -> list[list[str]]:
        """Each option's label of row ``k`` wrapped to ``width`` px."""
        return [
            self.screen.wrap(label, width - 12, font="legend") for _, label in self.state.options[k]
        ]

    def _widget_height(self, k: int, inner: pygame.Rect) -> int:
        item = self.state.items[k]
        if item.kind == "slider":
            return 36
        if item.kind == "number":
            return self._opt_line + 18
        n = len(self.state.options[k])
        width = (inner.width - GAP * (n - 1)) // n
        lines = max(len(w) for w in self._option_lines(k, width))
        return lines * self._opt_line + 14

    def _row_height(self, k: int, inner: pygame.Rect) -> int:
        lines = len(self.screen.wrap(self._label(self.state.items[k]), inner.width, font="small"))
        return 2 * PAD + lines * self._line + 4 + self._widget_height(k, inner)

    # -------------------------------------------------------------- drawing

    def draw(self) -> None:
        sc, st = self.screen, self.state
        sc.surface.fill(BACKGROUND)
        w, h = sc.width, sc.height
        margin = int(w * 0.06)
        y = int(h * 0.03)
        sc.text(st.instrument.title, (margin, y), font="large")
        y += sc.fonts["large"].get_linesize()
        text_rect = pygame.Rect(margin, y, w - 2 * margin, h)
        y = sc.paragraph(st.instrument.instructions, text_rect, font="small", colour=DIM) + 4
        inner = pygame.Rect(margin, 0, w - 2 * margin, 0)
        heights = [self._row_height(k, inner) for k in range(len(st.items))]
        self.done_button = pygame.Rect(0, 0, int(w * 0.18), int(h * 0.065))
        self.done_button.midbottom = (w // 2, sc.legend_rect.top - 8)
        spare = self.done_button.top - self._line * 3 - y - sum(heights)
        gap = max(2, min(14, spare // max(1, len(heights))))
        self.tracks, self.options, self.rows = [], [], []
        for k, item in enumerate(st.items):
            frame = pygame.Rect(margin - PAD, y, w - 2 * margin + 2 * PAD, heights[k])
            self.rows.append(frame)
            self._row(k, item, frame)
            y = frame.bottom + gap
        self._footer(y)
        sc.legend(self.legend)
        sc.flip()

    def _row(self, k: int, item: Item, frame: pygame.Rect) -> None:
        sc, st = self.screen, self.state
        if k == st.row:
            pygame.draw.rect(sc.surface, PANEL, frame, border_radius=6)
            pygame.draw.rect(sc.surface, HIGHLIGHT, frame, width=2, border_radius=6)
        inner = frame.inflate(-2 * PAD, -2 * PAD)
        y = sc.paragraph(self._label(item), inner, font="small") + 4
        widget = pygame.Rect(inner.left, y, inner.width, inner.bottom - y)
        self.tracks.append(None)
        self.options.append([])
        if item.kind == "slider":
            self.tracks[k] = self._slider(k, item, widget)
        elif item.kind == "number":
            self._number(k, item, widget)
        else:
            self._choices(k, widget)

    def _chip(self, rect: pygame.Rect, lines: Sequence[str], on: bool) -> None:
        sc = self.screen
        pygame.draw.rect(sc.surface, HIGHLIGHT if on else PANEL, rect, border_radius=6)
        pygame.draw.rect(sc.surface, HIGHLIGHT if on else DIM, rect, width=1, border_radius=6)
        top = rect.centery - len(lines) * self._opt_line // 2
        for n, line in enumerate(lines):
            sc.text(line, (rect.centerx, top + n * self._opt_line), font="legend",
                    anchor="midtop", colour=BACKGROUND if on else TEXT)  # fmt: skip

    def _choices(self, k: int, widget: pygame.Rect) -> None:
        st = self.state
        n = len(st.options[k])
        width = (widget.width - GAP * (n - 1)) // n
        wrapped = self._option_lines(k, width)
        for i, lines in enumerate(wrapped):
            rect = pygame.Rect(widget.left + i * (width + GAP), widget.top, width, widget.height)
            self._chip(rect, lines, st.index[k] == i)
            self.options[k].append(rect)

    def _number(self, k: int, item: Item, widget: pygame.Rect) -> None:
        sc, st = self.screen, self.state
        box = pygame.Rect(widget.left, widget.top, max(90, widget.width // 10), widget.height)
        selected = k == st.row
        pygame.draw.rect(sc.surface, BACKGROUND, box, border_radius=4)
        pygame.draw.rect(sc.surface, HIGHLIGHT if selected else DIM, box, width=2, border_radius=4)
        shown = st.typed[k] + ("|" if selected else "")
        if shown:
            sc.text(shown, box.center, font="small", anchor="center")
        x = sc.text(item.unit, (box.right + 10, box.centery), font="small",
                    anchor="midleft").right + 24  # fmt: skip
        for _, label in st.options[k]:  # "Prefer not to say"
            width = sc.fonts["legend"].size(label)[0] + 24
            rect = pygame.Rect(x, widget.top, width, widget.height)
            self._chip(rect, [label], st.declined[k])
            self.options[k].append(rect)
            x = rect.right + 24
        problem = st.problem(k)
        hint = problem or ("type the number, or step it with left / right" if selected else "")
        if hint:
            sc.text(hint, (x, box.centery), font="legend", anchor="midleft",
                    colour=HIGHLIGHT if problem else DIM)  # fmt: skip

    def _slider(self, k: int, item: Item, widget: pygame.Rect) -> pygame.Rect:
        sc, st = self.screen, self.state
        s = sc.surface
        left = widget.left + int(widget.width * 0.2)
        right = widget.right - int(widget.width * 0.2)
        cy = widget.centery
        track = pygame.Rect(left, cy - 7, right - left, 14)
        scale = [o for o in st.options[k] if o[0] != DECLINE]
        pygame.draw.line(s, TEXT, (left, cy), (right, cy), 2)
        if len(scale) <= 25:
            for i in range(len(scale)):
                x = left + (right - left) * i / max(1, len(scale) - 1)
                tall = 8 if i % 2 == 0 else 5
                pygame.draw.line(s, TEXT, (x, cy - tall), (x, cy + tall), 1)
        if item.anchors:
            sc.text(item.anchors[0], (left - 12, cy), font="small", anchor="midright")
            sc.text(item.anchors[1], (right + 12, cy), font="small", anchor="midleft")
        i = st.index[k]
        if i is not None:  # the mark, without its number (a number could anchor ratings)
            x = left + (right - left) * i / max(1, len(scale) - 1)
            pygame.draw.circle(s, HIGHLIGHT, (int(x), cy), 9)
        return track

    def _footer(self, y: int) -> None:
        sc, st = self.screen, self.state
        w = sc.width
        margin = int(w * 0.06)
        current = st.items[st.row] if st.row < st.done_row else None
        if current is not None and current.description:
            bottom = self.done_button.top - self._line - 8  # room for the reminder
            for line in sc.wrap(current.description, w - 2 * margin, font="small"):
                if y + self._line > bottom:
                    break
                sc.text(line, (margin, y), font="small", colour=DIM)
                y += self._line
        active = st.row == st.done_row
        pygame.draw.rect(sc.surface, HIGHLIGHT if active else PANEL, self.done_button,
                         border_radius=8)  # fmt: skip
        sc.text("Done", self.done_button.center, anchor="center",
                colour=BACKGROUND if active else TEXT)  # fmt: skip
        if st.reminder:
            sc.text(st.reminder, (w // 2, self.done_button.top - 6), font="small",
                    anchor="midbottom", colour=HIGHLIGHT)  # fmt: skip

    # -------------------------------------------------------------- mouse

    def click(self, pos: tuple[int, int]) -> None:
        """A mouse click at ``pos``."""
        st = self.state
        if self.done_button.collidepoint(pos):
            st.select(st.done_row)
            st.finish()
            return
        for k, boxes in enumerate(self.options):
            for i, rect in enumerate(boxes):
                if rect.collidepoint(pos):
                    st.choose(k, i)
                    return
        for k, track in enumerate(self.tracks):
            if track is not None and track.inflate(20, 20).collidepoint(pos):
                st.set_fraction(k, (pos[0] - track.left) / max(1, track.width))
                return
        for k, frame in enumerate(self.rows):
            if frame.collidepoint(pos):
                st.select(k)
                return


class PairView:
    """One NASA-TLX pairwise comparison: two subscales, choose the bigger contributor."""

    def __init__(
        self,
        screen: Screen,
        pair: Sequence[str],
        titles: dict[str, str],
        texts: dict[str, str],
        legend: Legend = (),
    ) -> None:
        self.screen = screen
        self.pair = (pair[0], pair[1])
        self.titles = titles
        self.texts = texts
        self.legend = legend
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
        bottom = sc.legend_rect.top - 16
        for i, sid in enumerate(self.pair):
            rect = pygame.Rect(0, 0, int(w * 0.4), min(int(h * 0.5), bottom - int(h * 0.24)))
            rect.midtop = (int(w * (0.28 + 0.44 * i)), int(h * 0.24))
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
        sc.legend(self.legend)
        sc.flip()
