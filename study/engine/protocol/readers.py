"""Reading one TOML table's fields of a protocol: the checks every table shares
(:class:`sim.fields.FieldReader` does numbers, strings and vectors)."""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

from sim.fields import FieldReader


def raw(r: FieldReader, key: str, default: Any = None) -> Any:
    """The raw value of ``key`` (marked as known), ``default`` when absent, or "is required"."""
    r.used.add(key)
    if key in r.data:
        return r.data[key]
    if default is None:
        raise r.fail(key, "is required")
    return default


def boolean(r: FieldReader, key: str, default: bool) -> bool:
    value = raw(r, key, default)
    if not isinstance(value, bool):
        raise r.fail(key, f"must be true or false, got {value!r}")
    return value


def text(r: FieldReader, key: str, default: str | None = None) -> str:
    value = r.string(key, default)
    if default is None and not value.strip():
        raise r.fail(key, "must not be empty")
    return value


def string_list(
    r: FieldReader,
    key: str,
    default: list[str] | None,
    *,
    allowed: Collection[str] = (),
    unique: bool = True,
) -> tuple[str, ...]:
    value = raw(r, key, default)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise r.fail(key, f"must be a list of strings, got {value!r}")
    for i, v in enumerate(value):
        if allowed and v not in allowed:
            raise r.fail(f"{key}[{i}]", f"must be one of {', '.join(allowed)}, got {v!r}")
    duplicates = sorted({v for v in value if value.count(v) > 1})
    if duplicates and unique:
        raise r.fail(key, f"must not repeat names; {duplicates[0]!r} appears twice")
    return tuple(value)
