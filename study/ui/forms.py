"""Questionnaires on the participant's screen (issue 5, "Questionnaires on screen"; issue 19:
quick to fill): where a participant is in a questionnaire page, without drawing
(:class:`FormState`); :mod:`study.ui.form_view` draws it. How rows, typed numbers, choices,
sliders and the reminder behave: docs/decisions.md, "study/ui/forms.py".
"""

from __future__ import annotations

from questionnaires.base import DECLINE, DECLINE_LABEL, Instrument, Item

MISSING = "Please answer every question before you continue."


def options(item: Item) -> list[tuple[object, str]]:
    """``(value, label)`` of every option of ``item``, in display order (a number item:
    only "Prefer not to say", if it may be declined)."""
    if item.kind == "number":
        return [(DECLINE, DECLINE_LABEL)] if item.can_decline else []
    return [(v, label) for v, label in item.choices]


class FormState:
    """Where the participant is in a questionnaire page (no drawing)."""

    def __init__(self, instrument: Instrument) -> None:
        self.instrument = instrument
        self.items = instrument.items
        self.options = [options(item) for item in self.items]
        n = len(self.items)
        self.index: list[int | None] = [None] * n  # option items: the chosen option
        self.typed = [""] * n  # number items: the digits typed
        self.declined = [False] * n  # number items: "Prefer not to say"
        self.row = 0  # selected row; len(items) is the Done row
        self.done = False
        self._tried = False  # "Done" was pressed while something was missing
        self._fresh = True  # the next digit starts a new number

    @property
    def done_row(self) -> int:
        return len(self.items)

    def start_index(self, row: int) -> int:
        """The option selected by the first step on an unanswered row: the first of a
        choice, the middle of a scale."""
        if self.items[row].kind == "choice":
            return 0
        n = sum(1 for value, _ in self.options[row] if value != DECLINE)
        return (n - 1) // 2

    # -------------------------------------------------------------- answers

    def value(self, row: int) -> object | None:
        """The answer at ``row``: None when unanswered or a typed number is out of range."""
        item = self.items[row]
        if item.kind != "number":
            i = self.index[row]
            return None if i is None else self.options[row][i][0]
        if self.declined[row]:
            return DECLINE
        if not self.typed[row]:
            return None
        number = int(self.typed[row])
        return number if item.minimum <= number <= item.maximum else None  # type: ignore[operator]

    def problem(self, row: int) -> str:
        """Why the typed number at ``row`` is refused ("" if it is not)."""
        item = self.items[row]
        if item.kind != "number" or not self.typed[row] or self.value(row) is not None:
            return ""
        return f"{item.title or 'Please'}: enter a number from {item.minimum} to {item.maximum}."

    def missing(self) -> list[int]:
        """Rows that block "Done": required and unanswered, or a number out of range."""
        return [
            i
            for i, item in enumerate(self.items)
            if (self.value(i) is None and not item.optional) or self.problem(i)
        ]

    @property
    def reminder(self) -> str:
        """What still blocks "Done", once "Done" was tried; "" when nothing does."""
        missing = self.missing() if self._tried else []
        if not missing:
            return ""
        return self.problem(missing[0]) or MISSING

    def answers(self) -> dict[str, object]:
        """Item id -> value (None for an optional item left unanswered)."""
        return {item.id: self.value(k) for k, item in enumerate(self.items)}

    # -------------------------------------------------------------- input

    def action(self, name: str) -> None:
        """Apply one input action (``up``, ``down``, ``left``, ``right``, ``confirm``/``yes``)."""
        if name == "up":
            self.select(max(0, self.row - 1))
        elif name == "down":
            self.select(min(self.done_row, self.row + 1))
        elif name in ("left", "right") and self.row < self.done_row:
            step = 1 if name == "right" else -1
            if self.items[self.row].kind == "number":
                self._step_number(self.row, step)
            else:
                self._step_option(self.row, step)
        elif name in ("confirm", "yes"):
            if self.row < self.done_row:
                self.select(self.row + 1)
            else:
                self.finish()

    def select(self, row: int) -> None:
        """Move the selection to ``row``."""
        self.row = row
        self._fresh = True

    def type_digit(self, digit: str) -> None:
        """A digit typed on the selected row (ignored on other rows and past the longest
        number the item allows)."""
        if self.row >= self.done_row or self.items[self.row].kind != "number":
            return
        item, k = self.items[self.row], self.row
        if self._fresh:
            self.typed[k], self._fresh = "", False
        if len(self.typed[k]) < len(str(item.maximum)):
            self.typed[k] = (self.typed[k] + digit).lstrip("0") or "0"
        self.declined[k] = False

    def backspace(self) -> None:
        """Delete the last digit typed on the selected row (or a "Prefer not to say")."""
        if self.row < self.done_row and self.items[self.row].kind == "number":
            self.typed[self.row] = self.typed[self.row][:-1]
            self.declined[self.row] = False
            self._fresh = False

    def choose(self, row: int, index: int) -> None:
        """Option ``index`` of ``row`` chosen directly (a click)."""
        self.select(row)
        if self.items[row].kind == "number":
            self.declined[row], self.typed[row] = True, ""
        else:
            self.index[row] = index

    def set_fraction(self, row: int, fraction: float) -> None:
        """A click at ``fraction`` (0..1) along the row's track (its scale without the
        decline option)."""
        n = sum(1 for value, _ in self.options[row] if value != DECLINE)
        self.index[row] = min(n - 1, max(0, round(fraction * (n - 1))))
        self.select(row)

    def finish(self) -> None:
        """ "Done": finished, or the selection on the first row that blocks it."""
        missing = self.missing()
        if missing:
            self._tried = True
            self.select(missing[0])
        else:
            self.done = True

    def _step_option(self, row: int, step: int) -> None:
        current = self.index[row]
        if current is None:
            self.index[row] = self.start_index(row)
        else:
            self.index[row] = min(len(self.options[row]) - 1, max(0, current + step))

    def _step_number(self, row: int, step: int) -> None:
        item = self.items[row]
        lo, hi = item.minimum, item.maximum
        assert lo is not None and hi is not None  # checked by Item
        self._fresh = True
        if self.declined[row]:
            if step > 0:
                self.declined[row], self.typed[row] = False, str(lo)
            return
        if not self.typed[row]:
            below = step < 0 and item.can_decline
            self.declined[row], self.typed[row] = below, "" if below else str(lo)
            return
        number = int(self.typed[row]) + step
        if number < lo and step < 0 and item.can_decline and int(self.typed[row]) <= lo:
            self.declined[row], self.typed[row] = True, ""
        else:
            self.typed[row] = str(min(hi, max(lo, number)))
