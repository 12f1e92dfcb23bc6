"""Bounds on what a user can write in a file or type as an option, and a TOML reader that
fails in one line (issue 20).

Shared by the loaders of every layer (``sim`` may import nothing of ``study``, so the
limits live here, at the bottom): scenario files (:mod:`sim.scenario`), protocols
(:mod:`study.engine.protocol`), the ``asa`` options. Each limit is far beyond any real
study or room and far below what would exhaust memory or overflow storage.
"""

from __future__ import annotations

import re
import tomllib
from typing import Any

__all__ = [
    "MAX_CELLS",
    "MAX_COORDINATE_M",
    "MAX_COUNT",
    "MAX_DURATION_S",
    "MAX_EXTENT_M",
    "MAX_PARTICIPANTS",
    "MAX_SEED",
    "MAX_TOML_DEPTH",
    "SAFE_NAME",
    "check_name",
    "loads_toml",
    "short_repr",
]

MAX_PARTICIPANTS = 10_000  # participants of one study (protocol, --participants)
MAX_SEED = 2**63 - 1  # seeds are stored in SQLite's signed 64-bit INTEGER
MAX_DURATION_S = 86_400.0  # [s] any duration or timeout: 24 h
MAX_COUNT = 100_000  # questions, attempts, block sizes and other counts
MAX_EXTENT_M = 200.0  # [m] a scene's width and depth
MAX_COORDINATE_M = 10_000.0  # [m] |x|, |y| of any point in a scene file
MAX_CELLS = 16_000_000  # cells of a scene's occupancy grid at its resolution (64 MB as bool)
MAX_TOML_DEPTH = 64  # nesting of arrays and tables in a TOML file

# A name that may become part of a file name: like a participant code
# (study.engine.session.CODE_PATTERN; a test keeps the two equal).
SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")


def check_name(value: object, where: str) -> str:
    """``value`` when it is a safe name (:data:`SAFE_NAME`), else ``ValueError`` naming
    ``where`` (``"FILE: field 'name'"``)."""
    if not isinstance(value, str) or not SAFE_NAME.match(value):
        raise ValueError(
            f"{where}: must be 1-64 letters, digits, '_' or '-' starting with a letter or "
            f"digit (it becomes part of file names), got {short_repr(value)}"
        )
    return value


def short_repr(value: object, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters."""
    try:
        text = repr(value)
    except RecursionError:
        return f"a deeply nested {type(value).__name__}"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _depth(value: Any) -> int:
    """Nesting depth of lists and dicts in ``value`` (a scalar is 0), iteratively."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, dict):
            children = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        deepest = max(deepest, level + 1)
        stack.extend((child, level + 1) for child in children)
    return deepest


def loads_toml(text: str, source: str) -> dict[str, Any]:
    """Parse TOML ``text``; every failure a ``ValueError`` naming ``source`` in one line.

    Malformed TOML, nesting deeper than :data:`MAX_TOML_DEPTH` (Python's ``tomllib``
    recurses once per level and raises ``RecursionError`` at about a thousand).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{source}: not valid TOML: {' '.join(str(error).split())}") from None
    except RecursionError:
        raise ValueError(
            f"{source}: not valid here: arrays or tables nested deeper than {MAX_TOML_DEPTH}"
        ) from None
    if _depth(data) > MAX_TOML_DEPTH:
        raise ValueError(
            f"{source}: not valid here: arrays or tables nested deeper than {MAX_TOML_DEPTH}"
        )
    return data
