"""A study's identity, checked on every write into an existing study (issue 20): the
protocol's SHA-256, the seed and the platform version a study was made with must be those of
the writer, or the writer must say ``force`` (then the override is recorded in the session's
``forced``/``note``). Pure: compares values, words the refusal and the note."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True, slots=True)
class Mismatch:
    """One field of the study's identity that differs: ``field`` as stored (e.g.
    ``study.seed``), the study's value and the writer's."""

    field: str
    stored: Any
    wanted: Any

    def words(self) -> str:
        return (
            f"field '{self.field}': the study has {show(self.stored)}, this run {show(self.wanted)}"
        )


def show(value: Any) -> str:
    """A value as the messages show it (a SHA-256 shortened to 12 hex digits)."""
    text = str(value)
    sha = len(text) == 64 and all(c in "0123456789abcdef" for c in text)
    return text[:12] + "..." if sha else text


def mismatches(
    stored: dict[str, Any], wanted: dict[str, Any], prefix: str = "study"
) -> list[Mismatch]:
    """The fields of ``wanted`` whose value differs from ``stored`` (a key missing from
    ``stored`` is not compared: an older database did not store it)."""
    return [
        Mismatch(f"{prefix}.{k}", stored[k], v)
        for k, v in wanted.items()
        if k in stored and stored[k] is not None and stored[k] != v
    ]


def check(
    db: str | Path, found: list[Mismatch], force: bool, *, flag: str = "force=True"
) -> list[str]:
    """Refuse ``found`` with one line naming the database, the fields and both values
    (``ValueError``), unless ``force``; then the notes to record, one per field."""
    if not found:
        return []
    if not force:
        raise ValueError(
            f"{db}: "
            + "; ".join(m.words() for m in found)
            + f"; give a new database file, or use {flag} to write into this study anyway"
        )
    return [
        f"forced: {m.field} {show(m.wanted)} differs from the study's {show(m.stored)}"
        for m in found
    ]
