"""The messages between the study server and the participant's page: this module is their
specification (``static/messages.js`` mirrors it; docs/decisions.md, "Participants in a
browser"). Frequent messages are binary, little-endian; rare ones JSON text.

Server to page (binary; the first byte is the type):

- ``STATE`` (20 Hz): type, flags (bit 0 paused), number of laser hits *n* (uint16), tick
  (uint32: the trial's count of ``act`` calls), simulated time [s], estimated pose x, y
  [m], yaw [rad], stick (forwards, left, turn left) in [-1, 1] (float32 each), then *n*
  hits (x, y) in the map frame as int16 centimetres. 36 + 4 n bytes.
- ``CAMERA``: type, which (0 front, 1 tail), 2 bytes zero, tick (uint32), a JPEG image.
- ``MAP`` (once per scenario): type, 3 bytes zero, map id (uint32), columns, rows (uint16),
  resolution [m], origin x, y [m] (float32), then rows x columns cells (uint8: 0 free,
  1 question region, 2 occupied), row 0 at the origin's y.

Page to server (binary):

- ``INPUT`` (32 bytes): type, flags (bit 0 a gamepad is connected), the standard-mapping
  gamepad's buttons 0-15 pressed (uint16 bits), sequence number (uint32, rising), the last
  tick the page drew (uint32), the four standard axes (left x, left y, right x, right y,
  float32 in [-1, 1]), the keys held (uint32 bits of :data:`KEYS`).

JSON text both ways carries a ``type``; :func:`client_json` accepts only the page's types
(:data:`CLIENT_TYPES`) with their fields checked. A message that fails is dropped and
counted, never trusted.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

STATE, CAMERA, MAP = 1, 2, 3  # server -> page
INPUT = 1  # page -> server
STATE_HEAD = struct.Struct("<BBHIfffffff")  # 36 bytes
CAMERA_HEAD = struct.Struct("<BBHI")  # 8 bytes
MAP_HEAD = struct.Struct("<BBHIHHfff")  # 24 bytes
INPUT_FORMAT = struct.Struct("<BBHIIffffI")  # 32 bytes
MAX_BINARY = 64  # [bytes] the longest binary message a page may send
MAX_TEXT = 2048  # [bytes] the longest JSON message a page may send
MAX_POINTS = 4000  # laser hits in one state message
# the keys the page reports as held: the protocol's [input.keys] actions, then the
# arrows and Enter of pages and forms (the page maps the protocol's letters to these)
KEYS = (
    "forward",
    "back",
    "left",
    "right",
    "turn_left",
    "turn_right",
    "yes",
    "no",
    "pause",
    "arrow_up",
    "arrow_down",
    "arrow_left",
    "arrow_right",
    "enter",
)
CLIENT_TYPES = ("pong", "check", "key", "click", "visibility", "focus", "hello")
CLICK_TARGETS = ("page", "option", "fraction", "row", "done", "pair")
FORM_KEYS = tuple("0123456789") + ("Backspace",)


@dataclass(frozen=True, slots=True)
class InputMessage:
    """One ``INPUT`` from the page, checked."""

    seq: int
    last_tick: int  # the last state tick the page drew
    gamepad: bool  # a gamepad is connected
    buttons: int  # standard-mapping buttons 0-15 pressed (bits)
    axes: tuple[float, float, float, float]  # left x, left y, right x, right y in [-1, 1]
    keys: int  # KEYS held (bits)

    def held(self) -> set[str]:
        """The names of the keys held."""
        return {name for i, name in enumerate(KEYS) if self.keys >> i & 1}


def pack_state(
    tick: int, t: float, pose: tuple[float, float, float], stick: np.ndarray, points: np.ndarray,
    *, paused: bool,
) -> bytes:  # fmt: skip
    """A ``STATE`` message; ``points`` (k, 2) [m] in the map frame (at most
    :data:`MAX_POINTS`, the rest dropped)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)[:MAX_POINTS]
    cm = np.clip(np.round(pts * 100.0), -32768, 32767).astype("<i2")
    head = STATE_HEAD.pack(
        STATE, 1 if paused else 0, len(cm), tick & 0xFFFFFFFF, t, *pose,
        *(float(v) for v in stick[:3]),
    )  # fmt: skip
    return head + cm.tobytes()


def unpack_state(data: bytes) -> dict[str, Any]:
    """Inverse of :func:`pack_state` (tests; the page's reader mirrors it)."""
    kind, flags, n, tick, t, x, y, yaw, s0, s1, s2 = STATE_HEAD.unpack_from(data)
    pts = np.frombuffer(data, dtype="<i2", offset=STATE_HEAD.size, count=2 * n)
    return {
        "tick": tick, "t": t, "pose": (x, y, yaw), "stick": (s0, s1, s2),
        "paused": bool(flags & 1), "points": pts.reshape(-1, 2) / 100.0,
    }  # fmt: skip


def pack_camera(tick: int, which: str, jpeg: bytes) -> bytes:
    """A ``CAMERA`` message: ``which`` "front" or "tail"."""
    return CAMERA_HEAD.pack(CAMERA, 1 if which == "tail" else 0, 0, tick & 0xFFFFFFFF) + jpeg


def pack_map(
    map_id: int, cells: np.ndarray, resolution: float, origin: tuple[float, float]
) -> bytes:
    """A ``MAP`` message: ``cells`` (rows, cols) uint8 (0 free, 1 region, 2 occupied)."""
    rows, cols = cells.shape
    head = MAP_HEAD.pack(MAP, 0, 0, map_id, cols, rows, resolution, origin[0], origin[1])
    return head + np.ascontiguousarray(cells, dtype=np.uint8).tobytes()


def pack_input(
    seq: int, last_tick: int, axes: tuple[float, ...], *, buttons: int = 0, keys: int = 0,
    gamepad: bool = False,
) -> bytes:  # fmt: skip
    """An ``INPUT`` message as the page packs it (tests and benchmarks)."""
    return INPUT_FORMAT.pack(INPUT, 1 if gamepad else 0, buttons, seq, last_tick, *axes, keys)


def unpack_input(data: bytes) -> InputMessage:
    """An ``INPUT`` checked: its length, type, flags and finite axes within [-1, 1];
    raises ``ValueError`` naming what is wrong."""
    if len(data) != INPUT_FORMAT.size:
        raise ValueError(f"input: {len(data)} bytes, expected {INPUT_FORMAT.size}")
    kind, flags, buttons, seq, last_tick, a0, a1, a2, a3, keys = INPUT_FORMAT.unpack(data)
    if kind != INPUT:
        raise ValueError(f"input: type {kind}, expected {INPUT}")
    if flags > 1 or keys >> len(KEYS):
        raise ValueError("input: unknown flag or key bits")
    axes = (a0, a1, a2, a3)
    if not all(math.isfinite(a) and -1.0001 <= a <= 1.0001 for a in axes):
        raise ValueError("input: an axis is not a number in [-1, 1]")
    clipped = tuple(max(-1.0, min(1.0, a)) for a in axes)
    return InputMessage(seq, last_tick, bool(flags & 1), buttons, clipped, keys)  # type: ignore[arg-type]


def _integer(msg: dict[str, Any], key: str, lo: int, hi: int) -> int:
    value = msg.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ValueError(f"{msg.get('type')}: field {key!r} must be an integer {lo}-{hi}")
    return value


def client_json(text: str) -> dict[str, Any]:
    """A JSON message from the page, checked field by field; raises ``ValueError``."""
    if len(text) > MAX_TEXT:
        raise ValueError(f"text: {len(text)} characters, at most {MAX_TEXT}")
    try:
        msg = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"text: not JSON ({error.msg})") from None
    if not isinstance(msg, dict) or msg.get("type") not in CLIENT_TYPES:
        raise ValueError("text: not a message of the page")
    kind = msg["type"]
    if kind == "pong":
        return {"type": kind, "id": _integer(msg, "id", 0, 2**31)}
    if kind == "key":
        if msg.get("key") not in FORM_KEYS:
            raise ValueError("key: field 'key' must be a digit or Backspace")
        return {"type": kind, "key": msg["key"]}
    if kind == "click":
        return _click(msg)
    if kind in ("visibility", "focus"):
        field = "hidden" if kind == "visibility" else "focused"
        if not isinstance(msg.get(field), bool):
            raise ValueError(f"{kind}: field {field!r} must be true or false")
        return {"type": kind, field: msg[field]}
    if kind == "hello":
        return {"type": kind}
    return _check(msg)


def _click(msg: dict[str, Any]) -> dict[str, Any]:
    target = msg.get("target")
    if target not in CLICK_TARGETS:
        raise ValueError(f"click: field 'target' must be one of {', '.join(CLICK_TARGETS)}")
    out: dict[str, Any] = {"type": "click", "target": target}
    if target in ("option", "fraction", "row"):
        out["row"] = _integer(msg, "row", 0, 200)
    if target in ("option", "pair"):
        out["index"] = _integer(msg, "index", 0, 200)
    if target == "fraction":
        f = msg.get("fraction")
        if isinstance(f, bool) or not isinstance(f, int | float) or not 0.0 <= f <= 1.0:
            raise ValueError("click: field 'fraction' must be a number in [0, 1]")
        out["fraction"] = float(f)
    return out


def _check(msg: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {"type": "check"}
    out["width"] = _integer(msg, "width", 0, 100_000)
    out["height"] = _integer(msg, "height", 0, 100_000)
    for key in ("mobile", "gamepad"):
        if not isinstance(msg.get(key), bool):
            raise ValueError(f"check: field {key!r} must be true or false")
        out[key] = msg[key]
    agent = msg.get("agent", "")
    out["agent"] = agent[:200] if isinstance(agent, str) else ""
    return out


def server_json(kind: str, **fields: Any) -> str:
    """A JSON message to the page."""
    return json.dumps({"type": kind, **fields}, separators=(",", ":"))
