"""Numerical helpers shared by the statistics: rounding tests and JSON-safe numbers."""

from __future__ import annotations

import math

import numpy as np

# A sum of squares or an SD below this many ulps of the data's magnitude is rounding, not data.
_ZERO_ULPS = 64.0


def _is_rounding(value: float, y: np.ndarray, *, squared: bool) -> bool:
    """Whether ``value`` (an SD, or a sum of squares over y's cells) is rounding noise."""
    scale = _ZERO_ULPS * np.finfo(float).eps * float(np.max(np.abs(y)))
    if squared:
        return value <= y.size * scale**2
    return value <= scale


def _number(value: float) -> float | None:
    """A plain float, or None for NaN and infinities (JSON has neither)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _clean(value):
    """Recursively turn numpy scalars into Python ones and NaN/inf into None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return _number(value)
    return value


def _check_alpha(alpha: float, name: str = "alpha") -> None:
    if not (isinstance(alpha, int | float) and 0.0 < float(alpha) < 1.0):
        raise ValueError(f"{name} must be a number strictly between 0 and 1, got {alpha!r}")
