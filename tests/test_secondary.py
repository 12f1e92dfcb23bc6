"""The secondary arithmetic task: questions, the block state machine, the summary."""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Callable, Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tasks.secondary import (
    ArithmeticQuestion,
    SecondaryEvent,
    SecondarySettings,
    SecondaryTask,
    make_question,
    summarise,
)

DT = 0.05  # [s], the 20 Hz control tick
S = SecondarySettings()


def drive(
    task: SecondaryTask,
    region: Sequence[bool],
    rng: np.random.Generator,
    *,
    delay: Callable[[np.random.Generator], float] = lambda r: float(r.uniform(0.2, 10.0)),
    p_right: float = 0.8,
    t0: float = 0.0,
) -> list[SecondaryEvent]:
    """Tick a task through ``region`` (one flag per tick) with a scripted participant.

    The participant answers each question after ``delay`` seconds (beyond the
    timeout it never does) and is right with probability ``p_right``. As in the
    control loop, the participant acts before the task updates. Tick k is at
    ``t0 + k * DT``.
    """
    events: list[SecondaryEvent] = []
    due_t: float | None = None
    for k, inside in enumerate(region):
        t = t0 + k * DT
        if due_t is not None and t >= due_t and task.current is not None:
            right = rng.random() < p_right
            says = task.current.shown_is_correct if right else not task.current.shown_is_correct
            events.append(task.answer(t, says))
            due_t = None
        new = task.update(t, inside)
        events += new
        if any(e.kind == "question_shown" for e in new):
            due_t = t + delay(rng)
    return events


def kinds(events: Sequence[SecondaryEvent], kind: str) -> list[SecondaryEvent]:
    return [e for e in events if e.kind == kind]


def region_run(*runs: tuple[bool, float]) -> list[bool]:
    """``(inside, seconds)`` runs -> one flag per tick."""
    return [inside for inside, seconds in runs for _ in range(round(seconds / DT))]


def check_block_structure(events: Sequence[SecondaryEvent], size: int) -> None:
    """Each block: started, ``size`` questions each resolved once before the next, finished."""
    assert all(a.t <= b.t + 1e-9 for a, b in zip(events, events[1:], strict=False))
    by_block: dict[int, list[SecondaryEvent]] = {}
    for e in events:
        by_block.setdefault(e.block_index, []).append(e)
    assert sorted(by_block) == list(range(len(by_block)))
    for block in by_block.values():
        assert block[0].kind == "block_started" and block[-1].kind == "block_finished"
        body = block[1:-1]
        assert len(body) == 2 * size
        for i in range(size):
            shown, resolved = body[2 * i], body[2 * i + 1]
            assert shown.kind == "question_shown" and shown.question_index == i
            assert resolved.kind in ("answer_given", "question_timeout")
            assert resolved.question == shown.question and resolved.question_index == i
        assert block[-1].t == body[-1].t  # the block ends with its last question


# -- questions ----------------------------------------------------------------------------


def test_questions_are_well_formed(rng: np.random.Generator) -> None:
    offsets = set(S.near_miss_offsets)
    for _ in range(3000):
        q = make_question(rng, settings=S)
        assert 10 <= q.a <= 99 and 10 <= q.b <= 99 and q.op in ("+", "-")
        assert q.result == (q.a + q.b if q.op == "+" else q.a - q.b)
        assert q.result >= 0 and q.shown >= 0
        if q.op == "-":
            assert q.a > q.b
        assert q.shown_is_correct == (q.shown == q.result)
        if not q.shown_is_correct:
            assert q.shown - q.result in offsets
        assert q.text == f"{q.a} {q.op} {q.b} = {q.shown} ?"


@pytest.mark.parametrize("p_correct", [0.5, 0.2, 0.9])
def test_share_of_correct_answers_matches_p_correct(rng: np.random.Generator, p_correct) -> None:
    n = 4000
    s = dataclasses.replace(S, p_correct=p_correct)
    questions = [make_question(rng, settings=s) for _ in range(n)]
    share = np.mean([q.shown_is_correct for q in questions])
    share_add = np.mean([q.op == "+" for q in questions])
    tolerance = 5.0 * math.sqrt(p_correct * (1 - p_correct) / n)  # binomial, 5 sigma
    assert abs(share - p_correct) < tolerance
    assert abs(share_add - 0.5) < 5.0 * math.sqrt(0.25 / n)


def test_extreme_probabilities(rng: np.random.Generator) -> None:
    always = dataclasses.replace(S, p_correct=1.0, p_addition=0.0)
    never = dataclasses.replace(S, p_correct=0.0, p_addition=1.0)
    assert all(
        q.shown_is_correct and q.op == "-"
        for q in (make_question(rng, settings=always) for _ in range(200))
    )
    assert all(
        not q.shown_is_correct and q.op == "+"
        for q in (make_question(rng, settings=never) for _ in range(200))
    )


def test_wrong_answers_use_the_configured_offsets_and_stay_non_negative(
    rng: np.random.Generator,
) -> None:
    s = dataclasses.replace(S, p_correct=0.0, p_addition=0.0, near_miss_offsets=(-50, 3))
    for _ in range(1000):
        q = make_question(rng, settings=s)
        assert q.shown - q.result in (-50, 3) and q.shown >= 0
        if q.result < 50:
            assert q.shown - q.result == 3


def test_questions_are_deterministic_given_the_seed(seed: int) -> None:
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    assert [make_question(a) for _ in range(50)] == [make_question(b) for _ in range(50)]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("block_size", 0),
        ("baseline_size", 2.5),
        ("p_correct", 1.5),
        ("p_addition", float("nan")),
        ("timeout_s", 0.0),
        ("timeout_s", float("nan")),
        ("gap_s", -0.1),
        ("near_miss_offsets", (0, 1)),
        ("near_miss_offsets", (-1, -2)),
        ("near_miss_offsets", [1, 2]),
    ],
)
def test_bad_settings_name_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"SecondarySettings.{field}"):
        dataclasses.replace(S, **{field: value})


def test_inconsistent_question_is_refused() -> None:
    assert ArithmeticQuestion(47, 38, "+", 85, 85).text == "47 + 38 = 85 ?"
    with pytest.raises(ValueError, match="result"):
        ArithmeticQuestion(47, 38, "+", 84, 84)
    with pytest.raises(ValueError, match="a >= b"):
        ArithmeticQuestion(38, 47, "-", -9, -9)
    with pytest.raises(ValueError, match="two-digit"):
        ArithmeticQuestion(7, 38, "+", 45, 45)


# -- the state machine --------------------------------------------------------------------


def test_entering_the_region_gives_one_block_of_block_size(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng)
    region = region_run((False, 2.0), (True, 400.0))
    events = drive(task, region, rng)
    check_block_structure(events, S.block_size)
    assert len(kinds(events, "block_started")) == 1
    assert events[0].t == pytest.approx(2.0)  # the first question appears on entry
    assert task.shown == 20 and task.answered + task.timeouts == 20
    assert not task.block_active and task.current is None and task.blocks_finished == 1
    # The next question appears gap_s after the previous one was answered or timed out.
    shown = kinds(events, "question_shown")
    resolved = [e for e in events if e.kind in ("answer_given", "question_timeout")]
    for prev, nxt in zip(resolved, shown[1:], strict=False):
        assert S.gap_s - 1e-9 <= nxt.t - prev.t < S.gap_s + DT


def test_timeouts_replace_unanswered_questions(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng)
    events = drive(task, region_run((True, 300.0)), rng, delay=lambda r: math.inf)
    check_block_structure(events, S.block_size)
    shown = kinds(events, "question_shown")
    timeouts = kinds(events, "question_timeout")
    assert len(timeouts) == 20 and task.answered == 0
    for s, t in zip(shown, timeouts, strict=True):
        assert S.timeout_s - 1e-9 <= t.t - s.t < S.timeout_s + DT
    assert summarise(events)["errors"] == 20


def test_leaving_mid_block_does_not_stop_it_and_flicker_starts_no_second_block(
    rng: np.random.Generator,
) -> None:
    flicker = [bool(x) for x in rng.random(round(30.0 / DT)) < 0.5]
    region = region_run((False, 1.0), (True, 3.0)) + flicker + region_run((False, 400.0))
    task = SecondaryTask(rng)
    events = drive(task, region, rng)
    check_block_structure(events, S.block_size)
    assert len(kinds(events, "block_started")) == 1 and task.blocks_finished == 1
    assert len(kinds(events, "question_shown")) == 20


def test_staying_inside_after_a_block_starts_no_new_block(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng)
    events = drive(task, region_run((True, 600.0)), rng)
    assert len(kinds(events, "block_started")) == 1


def test_a_new_entry_after_the_block_ended_starts_a_new_block(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng)
    region = region_run((True, 1.0), (False, 250.0), (True, 1.0), (False, 250.0))
    events = drive(task, region, rng)
    check_block_structure(events, S.block_size)
    started = kinds(events, "block_started")
    assert [e.block_index for e in started] == [0, 1]
    assert started[1].t == pytest.approx(251.0)
    assert task.shown == 40 and task.blocks_finished == 2


def test_answer_times_are_answer_minus_shown_time(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng)
    events = drive(task, region_run((True, 300.0)), rng)
    shown_t = {(e.block_index, e.question_index): e.t for e in kinds(events, "question_shown")}
    answers = kinds(events, "answer_given")
    assert answers
    for e in answers:
        assert e.answer_time_s == pytest.approx(e.t - shown_t[(e.block_index, e.question_index)])
        assert 0.0 <= e.answer_time_s <= S.timeout_s
        assert e.correct == (e.response == e.question.shown_is_correct)


def test_answering_with_no_question_changes_nothing(seed: int) -> None:
    plain, poked = (SecondaryTask(np.random.default_rng(seed)) for _ in range(2))
    assert poked.answer(0.0, True) is None
    region = region_run((False, 1.0), (True, 200.0))
    events_plain, events_poked = [], []
    for k, inside in enumerate(region):
        t = k * DT
        for task, events in ((plain, events_plain), (poked, events_poked)):
            events += task.update(t, inside)
            if task.current is not None and k % 37 == 0:
                events.append(task.answer(t, True))
        # Between a question's answer and the next one, the screen is blank.
        if poked.current is None:
            before = (poked.answered, poked.shown, poked.block_active)
            assert poked.answer(t, False) is None
            assert (poked.answered, poked.shown, poked.block_active) == before
    assert events_plain == events_poked


def test_baseline_gives_baseline_size_questions_without_a_region(rng: np.random.Generator) -> None:
    task = SecondaryTask.baseline(rng)
    assert not task.block_active  # starts at the first update
    events = drive(task, [False] * round(600.0 / DT), rng)
    check_block_structure(events, S.baseline_size)
    assert events[0].t == 0.0 and task.shown == 40 and task.blocks_finished == 1
    assert drive(task, [True, False, True], rng, t0=600.0) == []  # the region starts nothing


def test_same_seed_same_session(seed: int) -> None:
    runs = []
    for _ in range(2):
        rng = np.random.default_rng(seed)
        region = region_run((False, 1.0), (True, 5.0), (False, 200.0), (True, 200.0))
        runs.append(drive(SecondaryTask(rng), region, rng))
    assert runs[0] == runs[1]


def test_time_must_not_go_backwards(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng)
    task.update(1.0, True)
    with pytest.raises(ValueError, match="backwards"):
        task.update(0.5, True)
    with pytest.raises(ValueError, match="backwards"):
        task.answer(0.5, True)
    with pytest.raises(ValueError, match="finite"):
        task.update(math.nan, True)


def test_gap_zero_shows_the_next_question_at_once(rng: np.random.Generator) -> None:
    task = SecondaryTask(rng, settings=dataclasses.replace(S, gap_s=0.0, block_size=3))
    task.update(0.0, True)
    for k in range(1, 3):
        assert task.answer(k * DT, True) is not None
        (shown,) = task.update(k * DT, True)
        assert shown.kind == "question_shown" and shown.question_index == k


@settings(max_examples=25, deadline=None)
@given(
    runs=st.lists(st.tuples(st.booleans(), st.integers(1, 1500)), min_size=1, max_size=10),
    seed=st.integers(0, 2**32 - 1),
    block_size=st.integers(1, 6),
)
def test_blocks_start_exactly_on_entries_when_idle(
    runs: list[tuple[bool, int]], seed: int, block_size: int
) -> None:
    region = [inside for inside, n in runs for _ in range(n)]
    rng = np.random.default_rng(seed)
    task = SecondaryTask(rng, settings=dataclasses.replace(S, block_size=block_size))
    events = drive(task, region, rng)
    started = {round(e.t / DT) for e in kinds(events, "block_started")}
    finished = [e.t for e in kinds(events, "block_finished")]
    # Reference model: an entry starts a block iff the previous block had ended.
    end_t = -math.inf
    for k, inside in enumerate(region):
        entry = inside and (k == 0 or not region[k - 1])
        idle = end_t is not None and end_t <= k * DT + 1e-9
        assert (k in started) == (entry and idle), k
        if k in started:
            n = len([s for s in started if s <= k])
            end_t = finished[n - 1] if len(finished) >= n else None
    # Completed blocks are whole; a block cut off by the end of the run is a prefix.
    summary = summarise(events)
    assert summary["shown"] <= block_size * len(started)
    assert summary["shown"] >= block_size * len(finished)
    assert summary["unresolved"] in (0, 1)


# -- summary ------------------------------------------------------------------------------


def test_summary_counts_and_times(rng: np.random.Generator) -> None:
    task = SecondaryTask.baseline(rng)
    events = drive(task, [False] * round(600.0 / DT), rng, p_right=0.7)
    summary = summarise(events)
    answers = kinds(events, "answer_given")
    times = [e.answer_time_s for e in answers]
    assert summary["shown"] == 40 and summary["blocks"] == 1 and summary["unresolved"] == 0
    assert summary["answered"] == len(answers) == task.answered
    assert summary["correct"] == sum(e.correct for e in answers) == task.correct
    assert summary["wrong"] == summary["answered"] - summary["correct"]
    assert summary["timeouts"] == task.timeouts
    assert summary["errors"] == summary["wrong"] + summary["timeouts"]
    assert summary["answered"] + summary["timeouts"] == 40
    assert summary["mean_answer_time_s"] == pytest.approx(statistics.fmean(times))
    assert summary["median_answer_time_s"] == pytest.approx(statistics.median(times))


def test_summary_of_nothing_answered() -> None:
    summary = summarise([])
    assert summary["answered"] == summary["errors"] == 0
    assert summary["mean_answer_time_s"] is None and summary["median_answer_time_s"] is None
