"""Fuzzing the protocol and scenario loaders (issue 20): mutated shipped files either load
or are refused with one ``ValueError`` line; never another exception.

Each example takes a shipped file (``protocols/*.toml``, ``sim/scenarios/*.toml``) and
mutates it: a key dropped, a value replaced by another type, a huge or negative number,
NaN or infinity, a string that looks like a path, a deeply nested array, or the text
itself cut, spliced or sprinkled with random bytes. The file is then loaded through the
same function the ``asa`` commands use (:func:`study.engine.protocol.load_protocol`,
:func:`study.jobs.scenes.load`). About 200 examples per format in the default run; the
``slow`` variants run 2,000, and 300 that also derive the components of a scene that
loads and check it (``asa scenario show``, ``asa scenario check``).
"""

from __future__ import annotations

import json
import math
import tempfile
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from protocols import PROTOCOL_DIR
from sim.scenario import SCENARIO_DIR
from study.engine.protocol import load_protocol
from study.jobs.scenes import load as load_scene

PROTOCOLS = sorted(PROTOCOL_DIR.glob("*.toml"))
SCENES = sorted(SCENARIO_DIR.glob("*.toml"))
FOLDER = Path(tempfile.mkdtemp(prefix="asa-fuzz-"))


class Deep:
    """A value written as an array nested ``depth`` levels deep."""

    def __init__(self, depth: int) -> None:
        self.depth = depth


# ------------------------------------------------------------------ writing TOML


def _key(key: str) -> str:
    return key if key and all(c.isalnum() or c in "_-" for c in key) else json.dumps(key)


def _value(v: Any) -> str:
    """``v`` as a TOML value; tables inline, so one writer serves every nesting."""
    if isinstance(v, Deep):
        return "[" * v.depth + "]" * v.depth
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dumps(data: dict[str, Any]) -> str:
    return "".join(f"{_key(k)} = {_value(v)}\n" for k, v in data.items())


# ------------------------------------------------------------------ mutations

NUMBERS = st.one_of(
    st.integers(),
    st.sampled_from([0, -1, 2**63 - 1, 2**63, -(2**63), 10**12, 10**23, 10**400]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e308, -1e308, 1e-308, 5e-324, float("nan"), float("inf"), 1e7, -0.0]),
)
STRINGS = st.one_of(
    st.text(max_size=20),
    st.sampled_from(
        ["", "../../escaped", "/etc/passwd", "..", "a b", "x" * 70, "nul\0", "\u202e", "nan"]
    ),
)
SCALARS = st.one_of(NUMBERS, STRINGS, st.booleans())
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.text(min_size=1, max_size=8), inner, max_size=3),
    ),
    max_leaves=8,
) | st.builds(Deep, st.integers(1, 3000))


def _paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path (dict keys and list indices) into ``data``."""
    out = []
    if isinstance(data, dict):
        items = data.items()
    elif isinstance(data, list):
        items = enumerate(data)
    else:
        return out
    for k, v in items:
        out.append((*prefix, k))
        out += _paths(v, (*prefix, k))
    return out


@st.composite
def mutated(draw: st.DrawFn, files: list[Path]) -> str | bytes:
    """A shipped file's text, mutated one to three times."""
    path = draw(st.sampled_from(files))
    text = path.read_text(encoding="utf-8")
    if draw(st.integers(0, 4)) == 0:  # the bytes themselves
        raw = bytearray(text.encode("utf-8"))
        for _ in range(draw(st.integers(1, 8))):
            at = draw(st.integers(0, len(raw)))
            kind = draw(st.sampled_from(["insert", "replace", "cut"]))
            if kind == "cut":
                del raw[at : at + draw(st.integers(1, 400))]
            else:
                chunk = draw(st.binary(min_size=1, max_size=8))
                raw[at : at + (len(chunk) if kind == "replace" else 0)] = chunk
        return bytes(raw)
    data = tomllib.loads(text)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(data)
        if not paths:
            break
        where = draw(st.sampled_from(paths))
        parent = data
        for k in where[:-1]:
            parent = parent[k]
        if draw(st.booleans()) and isinstance(parent, dict):
            del parent[where[-1]]
        else:
            parent[where[-1]] = draw(VALUES)
    return dumps(data)


def _write(content: str | bytes, name: str) -> Path:
    path = FOLDER / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _loads_or_refuses(load: Any, path: Path) -> None:
    try:
        load(path)
    except ValueError as error:
        text = str(error)
        assert text and "\n" not in text.strip(), text
        assert "Traceback" not in text


# ------------------------------------------------------------------ tests

FAST = settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize=False,
)
LONG = settings(FAST, max_examples=2000)


def _protocol(content: str | bytes) -> None:
    # protocols name shipped scenes; one beside them is found relative to the file
    _loads_or_refuses(load_protocol, _write(content, "protocol.toml"))


def _scene(content: str | bytes) -> None:
    _loads_or_refuses(load_scene, _write(content, "scene.toml"))


@FAST
@given(mutated(PROTOCOLS))
def test_mutated_protocols_load_or_are_refused_in_one_line(content: str | bytes) -> None:
    _protocol(content)


@FAST
@given(mutated(SCENES))
def test_mutated_scenarios_load_or_are_refused_in_one_line(content: str | bytes) -> None:
    _scene(content)


@pytest.mark.slow
@LONG
@given(mutated(PROTOCOLS))
def test_mutated_protocols_long_run(content: str | bytes) -> None:
    _protocol(content)


@pytest.mark.slow
@LONG
@given(mutated(SCENES))
def test_mutated_scenarios_long_run(content: str | bytes) -> None:
    _scene(content)


def _scene_checked(path: Path) -> None:
    """What ``asa scenario show`` and ``asa scenario check`` do with a file."""
    from sim.check import check_scene
    from sim.semantics import derive_components

    scene = load_scene(path)
    components = derive_components(scene)
    check_scene(scene, components=components)


@pytest.mark.slow
@settings(FAST, max_examples=300)
@given(mutated(SCENES))
def test_mutated_scenarios_that_load_can_be_checked(content: str | bytes) -> None:
    """A mutated scene that loads also has its components derived and is checked."""
    _loads_or_refuses(_scene_checked, _write(content, "scene.toml"))


def test_the_writer_round_trips_every_shipped_file() -> None:
    """The fuzzer's TOML writer keeps an unmutated file's content."""
    for path in (*PROTOCOLS, *SCENES):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        assert tomllib.loads(dumps(data)) == data
