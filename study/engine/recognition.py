"""In-the-loop recognition against a synthetic driver's true intention (thesis Sec. 7.2.2,
7.4; issues 16 and 40): per tick, whether the mode's recognised task type (its label,
translated by the mode's ``label_tasks``) and target match the task and target the driver
was executing, and whether the assistance that the recognition drove was right.

The measures (definitions and the choices behind them: docs/decisions.md, "Recognition
measures"): task and task + target match over the labelled ticks, per true task type and
per decile of each trial's labelled time; *assist precision*, the share of the ticks with
blend weight ``beta >= CONFIDENT_BETA`` whose recognised task and target are the driver's
true ones (an unlabelled tick counts as wrong assistance); *assist coverage*, the share of
the labelled ticks with ``beta >= CONFIDENT_BETA``; *confident-wrong time*, the seconds
with ``beta >= CONFIDENT_BETA`` on a target other than the true one, per minute of trial,
and the longest such episode.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

CONFIDENT_BETA = 0.5  # a blend weight at or above this is assistance the driver feels
DECILES = 10

# per true task: labelled ticks, task matches, task + target matches, null recognitions,
# ticks assisted, assisted and right (task and target), assisted on a wrong target
_COUNTS = ("labelled_ticks", "task_matches", "task_target_matches", "null_ticks")
_TASK_ASSIST = ("assist_ticks", "assist_correct_ticks", "confident_wrong_ticks")
# per decile of a trial's labelled ticks
_DECILE = ("labelled_ticks", "task_matches", "task_target_matches", "assist_ticks")
# every tick of the trials whose blend weight was scored (integers, then seconds)
_ASSIST_N = (
    "ticks",  # all ticks scored, labelled or not
    "assist_labelled_ticks",  # labelled ticks of those (coverage's denominator)
    "assist_all_ticks",  # ticks with beta >= CONFIDENT_BETA (precision's denominator)
    "assist_correct_ticks",  # of those, task and target right
    "assist_unlabelled_ticks",  # of those, the driver was doing no task
    "assist_covered_ticks",  # labelled ticks with beta >= CONFIDENT_BETA
    "confident_wrong_ticks",  # beta >= CONFIDENT_BETA on a target other than the true one
)
_ASSIST_S = ("seconds", "confident_wrong_s", "confident_wrong_longest_s")


class RecognitionTally:
    """Counts of the ticks of whole trials: labelled ticks (ticks with a true task) and
    their matches, overall, per true task type and per decile of each trial's labelled
    ticks, and, for ticks scored with their blend weight, the assistance measures.

    Every count adds over ticks, so a merged tally equals one tally of all the ticks,
    except two per-trial quantities: the deciles (each trial's labelled ticks split into
    its own ten parts, the parts' counts summed over trials) and the longest
    confident-wrong episode (the longest of any trial's).

    Parameters
    ----------
    label_tasks : mapping
        The mode's label -> task type (``Mode.label_tasks()``); labels not in it, and the
        empty label (nothing recognised), count as null recognitions.
    dt_s : float, optional
        The duration of one tick [s] (the trial loop's); needed to score blend weights.
    """

    def __init__(self, label_tasks: Mapping[str, str], *, dt_s: float | None = None) -> None:
        self.label_tasks = dict(label_tasks)
        self.dt_s = dt_s
        # true task -> [*_COUNTS, *_TASK_ASSIST]
        self.counts: dict[str, list[int]] = {}
        self.deciles = [[0] * len(_DECILE) for _ in range(DECILES)]  # of ended trials
        self.assist: dict[str, float] = {
            **dict.fromkeys(_ASSIST_N, 0),
            **dict.fromkeys(_ASSIST_S, 0.0),
        }
        self._trial: list[tuple[int, int, int]] = []  # this trial's labelled ticks
        self._run_s = 0.0  # the confident-wrong episode under way [s]

    def add(
        self,
        label: str,
        target: str,
        true_task: str,
        true_target: str,
        beta: float | None = None,
    ) -> None:
        """Score one tick of the current trial; ``beta`` (the blend weight in [0, 1], None:
        not scored) needs ``dt_s``. Ticks without a true task count for the assistance
        measures only."""
        task = self.label_tasks.get(label, "")
        same = bool(task) and task == true_task
        both = same and target == true_target
        assisted = beta is not None and beta >= CONFIDENT_BETA
        if beta is not None:
            self._assist(assisted, bool(true_task), both, target != true_target)
        if not true_task:
            return
        c = self.counts.get(true_task)
        if c is None:
            c = self.counts[true_task] = [0] * (len(_COUNTS) + len(_TASK_ASSIST))
        c[0] += 1
        c[1] += same
        c[2] += both
        c[3] += not task
        if assisted:
            c[4] += 1
            c[5] += both
            c[6] += target != true_target
        self._trial.append((same, both, assisted))

    def _assist(self, assisted: bool, labelled: bool, right: bool, wrong_target: bool) -> None:
        """The blend weight's part of :meth:`add`."""
        if self.dt_s is None:
            raise ValueError("RecognitionTally: dt_s is needed to score the blend weight")
        a, dt = self.assist, self.dt_s
        a["ticks"] += 1
        a["seconds"] += dt
        a["assist_labelled_ticks"] += labelled
        if not assisted:
            self._run_s = 0.0
            return
        a["assist_all_ticks"] += 1
        a["assist_correct_ticks"] += right and labelled
        a["assist_unlabelled_ticks"] += not labelled
        a["assist_covered_ticks"] += labelled
        if wrong_target:
            a["confident_wrong_ticks"] += 1
            a["confident_wrong_s"] += dt
            self._run_s += dt
            a["confident_wrong_longest_s"] = max(a["confident_wrong_longest_s"], self._run_s)
        else:
            self._run_s = 0.0

    def add_rows(self, rows: Iterable[Sequence[Any]]) -> RecognitionTally:
        """:meth:`add` for every ``(label, target, true_task, true_target[, beta])`` of one
        trial, in time order; the trial ended (:meth:`end_trial`); self."""
        for row in rows:
            self.add(*row)
        return self.end_trial()

    def end_trial(self) -> RecognitionTally:
        """End the current trial: its labelled ticks go to their deciles and its
        confident-wrong episode ends; self."""
        _add_deciles(self.deciles, _trial_deciles(self._trial))
        self._trial = []
        self._run_s = 0.0
        return self

    def merge(self, other: RecognitionTally) -> RecognitionTally:
        """Add ``other``'s counts to these (each one's current trial ended first); self."""
        self.end_trial()
        width = len(_COUNTS) + len(_TASK_ASSIST)
        for task, c in other.counts.items():
            mine = self.counts.setdefault(task, [0] * width)
            for k in range(width):
                mine[k] += c[k]
        _add_deciles(self.deciles, other.deciles)
        _add_deciles(self.deciles, _trial_deciles(other._trial))
        for key, value in other.assist.items():
            if key == "confident_wrong_longest_s":
                self.assist[key] = max(self.assist[key], value)
            else:
                self.assist[key] += value
        return self

    @classmethod
    def from_summary(cls, summary: Mapping[str, Any]) -> RecognitionTally:
        """The tally behind a :meth:`summary` (its counts; a summary stored before the
        assistance measures gives a tally without them)."""
        out = cls({})
        for task, c in summary["per_task"].items():
            out.counts[task] = [int(c.get(k, 0)) for k in (*_COUNTS, *_TASK_ASSIST)]
        for d, row in zip(out.deciles, summary.get("deciles") or (), strict=False):
            d[:] = [int(row[k]) for k in _DECILE]
        stored = summary.get("assist") or {}
        for key in _ASSIST_N:
            out.assist[key] = int(stored.get(key, 0))
        for key in _ASSIST_S:
            out.assist[key] = float(stored.get(key, 0.0))
        return out

    def summary(self) -> dict[str, Any]:
        """``labelled_ticks``, ``task_matches``, ``task_target_matches``, ``null_ticks``;
        ``loop_task_match``, ``loop_task_target_match`` and ``loop_null_rate`` (their
        shares of the labelled ticks, None without any); the assistance measures of
        :func:`assist_measures` (None where not scored); the same per true task type under
        ``per_task`` (with ``assist_ticks``, ``assist_correct_ticks``,
        ``confident_wrong_ticks`` among its labelled ticks and their shares); ``deciles``
        (ten parts of the trials' labelled time, counts and shares); ``assist`` the counts
        and seconds behind the assistance measures."""
        width = len(_COUNTS) + len(_TASK_ASSIST)
        total = [sum(c[k] for c in self.counts.values()) for k in range(width)]
        deciles = [list(d) for d in self.deciles]
        _add_deciles(deciles, _trial_deciles(self._trial))
        out = _shares(total[: len(_COUNTS)])
        out.update(assist_measures(self.assist))
        out["per_task"] = {t: _shares(c) for t, c in sorted(self.counts.items())}
        out["deciles"] = [_decile_shares(d) for d in deciles]
        out["assist"] = {k: _rounded(v) for k, v in self.assist.items()}
        return out


def _trial_deciles(trial: list[tuple[int, int, int]]) -> list[list[int]]:
    """One trial's labelled ticks ``(task match, task + target match, assisted)`` in time
    order split into :data:`DECILES` equal parts (tick ``k`` of ``n`` in part
    ``floor(DECILES k / n)``): each part's :data:`_DECILE` counts."""
    out = [[0] * len(_DECILE) for _ in range(DECILES)]
    n = len(trial)
    for k, (same, both, assisted) in enumerate(trial):
        d = out[DECILES * k // n]
        d[0] += 1
        d[1] += same
        d[2] += both
        d[3] += assisted
    return out


def _add_deciles(into: list[list[int]], other: Iterable[Sequence[int]]) -> None:
    for mine, theirs in zip(into, other, strict=True):
        for k, v in enumerate(theirs):
            mine[k] += v


def _share(num: float, den: float) -> float | None:
    return round(num / den, 4) if den else None


def _rounded(v: float) -> float:
    return v if isinstance(v, int) else round(v, 6)


def assist_measures(a: Mapping[str, float]) -> dict[str, Any]:
    """The assistance measures of the counts and seconds ``a`` (a summary's ``assist``).

    Returns
    -------
    dict
        ``assist_precision`` (right / assisted ticks, unlabelled assisted ticks counted
        wrong), ``assist_precision_labelled`` (the same over the labelled assisted ticks),
        ``assist_coverage`` (assisted / labelled ticks), ``assist_unlabelled_ticks``,
        ``confident_wrong_s``, ``confident_wrong_s_per_min`` [s/min] of trial time,
        ``confident_wrong_longest_s``; None where a denominator is 0 or nothing was scored.
    """
    scored = a["ticks"] > 0
    labelled_assisted = a["assist_all_ticks"] - a["assist_unlabelled_ticks"]
    minutes = a["seconds"] / 60.0
    return {
        "assist_precision": _share(a["assist_correct_ticks"], a["assist_all_ticks"]),
        "assist_precision_labelled": _share(a["assist_correct_ticks"], labelled_assisted),
        "assist_coverage": _share(a["assist_covered_ticks"], a["assist_labelled_ticks"]),
        "assist_unlabelled_ticks": int(a["assist_unlabelled_ticks"]) if scored else None,
        "confident_wrong_s": round(a["confident_wrong_s"], 4) if scored else None,
        "confident_wrong_s_per_min": (
            round(a["confident_wrong_s"] / minutes, 4) if minutes > 0 else None
        ),
        "confident_wrong_longest_s": round(a["confident_wrong_longest_s"], 4) if scored else None,
    }


def _shares(c: list[int]) -> dict[str, Any]:
    n = c[0]
    out: dict[str, Any] = dict(zip(_COUNTS, c, strict=False))
    out.update(
        loop_task_match=_share(c[1], n),
        loop_task_target_match=_share(c[2], n),
        loop_null_rate=_share(c[3], n),
    )
    if len(c) > len(_COUNTS):  # a true task's assistance among its labelled ticks
        out.update(zip(_TASK_ASSIST, c[len(_COUNTS) :], strict=True))
        out["assist_coverage"] = _share(c[4], n)
        out["assist_precision_labelled"] = _share(c[5], c[4])
        out["confident_wrong_share"] = _share(c[6], n)
    return out


def _decile_shares(d: list[int]) -> dict[str, Any]:
    n = d[0]
    out: dict[str, Any] = dict(zip(_DECILE, d, strict=True))
    out.update(
        loop_task_match=_share(d[1], n),
        loop_task_target_match=_share(d[2], n),
        assist_coverage=_share(d[3], n),
    )
    return out
