"""A small TOML writer for the subset scenario files use (``sim/scenarios/FORMAT.md``).

Top-level keys with strings, numbers, booleans and (nested) arrays of numbers; tables
of such values (``[start]``); arrays of such tables (``[[walls]]``). Output is
deterministic: keys in the dict's order, floats by ``repr``, so the same dict always
gives the same bytes. No dependency (``tomli_w`` is not installed, and the subset is
small).
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["dumps"]


def _value(v: Any, where: str) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"{where}: TOML has no {v!r} here; got a non-finite number")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a valid TOML basic string
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value(x, where) for x in v) + "]"
    raise ValueError(f"{where}: cannot write a {type(v).__name__} as TOML")


def _is_table_list(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _plain(table: dict[str, Any], prefix: str) -> list[str]:
    lines = []
    for key, v in table.items():
        if isinstance(v, dict) or _is_table_list(v):
            raise ValueError(f"{prefix}{key}: nested tables are not in the scenario subset")
        lines.append(f"{key} = {_value(v, prefix + key)}")
    return lines


def dumps(data: dict[str, Any]) -> str:
    """``data`` as TOML text: plain keys, then ``[tables]``, then ``[[arrays of tables]]``.

    Raises ``ValueError`` naming the key for a value outside the subset (a nested
    table, a non-finite float, an object).
    """
    plain = {k: v for k, v in data.items() if not (isinstance(v, dict) or _is_table_list(v))}
    lines = _plain(plain, "")
    for key, v in data.items():
        if isinstance(v, dict):
            lines += ["", f"[{key}]", *_plain(v, key + ".")]
    for key, v in data.items():
        if _is_table_list(v):
            for k, item in enumerate(v):
                lines += ["", f"[[{key}]]", *_plain(item, f"{key}[{k}].")]
    return "\n".join(lines) + "\n"
