"""Checked reading of TOML tables: every field typed, ranged and named on error.

Used by every loader of user-written files (scenarios, protocols) so that a bad
value always produces the same kind of one-line message:
``FILE: field 'walls[3].thickness': must be a positive number, got -1``.
Unknown keys are refused (:meth:`FieldReader.finish`): a typo must never
silently become a default.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sim.limits import MAX_COORDINATE_M, MAX_COUNT
from sim.limits import short_repr as _short

_REQUIRED = object()
MAX_NUMBER = 1e6  # |x| of any number field without a bound of its own


class FieldReader:
    """Reads and checks the fields of one TOML table, naming file and field on error.

    ``default=None`` means the field is required.
    """

    def __init__(self, path: str, data: dict[str, Any], prefix: str = "") -> None:
        self.path, self.data, self.prefix = path, data, prefix
        self.used: set[str] = set()

    def fail(self, key: str, message: str) -> ValueError:
        return ValueError(f"{self.path}: field '{self.prefix}{key}': {message}")

    def _get(self, key: str, default: Any) -> Any:
        self.used.add(key)
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            raise self.fail(key, "is required")
        return default

    def number(
        self,
        key: str,
        default: Any = None,
        *,
        positive: bool = False,
        non_negative: bool = False,
        maximum: float = math.inf,
    ) -> float:
        """A finite number, ``x <= maximum`` and ``|x| <= MAX_NUMBER``."""
        value = self._get(key, _REQUIRED if default is None else default)
        if not _finite(value, math.inf):
            raise self.fail(key, f"must be a number, got {_short(value)}")
        if positive and value <= 0:
            raise self.fail(key, f"must be a positive number, got {value!r}")
        if non_negative and value < 0:
            raise self.fail(key, f"must be zero or positive, got {value!r}")
        if value > maximum:
            raise self.fail(key, f"must be at most {maximum:g}, got {value!r}")
        if abs(value) > MAX_NUMBER:
            raise self.fail(key, f"must lie within -{MAX_NUMBER:g}..{MAX_NUMBER:g}, got {value!r}")
        return float(value)

    def integer(
        self, key: str, default: Any = None, *, minimum: int = 1, maximum: int = MAX_COUNT
    ) -> int:
        """An integer in ``minimum..maximum``."""
        value = self._get(key, _REQUIRED if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise self.fail(key, f"must be an integer >= {minimum}, got {_short(value)}")
        if value > maximum:
            raise self.fail(key, f"must be an integer in {minimum}..{maximum}, got {value!r}")
        return value

    def string(self, key: str, default: Any = None, *, allowed: tuple[str, ...] = ()) -> str:
        value = self._get(key, _REQUIRED if default is None else default)
        if not isinstance(value, str):
            raise self.fail(key, f"must be a string, got {_short(value)}")
        if allowed and value not in allowed:
            raise self.fail(key, f"must be one of {', '.join(allowed)}, got {_short(value)}")
        return value

    def vector(
        self, key: str, n: int, default: Any = None, *, unit: bool = False, positive: bool = False
    ) -> tuple[float, ...]:
        value = self._get(key, _REQUIRED if default is None else default)
        ok = (
            isinstance(value, list)
            and len(value) == n
            and all(_finite(v, MAX_COORDINATE_M) for v in value)
        )
        if not ok:
            raise self.fail(
                key,
                f"must be a list of {n} numbers of size at most {MAX_COORDINATE_M:g}, "
                f"got {_short(value)}",
            )
        if unit and not all(0.0 <= v <= 1.0 for v in value):
            raise self.fail(key, f"must hold numbers in [0, 1], got {value!r}")
        if positive and not all(v > 0 for v in value):
            raise self.fail(key, f"must hold positive numbers, got {value!r}")
        return tuple(float(v) for v in value)

    def points(self, key: str, *, minimum: int, default: Any = None) -> np.ndarray:
        value = self._get(key, _REQUIRED if default is None else default)
        if value is default and default == []:
            return np.empty((0, 2))
        ok = (
            isinstance(value, list)
            and len(value) >= minimum
            and all(
                isinstance(p, list) and len(p) == 2 and all(_finite(v, MAX_COORDINATE_M) for v in p)
                for p in value
            )
        )
        if not ok:
            raise self.fail(
                key,
                f"must be a list of at least {minimum} [x, y] points of finite numbers of "
                f"size at most {MAX_COORDINATE_M:g} m",
            )
        return np.array(value, dtype=float).reshape(-1, 2)

    def table(self, key: str) -> dict[str, Any] | None:
        value = self._get(key, {})
        if not isinstance(value, dict):
            raise self.fail(key, "must be a table")
        return value or None

    def tables(self, key: str) -> list[FieldReader]:
        value = self._get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.fail(key, "must be an array of tables ([[...]])")
        return [FieldReader(self.path, v, f"{self.prefix}{key}[{i}].") for i, v in enumerate(value)]

    def sub(self, key: str) -> FieldReader:
        return FieldReader(self.path, self.table(key) or {}, f"{self.prefix}{key}.")

    def finish(self) -> None:
        """Refuse unknown keys: a typo must not silently become a default."""
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise self.fail(unknown[0], "is not a known field")


def _finite(value: Any, limit: float) -> bool:
    """Whether ``value`` is a number (not a bool) with ``|value| <= limit``; an integer too
    large for a float is not (``math.isfinite`` would raise ``OverflowError``)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    if isinstance(value, int):
        return abs(value) <= min(limit, 1e300)
    return math.isfinite(value) and abs(value) <= limit
