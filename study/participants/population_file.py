"""Population files: a synthetic population model as TOML (issue 39), read by ``asa synth``,
``asa pilot`` and ``asa power`` (``--population``); ``asa calibrate`` writes them
(with a ``[calibration]`` table of its provenance).

The file has one table ``[population]`` whose keys are fields of
:class:`study.participants.population.Population` (any subset; the rest keep their
defaults), and optionally a ``[calibration]`` table that records how the values were found
(read and kept, never used)::

    [population]
    speed_median = 0.32          # [m/s]
    speed_range = [0.2, 0.45]    # [m/s] low, high
    tlx_bias_mean = 4.0          # [points]

Every value is checked against :data:`BOUNDS`; an unknown table or key, a value out of range
or of the wrong shape is refused with the file, the field and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from study.participants.population import Population

# field -> (low, high) of each number; a pair field's two numbers must also be ordered
BOUNDS: dict[str, tuple[float, float]] = {
    "speed_median": (0.05, 1.0),
    "speed_sigma": (0.0, 1.0),
    "speed_range": (0.05, 1.0),
    "noise_range": (0.0, 5.0),
    "delay_range_s": (0.0, 2.0),
    "disturbance_range": (0.0, 1.0),
    "distraction_p": (0.0, 1.0),
    "answer_time_median_s": (0.2, 10.0),
    "answer_time_sigma": (0.0, 1.0),
    "error_range": (0.0, 1.0),
    "slowdown_range": (1.0, 5.0),
    "error_factor_range": (1.0, 10.0),
    "age_range": (16, 100),
    "tlx_bias_mean": (-50.0, 50.0),
    "tlx_bias_sd": (0.0, 50.0),
    "tlx_gain_range": (0.0, 3.0),
}
TABLES = ("population", "calibration")


def _fail(source: str, name: str, message: str) -> ValueError:
    return ValueError(f"{source}: field 'population.{name}' {message}")


def _number(source: str, name: str, value: Any, integer: bool) -> float:
    low, high = BOUNDS[name]
    kind = "an integer" if integer else "a number"
    ok = isinstance(value, int) if integer else isinstance(value, int | float)
    if isinstance(value, bool) or not ok or not math.isfinite(float(value)):
        raise _fail(source, name, f"must be {kind} in [{low:g}, {high:g}], got {value!r}")
    if not low <= value <= high:
        raise _fail(source, name, f"must lie in [{low:g}, {high:g}], got {value!r}")
    return value


def _field(source: str, name: str, value: Any, default: Any) -> Any:
    """One checked value, shaped as the default (a number, a pair or a triple)."""
    integer = name == "age_range"
    if not isinstance(default, tuple):
        return float(_number(source, name, value, integer))
    size = len(default)
    if not isinstance(value, list) or len(value) != size:
        raise _fail(source, name, f"must be a list of {size} numbers, got {value!r}")
    numbers = tuple(_number(source, name, v, integer) for v in value)
    if name == "distraction_p":
        if abs(sum(numbers) - 1.0) > 1e-6:
            raise _fail(source, name, f"must sum to 1 (hold, drift, release), got {value!r}")
    elif numbers[0] > numbers[1]:
        raise _fail(source, name, f"must be [low, high] with low <= high, got {value!r}")
    return numbers if integer else tuple(float(v) for v in numbers)


def population_from_mapping(values: Mapping[str, Any], source: str) -> Population:
    """A :class:`Population` from ``[population]``'s keys, each checked (see :data:`BOUNDS`)."""
    defaults = Population()
    allowed = ", ".join(f.name for f in dataclasses.fields(Population))
    changes = {}
    for name, value in values.items():
        if name not in BOUNDS:
            raise _fail(source, name, f"is not a population parameter; allowed: {allowed}")
        changes[name] = _field(source, name, value, getattr(defaults, name))
    population = dataclasses.replace(defaults, **changes)
    if population.speed_range[0] > population.speed_median or (
        population.speed_median > population.speed_range[1]
    ):
        raise _fail(source, "speed_median", f"must lie in speed_range {population.speed_range}")
    return population


def load_population(path: str | Path) -> Population:
    """Read and check a population file.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        Naming the file and field: not TOML, an unknown table or key, a value out of range.
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(2, "no such population file", str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path}: not a valid TOML file: {error}") from None
    for key in doc:
        if key not in TABLES:
            raise ValueError(f"{path}: table '{key}' is not allowed; allowed: {', '.join(TABLES)}")
    table = doc.get("population")
    if not isinstance(table, dict):
        raise ValueError(f"{path}: field 'population' must be a table of parameters")
    return population_from_mapping(table, str(path))


def population_toml(population: Population, calibration: Mapping[str, Any] | None = None) -> str:
    """The text of a population file with every field of ``population`` (and, when given,
    a ``[calibration]`` table of plain numbers, strings and lists)."""
    lines = ["[population]"]
    for f in dataclasses.fields(Population):
        lines.append(f"{f.name} = {_toml_value(getattr(population, f.name))}")
    if calibration:
        lines += ["", "[calibration]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in calibration.items()]
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(round(value, 6))
    return str(value)
