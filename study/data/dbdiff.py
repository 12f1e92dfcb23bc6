"""Comparing two study databases row by row (``asa db diff``): is a rerun, a resumed
study or the same study on an optimised platform the same data?

Every table of the data model (:mod:`study.data.storage`) is read in primary-key order
from both databases and compared column by column, except the columns that record when
or where something happened on the machine rather than what happened in the study
(:data:`WALL_CLOCK_COLUMNS`: creation and start/end times, the humans' tick jitter, the
recordings' file names, the platform version, the model file's path, the machine, a
session's random global key), including such keys inside JSON columns.
Floats compare equal within ``tolerance`` (absolute); everything else exactly. For
each differing table the report says, per column, how many values differ and by how
much at most, and which rows only one database has: the same study run on two machines
whose CPUs round differently is compared this way (docs/decisions.md, "Reproducibility
across machines").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.storage import Base, open_database

# when and where on the machine, not what in the study: never compared (``model_path``:
# the file a mode's model was read from, a folder that differs between checkouts)
WALL_CLOCK_COLUMNS = frozenset(
    {
        "model_path",
        "created_at",
        "started_at",
        "ended_at",
        "released_at",
        "tick_jitter_ms",
        "recording_path",
        "platform_version",
        "machine",
        "uid",
        "lsl_clock_s",
        "received_clock_s",
        "input_age_ticks",
        "rtt_ms",
    }
)
MAX_SHOWN = 5  # differing rows shown per table


@dataclass(frozen=True, slots=True)
class ColumnDiff:
    """How one column differs over the common rows: values beyond the tolerance, and the
    largest absolute difference of its floats (inf where non-float values differ)."""

    column: str
    differing: int
    largest: float


@dataclass(frozen=True, slots=True)
class TableDiff:
    """How one table differs: row counts, the number of differing rows, the first
    few differences as ``(primary key, column, value in a, value in b)``, each differing
    column's :class:`ColumnDiff` and the first keys found in only one database."""

    table: str
    rows_a: int
    rows_b: int
    differing_rows: int
    first: tuple[tuple[Any, str, Any, Any], ...]
    largest_float_difference: float  # over all compared floats of the common rows
    columns: tuple[ColumnDiff, ...] = ()
    only_a: tuple[Any, ...] = ()  # the first MAX_SHOWN keys
    only_b: tuple[Any, ...] = ()


@dataclass(frozen=True, slots=True)
class DiffReport:
    """What :func:`diff` found: a :class:`TableDiff` per table that differs."""

    a: str
    b: str
    tolerance: float
    tables: tuple[str, ...]  # compared
    differences: tuple[TableDiff, ...] = field(default_factory=tuple)

    @property
    def identical(self) -> bool:
        return not self.differences

    def as_dict(self) -> dict[str, Any]:
        return {
            "a": self.a,
            "b": self.b,
            "tolerance": self.tolerance,
            "identical": self.identical,
            "tables": list(self.tables),
            "ignored_columns": sorted(WALL_CLOCK_COLUMNS),
            "differences": [
                {
                    "table": d.table,
                    "rows_a": d.rows_a,
                    "rows_b": d.rows_b,
                    "differing_rows": d.differing_rows,
                    "largest_float_difference": d.largest_float_difference,
                    "columns": {
                        c.column: {"differing": c.differing, "largest": _json_float(c.largest)}
                        for c in d.columns
                    },
                    "only_a": [repr(k) for k in d.only_a],
                    "only_b": [repr(k) for k in d.only_b],
                    "first": [
                        {"key": k, "column": c, "a": repr(x), "b": repr(y)}
                        for k, c, x, y in d.first
                    ],
                }
                for d in self.differences
            ],
        }

    def text(self) -> str:
        head = f"{self.a} vs {self.b}: "
        if self.identical:
            return head + (
                f"identical ({len(self.tables)} tables; wall-clock columns ignored: "
                f"{', '.join(sorted(WALL_CLOCK_COLUMNS))})"
            )
        lines = [head + f"{len(self.differences)} of {len(self.tables)} tables differ"]
        for d in self.differences:
            lines.append(
                f"  {d.table}: rows {d.rows_a} vs {d.rows_b}, {d.differing_rows} common rows "
                f"differ (largest float difference {d.largest_float_difference:.3g})"
            )
            lines += [
                f"    column {c.column}: {c.differing} values differ, largest difference "
                + ("(not numbers)" if math.isinf(c.largest) else f"{c.largest:.3g}")
                for c in d.columns
            ]
            for side, keys in (("a", d.only_a), ("b", d.only_b)):
                if keys:
                    lines.append(f"    only in {side}: " + ", ".join(repr(k) for k in keys))
            lines += [f"    {k}: {c}: {x!r} vs {y!r}" for k, c, x, y in d.first]
        return "\n".join(lines)


def _strip(value: Any) -> Any:
    """A JSON value without its wall-clock keys, at any depth."""
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in WALL_CLOCK_COLUMNS}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def _gap(x: Any, y: Any) -> float:
    """The largest absolute difference of the floats in ``x`` and ``y`` (same shape), 0
    without floats, inf where the shapes or the other values differ."""
    if isinstance(x, float) and isinstance(y, float):
        if math.isnan(x) and math.isnan(y):
            return 0.0
        if math.isfinite(x) and math.isfinite(y):
            return abs(x - y)
        return 0.0 if x == y else math.inf
    if isinstance(x, dict) and isinstance(y, dict):
        if x.keys() != y.keys():
            return math.inf
        return max((_gap(x[k], y[k]) for k in x), default=0.0)
    if isinstance(x, list) and isinstance(y, list):
        if len(x) != len(y):
            return math.inf
        return max((_gap(a, b) for a, b in zip(x, y, strict=True)), default=0.0)
    return 0.0 if x == y else math.inf


def _leaf(x: Any, y: Any, tolerance: float, path: str) -> tuple[str, Any, Any]:
    """The first place inside JSON values ``x`` and ``y`` where they differ by more than
    ``tolerance``: (its path, e.g. ``outcome.recognition.null_ticks``, x's, y's)."""
    if isinstance(x, dict) and isinstance(y, dict) and x.keys() == y.keys():
        for k in x:
            if _gap(x[k], y[k]) > tolerance:
                return _leaf(x[k], y[k], tolerance, f"{path}.{k}")
    if isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
        for i, (a, b) in enumerate(zip(x, y, strict=True)):
            if _gap(a, b) > tolerance:
                return _leaf(a, b, tolerance, f"{path}[{i}]")
    return path, x, y


def _rows(session: Session, table: Any) -> dict[Any, dict[str, Any]]:
    """Primary key -> {column: value} of the compared columns of ``table``."""
    keys = [c.name for c in table.primary_key.columns]
    names = [c.name for c in table.columns if c.name not in WALL_CLOCK_COLUMNS]
    out = {}
    for row in session.execute(select(table).order_by(*table.primary_key.columns)).mappings():
        key = row[keys[0]] if len(keys) == 1 else tuple(row[k] for k in keys)
        out[key] = {n: _strip(row[n]) for n in names}
    return out


def _compare(name: str, a: dict, b: dict, tolerance: float) -> TableDiff | None:
    differing, first, largest = 0, [], 0.0
    per_column: dict[str, list[float]] = {}  # column -> [values differing, largest gap]
    for key in sorted(a.keys() & b.keys(), key=repr):
        bad = False
        for column, x in a[key].items():
            y = b[key][column]
            gap = _gap(x, y)
            if math.isfinite(gap):
                largest = max(largest, gap)
            if gap > tolerance:
                bad = True
                stats = per_column.setdefault(column, [0, 0.0])
                stats[0] += 1
                stats[1] = max(stats[1], gap)
                if len(first) < MAX_SHOWN:
                    first.append((key, *_leaf(x, y, tolerance, column)))
        differing += bad
    if differing == 0 and len(a) == len(b) and a.keys() == b.keys():
        return None
    columns = tuple(ColumnDiff(c, int(n), float(g)) for c, (n, g) in per_column.items())
    only_a = tuple(sorted(a.keys() - b.keys(), key=repr)[:MAX_SHOWN])
    only_b = tuple(sorted(b.keys() - a.keys(), key=repr)[:MAX_SHOWN])
    return TableDiff(
        name, len(a), len(b), differing, tuple(first), largest, columns, only_a, only_b
    )


def _json_float(x: float) -> float | str:
    """``x`` for JSON: ``"inf"`` for an infinity (non-float values that differ)."""
    return x if math.isfinite(x) else "inf"


def diff(a: str | Path, b: str | Path, *, tolerance: float = 0.0) -> DiffReport:
    """Compare the study databases ``a`` and ``b`` (files or URLs, opened read-only).

    ``tolerance`` [the column's unit]: floats within it of each other count as equal.
    Raises ValueError (one line) for what is not a study database.
    """
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise ValueError(f"--tolerance: must be a finite number >= 0, got {tolerance}")
    engines = [open_database(db, create=False) for db in (a, b)]
    try:
        tables = sorted(Base.metadata.tables)
        differences = []
        with Session(engines[0]) as sa, Session(engines[1]) as sb:
            for name in tables:
                table = Base.metadata.tables[name]
                found = _compare(name, _rows(sa, table), _rows(sb, table), tolerance)
                if found is not None:
                    differences.append(found)
    finally:
        for engine in engines:
            engine.dispose()
    return DiffReport(str(a), str(b), tolerance, tuple(tables), tuple(differences))
