"""From the raw tables to the tidy frames of the report (thesis Sec. 7.6.1.3, 7.6.2, 7.5).

One row per counted main trial with every metric of :mod:`analysis.metrics`, one row per
secondary question (main trials and the baseline block), one row per questionnaire answer,
one row per trial and true task type of the in-the-loop recognition (issue 16).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.data.assistance import Assistance, assistance, empty_assistance
from analysis.data.load import AnalysisConfig, StudyData
from analysis.data.recognition import per_trial, recognition_counts
from questionnaires import nasa_tlx

BASELINE = "baseline"
# trial statuses of a trial that ran to its end (study.data.storage.TRIAL_FINISHED; repeated
# so that the analysis of a CSV export does not import SQLAlchemy)
FINISHED: tuple[str, ...] = ("completed", "timed_out")

ASSIST_THRESHOLD = 0.05  # beta above this counts as assisted


@dataclass(frozen=True, slots=True)
class Frames:
    """The tidy frames of one study.

    Attributes
    ----------
    trials : one row per counted main trial: ``participant``, ``kind``, ``mode``,
        ``position`` (0-based place in the participant's order), ``order`` (the order as
        "a > b > c"), ``order_index``, ``trial_id`` and one column per metric.
    questions : one row per secondary question of counted main trials and completed
        baseline blocks: ``participant``, ``mode`` ("baseline" for the block), ``trial_id``,
        ``block``, ``index``, ``answered``, ``correct``, ``answer_time_s``.
    responses : one row per questionnaire answer: ``participant``, ``trial_id``, ``mode``
        ("" outside a main trial), ``instrument``, ``item``, ``value``, ``text``.
    participants : one row per participant: ``participant``, ``kind``, ``order_index``,
        ``order``, ``main_trials`` (counted), ``complete`` (one per mode).
    aborted : one row per main trial not counted: ``participant``, ``mode``, ``ordinal``,
        ``attempt``, ``status``, ``reason``.
    recognition : in-the-loop recognition of counted trials, one row per (trial, true task
        type) with labelled ticks: ``trial_id``, ``participant``, ``mode``, ``task``, the
        counts of :data:`analysis.data.recognition.COUNTS` and ``source`` ("outcome" or
        "samples"); empty when no mode recognises tasks or no driver reported intentions.
    modes : the mode levels in report order (protocol order).
    warnings : notes for the report's data-quality section.
    assistance : the assistance measures of the recognition's trials (issue 40;
        :class:`analysis.data.assistance.Assistance`), counted trials only.
    """

    trials: pd.DataFrame
    questions: pd.DataFrame
    responses: pd.DataFrame
    participants: pd.DataFrame
    aborted: pd.DataFrame
    recognition: pd.DataFrame
    modes: tuple[str, ...]
    warnings: tuple[str, ...] = ()
    assistance: Assistance = field(default_factory=empty_assistance)


def _mode_levels(config: AnalysisConfig, seen: list[str]) -> tuple[str, ...]:
    levels = [m for m in config.modes if m in seen]
    levels += [m for m in seen if m not in levels]
    return tuple(levels)


def _tlx_scores(responses: pd.DataFrame, trial_ids: list[int], last_trial: dict) -> pd.DataFrame:
    """Per trial: tlx_raw, tlx_weighted, tlx_<subscale>."""
    tlx = responses[responses["instrument"] == nasa_tlx.INSTRUMENT_ID]
    by_trial = {tid: g for tid, g in tlx.groupby("trial_id")}
    choices_by_trial: dict[int, dict] = {}
    for tid, g in by_trial.items():
        pairs = g[g["item"].str.startswith("pair:")]
        if len(pairs):
            choices_by_trial[int(tid)] = {
                item[5:].replace("|", "_vs_"): chosen
                for item, chosen in zip(pairs["item"], pairs["text"], strict=True)
            }
    rows = []
    for tid in trial_ids:
        row: dict[str, float] = {"trial_id": tid, "tlx_raw": np.nan, "tlx_weighted": np.nan}
        row.update({f"tlx_{sid}": np.nan for sid in nasa_tlx.SUBSCALE_IDS})
        g = by_trial.get(tid)
        if g is not None:
            ratings = {
                item: value
                for item, value in zip(g["item"], g["value"], strict=True)
                if item in nasa_tlx.SUBSCALE_IDS and not pd.isna(value)
            }
            if len(ratings) == len(nasa_tlx.SUBSCALE_IDS):
                ratings = {k: int(round(v)) for k, v in ratings.items()}
                choices = choices_by_trial.get(tid) or choices_by_trial.get(last_trial.get(tid))
                weights = None
                if choices:
                    try:
                        weights = nasa_tlx.weights_from_choices(choices)
                    except ValueError:
                        weights = None
                result = nasa_tlx.score(ratings, weights)
                row["tlx_raw"] = result.raw
                row["tlx_weighted"] = np.nan if result.weighted is None else result.weighted
                row.update({f"tlx_{k}": float(v) for k, v in result.ratings.items()})
        rows.append(row)
    return pd.DataFrame(rows)


def _sample_metrics(samples: pd.DataFrame) -> pd.DataFrame:
    """Per trial_id: assist_share, beta_mean, clearance from samples, n_samples."""
    if samples.empty:
        return pd.DataFrame(
            columns=[
                "trial_id",
                "assist_share",
                "beta_mean",
                "sample_clearance_mean_m",
                "sample_clearance_min_m",
                "clearance_std_m",
                "n_samples",
            ]
        )
    s = samples
    work = pd.DataFrame(
        {
            "trial_id": s["trial_id"].astype(int),
            "assisted": (s["beta"].astype(float) > ASSIST_THRESHOLD).astype(float),
            "beta": s["beta"].astype(float),
            "clearance": s["min_clearance_m"].astype(float),
        }
    )
    g = work.groupby("trial_id")
    out = pd.DataFrame(
        {
            "assist_share": g["assisted"].mean(),
            "beta_mean": g["beta"].mean(),
            "sample_clearance_mean_m": g["clearance"].mean(),
            "sample_clearance_min_m": g["clearance"].min(),
            "clearance_std_m": g["clearance"].std(ddof=1),
            "n_samples": g["beta"].size(),
        }
    )
    return out.reset_index()


def secondary_metrics(questions: pd.DataFrame, by: str) -> pd.DataFrame:
    """Secondary-task metrics of the questions grouped by column ``by`` (``trial_id`` for
    the trial frame, ``participant`` for the baseline level): ``secondary_questions``,
    ``secondary_answer_time_s`` (mean over answered), ``secondary_errors`` (not correct),
    ``secondary_misses`` (unanswered) and ``secondary_error_rate``; one row per group."""
    work = questions.assign(
        error=~questions["correct"].astype(bool), miss=~questions["answered"].astype(bool)
    )
    g = work.groupby(by)
    out = pd.DataFrame(
        {
            "secondary_questions": g["error"].size(),
            "secondary_answer_time_s": g["answer_time_s"].mean(),
            "secondary_errors": g["error"].sum().astype(float),
            "secondary_misses": g["miss"].sum().astype(float),
        }
    )
    out["secondary_error_rate"] = out["secondary_errors"] / out["secondary_questions"]
    return out.reset_index()


def tidy(data: StudyData) -> Frames:
    """The tidy frames of a study (every decision is in docs/decisions.md, analysis/data).

    Parameters
    ----------
    data : StudyData
        The raw tables of :func:`analysis.data.load_study`.

    Returns
    -------
    Frames

    Raises
    ------
    ValueError
        Naming the source when there is no completed main trial.
    """
    t = data.tables
    people = _people(t["participant"])
    trials = t["trial"].merge(people, on="participant_id", how="left")
    main = trials[trials["phase"] == "main"]
    counted = _counted(main, data.source)
    aborted = _aborted(main, counted)
    modes = _mode_levels(data.config, list(dict.fromkeys(counted["mode"])))
    frame = _trial_frame(counted, data.config.collision_penalty_s)
    frame, timeout_notes = _with_timeouts(frame, counted, data.config)
    frame, recognition, warnings = _with_sample_metrics(frame, counted, t["sample"], data.source)
    warnings = timeout_notes + warnings
    level_of = _levels_of_trials(trials, frame)
    questions = _questions(trials, t["question"], level_of)
    frame = _with_secondary(frame, questions)
    tlx = _tlx_scores(t["response"], frame["trial_id"].tolist(), _last_trial(frame))
    frame = frame.merge(tlx, on="trial_id", how="left")
    responses = _responses(t["response"], people, level_of)
    order = {m: i for i, m in enumerate(modes)}
    frame = frame.sort_values(
        ["participant", "mode"], key=lambda c: c.map(order) if c.name == "mode" else c
    ).reset_index(drop=True)
    return Frames(
        trials=frame,
        questions=questions,
        responses=responses,
        participants=_participants(people, frame, modes),
        aborted=aborted,
        recognition=recognition,
        modes=modes,
        warnings=tuple(warnings),
        assistance=assistance(counted["id"], counted["outcome"], t["sample"], source=data.source),
    )


def _people(participant: pd.DataFrame) -> pd.DataFrame:
    """participant_id, participant (code), kind, order_index, mode_order, order ("a > b"),
    site ("" without sites; a study from before revision 0003 has none)."""
    people = participant.rename(columns={"id": "participant_id", "code": "participant"})
    site = people["site"] if "site" in people.columns else ""
    people = people[["participant_id", "participant", "kind", "order_index", "mode_order"]]
    return people.assign(
        order=[" > ".join(o or []) for o in people["mode_order"]],
        site=site,
    )


def _counted(main: pd.DataFrame, source: str) -> pd.DataFrame:
    """The finished main trials that count (completed or timed out; a database written
    before ``timed_out`` existed stores a timeout as ``completed``): the last attempt of
    each (participant, ordinal)."""
    completed = main[main["status"].isin(FINISHED)]
    counted = completed.sort_values(["participant_id", "ordinal", "attempt", "id"]).drop_duplicates(
        ["participant_id", "ordinal"], keep="last"
    )
    if counted.empty:
        raise ValueError(
            f"{source}: no completed main trial (table 'trial', phase 'main', status "
            "'completed' or 'timed_out'); nothing to analyse"
        )
    return counted


def _aborted(main: pd.DataFrame, counted: pd.DataFrame) -> pd.DataFrame:
    """The main trials not counted (aborted, still running, superseded) and why."""
    not_counted = main[~main["id"].isin(counted["id"])]
    return pd.DataFrame(
        {
            "participant": not_counted["participant"],
            "mode": not_counted["mode"],
            "ordinal": not_counted["ordinal"].astype(int),
            "attempt": not_counted["attempt"].astype(int),
            "status": not_counted["status"],
            "reason": [
                (o or {}).get("aborted_reason", "") if s not in FINISHED else "superseded attempt"
                for o, s in zip(not_counted["outcome"], not_counted["status"], strict=True)
            ],
        }
    ).reset_index(drop=True)


def _trial_frame(counted: pd.DataFrame, collision_penalty_s: float) -> pd.DataFrame:
    """One row per counted trial with the stored outcome metrics (and the participant's
    site in a multi-site study); score recomputed if absent."""
    frame = pd.DataFrame(
        {
            "participant": counted["participant"].astype(str),
            "kind": counted["kind"],
            "mode": counted["mode"],
            "position": counted["ordinal"].astype(int),
            "order": counted["order"],
            "order_index": counted["order_index"].astype(int),
            "trial_id": counted["id"].astype(int),
            "completed_task": counted["completed_task"],
            "completion_time_s": counted["completion_time_s"].astype(float),
            "collisions": counted["collisions"].astype(float),
            "score_s": counted["score"].astype(float),
            "path_length_m": counted["path_length_m"].astype(float),
            "clearance_mean_m": counted["clearance_mean_m"].astype(float),
            "clearance_min_m": counted["clearance_min_m"].astype(float),
        }
    ).reset_index(drop=True)
    if (counted["site"] != "").any():  # a multi-site study: the site, e.g. a factor in R
        frame.insert(1, "site", counted["site"].to_numpy())
    recomputed = frame["completion_time_s"] + collision_penalty_s * frame["collisions"]
    frame["score_s"] = frame["score_s"].fillna(recomputed)
    return frame


TIMED_METRICS: tuple[str, ...] = ("completion_time_s", "score_s")


def _crashed(counted: pd.DataFrame, end_on_collision: bool) -> pd.Series:
    """Whether a collision ended each counted trial: the outcome's ``crashed`` flag, or
    for databases written before it, a collision in a protocol that ends trials on one."""
    out = []
    for outcome, collisions in zip(counted["outcome"], counted["collisions"], strict=True):
        o = outcome if isinstance(outcome, dict) else {}
        hit = bool(collisions == collisions and collisions > 0)  # NaN: no collision stored
        out.append(bool(o["crashed"]) if "crashed" in o else end_on_collision and hit)
    return pd.Series(out, dtype=bool)


def _with_timeouts(
    frame: pd.DataFrame, counted: pd.DataFrame, config: AnalysisConfig
) -> tuple[pd.DataFrame, list[str]]:
    """Mark the trials that ended without finishing the route: ``crashed`` (a collision
    ended it, Sec. 7.5) or ``timed_out`` (the time limit). A crashed trial's completion
    time and score are missing (Fig. 7.44a averages successful tests only); a timed-out
    trial's are as ``config.timeouts`` says ([analysis] timeouts): missing (``"exclude"``;
    the repeated-measures tests then drop the participant listwise) or the time limit kept
    as a right-censored value (``"censor"``, ``censored`` True). The notes for the report."""
    unfinished = frame["completed_task"].eq(False).to_numpy()
    crashed = unfinished & _crashed(counted, config.end_on_collision).to_numpy()
    timed_out = unfinished & ~crashed
    policy = config.timeouts
    frame = frame.assign(
        crashed=crashed, timed_out=timed_out, censored=timed_out & (policy == "censor")
    )
    notes = []
    if crashed.any():
        frame.loc[crashed, list(TIMED_METRICS)] = np.nan
        notes.append(
            f"{int(crashed.sum())} main trial(s) ended in a crash ({_per_mode(frame, crashed)}):"
            " their completion time and score are missing (thesis Sec. 7.5: successful tests"
            " only)"
        )
    if timed_out.any():
        if policy == "exclude":
            frame.loc[timed_out, list(TIMED_METRICS)] = np.nan
            what = "their completion time and score are excluded as missing"
        else:
            what = "their completion time and score are the time limit, a censored lower bound"
        notes.append(
            f"{int(timed_out.sum())} main trial(s) timed out without finishing the route "
            f'({_per_mode(frame, timed_out)}): {what} ([analysis] timeouts = "{policy}")'
        )
    return frame, notes


def _per_mode(frame: pd.DataFrame, mask: np.ndarray) -> str:
    per_mode = frame.loc[mask, "mode"].value_counts(sort=False)
    return ", ".join(f"{mode} {n}" for mode, n in per_mode.items())


def _with_sample_metrics(
    frame: pd.DataFrame, counted: pd.DataFrame, sample: pd.DataFrame, source: str
) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """The trial frame with the metrics of its samples and its recognition accuracy, the
    recognition counts (:attr:`Frames.recognition`), and a warning for trials without
    samples."""
    samples = sample[sample["trial_id"].isin(set(frame["trial_id"]))]
    frame = frame.merge(_sample_metrics(samples), on="trial_id", how="left")
    frame["clearance_mean_m"] = frame["clearance_mean_m"].fillna(frame["sample_clearance_mean_m"])
    frame["clearance_min_m"] = frame["clearance_min_m"].fillna(frame["sample_clearance_min_m"])
    frame = frame.drop(columns=["sample_clearance_mean_m", "sample_clearance_min_m"])
    frame["n_samples"] = frame["n_samples"].fillna(0).astype(int)
    counts = recognition_counts(counted["id"], counted["outcome"], samples, source=source)
    accuracy = per_trial(counts)[["trial_id", "loop_task_target_match"]]
    frame = frame.merge(accuracy, on="trial_id", how="left")
    frame = frame.rename(columns={"loop_task_target_match": "recognition_accuracy"})
    who = frame[["trial_id", "participant", "mode"]]
    counts = who.merge(counts, on="trial_id", how="inner")
    warnings: list[str] = []
    if (frame["n_samples"] == 0).any():
        missing = frame.loc[frame["n_samples"] == 0, "participant"].tolist()
        warnings.append(f"main trials without samples (participants {', '.join(missing)})")
    return frame, counts, warnings


def _levels_of_trials(trials: pd.DataFrame, frame: pd.DataFrame) -> dict[int, str]:
    """Trial id -> level: the mode of each counted main trial, BASELINE for the last
    completed baseline block of each participant."""
    baseline = trials[(trials["phase"] == "baseline") & trials["status"].isin(FINISHED)]
    baseline = baseline.sort_values(["participant_id", "attempt", "id"]).drop_duplicates(
        "participant_id", keep="last"
    )
    level_of = dict(zip(frame["trial_id"], frame["mode"], strict=True))
    level_of.update(dict.fromkeys(baseline["id"].astype(int), BASELINE))
    return level_of


def _questions(trials: pd.DataFrame, question: pd.DataFrame, level_of: dict) -> pd.DataFrame:
    """One row per secondary question of the trials in ``level_of``."""
    who = dict(zip(trials["id"].astype(int), trials["participant"].astype(str), strict=True))
    q = question[question["trial_id"].isin(level_of)]
    return pd.DataFrame(
        {
            "participant": [who[int(i)] for i in q["trial_id"]],
            "mode": [level_of[int(i)] for i in q["trial_id"]],
            "trial_id": q["trial_id"].astype(int),
            "block": q["block"].astype(int),
            "index": q["index"].astype(int),
            "answered": [r is not None for r in q["response"]],
            "correct": [bool(c) for c in q["correct"]],
            "answer_time_s": q["answer_time_s"].astype(float),
        }
    ).reset_index(drop=True)


def _with_secondary(frame: pd.DataFrame, questions: pd.DataFrame) -> pd.DataFrame:
    """The trial frame with the secondary-task metrics of its main-trial questions."""
    if len(questions):
        drive = questions[questions["mode"] != BASELINE]
        return frame.merge(secondary_metrics(drive, "trial_id"), on="trial_id", how="left")
    for col in (
        "secondary_questions",
        "secondary_answer_time_s",
        "secondary_errors",
        "secondary_misses",
        "secondary_error_rate",
    ):
        frame[col] = np.nan
    return frame


def _last_trial(frame: pd.DataFrame) -> dict[int, int]:
    """Trial id -> the id of the same participant's last main trial (by position)."""
    last_trial = {}
    for _, g in frame.groupby("participant"):
        last = int(g.sort_values("position")["trial_id"].iloc[-1])
        last_trial.update(dict.fromkeys(g["trial_id"].astype(int), last))
    return last_trial


def _responses(r: pd.DataFrame, people: pd.DataFrame, level_of: dict) -> pd.DataFrame:
    """One row per questionnaire answer; mode "" outside a main trial."""
    pid_code = dict(zip(people["participant_id"], people["participant"].astype(str), strict=True))
    return pd.DataFrame(
        {
            "participant": [pid_code.get(int(p), str(p)) for p in r["participant_id"]],
            "trial_id": r["trial_id"].astype("Int64"),
            "mode": [
                "" if pd.isna(i) or level_of.get(int(i)) == BASELINE else level_of.get(int(i), "")
                for i in r["trial_id"]
            ],
            "instrument": r["instrument"],
            "item": r["item"],
            "value": r["value"].astype(float),
            "text": r["text"],
        }
    ).reset_index(drop=True)


def _participants(people: pd.DataFrame, frame: pd.DataFrame, modes: tuple) -> pd.DataFrame:
    """One row per participant: (site,) kind, order, counted main trials, complete set of
    modes."""
    counts = frame.groupby("participant")["mode"].nunique()
    columns = ["participant", "kind", "order_index", "order"]
    if (people["site"] != "").any():  # a multi-site study: each participant's site
        columns.insert(1, "site")
    participants = people.assign(participant=people["participant"].astype(str))[columns].copy()
    participants["main_trials"] = (
        participants["participant"].map(frame.groupby("participant").size()).fillna(0).astype(int)
    )
    participants["complete"] = participants["participant"].map(counts).fillna(0) == len(modes)
    return participants.reset_index(drop=True)
