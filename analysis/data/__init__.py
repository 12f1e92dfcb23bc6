"""From a study database (or the CSV folder of ``asa export``) to tidy pandas frames.

Thesis Sec. 7.6.1.3 and 7.6.2 (spec section 7): per main trial the primary-task completion
time, collisions and score (time + 60 s per collision), the answer time of each secondary
question and the errors, the NASA-TLX after each trial; the baseline block of questions is a
fourth level of the secondary metrics. Sec. 7.5 adds clearance to obstacles (Fig. 7.44b).

:func:`load_study` reads the raw tables into a :class:`StudyData`, the same from a database
and from its CSV export (JSON columns parsed, booleans as bool, NULL as NaN/None);
:func:`tidy` turns it into :class:`Frames`: one row per completed main trial with every
metric of :mod:`analysis.metrics`, one row per secondary question (main and baseline), one
row per questionnaire answer.

Decisions where the spec is silent
----------------------------------
- **Which trials count.** Only ``phase == "main"`` trials with status ``completed``; when a
  participant has more than one completed attempt of the same ordinal, the last attempt
  counts (a resumed session reruns the aborted trial). Aborted and still running main trials
  are listed in :attr:`Frames.aborted` for the report's data-quality section.
- **Score** is the stored ``score`` when present, else completion time + the protocol's
  ``[scoring] collision_penalty_s`` (60 s by default) x collisions.
- **Assistance.** ``assist_share`` is the share of samples with ``beta > 0.05`` (a small
  threshold so that numerical noise in a blend does not count as help); ``beta_mean`` is the
  mean of beta over all samples. Samples are evenly spaced ticks, so shares of samples are
  shares of time.
- **Clearance** columns come from the trial's outcome; when missing they are recomputed from
  the samples' ``min_clearance_m`` (mean and minimum); ``clearance_std_m`` always from the
  samples.
- **Secondary errors** are the questions not answered correctly: wrong answers plus
  questions left unanswered (``correct`` is False for both), the thesis's "number of
  errors" (Fig. 7.51b) and ``tasks.secondary.summarise``'s ``errors``; ``secondary_misses``
  counts the unanswered ones alone and ``secondary_error_rate`` divides errors by the
  questions shown (the baseline block has 40 questions, a main trial as many as the driver
  met). ``secondary_answer_time_s`` is the mean over answered questions.
- **NASA-TLX** scores by :func:`questionnaires.nasa_tlx.score`: ``tlx_raw`` always,
  ``tlx_weighted`` when the 15 pairwise choices of that trial are stored, else those of the
  participant's last main trial (the protocol's ``weights = "once"``), else NaN; per subscale
  ``tlx_<id>``. A trial with incomplete ratings has NaN TLX values.
- **Recognition accuracy** (synthetic participants only, where samples carry the true
  intention): the share of samples with a non-empty ``true_task`` whose recognised task
  equals ``true_task`` and ``target`` equals ``true_target``. The recognised task is the
  ``label`` translated by the trial's stored ``outcome["label_tasks"]`` (the contextual
  mode labels ticks with its motion primitives and stores each primitive's dominant task
  type); NaN for a trial whose mode recognises no tasks (no such table: manual, the
  reactive mode's situations), for a trial whose mode labelled nothing, and for humans.
- **Modes** are ordered as the protocol's ``[modes] names``, then any others in order of
  appearance; the baseline level is called ``"baseline"`` and comes last.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from questionnaires import nasa_tlx

BASELINE = "baseline"
ASSIST_THRESHOLD = 0.05  # beta above this counts as assisted
TABLES: tuple[str, ...] = (
    "study",
    "participant",
    "session",
    "trial",
    "sample",
    "event",
    "question",
    "response",
)
_JSON = {"participant": ("parameters", "mode_order"), "trial": ("outcome",), "event": ("detail",)}
_BOOL = {
    "trial": ("completed_task",),
    "sample": ("in_region",),
    "question": ("shown_is_correct", "response", "correct"),
    "session": ("resumed", "forced"),
}
_TEXT = {
    "trial": ("mode", "phase", "status", "scenario", "recording_path"),
    "sample": ("label", "target", "true_task", "true_target"),
    "response": ("instrument", "item", "text"),
    "participant": ("code", "kind"),
    "question": ("text",),
    "event": ("kind",),
}


@dataclass(frozen=True, slots=True)
class AnalysisConfig:
    """The analysis settings of the study's protocol (read with tomllib from its text).

    Attributes
    ----------
    alpha : significance level ([analysis] alpha, 0.05).
    gate : which p gates the post-hoc tests ([analysis] gate, "auto").
    posthoc : the LSD form the report leads with ([analysis] posthoc, "lsd_paired").
    metrics : the protocol's planned metrics ([analysis] metrics).
    secondary_baseline_level : the baseline as a level of secondary metrics.
    collision_penalty_s : [s] per collision in the score ([scoring], 60).
    modes : the protocol's mode names in its order ([modes] names).
    """

    alpha: float = 0.05
    gate: str = "auto"
    posthoc: str = "lsd_paired"
    metrics: tuple[str, ...] = ()
    secondary_baseline_level: bool = True
    collision_penalty_s: float = 60.0
    modes: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class StudyData:
    """The raw tables of one study, typed the same whatever the source.

    Attributes
    ----------
    source : the database or folder read.
    study : {name, protocol_text, protocol_sha256, platform_version, seed}.
    config : the protocol's analysis settings.
    tables : table name -> DataFrame with the storage columns (see :data:`TABLES`).
    """

    source: str
    study: dict[str, Any]
    config: AnalysisConfig
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)


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
    modes : the mode levels in report order (protocol order).
    warnings : notes for the report's data-quality section.
    """

    trials: pd.DataFrame
    questions: pd.DataFrame
    responses: pd.DataFrame
    participants: pd.DataFrame
    aborted: pd.DataFrame
    modes: tuple[str, ...]
    warnings: tuple[str, ...] = ()


# --------------------------------------------------------------------------- reading


def read_config(protocol_text: str, *, source: str = "protocol") -> AnalysisConfig:
    """The analysis settings of a protocol text; defaults where a field is absent.

    Raises ``ValueError`` naming ``source`` when the text is not TOML.
    """
    try:
        doc = tomllib.loads(protocol_text or "")
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{source}: field 'study.protocol_text' is not TOML: {error}") from error
    analysis = doc.get("analysis", {}) or {}
    scoring = doc.get("scoring", {}) or {}
    modes = (doc.get("modes", {}) or {}).get("names", []) or []
    return AnalysisConfig(
        alpha=float(analysis.get("alpha", 0.05)),
        gate=str(analysis.get("gate", "auto")),
        posthoc=str(analysis.get("posthoc", "lsd_paired")),
        metrics=tuple(str(m) for m in analysis.get("metrics", ())),
        secondary_baseline_level=bool(analysis.get("secondary_baseline_level", True)),
        collision_penalty_s=float(scoring.get("collision_penalty_s", 60.0)),
        modes=tuple(str(m) for m in modes),
    )


def _read_db(db: Path | str) -> dict[str, pd.DataFrame]:
    from sqlalchemy import text
    from sqlalchemy.exc import DatabaseError

    from study.data.storage import open_database

    try:
        engine = open_database(db, create=False)
    except DatabaseError as error:
        raise ValueError(f"{db}: not an SQLite database ({error.orig})") from error
    try:
        tables: dict[str, pd.DataFrame] = {}
        with engine.connect() as conn:
            for name in TABLES:
                tables[name] = pd.read_sql_query(text(f'SELECT * FROM "{name}" ORDER BY id'), conn)
    except DatabaseError as error:
        raise ValueError(f"{db}: cannot read the study tables ({error.orig})") from error
    finally:
        engine.dispose()
    return tables


def _read_csv_folder(folder: Path) -> dict[str, pd.DataFrame]:
    tables = {}
    for name in TABLES:
        path = folder / f"{name}.csv"
        if not path.is_file():
            raise ValueError(
                f"{folder}: not an 'asa export' folder: file {name}.csv is missing "
                f"(expected {', '.join(t + '.csv' for t in TABLES)})"
            )
        text_cols = {c: str for c in _TEXT.get(name, ()) + _JSON.get(name, ())}
        if name == "study":
            text_cols.update(protocol_text=str, protocol_sha256=str, name=str)
        try:
            tables[name] = pd.read_csv(path, dtype=text_cols, keep_default_na=False, na_values=[""])
        except (pd.errors.ParserError, UnicodeDecodeError) as error:
            raise ValueError(f"{path}: not a readable CSV ({error})") from error
    return tables


def _parse_json(value: Any, where: str) -> Any:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if not isinstance(value, str):
        return value
    if value == "":
        return None
    try:
        return json.loads(value)
    except json.JSONDecodeError as error:
        raise ValueError(f"{where}: not JSON: {value[:40]!r}") from error


def _to_bool(value: Any) -> Any:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1")
    return bool(value)


def _normalise(tables: dict[str, pd.DataFrame], source: str) -> dict[str, pd.DataFrame]:
    out = {}
    for name, frame in tables.items():
        frame = frame.copy()
        if "id" not in frame.columns:
            raise ValueError(f"{source}: table {name!r} has no column 'id'")
        for col in _JSON.get(name, ()):
            if col in frame.columns:
                frame[col] = [_parse_json(v, f"{source}: {name}.{col}") for v in frame[col]]
        for col in _BOOL.get(name, ()):
            if col in frame.columns:
                frame[col] = pd.Series([_to_bool(v) for v in frame[col]], dtype=object)
        for col in _TEXT.get(name, ()):
            if col in frame.columns:
                frame[col] = frame[col].fillna("").astype(str)
        out[name] = frame.sort_values("id", kind="stable").reset_index(drop=True)
    return out


def load_study(source: str | Path) -> StudyData:
    """Read a study database (SQLite file or SQLAlchemy URL) or an ``asa export`` folder.

    Raises
    ------
    FileNotFoundError
        When ``source`` does not exist.
    ValueError
        Naming ``source``: not an asa-study database or export folder, or a study table
        without its study row.
    """
    text = str(source)
    path = Path(text)
    if "://" not in text and not path.exists():
        raise FileNotFoundError(2, "No such file", text)
    if "://" not in text and path.is_dir():
        raw = _read_csv_folder(path)
    else:
        raw = _read_db(source)
    tables = _normalise(raw, text)
    if tables["study"].empty:
        raise ValueError(f"{text}: table 'study' is empty; no study has been run into it")
    row = tables["study"].iloc[0]
    study = {
        "name": str(row.get("name", "")),
        "protocol_text": "" if pd.isna(row.get("protocol_text")) else str(row["protocol_text"]),
        "protocol_sha256": str(row.get("protocol_sha256", "")),
        "platform_version": str(row.get("platform_version", "")),
        "seed": int(row["seed"]) if not pd.isna(row.get("seed")) else None,
    }
    config = read_config(study["protocol_text"], source=text)
    return StudyData(source=text, study=study, config=config, tables=tables)


# --------------------------------------------------------------------------- tidy frames


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


def _sample_metrics(
    samples: pd.DataFrame, label_tasks: dict[int, dict[str, str]] | None = None
) -> pd.DataFrame:
    """Per trial_id: assist_share, beta_mean, clearance from samples, recognition_accuracy
    (only for trials in ``label_tasks``: trial id -> {label -> task type})."""
    if samples.empty:
        return pd.DataFrame(
            columns=[
                "trial_id",
                "assist_share",
                "beta_mean",
                "sample_clearance_mean_m",
                "sample_clearance_min_m",
                "clearance_std_m",
                "recognition_accuracy",
                "n_samples",
            ]
        )
    s = samples
    label_tasks = label_tasks or {}
    truth = s["true_task"] != ""
    recognised = pd.Series("", index=s.index, dtype=object)
    for tid, table in label_tasks.items():
        rows = s["trial_id"] == tid
        recognised[rows] = s.loc[rows, "label"].map(table).fillna("")
    hit = (recognised == s["true_task"]) & (s["target"] == s["true_target"]) & truth
    work = pd.DataFrame(
        {
            "trial_id": s["trial_id"].astype(int),
            "assisted": (s["beta"].astype(float) > ASSIST_THRESHOLD).astype(float),
            "beta": s["beta"].astype(float),
            "clearance": s["min_clearance_m"].astype(float),
            "truth": truth.astype(float),
            "hit": hit.astype(float),
            "labelled": ((s["label"] != "") & s["trial_id"].isin(list(label_tasks))).astype(float),
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
            "n_truth": g["truth"].sum(),
            "n_hit": g["hit"].sum(),
            "n_labelled": g["labelled"].sum(),
            "n_samples": g["beta"].size(),
        }
    )
    ok = (out["n_truth"] > 0) & (out["n_labelled"] > 0)
    out["recognition_accuracy"] = np.where(ok, out["n_hit"] / out["n_truth"].where(ok, 1), np.nan)
    return out.drop(columns=["n_truth", "n_hit", "n_labelled"]).reset_index()


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
    """The tidy frames of a study (see the module docstring for every decision).

    Raises
    ------
    ValueError
        Naming the source when there is no completed main trial.
    """
    t = data.tables
    cfg = data.config
    people = t["participant"].rename(columns={"id": "participant_id", "code": "participant"})
    people = people[["participant_id", "participant", "kind", "order_index", "mode_order"]]
    people = people.assign(
        order=[" > ".join(o or []) for o in people["mode_order"]],
    )
    trials = t["trial"].merge(people, on="participant_id", how="left")
    main = trials[trials["phase"] == "main"]
    completed = main[main["status"] == "completed"]
    # the last completed attempt of each (participant, ordinal) counts
    counted = completed.sort_values(["participant_id", "ordinal", "attempt", "id"]).drop_duplicates(
        ["participant_id", "ordinal"], keep="last"
    )
    if counted.empty:
        raise ValueError(
            f"{data.source}: no completed main trial (table 'trial', phase 'main', status "
            "'completed'); nothing to analyse"
        )
    warnings: list[str] = []
    not_counted = main[~main["id"].isin(counted["id"])]
    aborted = pd.DataFrame(
        {
            "participant": not_counted["participant"],
            "mode": not_counted["mode"],
            "ordinal": not_counted["ordinal"].astype(int),
            "attempt": not_counted["attempt"].astype(int),
            "status": not_counted["status"],
            "reason": [
                (o or {}).get("aborted_reason", "") if s != "completed" else "superseded attempt"
                for o, s in zip(not_counted["outcome"], not_counted["status"], strict=True)
            ],
        }
    ).reset_index(drop=True)
    modes = _mode_levels(cfg, list(dict.fromkeys(counted["mode"])))

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
    recomputed = frame["completion_time_s"] + cfg.collision_penalty_s * frame["collisions"]
    frame["score_s"] = frame["score_s"].fillna(recomputed)

    counted_ids = set(frame["trial_id"])
    samples = t["sample"][t["sample"]["trial_id"].isin(counted_ids)]
    label_tasks = {
        int(tid): dict(o["label_tasks"])
        for tid, o in zip(counted["id"], counted["outcome"], strict=True)
        if isinstance(o, dict) and isinstance(o.get("label_tasks"), dict)
    }
    frame = frame.merge(_sample_metrics(samples, label_tasks), on="trial_id", how="left")
    frame["clearance_mean_m"] = frame["clearance_mean_m"].fillna(frame["sample_clearance_mean_m"])
    frame["clearance_min_m"] = frame["clearance_min_m"].fillna(frame["sample_clearance_min_m"])
    frame = frame.drop(columns=["sample_clearance_mean_m", "sample_clearance_min_m"])
    frame["n_samples"] = frame["n_samples"].fillna(0).astype(int)
    if (frame["n_samples"] == 0).any():
        missing = frame.loc[frame["n_samples"] == 0, "participant"].tolist()
        warnings.append(f"main trials without samples (participants {', '.join(missing)})")

    # questions: counted main trials and completed baseline blocks
    baseline = trials[(trials["phase"] == "baseline") & (trials["status"] == "completed")]
    baseline = baseline.sort_values(["participant_id", "attempt", "id"]).drop_duplicates(
        "participant_id", keep="last"
    )
    level_of = dict(zip(frame["trial_id"], frame["mode"], strict=True))
    level_of.update(dict.fromkeys(baseline["id"].astype(int), BASELINE))
    who = dict(zip(trials["id"].astype(int), trials["participant"].astype(str), strict=True))
    q = t["question"]
    q = q[q["trial_id"].isin(level_of)]
    questions = pd.DataFrame(
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
    if len(questions):
        drive = questions[questions["mode"] != BASELINE]
        frame = frame.merge(secondary_metrics(drive, "trial_id"), on="trial_id", how="left")
    else:
        for col in (
            "secondary_questions",
            "secondary_answer_time_s",
            "secondary_errors",
            "secondary_misses",
            "secondary_error_rate",
        ):
            frame[col] = np.nan

    # questionnaires
    r = t["response"]
    last_trial = {}
    for _, g in frame.groupby("participant"):
        last = int(g.sort_values("position")["trial_id"].iloc[-1])
        last_trial.update(dict.fromkeys(g["trial_id"].astype(int), last))
    tlx = _tlx_scores(r, frame["trial_id"].tolist(), last_trial)
    frame = frame.merge(tlx, on="trial_id", how="left")
    pid_code = dict(zip(people["participant_id"], people["participant"].astype(str), strict=True))
    responses = pd.DataFrame(
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

    order = {m: i for i, m in enumerate(modes)}
    frame = frame.sort_values(
        ["participant", "mode"], key=lambda c: c.map(order) if c.name == "mode" else c
    ).reset_index(drop=True)
    counts = frame.groupby("participant")["mode"].nunique()
    participants = people.assign(participant=people["participant"].astype(str))[
        ["participant", "kind", "order_index", "order"]
    ].copy()
    participants["main_trials"] = (
        participants["participant"].map(frame.groupby("participant").size()).fillna(0).astype(int)
    )
    participants["complete"] = participants["participant"].map(counts).fillna(0) == len(modes)
    return Frames(
        trials=frame,
        questions=questions,
        responses=responses,
        participants=participants.reset_index(drop=True),
        aborted=aborted,
        modes=modes,
        warnings=tuple(warnings),
    )
