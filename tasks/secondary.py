"""The secondary task: judging shown answers to two-digit arithmetic questions (thesis
Sec. 7.6.1.2, 7.6.1.3 and footnote 30; spec section 7).

Whenever the robot enters the marked region, the participant does 20 consecutive
questions; each adds or subtracts two two-digit numbers and shows an answer that is
either correct or very close to the correct one; the participant presses Yes or No on
the gamepad. Answer time and correctness are recorded. Before the trials, a baseline
block of 40 questions without driving. Pure: the control loop calls
:meth:`SecondaryTask.update` once per tick and :meth:`SecondaryTask.answer` on a
button press; both return :class:`SecondaryEvent` values to record and display.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np

OPERAND_MIN = 10
OPERAND_MAX = 99
OPERATIONS: tuple[str, ...] = ("+", "-")
EVENT_KINDS: tuple[str, ...] = (
    "block_started",
    "question_shown",
    "answer_given",
    "question_timeout",
    "block_finished",
)
EventKind = Literal[
    "block_started", "question_shown", "answer_given", "question_timeout", "block_finished"
]
_EPS_S = 1e-9  # tolerance on time comparisons, against sums of float tick periods


@dataclass(frozen=True, slots=True)
class SecondarySettings:
    """Settings of the secondary task; change with ``dataclasses.replace``.

    Attributes
    ----------
    block_size : int
        Questions per entry into the region (thesis: 20).
    baseline_size : int
        Questions in the baseline block without driving (thesis: 40).
    p_correct : float
        Probability that the shown answer is the correct result.
    timeout_s : float
        Time [s] after which an unanswered question counts as a miss.
    gap_s : float
        Blank time [s] between an answer or timeout and the next question.
    near_miss_offsets : tuple of int
        Non-zero offsets of a wrong shown answer from the result, drawn uniformly.
    p_addition : float
        Probability that a question is an addition rather than a subtraction.
    """

    block_size: int = 20
    baseline_size: int = 40
    p_correct: float = 0.5
    timeout_s: float = 8.0
    gap_s: float = 0.5
    near_miss_offsets: tuple[int, ...] = (-10, -2, -1, 1, 2, 10)
    p_addition: float = 0.5

    def __post_init__(self) -> None:
        for name in ("block_size", "baseline_size"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise _bad(name, "must be an integer >= 1", value)
        for name in ("p_correct", "p_addition"):
            value = getattr(self, name)
            if not _is_real(value) or not 0.0 <= value <= 1.0:
                raise _bad(name, "must be a probability from 0 to 1", value)
        if not _is_finite(self.timeout_s) or self.timeout_s <= 0.0:
            raise _bad("timeout_s", "must be a positive number of seconds", self.timeout_s)
        if not _is_finite(self.gap_s) or self.gap_s < 0.0:
            raise _bad("gap_s", "must be zero or a positive number of seconds", self.gap_s)
        offsets = self.near_miss_offsets
        if (
            not isinstance(offsets, tuple)
            or not offsets
            or any(isinstance(o, bool) or not isinstance(o, int) or o == 0 for o in offsets)
            or len(set(offsets)) != len(offsets)
            or max(offsets) < 1
        ):
            raise _bad(
                "near_miss_offsets",
                "must be a tuple of distinct non-zero integers with at least one positive",
                offsets,
            )


@dataclass(frozen=True, slots=True)
class ArithmeticQuestion:
    """One question: ``a op b = shown ?``.

    Attributes
    ----------
    a, b : int
        Two-digit operands, 10..99; ``a >= b`` for subtraction.
    op : {"+", "-"}
    result : int
        The correct result, ``a + b`` or ``a - b`` (never negative).
    shown : int
        The answer shown to the participant (never negative).
    """

    a: int
    b: int
    op: str
    result: int
    shown: int

    def __post_init__(self) -> None:
        if self.op not in OPERATIONS:
            raise ValueError(f"ArithmeticQuestion.op: must be '+' or '-', got {self.op!r}")
        for name in ("a", "b"):
            value = getattr(self, name)
            if not OPERAND_MIN <= value <= OPERAND_MAX:
                raise ValueError(
                    f"ArithmeticQuestion.{name}: must be a two-digit number "
                    f"{OPERAND_MIN}..{OPERAND_MAX}, got {value!r}"
                )
        if self.op == "-" and self.a < self.b:
            raise ValueError(f"ArithmeticQuestion: subtraction needs a >= b, got {self.text!r}")
        expected = self.a + self.b if self.op == "+" else self.a - self.b
        if self.result != expected:
            raise ValueError(
                f"ArithmeticQuestion.result: {self.a} {self.op} {self.b} is {expected}, "
                f"got {self.result!r}"
            )
        if self.shown < 0:
            raise ValueError(f"ArithmeticQuestion.shown: must be >= 0, got {self.shown!r}")

    @property
    def shown_is_correct(self) -> bool:
        """Whether the shown answer is the correct result (the right response is Yes)."""
        return self.shown == self.result

    @property
    def text(self) -> str:
        """As displayed: ``"47 + 38 = 85 ?"``."""
        return f"{self.a} {self.op} {self.b} = {self.shown} ?"


@dataclass(frozen=True, slots=True)
class SecondaryEvent:
    """Something that happened in the secondary task, for recording and display.

    Attributes
    ----------
    kind : str
        One of :data:`EVENT_KINDS`.
    t : float
        Simulated time [s].
    block_index : int
        0-based index of the block in this task (a baseline task has block 0 only).
    question_index : int or None
        0-based index of the question within its block; None for block events.
    question : ArithmeticQuestion or None
        The question concerned; None for block events.
    response : bool or None
        ``answer_given``: True if the participant said the shown answer is correct.
    correct : bool or None
        ``answer_given``: whether the response was right.
    answer_time_s : float or None
        ``answer_given``: time [s] from the question appearing to the answer.
    """

    kind: EventKind
    t: float
    block_index: int
    question_index: int | None = None
    question: ArithmeticQuestion | None = None
    response: bool | None = None
    correct: bool | None = None
    answer_time_s: float | None = None


def make_question(
    rng: np.random.Generator, *, settings: SecondarySettings | None = None
) -> ArithmeticQuestion:
    """Draw one question (see the module docstring for the distribution).

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness.
    settings : SecondarySettings, optional
        Defaults to ``SecondarySettings()``.

    Returns
    -------
    ArithmeticQuestion
    """
    s = settings if settings is not None else SecondarySettings()
    n_operands = OPERAND_MAX - OPERAND_MIN + 1
    if rng.random() < s.p_addition:
        op = "+"
        a, b = (int(x) for x in rng.integers(OPERAND_MIN, OPERAND_MAX + 1, size=2))
        result = a + b
    else:
        op = "-"
        x, y = (int(v) + OPERAND_MIN for v in rng.choice(n_operands, size=2, replace=False))
        a, b = max(x, y), min(x, y)  # a > b: the result is positive
        result = a - b
    if rng.random() < s.p_correct:
        shown = result
    else:
        # "Very close to the correct one" (thesis footnote 30); never negative.
        admissible = [o for o in s.near_miss_offsets if result + o >= 0]
        shown = result + admissible[int(rng.integers(len(admissible)))]
    return ArithmeticQuestion(a=a, b=b, op=op, result=result, shown=shown)


class SecondaryTask:
    """The secondary-task state machine of one trial (or of the baseline).

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the questions; the question sequence depends on the generator only,
        not on the timing of ticks and answers.
    settings : SecondarySettings, optional
        Defaults to ``SecondarySettings()``.
    region_triggered : bool
        Whether entries into the region start blocks (False for the baseline).
    first_block : int
        Questions of a block that starts at the first :meth:`update` wherever the robot
        is (0: none); entries into the region start blocks after it as usual (training's
        rehearsal, issue 19).

    Notes
    -----
    Call :meth:`update` once per control tick with non-decreasing ``t`` and
    :meth:`answer` when the participant presses Yes or No. A baseline task
    (:meth:`baseline`) starts its block at its first ``update`` and is over when
    an ``update`` returns its ``block_finished`` event.
    """

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        settings: SecondarySettings | None = None,
        region_triggered: bool = True,
        first_block: int = 0,
    ) -> None:
        self.settings = settings if settings is not None else SecondarySettings()
        self.region_triggered = region_triggered
        if isinstance(first_block, bool) or not isinstance(first_block, int) or first_block < 0:
            raise ValueError(
                f"SecondaryTask.first_block: must be an integer >= 0, got {first_block!r}"
            )
        self._rng = rng
        self._t_last = -math.inf
        self._was_in_region = False
        # a block to start at the next update
        self._pending_block_size: int | None = first_block or None
        self._block_index = -1
        self._block_size = 0
        self._block_active = False
        self._n_shown_in_block = 0
        self._current: ArithmeticQuestion | None = None
        self._current_index = -1
        self._shown_t = math.nan
        self._next_due_t = math.nan
        self._finished_t: float | None = None  # block end not yet reported
        self._blocks_finished = 0
        self._n_shown = 0
        self._n_answered = 0
        self._n_correct = 0
        self._n_timeouts = 0

    @classmethod
    def baseline(
        cls, rng: np.random.Generator, *, settings: SecondarySettings | None = None
    ) -> SecondaryTask:
        """A task whose single block of ``baseline_size`` questions starts at once.

        The block starts at the first :meth:`update` (its ``in_region`` is ignored).
        """
        task = cls(rng, settings=settings, region_triggered=False)
        task._pending_block_size = task.settings.baseline_size
        return task

    # -- state ------------------------------------------------------------------------

    @property
    def current(self) -> ArithmeticQuestion | None:
        """The question on screen, or None."""
        return self._current

    @property
    def answered(self) -> int:
        """Questions answered (not timed out) so far, over all blocks."""
        return self._n_answered

    @property
    def correct(self) -> int:
        """Questions answered correctly so far."""
        return self._n_correct

    @property
    def timeouts(self) -> int:
        """Questions that timed out so far."""
        return self._n_timeouts

    @property
    def shown(self) -> int:
        """Questions shown so far."""
        return self._n_shown

    @property
    def block_active(self) -> bool:
        """Whether a block is running (from its start until its last question ends)."""
        return self._block_active

    @property
    def block_index(self) -> int:
        """0-based index of the current or last block; -1 before the first."""
        return self._block_index

    @property
    def blocks_finished(self) -> int:
        """Blocks whose last question has been answered or timed out."""
        return self._blocks_finished

    @property
    def questions_left(self) -> int:
        """Questions of the running block not yet shown (0 without a block)."""
        return self._block_size - self._n_shown_in_block if self._block_active else 0

    # -- driving ----------------------------------------------------------------------

    def update(self, t: float, in_region: bool) -> list[SecondaryEvent]:
        """Advance to time ``t`` [s]: time out, start blocks, show questions.

        Parameters
        ----------
        t : float
            Simulated time [s], not less than that of any earlier call.
        in_region : bool
            Whether the robot is inside the question region at ``t``.

        Returns
        -------
        list of SecondaryEvent
            In the order they happened (possibly empty).
        """
        self._advance(t)
        events: list[SecondaryEvent] = []
        self._report_finish(events)
        if self._current is not None and t - self._shown_t >= self.settings.timeout_s - _EPS_S:
            events.append(self._event("question_timeout", t))
            self._n_timeouts += 1
            self._resolve(t)
            self._report_finish(events)

        entered = bool(in_region) and not self._was_in_region
        self._was_in_region = bool(in_region)
        size = self._pending_block_size
        if size is None and entered and self.region_triggered and not self._block_active:
            size = self.settings.block_size
        if size is not None:
            self._pending_block_size = None
            self._block_index += 1
            self._block_size = size
            self._block_active = True
            self._n_shown_in_block = 0
            self._next_due_t = t
            events.append(
                SecondaryEvent("block_started", t=float(t), block_index=self._block_index)
            )

        if (
            self._block_active
            and self._current is None
            and self._n_shown_in_block < self._block_size
            and t >= self._next_due_t - _EPS_S
        ):
            self._current = make_question(self._rng, settings=self.settings)
            self._current_index = self._n_shown_in_block
            self._n_shown_in_block += 1
            self._n_shown += 1
            self._shown_t = t
            events.append(self._event("question_shown", t))
        return events

    def answer(self, t: float, says_correct: bool) -> SecondaryEvent | None:
        """The participant pressed Yes (``says_correct``) or No at time ``t`` [s].

        Returns
        -------
        SecondaryEvent or None
            The ``answer_given`` event, or None (and nothing changes) if no
            question is on screen.
        """
        self._advance(t)
        if self._current is None:
            return None
        response = bool(says_correct)
        right = response == self._current.shown_is_correct
        event = self._event(
            "answer_given",
            t,
            response=response,
            correct=right,
            answer_time_s=t - self._shown_t,
        )
        self._n_answered += 1
        self._n_correct += int(right)
        self._resolve(t)
        return event

    # -- internals --------------------------------------------------------------------

    def _advance(self, t: float) -> None:
        if not _is_finite(t):
            raise ValueError(f"SecondaryTask: t must be a finite time in seconds, got {t!r}")
        if t < self._t_last - _EPS_S:
            raise ValueError(f"SecondaryTask: time went backwards, from {self._t_last} s to {t} s")
        self._t_last = max(self._t_last, float(t))

    def _resolve(self, t: float) -> None:
        """The question on screen was answered or timed out at ``t``."""
        self._current = None
        if self._n_shown_in_block >= self._block_size:
            self._block_active = False
            self._blocks_finished += 1
            self._finished_t = t
        else:
            self._next_due_t = t + self.settings.gap_s

    def _report_finish(self, events: list[SecondaryEvent]) -> None:
        if self._finished_t is not None:
            events.append(
                SecondaryEvent("block_finished", t=self._finished_t, block_index=self._block_index)
            )
            self._finished_t = None

    def _event(self, kind: EventKind, t: float, **fields: object) -> SecondaryEvent:
        return SecondaryEvent(
            kind,
            t=float(t),
            block_index=self._block_index,
            question_index=self._current_index,
            question=self._current,
            **fields,  # type: ignore[arg-type]
        )


def summarise(events: Iterable[SecondaryEvent]) -> dict:
    """Secondary-task metrics of one trial or baseline (thesis Fig. 7.51).

    Parameters
    ----------
    events : iterable of SecondaryEvent
        The events of one task, e.g. everything its ``update``/``answer`` returned.

    Returns
    -------
    dict
        ``blocks`` (started), ``shown``, ``answered``, ``correct``, ``wrong``,
        ``timeouts``, ``errors`` (= wrong + timeouts, the thesis's "number of
        errors"), ``unresolved`` (shown but neither answered nor timed out, e.g.
        the trial ended), ``mean_answer_time_s`` and ``median_answer_time_s``
        over answered questions [s] (None if none was answered).
    """
    counts = dict.fromkeys(EVENT_KINDS, 0)
    times: list[float] = []
    n_correct = 0
    for event in events:
        if event.kind not in counts:
            raise ValueError(f"summarise: unknown event kind {event.kind!r}")
        counts[event.kind] += 1
        if event.kind == "answer_given":
            times.append(float(event.answer_time_s))  # type: ignore[arg-type]
            n_correct += bool(event.correct)
    answered = counts["answer_given"]
    timeouts = counts["question_timeout"]
    wrong = answered - n_correct
    return {
        "blocks": counts["block_started"],
        "shown": counts["question_shown"],
        "answered": answered,
        "correct": n_correct,
        "wrong": wrong,
        "timeouts": timeouts,
        "errors": wrong + timeouts,
        "unresolved": counts["question_shown"] - answered - timeouts,
        "mean_answer_time_s": statistics.fmean(times) if times else None,
        "median_answer_time_s": float(statistics.median(times)) if times else None,
    }


def _is_real(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _is_finite(value: object) -> bool:
    return _is_real(value) and math.isfinite(value)  # type: ignore[arg-type]


def _bad(field: str, message: str, value: object) -> ValueError:
    return ValueError(f"SecondarySettings.{field}: {message}, got {value!r}")
