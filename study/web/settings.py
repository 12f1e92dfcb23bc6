"""The protocol's ``[web]`` table: how a session run from a browser link behaves (issue 37;
docs/decisions.md, "Participants in a browser"). Plain data, read without aiohttp.

``[web]`` grace_s (60: how long a dropped connection may stay away before the session is
aborted, resumable), silent_s (1: a page that sends nothing for this long while driving
counts as gone), stale_ticks (4: an input older than this many ticks is stale),
latency_gate_ms (250: the highest median round trip of the check's pings), pings (20),
gamepad (false: the check asks for a gamepad button), min_window ([1024, 600] px),
camera_hz (10: camera frames a second to the page), completion_code and completion_url
(shown or followed once the session is stored).
"""

from __future__ import annotations

from dataclasses import dataclass

from sim.fields import FieldReader

MAX_GRACE_S = 3600.0


@dataclass(frozen=True, slots=True)
class WebSettings:
    """A browser session's settings (the protocol's ``[web]``)."""

    grace_s: float = 60.0  # [s] a dropped connection resumes within this
    silent_s: float = 1.0  # [s] no message for this long while driving: gone
    stale_ticks: int = 4  # an input older than this many ticks is stale
    latency_gate_ms: float = 250.0  # [ms] highest median round trip of the check
    pings: int = 20  # pings of the latency check
    gamepad: bool = False  # the check asks for a gamepad button press
    min_window: tuple[int, int] = (1024, 600)  # [px] the smallest page accepted
    camera_hz: float = 10.0  # [Hz] camera frames to the page (latest wins)
    completion_code: str = ""  # shown on the end page once the session is stored
    completion_url: str = ""  # https:// address the end page goes to (e.g. Prolific's)


def _boolean(r: FieldReader, key: str, default: bool) -> bool:
    r.used.add(key)
    value = r.data.get(key, default)
    if not isinstance(value, bool):
        raise r.fail(key, f"must be true or false, got {value!r}")
    return value


def _window(r: FieldReader) -> tuple[int, int]:
    r.used.add("min_window")
    value = r.data.get("min_window", [1024, 600])
    ok = isinstance(value, list) and len(value) == 2
    if not ok or not all(isinstance(v, int) and 200 <= v <= 10000 for v in value):
        raise r.fail("min_window", f"must be [width, height] in px, 200-10000, got {value!r}")
    return (value[0], value[1])


def web_settings(r: FieldReader) -> WebSettings:
    """The ``[web]`` table read by ``r`` (the defaults without one)."""
    url = r.string("completion_url", "")
    if url and not url.startswith("https://"):
        raise r.fail("completion_url", f"must start with https://, got {url!r}")
    s = WebSettings(
        grace_s=r.number("grace_s", 60.0, positive=True, maximum=MAX_GRACE_S),
        silent_s=r.number("silent_s", 1.0, positive=True, maximum=60.0),
        stale_ticks=r.integer("stale_ticks", 4, minimum=1, maximum=200),
        latency_gate_ms=r.number("latency_gate_ms", 250.0, positive=True, maximum=10_000.0),
        pings=r.integer("pings", 20, minimum=1, maximum=200),
        gamepad=_boolean(r, "gamepad", False),
        min_window=_window(r),
        camera_hz=r.number("camera_hz", 10.0, non_negative=True, maximum=30.0),
        completion_code=r.string("completion_code", ""),
        completion_url=url,
    )
    r.finish()
    return s
