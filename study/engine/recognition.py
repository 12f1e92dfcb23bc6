"""In-the-loop recognition against a synthetic driver's true intention (thesis Sec. 7.2.2,
7.4): per tick, whether the mode's recognised task type (its label, translated by the
mode's ``label_tasks``) and target match the task and target the driver was executing."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any


class RecognitionTally:
    """Counts of labelled ticks (ticks with a true task) and their matches, overall and
    per true task type.

    Parameters
    ----------
    label_tasks : mapping
        The mode's label -> task type (``Mode.label_tasks()``); labels not in it, and the
        empty label (nothing recognised), count as null recognitions.
    """

    def __init__(self, label_tasks: Mapping[str, str]) -> None:
        self.label_tasks = dict(label_tasks)
        self.counts: dict[str, list[int]] = {}  # true task -> [ticks, task, both, null]

    def add(self, label: str, target: str, true_task: str, true_target: str) -> None:
        """Score one tick; ticks without a true task are not counted."""
        if not true_task:
            return
        c = self.counts.get(true_task)
        if c is None:
            c = self.counts[true_task] = [0, 0, 0, 0]
        c[0] += 1
        task = self.label_tasks.get(label, "")
        if not task:
            c[3] += 1
        elif task == true_task:
            c[1] += 1
            c[2] += target == true_target

    def add_rows(self, rows: Iterable[tuple[str, str, str, str]]) -> RecognitionTally:
        """:meth:`add` for every ``(label, target, true_task, true_target)``; self."""
        for row in rows:
            self.add(*row)
        return self

    def merge(self, other: RecognitionTally) -> RecognitionTally:
        """Add ``other``'s counts to these; self."""
        for task, c in other.counts.items():
            mine = self.counts.setdefault(task, [0, 0, 0, 0])
            for k in range(4):
                mine[k] += c[k]
        return self

    @classmethod
    def from_summary(cls, summary: Mapping[str, Any]) -> RecognitionTally:
        """The tally behind a :meth:`summary` (its ``per_task`` counts)."""
        out = cls({})
        for task, c in summary["per_task"].items():
            out.counts[task] = [int(c[k]) for k in _COUNTS]
        return out

    def summary(self) -> dict[str, Any]:
        """``labelled_ticks``, ``task_matches``, ``task_target_matches``, ``null_ticks``;
        ``loop_task_match``, ``loop_task_target_match`` and ``loop_null_rate`` (their
        shares of the labelled ticks, None without any); the same per true task type
        under ``per_task``."""
        total = [sum(c[k] for c in self.counts.values()) for k in range(4)]
        out = _shares(total)
        out["per_task"] = {t: _shares(c) for t, c in sorted(self.counts.items())}
        return out


_COUNTS = ("labelled_ticks", "task_matches", "task_target_matches", "null_ticks")


def _shares(c: list[int]) -> dict[str, Any]:
    n = c[0]
    share = (lambda k: round(c[k] / n, 4)) if n else (lambda k: None)
    return {
        **dict(zip(_COUNTS, c, strict=True)),
        "loop_task_match": share(1),
        "loop_task_target_match": share(2),
        "loop_null_rate": share(3),
    }
