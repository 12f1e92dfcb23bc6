"""Generic questionnaire items and instruments, shared by every instrument.

An :class:`Instrument` is an ordered tuple of :class:`Item` s. Each item carries everything
a screen needs to render it without knowing the instrument (the question text, a short
title, the kind of widget, the allowed values with their display labels, the endpoint
anchors) and everything needed to validate an answer. The participant's screen renders any
instrument generically; the synthetic participant answers it from the same description;
storage keeps one ``(instrument, item, value)`` row per answer (DESIGN.md, "Data").
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

ItemKind = Literal["slider", "likert", "choice", "number"]
ITEM_KINDS: tuple[str, ...] = ("slider", "likert", "choice", "number")

DECLINE = "prefer_not_to_say"
"""The answer code for "Prefer not to say" on items with ``can_decline``."""
DECLINE_LABEL = "Prefer not to say"

Answer = int | str | None


@dataclass(frozen=True, slots=True)
class Item:
    """One question of an instrument: what to show and what to accept.

    Attributes
    ----------
    id : str
        Stable identifier, stored with every answer (``"mental"``, ``"age"``).
    text : str
        The question as shown to the participant.
    kind : {"slider", "likert", "choice", "number"}
        The widget. ``"slider"``: an integer scale with tick marks ``values`` (e.g.
        NASA-TLX: 0, 5, ..., 100) and two endpoint ``anchors`` (low, high). ``"likert"``:
        a few ordered integer points ``values`` (e.g. 1..5), each with a display label in
        ``labels``; ``anchors`` repeat the two end labels. ``"choice"``: one of a set of
        unordered string codes ``values`` with display ``labels``. ``"number"``: a whole
        number from ``minimum`` to ``maximum`` (e.g. age in years).
    values : tuple
        Allowed answers, in display order: ints for slider and likert, string
        codes for choice, empty for number.
    labels : tuple of str
        Display label of each value (same length as ``values``), or empty when
        the value itself is the label (slider ticks).
    anchors : tuple of str, optional
        ``(low, high)`` labels at the two ends of a slider or likert scale.
    title : str
        Short heading (``"Mental Demand"``); empty if the text suffices.
    description : str
        Longer explanation the screen may show on request.
    minimum, maximum : int, optional
        Inclusive range of a number item.
    unit : str
        Unit shown beside a number item (``"years"``).
    optional : bool
        Whether the item may be left unanswered.
    can_decline : bool
        Whether :data:`DECLINE` ("Prefer not to say") is a valid answer.
    """

    id: str
    text: str
    kind: ItemKind
    values: tuple[int | str, ...] = ()
    labels: tuple[str, ...] = ()
    anchors: tuple[str, str] | None = None
    title: str = ""
    description: str = ""
    minimum: int | None = None
    maximum: int | None = None
    unit: str = ""
    optional: bool = False
    can_decline: bool = False

    def __post_init__(self) -> None:
        # Definitions are code, not user input, but a malformed one must fail at import.
        where = f"Item {self.id!r}"
        if self.kind not in ITEM_KINDS:
            raise ValueError(f"{where}: kind must be one of {ITEM_KINDS}, got {self.kind!r}")
        if self.labels and len(self.labels) != len(self.values):
            raise ValueError(f"{where}: needs one label per value")
        if self.kind == "number":
            if self.minimum is None or self.maximum is None or self.minimum > self.maximum:
                raise ValueError(f"{where}: a number item needs minimum <= maximum")
        else:
            if not self.values:
                raise ValueError(f"{where}: a {self.kind} item needs values")
            want = str if self.kind == "choice" else int
            if not all(isinstance(v, want) and not isinstance(v, bool) for v in self.values):
                raise ValueError(f"{where}: {self.kind} values must be {want.__name__}s")
            if len(set(self.values)) != len(self.values):
                raise ValueError(f"{where}: values must be distinct")

    @property
    def choices(self) -> tuple[tuple[int | str, str], ...]:
        """``(value, label)`` pairs in display order, plus the decline option if allowed."""
        labels = self.labels or tuple(str(v) for v in self.values)
        pairs = tuple(zip(self.values, labels, strict=True))
        return pairs + (((DECLINE, DECLINE_LABEL),) if self.can_decline else ())

    def allowed(self) -> str:
        """What this item accepts, in words, for error messages."""
        if self.kind == "number":
            text = f"a whole number from {self.minimum} to {self.maximum}"
        elif self.kind == "slider" and _is_even_grid(self.values):
            lo, hi = self.values[0], self.values[-1]
            step = self.values[1] - self.values[0]
            text = f"a multiple of {step} from {lo} to {hi}"
        elif self.kind == "choice":
            text = "one of " + ", ".join(repr(v) for v in self.values)
        else:
            text = "one of " + ", ".join(str(v) for v in self.values)
        if self.can_decline:
            text += f", or {DECLINE!r}"
        if self.optional:
            text += ", or nothing"
        return text

    def validate(self, value: object, *, source: str = "answers", noun: str = "item") -> Answer:
        """Check one answer and return it normalised.

        Parameters
        ----------
        value : object
            The raw answer (``None`` for unanswered).
        source : str
            Named first in the error message (a file name, or the instrument id).
        noun : str
            What the message calls the item (``"subscale"`` for NASA-TLX).

        Returns
        -------
        int, str or None
            ``int`` for slider/likert/number, the code for choice, :data:`DECLINE`
            if declined, ``None`` if an optional item was left unanswered.

        Raises
        ------
        ValueError
            If the answer is not allowed; the message names ``source``, the item
            and what is allowed.
        """
        if value is None or (isinstance(value, float) and math.isnan(value)):
            if self.optional:
                return None
            raise self._fail(source, noun, "is required", value)
        if self.can_decline and value == DECLINE:
            return DECLINE
        if self.kind == "choice":
            if isinstance(value, str) and value in self.values:
                return value
            raise self._fail(source, noun, f"must be {self.allowed()}", value)
        number = _whole_number(value)
        if number is None:
            raise self._fail(source, noun, f"must be {self.allowed()}", value)
        if self.kind == "number":
            ok = self.minimum <= number <= self.maximum  # type: ignore[operator]
        else:
            ok = number in self.values
        if not ok:
            raise self._fail(source, noun, f"must be {self.allowed()}", value)
        return number

    def _fail(self, source: str, noun: str, message: str, value: object) -> ValueError:
        return ValueError(f"{source}: {noun} '{self.id}': {message}, got {value!r}")


@dataclass(frozen=True, slots=True)
class Instrument:
    """An ordered questionnaire: an id, a title, instructions and its items.

    Attributes
    ----------
    id : str
        Stored with every answer (``"nasa_tlx"``, ``"experience"``).
    title : str
        Heading shown to the participant.
    instructions : str
        Shown above the items.
    items : tuple of Item
        In presentation order; ids are unique.
    """

    id: str
    title: str
    instructions: str
    items: tuple[Item, ...]

    def __post_init__(self) -> None:
        ids = [item.id for item in self.items]
        if len(set(ids)) != len(ids):
            raise ValueError(f"Instrument {self.id!r}: item ids must be unique, got {ids}")

    @property
    def ids(self) -> tuple[str, ...]:
        """Item ids in presentation order."""
        return tuple(item.id for item in self.items)

    def item(self, item_id: str) -> Item:
        """The item with this id (``KeyError`` if there is none)."""
        for item in self.items:
            if item.id == item_id:
                return item
        raise KeyError(item_id)

    def validate(
        self, answers: Mapping[str, object], *, source: str | None = None, noun: str = "item"
    ) -> dict:
        """Check a full set of answers; return them normalised, in item order.

        Parameters
        ----------
        answers : Mapping[str, object]
            Item id -> raw answer. Optional items may be missing.
        source : str, optional
            Named first in error messages; defaults to the instrument id.
        noun : str
            What error messages call an item.

        Returns
        -------
        dict
            Item id -> normalised answer (see :meth:`Item.validate`) for every item.

        Raises
        ------
        ValueError
            On an unknown item id, a missing required item, or a value not allowed.
        """
        where = source or self.id
        if not isinstance(answers, Mapping):
            raise ValueError(f"{where}: answers must be a mapping of item id to value")
        unknown = [key for key in answers if key not in self.ids]
        if unknown:
            raise ValueError(
                f"{where}: unknown {noun} {unknown[0]!r}; allowed: {', '.join(self.ids)}"
            )
        return {
            item.id: item.validate(answers.get(item.id), source=where, noun=noun)
            for item in self.items
        }


def _whole_number(value: object) -> int | None:
    """``value`` as an int if it is a whole real number (not a bool), else ``None``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    if isinstance(value, numbers.Integral):
        return int(value)
    as_float = float(value)
    if not math.isfinite(as_float) or not as_float.is_integer():
        return None
    return int(as_float)


def _is_even_grid(values: tuple[int | str, ...]) -> bool:
    if len(values) < 2 or not all(isinstance(v, int) for v in values):
        return False
    step = values[1] - values[0]  # type: ignore[operator]
    return step > 0 and all(b - a == step for a, b in zip(values, values[1:], strict=False))
