"""Read a study database or its ``asa export`` CSV folder into typed raw tables.

The same :class:`StudyData` from both sources: JSON columns parsed, booleans as bool, NULL as
NaN/None; the protocol's analysis settings as :class:`AnalysisConfig` (thesis Sec. 7.6.2).
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

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

# the lab's recorded streams (revision 0004): read where the database or folder has them
OPTIONAL_TABLES: tuple[str, ...] = ("lsl_stream", "lsl_chunk", "lsl_offset", "lsl_gap")

# [analysis] timeouts: a timed-out main trial's completion time and score are missing
# ("exclude") or the time limit, a right-censored value ("censor"); docs/decisions.md
TIMEOUTS: tuple[str, ...] = ("exclude", "censor")

MAX_MAGNITUDE = 1e15  # |x| of any number read from a CSV file: beyond it sums of squares overflow

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
    "participant": ("code", "kind", "site"),
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
    posthoc : the post-hoc family the report leads with ([analysis] posthoc, "lsd_paired";
        also "lsd_pooled", "holm", "bonferroni").
    posthoc_gate : which post-hoc families wait for the omnibus test ([analysis]
        posthoc_gate, "auto": the LSD forms only; "omnibus", "none").
    metrics : the protocol's planned metrics ([analysis] metrics).
    secondary_baseline_level : the baseline as a level of secondary metrics.
    collision_penalty_s : [s] per collision in the score ([scoring], 60).
    modes : the protocol's mode names in its order ([modes] names).
    timeouts : what a timed-out main trial's completion time and score are
        ([analysis] timeouts): "exclude" (missing) or "censor" (the time limit).
    test : the planned omnibus test of every metric ([analysis] test, "rm_anova"; also
        "friedman", "auto").
    tests : metric -> planned test, overriding ``test`` ([analysis.tests]).
    end_on_collision : a collision ends a main trial (a main phase's ``end_on_collision``,
        the Sec. 7.5 kind of study: its crashes and Table 7.10 are reported).
    """

    alpha: float = 0.05
    gate: str = "auto"
    posthoc: str = "lsd_paired"
    posthoc_gate: str = "auto"
    metrics: tuple[str, ...] = ()
    secondary_baseline_level: bool = True
    collision_penalty_s: float = 60.0
    modes: tuple[str, ...] = ()
    timeouts: str = "exclude"
    end_on_collision: bool = False
    test: str = "rm_anova"
    tests: Mapping[str, str] = field(default_factory=dict)

    def test_for(self, metric: str) -> str:
        """The planned omnibus test of ``metric`` (its [analysis.tests] entry, else test)."""
        return self.tests.get(metric, self.test)


@dataclass(frozen=True, slots=True)
class StudyData:
    """The raw tables of one study, typed the same whatever the source.

    Attributes
    ----------
    source : the database or folder read.
    study : {name, protocol_text, protocol_sha256, platform_version, seed}.
    config : the protocol's analysis settings.
    tables : table name -> DataFrame with the storage columns (see :data:`TABLES`; and
        :data:`OPTIONAL_TABLES` where the source has them).
    """

    source: str
    study: dict[str, Any]
    config: AnalysisConfig
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)


_TESTS = ("rm_anova", "friedman", "auto")  # analysis.stats.TESTS, without importing scipy


def _test(value: Any, name: str, source: str) -> str:
    if value not in _TESTS:
        raise ValueError(
            f"{source}: field {name!r} must be one of {', '.join(_TESTS)}, got {value!r}"
        )
    return str(value)


def read_config(protocol_text: str, *, source: str = "protocol") -> AnalysisConfig:
    """The analysis settings of a protocol text; defaults where a field is absent.

    Raises ``ValueError`` naming ``source`` when the text is not TOML.
    """
    try:
        doc = tomllib.loads(protocol_text or "")
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{source}: field 'study.protocol_text' is not TOML: {error}") from error
    except RecursionError:
        raise ValueError(
            f"{source}: field 'study.protocol_text' nests arrays or tables too deeply"
        ) from None
    try:
        return _config(doc, source)
    except (AttributeError, TypeError, ValueError) as error:
        if str(error).startswith(f"{source}: "):
            raise
        raise ValueError(
            f"{source}: field 'study.protocol_text': a malformed [analysis], [scoring], "
            f"[modes] or [[phases]] table ({error})"
        ) from None


def _config(doc: dict[str, Any], source: str) -> AnalysisConfig:
    analysis = doc.get("analysis", {}) or {}
    scoring = doc.get("scoring", {}) or {}
    modes = (doc.get("modes", {}) or {}).get("names", []) or []
    timeouts = str(analysis.get("timeouts", "exclude"))
    if timeouts not in TIMEOUTS:
        raise ValueError(
            f"{source}: field 'analysis.timeouts' must be one of {', '.join(TIMEOUTS)}, got "
            f"{timeouts!r}"
        )
    return AnalysisConfig(
        alpha=float(analysis.get("alpha", 0.05)),
        gate=str(analysis.get("gate", "auto")),
        posthoc=str(analysis.get("posthoc", "lsd_paired")),
        posthoc_gate=str(analysis.get("posthoc_gate", "auto")),
        metrics=tuple(str(m) for m in analysis.get("metrics", ())),
        secondary_baseline_level=bool(analysis.get("secondary_baseline_level", True)),
        collision_penalty_s=float(scoring.get("collision_penalty_s", 60.0)),
        modes=tuple(str(m) for m in modes),
        timeouts=timeouts,
        test=_test(analysis.get("test", "rm_anova"), "analysis.test", source),
        tests={
            str(k): _test(v, f"analysis.tests.{k}", source)
            for k, v in (analysis.get("tests", {}) or {}).items()
        },
        end_on_collision=any(
            isinstance(ph, dict) and ph.get("kind") == "main" and ph.get("end_on_collision") is True
            for ph in doc.get("phases", []) or []
        ),
    )


def _read_db(db: Path | str) -> dict[str, pd.DataFrame]:
    from sqlalchemy import inspect, text
    from sqlalchemy.exc import DatabaseError

    from study.data.storage import open_database

    try:
        engine = open_database(db, create=False)
    except DatabaseError as error:
        raise ValueError(f"{db}: not an SQLite database ({error.orig})") from error
    try:
        tables: dict[str, pd.DataFrame] = {}
        with engine.connect() as conn:
            present = set(inspect(conn).get_table_names())
            for name in TABLES + tuple(t for t in OPTIONAL_TABLES if t in present):
                tables[name] = pd.read_sql_query(text(f'SELECT * FROM "{name}" ORDER BY id'), conn)
    except DatabaseError as error:
        raise ValueError(f"{db}: cannot read the study tables ({error.orig})") from error
    finally:
        engine.dispose()
    return tables


def _read_csv_folder(folder: Path) -> dict[str, pd.DataFrame]:
    tables = {}
    optional = tuple(t for t in OPTIONAL_TABLES if (folder / f"{t}.csv").is_file())
    for name in TABLES + optional:
        path = folder / f"{name}.csv"
        if not path.is_file():
            raise ValueError(
                f"{folder}: not an 'asa export' folder: file {name}.csv is missing "
                f"(expected {', '.join(t + '.csv' for t in TABLES)})"
            )
        text_cols = {c: str for c in _TEXT.get(name, ()) + _JSON.get(name, ())}
        if name == "study":
            text_cols.update(protocol_text=str, protocol_sha256=str, name=str)
        if name == "lsl_chunk":  # the samples as base64 text (asa export)
            text_cols.update(timestamps=str, data=str)
        if name == "lsl_stream":
            text_cols.update(name=str, type=str, source_id=str, hostname=str, channels=str,
                             info_xml=str, source=str, dtype=str, channel_format=str)  # fmt: skip
        try:
            tables[name] = pd.read_csv(path, dtype=text_cols, keep_default_na=False, na_values=[""])
        except (pd.errors.ParserError, UnicodeDecodeError) as error:
            what = " ".join(str(error).split())
            raise ValueError(f"{path}: not a readable CSV ({what})") from None
        except pd.errors.EmptyDataError:
            raise ValueError(f"{path}: empty file; expected a header row") from None
        _check_numbers(path, name, tables[name])
    return tables


def _check_numbers(path: Path, name: str, frame: pd.DataFrame) -> None:
    """Every cell of a numeric column of the storage schema is empty or a finite number of
    sane size (``|x| <= MAX_MAGNITUDE``); else ``ValueError`` naming file, column and line."""
    from study.data.storage import Base

    table = Base.metadata.tables[name]
    for column in table.columns:
        if column.name not in frame.columns or column.type.python_type not in (int, float):
            continue
        raw = frame[column.name]
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = raw.notna().to_numpy() & ~(np.abs(values) <= MAX_MAGNITUDE)  # NaN: not a number
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            cell = raw.iloc[row]
            cell = cell.item() if isinstance(cell, np.generic) else cell
            raise ValueError(
                f"{path}: column {column.name!r} line {row + 2}: {cell!r} is not a "
                f"finite number of size at most {MAX_MAGNITUDE:g}"
            )


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
