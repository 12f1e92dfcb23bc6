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

from study.ui.controls import Controls
from study.ui.describe import FormRow, FormScreen, form_screen, pair_screen
from study.ui.forms import FormState
from study.ui.screen import BACKGROUND, DIM, HIGHLIGHT, PANEL, TEXT, Screen

PAD = 8  # [px] inside a row's frame
GAP = 8  # [px] between options


class FormView:
    """Draws a :class:`FormState` through its description (:func:`study.ui.describe.form_screen`)
    and turns mouse clicks into answers."""

    def __init__(self, screen: Screen, state: FormState, controls: Controls | None = None) -> None:
        self.screen = screen
        self.state = state
        self.controls = controls
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

    def _option_lines(self, row: FormRow, width: int) -> list[list[str]]:
        """Each option's label of ``row`` wrapped to ``width`` px."""
        return [self.screen.wrap(label, width - 12, font="legend") for label in row.options]

    def _widget_height(self, row: FormRow, inner: pygame.Rect) -> int:
        if row.kind == "slider":
            return 36
        if row.kind == "number":
            return self._opt_line + 18
        n = len(row.options)
        width = (inner.width - GAP * (n - 1)) // n
        lines = max(len(w) for w in self._option_lines(row, width))
        return lines * self._opt_line + 14

    def _row_height(self, row: FormRow, inner: pygame.Rect) -> int:
        lines = len(self.screen.wrap(row.label, inner.width, font="small"))
        return 2 * PAD + lines * self._line + 4 + self._widget_height(row, inner)

    # -------------------------------------------------------------- drawing

    def draw(self) -> None:
        sc = self.screen
        desc = form_screen(self.state, self.controls)
        sc.surface.fill(BACKGROUND)
        w, h = sc.width, sc.height
        margin = int(w * 0.06)
        y = int(h * 0.03)
        sc.text(desc.title, (margin, y), font="large")
        y += sc.fonts["large"].get_linesize()
        text_rect = pygame.Rect(margin, y, w - 2 * margin, h)
        y = sc.paragraph(desc.instructions, text_rect, font="small", colour=DIM) + 4
        inner = pygame.Rect(margin, 0, w - 2 * margin, 0)
        heights = [self._row_height(row, inner) for row in desc.rows]
        self.done_button = pygame.Rect(0, 0, int(w * 0.18), int(h * 0.065))
        self.done_button.midbottom = (w // 2, sc.legend_rect.top - 8)
        spare = self.done_button.top - self._line * 3 - y - sum(heights)
        gap = max(2, min(14, spare // max(1, len(heights))))
        self.tracks, self.options, self.rows = [], [], []
        for k in range(len(desc.rows)):
            frame = pygame.Rect(margin - PAD, y, w - 2 * margin + 2 * PAD, heights[k])
            self.rows.append(frame)
            self._row(desc, k, frame)
            y = frame.bottom + gap
        self._footer(desc, y)
        sc.legend(desc.legend)
        sc.flip()

    def _row(self, desc: FormScreen, k: int, frame: pygame.Rect) -> None:
        sc, row = self.screen, desc.rows[k]
        if k == desc.row:
            pygame.draw.rect(sc.surface, PANEL, frame, border_radius=6)
            pygame.draw.rect(sc.surface, HIGHLIGHT, frame, width=2, border_radius=6)
        inner = frame.inflate(-2 * PAD, -2 * PAD)
        y = sc.paragraph(row.label, inner, font="small") + 4
        widget = pygame.Rect(inner.left, y, inner.width, inner.bottom - y)
        self.tracks.append(None)
        self.options.append([])
        if row.kind == "slider":
            self.tracks[k] = self._slider(row, widget)
        elif row.kind == "number":
            self._number(desc, k, widget)
        else:
            self._choices(k, row, widget)

    def _chip(self, rect: pygame.Rect, lines: Sequence[str], on: bool) -> None:
        sc = self.screen
        pygame.draw.rect(sc.surface, HIGHLIGHT if on else PANEL, rect, border_radius=6)
        pygame.draw.rect(sc.surface, HIGHLIGHT if on else DIM, rect, width=1, border_radius=6)
        top = rect.centery - len(lines) * self._opt_line // 2
        for n, line in enumerate(lines):
            sc.text(line, (rect.centerx, top + n * self._opt_line), font="legend",
                    anchor="midtop", colour=BACKGROUND if on else TEXT)  # fmt: skip

    def _choices(self, k: int, row: FormRow, widget: pygame.Rect) -> None:
        n = len(row.options)
        width = (widget.width - GAP * (n - 1)) // n
        wrapped = self._option_lines(row, width)
        for i, lines in enumerate(wrapped):
            rect = pygame.Rect(widget.left + i * (width + GAP), widget.top, width, widget.height)
            self._chip(rect, lines, row.chosen == i)
            self.options[k].append(rect)

    def _number(self, desc: FormScreen, k: int, widget: pygame.Rect) -> None:
        sc, row = self.screen, desc.rows[k]
        box = pygame.Rect(widget.left, widget.top, max(90, widget.width // 10), widget.height)
        selected = k == desc.row
        pygame.draw.rect(sc.surface, BACKGROUND, box, border_radius=4)
        pygame.draw.rect(sc.surface, HIGHLIGHT if selected else DIM, box, width=2, border_radius=4)
        shown = row.typed + ("|" if selected else "")
        if shown:
            sc.text(shown, box.center, font="small", anchor="center")
        x = sc.text(row.unit, (box.right + 10, box.centery), font="small",
                    anchor="midleft").right + 24  # fmt: skip
        for label in row.options:  # "Prefer not to say"
            width = sc.fonts["legend"].size(label)[0] + 24
            rect = pygame.Rect(x, widget.top, width, widget.height)
            self._chip(rect, [label], row.declined)
            self.options[k].append(rect)
            x = rect.right + 24
        hint = row.problem or (desc.hint if selected else "")
        if hint:
            sc.text(hint, (x, box.centery), font="legend", anchor="midleft",
                    colour=HIGHLIGHT if row.problem else DIM)  # fmt: skip

    def _slider(self, row: FormRow, widget: pygame.Rect) -> pygame.Rect:
        sc = self.screen
        s = sc.surface
        left = widget.left + int(widget.width * 0.2)
        right = widget.right - int(widget.width * 0.2)
        cy = widget.centery
        track = pygame.Rect(left, cy - 7, right - left, 14)
        n = row.scale
        pygame.draw.line(s, TEXT, (left, cy), (right, cy), 2)
        if n <= 25:
            for i in range(n):
                x = left + (right - left) * i / max(1, n - 1)
                tall = 8 if i % 2 == 0 else 5
                pygame.draw.line(s, TEXT, (x, cy - tall), (x, cy + tall), 1)
        if row.anchors:
            sc.text(row.anchors[0], (left - 12, cy), font="small", anchor="midright")
            sc.text(row.anchors[1], (right + 12, cy), font="small", anchor="midleft")
        i = row.chosen
        if i is not None:  # the mark, without its number (a number could anchor ratings)
            x = left + (right - left) * i / max(1, n - 1)
            pygame.draw.circle(s, HIGHLIGHT, (int(x), cy), 9)
        return track

    def _footer(self, desc: FormScreen, y: int) -> None:
        sc = self.screen
        w = sc.width
        margin = int(w * 0.06)
        if desc.description:
            bottom = self.done_button.top - self._line - 8  # room for the reminder
            for line in sc.wrap(desc.description, w - 2 * margin, font="small"):
                if y + self._line > bottom:
                    break
                sc.text(line, (margin, y), font="small", colour=DIM)
                y += self._line
        active = desc.row == len(desc.rows)
        pygame.draw.rect(sc.surface, HIGHLIGHT if active else PANEL, self.done_button,
                         border_radius=8)  # fmt: skip
        sc.text("Done", self.done_button.center, anchor="center",
                colour=BACKGROUND if active else TEXT)  # fmt: skip
        if desc.reminder:
            sc.text(desc.reminder, (w // 2, self.done_button.top - 6), font="small",
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
    """One NASA-TLX pairwise comparison (:func:`study.ui.describe.pair_screen`): two
    subscales, choose the bigger contributor."""

    def __init__(
        self,
        screen: Screen,
        pair: tuple[str, str],
        k: int,
        n: int,
        controls: Controls | None = None,
    ) -> None:
        self.screen = screen
        self.pair = pair
        self.k, self.n = k, n
        self.controls = controls
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

    def draw(self) -> None:
        sc = self.screen
        desc = pair_screen(self.pair, self.k, self.n, self.highlight, self.controls)
        s = sc.surface
        s.fill(BACKGROUND)
        w, h = sc.width, sc.height
        sc.text(desc.question, (w // 2, int(h * 0.1)), font="large", anchor="center")
        sc.text(desc.progress, (w // 2, int(h * 0.17)), font="small", anchor="center", colour=DIM)
        self.buttons = []
        bottom = sc.legend_rect.top - 16
        for i in range(2):
            rect = pygame.Rect(0, 0, int(w * 0.4), min(int(h * 0.5), bottom - int(h * 0.24)))
            rect.midtop = (int(w * (0.28 + 0.44 * i)), int(h * 0.24))
            on = desc.highlight == i
            pygame.draw.rect(s, PANEL, rect, border_radius=10)
            pygame.draw.rect(
                s, HIGHLIGHT if on else DIM, rect, width=4 if on else 2, border_radius=10
            )
            sc.text(desc.titles[i], (rect.centerx, rect.top + 30), font="large", anchor="center")
            sc.paragraph(
                desc.texts[i], rect.inflate(-30, -90).move(0, 30), font="small", colour=DIM
            )
            self.buttons.append(rect)
        sc.legend(desc.legend)
        sc.flip()
